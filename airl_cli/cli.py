"""The ``airl`` command line: Typer owns the commands and their help, Hydra the configs.

Each command passes its extra arguments, unchanged and in order, to the ``@hydra.main`` app of
its job module (``airl_cli.jobs.<name>``), whose configs are loaded from the installed package
(``airl_cli.conf``, see ``airl_cli.paths``), so ``airl`` works from any folder. Only Hydra's own flags
(``--multirun``, ``--cfg``, ``--resolve``) are added, in front of the overrides.
"""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import typer

from airl_cli.paths import conf_dir

PASS_THROUGH = {"allow_extra_args": True, "ignore_unknown_options": True}


def config_groups() -> dict[str, list[str]]:
    """Config group -> its options, read from the packaged ``conf/`` folder."""
    root = Path(conf_dir())
    groups: dict[str, list[str]] = {}
    for entry in sorted(root.iterdir(), key=lambda e: e.name):
        if entry.is_dir() and not entry.name.startswith(("_", ".")) and entry.name != "hydra":
            options = sorted(e.name[:-5] for e in entry.iterdir() if e.name.endswith(".yaml"))
            if options:
                groups[entry.name] = options
    return groups


def _groups_epilog() -> str:
    lines = ["Config groups (choose with GROUP=OPTION; change a value with GROUP.KEY=VALUE):", "", "\b"]
    lines += [f"  {group:<10} {', '.join(options)}" for group, options in config_groups().items()]
    return "\n".join(lines) + "\n"


EPILOG = _groups_epilog()

app = typer.Typer(
    name="airl",
    help=(
        "Adversarial inverse reinforcement learning with changing dynamics: learn a reward from "
        "sub-optimal demonstrations given under several known dynamics."
    ),
    no_args_is_help=True,
    add_completion=False,
    rich_markup_mode=None,
)


def _version(value: bool) -> None:
    if value:
        from airl_cli import __version__

        typer.echo(f"airl {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(False, "--version", callback=_version, is_eager=True, help="Print the version and exit."),
) -> None:
    """Adversarial inverse reinforcement learning with changing dynamics.

    Every command takes Hydra overrides (GROUP=OPTION, KEY=VALUE) after its options; run
    `airl COMMAND --help` for its config groups and `airl COMMAND --cfg job` to see the config.
    """


def check_group_choices(overrides: list[str]) -> None:
    """Refuse ``GROUP=OPTION`` with an unknown OPTION in one sentence (Hydra would print its search path)."""
    groups = config_groups()
    for item in overrides:
        key, sep, value = item.partition("=")
        key = key.lstrip("+~")
        if not sep or key not in groups or value.startswith(("choice(", "range(", "glob(")):
            continue
        for option in value.split(","):
            if option and option not in groups[key]:
                typer.echo(f"error: '{option}' is not an option of the config group '{key}'; choose one of: {', '.join(groups[key])}", err=True)
                raise typer.Exit(2)


def run_hydra(job: str, overrides: list[str], *, cfg: str | None = None, resolve: bool = False, multirun: bool = False) -> None:
    """Run the Hydra app of ``airl_cli.jobs.<job>`` with these overrides."""
    check_group_choices(overrides)
    module = importlib.import_module(f"airl_cli.jobs.{job}")
    argv = [f"airl {job}"]
    if multirun:
        argv.append("--multirun")
    if cfg is not None:
        argv += ["--cfg", cfg]
    if resolve:
        argv.append("--resolve")
    saved = sys.argv
    sys.argv = argv + list(overrides)
    try:
        module.hydra_main()
    finally:
        sys.argv = saved


CfgOption = typer.Option(None, "--cfg", help="Print the composed config instead of running: job, hydra or all.")
ResolveOption = typer.Option(False, "--resolve", help="With --cfg, resolve interpolations before printing.")
MultirunOption = typer.Option(False, "--multirun", "-m", help="Run once per combination of comma-separated override values.")


@app.command(context_settings=PASS_THROUGH, epilog=EPILOG)
def generate(
    ctx: typer.Context,
    cfg: str | None = CfgOption,
    resolve: bool = ResolveOption,
    multirun: bool = MultirunOption,
) -> None:
    """Build a problem and its demonstrations; write the dataset file and a summary to a run folder.

    Takes Hydra overrides, e.g. mdp=grid dynamics=grid_suboptimal seed=3. The run folder is
    results/generate/<time>/ unless hydra.run.dir=PATH says otherwise.
    """
    run_hydra("generate", ctx.args, cfg=cfg, resolve=resolve, multirun=multirun)


@app.command(context_settings=PASS_THROUGH, epilog=EPILOG)
def fit(
    ctx: typer.Context,
    cfg: str | None = CfgOption,
    resolve: bool = ResolveOption,
    multirun: bool = MultirunOption,
) -> None:
    """Learn reward weights from demonstrations under several dynamics; write weights, metrics and history.

    With data=PATH it learns from a dataset file (ours or yours); without, from the problem the
    mdp/dynamics/demos groups describe, built in-process (and saved as dataset.npz).
    method=airl (default), mce, projection, mmp or bc picks the learner. The run folder is
    results/fit/<time>/ unless hydra.run.dir=PATH says otherwise.
    """
    run_hydra("fit", ctx.args, cfg=cfg, resolve=resolve, multirun=multirun)


@app.command()
def inspect(path: str = typer.Argument(..., help="A dataset file (.npz) of the schema in the README.")) -> None:
    """Check a dataset file against the schema and describe it; exit 2 with the reason if it is bad."""
    from airl_cli.jobs.inspect import main as inspect_main

    inspect_main(path)


def main() -> None:
    """Console-script entry point."""
    app()


if __name__ == "__main__":
    main()
