"""The ``airl`` command line: Typer owns the commands and their help, Hydra the configs.

Each command passes its extra arguments, unchanged and in order, to the ``@hydra.main`` app of
its job module (``airl_cli.jobs.<name>``; ``airl sweep``'s is ``airl_cli.sweep.job``), whose configs
are loaded from the installed package (``airl_cli.conf``, see ``airl_cli.settings.paths``), so ``airl`` works
from any folder. Only Hydra's own flags (``--multirun``, ``--cfg``, ``--resolve``) are added, in
front of the overrides.
"""

from __future__ import annotations

import gc

import typer
from typer.core import TyperCommand

from airl_cli.errors import AirlError, ConfigError, refuse, stop_on_sigterm
from airl_cli.heap import keep_heap_slack
from airl_cli.jobs.launch import quote_paths, run_hydra
from airl_cli.methods import NAMES
from airl_cli.settings.command_line import checked, config_groups
from airl_cli.settings.overrides import CommandLine, syntax_problem

PASS_THROUGH = {"allow_extra_args": True, "ignore_unknown_options": True}


def _groups_epilog() -> str:
    """The config groups, their options and the keys their options have (read from the YAML files)."""
    from pathlib import Path

    import yaml

    from airl_cli.settings.paths import conf_dir

    lines = ["Config groups (choose with GROUP=OPTION; change a value with GROUP.KEY=VALUE):", "", "\b"]
    for group, options in config_groups().items():
        lines.append(f"  {group:<10} {', '.join(options)}")
        keys: dict[str, None] = {}
        for option in options:
            text = (Path(conf_dir()) / group / f"{option}.yaml").read_text()
            if "@package _global_" in text.split("\n", 1)[0]:  # sets values across groups: no keys of its own
                keys = {}
                break
            keys.update(dict.fromkeys(str(k) for k in (yaml.safe_load(text) or {}) if k != "defaults"))
        if keys:
            lines.append(f"  {'':<10} keys: {', '.join(keys)}")
    return "\n".join(lines) + "\n"


EPILOG = _groups_epilog()


def _overrides(ctx: typer.Context) -> CommandLine:
    """The command's Hydra overrides (its extra arguments) as one value, each split once, and
    checked, once (``settings.command_line.checked``: group choices and keys; a problem's own
    dynamics added); refused in one sentence if one is not an override (an unknown option, a word
    without '='), Hydra cannot parse it, a key is set twice, or airl has no such option or key."""
    line = CommandLine.of(ctx.args)
    command = str(ctx.command.name)
    options = [o for p in ctx.command.params for o in getattr(p, "opts", []) if o.startswith("--")]
    problem = syntax_problem(quote_paths(line), command, options + ["--help"])
    if problem is not None:
        refuse(problem)
    try:
        return checked(command, line)
    except ConfigError as err:
        refuse(err)


def _usage_error() -> type[Exception]:
    """The command-line parser's usage error (Typer's own copy of Click's, or Click's in older Typer)."""
    import importlib

    return importlib.import_module(TyperCommand.__mro__[1].__module__.rsplit(".", 1)[0] + ".exceptions").UsageError


class _OneSentenceCommand(TyperCommand):
    """A command of its own options and arguments (inspect, plot, report): a misspelt option or a
    missing argument is one sentence and exit 2, as for the commands that take overrides, not the
    parser's usage block."""

    def parse_args(self, ctx, args):
        try:
            return super().parse_args(ctx, args)
        except _usage_error() as err:
            options = [o for p in self.params for o in getattr(p, "opts", []) if o.startswith("--")] + ["--help"]
            name = getattr(err, "option_name", None)
            if type(err).__name__ == "NoSuchOption":
                refuse(f"'{name}' is not an option of airl {self.name} (its options: {', '.join(options)}; see airl {self.name} --help)")
            message = err.format_message()
            refuse(f"{message[:1].lower()}{message[1:].rstrip('.')} (see airl {self.name} --help)")


class _SweepCommand(TyperCommand):
    """``airl sweep``, whose help ends with the experiments: read from their configs only for ``--help``."""

    def format_epilog(self, ctx, formatter) -> None:
        from airl_cli.settings.command_line import experiment_titles

        titles = experiment_titles()
        width = max(map(len, titles), default=0)
        lines = ["Experiments (choose with experiment=NAME; profile=quick for a small size):", "", "\b"]
        lines += [f"  {name:<{width}}  {title}" for name, title in titles.items()]
        self.epilog = "\n".join(lines) + "\n\n" + EPILOG
        super().format_epilog(ctx, formatter)

app = typer.Typer(
    name="airl",
    help=(
        "Adversarial inverse reinforcement learning with changing dynamics: learn a reward from "
        "sub-optimal demonstrations given under several known dynamics."
    ),
    no_args_is_help=True,
    add_completion=True,  # --install-completion / --show-completion for bash, zsh, fish, PowerShell
    pretty_exceptions_enable=False,
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


CfgOption = typer.Option(None, "--cfg", help="Print the composed config instead of running: job, hydra or all.")
ResolveOption = typer.Option(False, "--resolve", help="With --cfg, resolve interpolations before printing.")
MultirunOption = typer.Option(False, "--multirun", "-m", help="Run once per combination of comma-separated override values.")
ReplaceOption = typer.Option(
    False,
    "--replace",
    help="Let the run go into a folder that holds files (hydra.run.dir, or -m's hydra.sweep.dir): they are removed first (without it such a folder is refused).",
)


@app.command(context_settings=PASS_THROUGH, epilog=EPILOG)
def generate(
    ctx: typer.Context,
    cfg: str | None = CfgOption,
    resolve: bool = ResolveOption,
    multirun: bool = MultirunOption,
    replace: bool = ReplaceOption,
) -> None:
    """Build a problem and its demonstrations; write the dataset file and a summary to a run folder.

    Takes Hydra overrides, e.g. mdp=grid dynamics=grid_suboptimal seed=3. The run folder is
    results/generate/<time>/ unless hydra.run.dir=PATH (a new or empty folder) says otherwise.
    """
    run_hydra("generate", _overrides(ctx), cfg=cfg, resolve=resolve, multirun=multirun, replace=replace)


FIT_HELP = f"""Learn reward weights from demonstrations under several dynamics; write weights, metrics and history.

With data=PATH it learns from a dataset file (ours or yours); without, from the problem the
mdp/dynamics/demos groups describe, built in-process (and saved as dataset.npz).
method={NAMES[0]} (default), {", ".join(NAMES[1:-1])} or {NAMES[-1]} picks the learner. The run folder is
results/fit/<time>/ unless hydra.run.dir=PATH (a new or empty folder) says otherwise.
"""


@app.command(context_settings=PASS_THROUGH, epilog=EPILOG, help=FIT_HELP)
def fit(
    ctx: typer.Context,
    cfg: str | None = CfgOption,
    resolve: bool = ResolveOption,
    multirun: bool = MultirunOption,
    replace: bool = ReplaceOption,
    strict: bool = typer.Option(
        False,
        "--strict",
        help="Exit with status 3 if the fit warns (NOT converged, a degenerate optimum, a learned reward the same everywhere) or its bracket on eq. 5.9's minimum is wider than optim.tol.",
    ),
    verbose: bool = typer.Option(
        False, "--verbose", help="After the summary, what stands behind the certificate: the planner chosen and why, its own gap, the bracket's effort."
    ),
) -> None:
    """``airl fit`` (its help, ``FIT_HELP``, names the methods of the registry)."""
    if (strict or verbose) and multirun:
        refuse(f"{'--strict judges' if strict else '--verbose shows'} one fit; a multirun's jobs run in worker processes (read each job's metrics.json instead)")
    from airl_cli.jobs.fit import VERBOSE, WARNED

    WARNED.clear()  # what an earlier command in this process saw is not this fit's
    VERBOSE[:] = [True] if verbose else []
    run_hydra("fit", _overrides(ctx), cfg=cfg, resolve=resolve, multirun=multirun, replace=replace)
    if strict and cfg is None and WARNED:
        raise typer.Exit(3)


@app.command(context_settings=PASS_THROUGH, cls=_SweepCommand)
def sweep(
    ctx: typer.Context,
    cfg: str | None = CfgOption,
    resolve: bool = ResolveOption,
    plot: bool = typer.Option(True, "--plot/--no-plot", help="Draw the experiment's figures when the sweep is done."),
    partial: bool = typer.Option(
        False, "--partial", help="Run no job: a table and figures of the jobs that have finished (an interrupted sweep's), in FOLDER/partial/."
    ),
) -> None:
    """Run an experiment of thesis chapter 7 (a Hydra multirun on every core), collect its table, draw its figures.

    Takes experiment=NAME and any overrides, e.g. airl sweep experiment=fig05 profile=quick.
    Jobs that finished in an earlier run of the same command, or with the same config in another
    sweep folder beside this one (copied from there), are skipped (--partial: a table
    and figures of those alone, running nothing). The folder is
    results/sweeps/<experiment>-<profile>/ (fig14_15-<profile> for fig14 and fig15, one sweep;
    fig17_18-<profile> for fig17 and fig18) unless hydra.sweep.dir=PATH says otherwise.
    The jobs run on one warm worker per core (hydra.launcher.n_jobs=N for fewer);
    hydra/launcher=basic runs them one by one, hydra/launcher=submitit_slurm on a cluster.
    """
    args = _overrides(ctx)
    from airl_cli.jobs.launch import check_print_options

    check_print_options(cfg, resolve)
    if cfg is not None:  # print the config (Hydra takes --cfg without --multirun)
        from airl_cli.sweep.run import print_config

        print_config(args, cfg=cfg, resolve=resolve)
        return
    from airl_cli.jobs.common import err_console, out_console
    from airl_cli.sweep.run import run

    try:
        status = run(args, draw=plot, console=err_console, out=out_console, partial=partial)
    except AirlError as err:
        refuse(err, err_console)
    raise typer.Exit(status)


@app.command(name="plan", context_settings=PASS_THROUGH)
def plan_command(
    ctx: typer.Context,
    cfg: str | None = CfgOption,
    resolve: bool = ResolveOption,
    multirun: bool = MultirunOption,
    replace: bool = ReplaceOption,
) -> None:
    """Solve a multi-model MDP (the chapter-6 planner on its own, or WSU, MVP, CADP); write the policy and its returns.

    Takes plan.input=PATH (a folder of training.csv, initial.csv, [test.csv], [parameters.csv],
    or an .npz) and overrides such as plan.method=cadp plan.horizon=50 plan.iterations=8.
    The run folder is results/plan/<time>/ unless hydra.run.dir=PATH (a new or empty folder) says otherwise.
    """
    run_hydra("plan", _overrides(ctx), cfg=cfg, resolve=resolve, multirun=multirun, replace=replace)


@app.command(cls=_OneSentenceCommand)
def plot(
    folder: str = typer.Argument(..., help="A sweep folder (results/sweeps/NAME-PROFILE) or a fit's run folder (results/fit/TIME)."),
) -> None:
    """Draw a sweep's figure(s) from its results table, or a fit's convergence, as PNG and PDF into FOLDER/figures/.

    For a fit (optim=exact) the bounds on the objective per iteration and the relative gap against
    the tolerance; for optim=gradient the objective per step and the gradient's norm; for a
    comparison method the columns of its history.csv.
    """
    from pathlib import Path

    from airl_cli.io.files import describe_os_error
    from airl_cli.io.run_folder import read_experiment
    from airl_cli.jobs.common import err_console, out_console
    from airl_cli.readings.plotting import draw_folder
    from airl_cli.settings.experiments import study_siblings

    try:
        paths = draw_folder(folder, siblings=study_siblings(read_experiment(folder) or {}) if Path(folder).is_dir() else [])
    except (ValueError, FileNotFoundError) as err:
        refuse(err, err_console)
    except OSError as err:
        refuse(f"cannot write the figures ({describe_os_error(err)})", err_console)
    for path in paths:
        out_console.print(f"figure {path}", soft_wrap=True)


@app.command(cls=_OneSentenceCommand)
def report(
    folder: str = typer.Argument("results/sweeps", help="The folder holding the sweep folders (<experiment>-full/ ...)."),
    out: str = typer.Option("results/report", "--out", "-o", help="Where to write results.md, claims.md, claims.json and figures/."),
    profile: str = typer.Option("full", "--profile", help="Report the sweeps of this profile: full or quick."),
    replace: bool = typer.Option(False, "--replace", help="Write the report even if it drops experiments or claims that OUT reports."),
) -> None:
    """Write the claims table, results.md and the figures of chapter 7 from finished sweeps.

    Reads every <experiment>-full/results.csv under FOLDER (and the variants <experiment>-full-<overrides>/),
    computes each experiment's numbers, the method x experiment table and the claims table (each claim of
    the thesis with its verdict under each reading), and copies the sweeps' PNG figures. The claims
    table goes between the marker lines of OUT/README.md if it has them (experiments/README.md does),
    else into OUT/claims.md; the claims' numbers, one by one, into OUT/claims.json. A report from fewer
    sweeps than OUT reports is refused, naming what it would drop, unless --replace.
    """
    from airl_cli.io.files import describe_os_error
    from airl_cli.jobs.common import err_console, out_console
    from airl_cli.readings.report import make_report

    try:
        paths = make_report(folder, out, profile, replace=replace)
    except AirlError as err:
        refuse(err, err_console)
    except OSError as err:
        refuse(f"cannot write the report ({describe_os_error(err)})", err_console)
    # make_report writes the figures, then results.md, claims.json and the claims table
    n = len(paths) - 3
    out_console.print(f"wrote {paths[-3]}, {paths[-1]}, the claims' numbers {paths[-2]} and {n} figure{'' if n == 1 else 's'}", soft_wrap=True)


@app.command(cls=_OneSentenceCommand)
def inspect(path: str = typer.Argument(..., help="A dataset file (.npz) of the schema in docs/own-problem.md, 'The dataset file'.")) -> None:
    """Check a dataset file against the schema and describe it; exit 2 with the reason if it is bad."""
    from airl_cli.jobs.inspect import main as inspect_main

    inspect_main(path)


def main() -> None:
    """Console-script entry point."""
    stop_on_sigterm()  # kill PID stops a run as Ctrl-C does: one sentence, no half run folder
    keep_heap_slack()  # a fit's per-step arrays reuse freed pages (airl_cli.heap)
    try:
        app()
    finally:
        # the objects left are freed at exit without a cyclic collection over every imported
        # module (numba, scipy, pandas, matplotlib): the exit takes 0.03 s instead of 0.3 s
        gc.freeze()


if __name__ == "__main__":
    main()
