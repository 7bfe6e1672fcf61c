"""The command line checked against the configs before Hydra sees it: every ``GROUP=OPTION`` and
``GROUP.KEY=VALUE`` of a ``CommandLine`` refused in one sentence where airl has no such option or key
(Hydra would print its search path, or advise ``+KEY`` and run without reading it), read from the
YAML files themselves (milliseconds), not by composing the config; once per command (``checked``).
"""

from __future__ import annotations

import difflib
import re
from pathlib import Path

import yaml

from airl_cli.errors import ConfigError, refuse
from airl_cli.io.files import writable_problem
from airl_cli.settings.overrides import RENAMED_KEYS, CommandLine
from airl_cli.settings.paths import conf_dir
from airl_cli.settings.problem_defaults import with_problem_defaults


def config_groups() -> dict[str, list[str]]:
    """Config group -> its options, read from the packaged ``conf/`` folder."""
    root = Path(conf_dir())
    groups: dict[str, list[str]] = {}
    for entry in sorted(root.iterdir(), key=lambda e: e.name):
        if entry.is_dir() and not entry.name.startswith(("_", ".")) and entry.name != "hydra":
            options = sorted(e.name[:-5] for e in entry.iterdir() if e.name.endswith(".yaml") and not e.name.startswith("_"))
            if options:
                groups[entry.name] = options
    return groups


def experiment_titles() -> dict[str, str]:
    """Experiment name -> its title, from the packaged ``conf/experiment/`` group (``airl sweep --help``)."""
    root = Path(conf_dir()) / "experiment"
    titles = {}
    for name in config_groups().get("experiment", []):
        data, _ = _yaml(root / f"{name}.yaml")
        experiment = data.get("experiment") if isinstance(data.get("experiment"), dict) else {}
        title = str(experiment.get("title") or "")  # its own ${experiment.KEY}s filled in, as Hydra would
        titles[name] = re.sub(r"\$\{experiment\.(\w+)\}", lambda m: str(experiment.get(m.group(1), m.group(0))), title)
    return titles


def checked(job: str, overrides: CommandLine | list[str]) -> CommandLine:
    """The command line of ``airl JOB`` checked before Hydra sees it, once: a problem's own dynamics
    added (fit, generate), then every ``GROUP=OPTION`` and every key refused in one sentence if
    airl has no such option or key (``check_group_choices``, ``check_keys``). A command line
    checked already is returned as it is (a sweep's jobs).

    Raises:
        ConfigError: the one sentence (the command line says it and exits 2, the API raises it).
    """
    line = CommandLine.of(overrides)
    if line.checked:
        return line
    if job in ("fit", "generate"):  # a problem picked on the command line brings its own dynamics
        line = with_problem_defaults(line)
    check_group_choices(line)
    check_keys(line, "airl_plan" if job == "plan" else "airl")
    return CommandLine(line.items, checked=True)


#: Hydra's own group options that an extra of airl's installs (pyproject.toml's optional dependencies).
PLUGIN_EXTRAS = {("hydra/launcher", "ray"): "ray", ("hydra/launcher", "submitit_slurm"): "cluster", ("hydra/launcher", "submitit_local"): "cluster"}


def check_group_choices(line: CommandLine) -> None:
    """Refuse ``GROUP=OPTION`` with an unknown OPTION in one sentence (Hydra would print its search path)."""
    groups = config_groups()
    for o in line.items:
        if o.sets and o.key.startswith("hydra/") and o.key not in groups:  # Hydra's own groups (hydra/launcher)
            from airl_cli.settings.hydra_internals import hydra_group_options

            groups[o.key] = hydra_group_options(o.key, conf_dir())
            if not groups[o.key]:
                raise ConfigError(f"'{o.key}' is not a config group of Hydra's (hydra/launcher, hydra/sweeper, ... ; see airl fit --help)")
        if not o.sets or o.key not in groups or o.value.startswith(("choice(", "range(", "glob(")):
            continue
        for option in o.value.split(","):
            if option and option not in groups[o.key] and (o.key, option) in PLUGIN_EXTRAS:
                extra = PLUGIN_EXTRAS[o.key, option]
                raise ConfigError(f"{o.key}={option} needs its Hydra plugin, which airl's extra '{extra}' installs: pip install \".[{extra}]\" in airl's folder")
            if option and option not in groups[o.key]:
                raise ConfigError(f"'{option}' is not an option of the config group '{o.key}'; choose one of: {', '.join(groups[o.key])}")
    _check_problem_choice(line)


def _check_problem_choice(line: CommandLine) -> None:
    """Refuse ``problem=NAME`` beside a choice it would be merged into or lost under, in one sentence.

    A problem (``conf/problem/``) picks the mdp and dynamics groups and sets their values; beside
    ``mdp=``/``dynamics=`` its values would land in another problem's settings, beside ``data=`` it
    would not be read, and an experiment that does not sweep problems (``hydra.sweeper.params``) has
    its own problem, which would silently win over it or ignore it.
    """
    chosen = line.chosen
    problem = chosen.get("problem")
    if problem in (None, "", "null"):
        return
    clash = [f"{k}=" for k in ("mdp", "dynamics", "data") if k in chosen]
    if clash:
        raise ConfigError(
            f"'problem={problem}' picks the problem and its dynamics itself; drop {' and '.join(clash)} "
            "(change its values with mdp.KEY=VALUE or dynamics.KEY=VALUE), or drop problem="
        )
    path = Path(conf_dir()) / "experiment" / f"{chosen.get('experiment')}.yaml"
    params = ((_yaml(path)[0].get("hydra") or {}).get("sweeper") or {}).get("params") or {} if path.is_file() else None
    if params is not None and "problem" not in params:  # an experiment that does not sweep problems has its own
        raise ConfigError(f"'experiment={chosen['experiment']}' picks its own problem; drop problem={problem} (experiment=transfer sweeps the problems of conf/problem/)")


def _yaml(path: Path) -> tuple[dict, bool]:
    """A config file's mapping, and whether it is in the global package (``# @package _global_``)."""
    text = path.read_text()
    return (yaml.safe_load(text) or {}), "@package _global_" in text.split("\n", 1)[0]


def _known_keys(line: CommandLine, primary_name: str = "airl") -> tuple[dict[str, tuple[str, list[str] | None]], list[str]]:
    """Per config group, (its chosen option, its keys or None if unknown); and the top-level keys.

    Read from the YAML files themselves (milliseconds), not by composing the config (0.2-0.4 s).
    """
    root = Path(conf_dir())
    primary, _ = _yaml(root / f"{primary_name}.yaml")
    chosen: dict[str, str | None] = {}
    for entry in primary.get("defaults", []):
        if isinstance(entry, dict):
            for key, value in entry.items():
                if not key.startswith("override "):
                    chosen[key] = value
    groups = config_groups()
    on_command_line = {o.key: o.value.split(",")[0] for o in line.items if o.sets and o.key in groups}
    # a problem, an experiment or a variant picks its own options (``override /mdp: gymnasium``);
    # the command line's win
    for bundle in ("problem", "experiment", "variant"):
        path = root / bundle / f"{on_command_line.get(bundle, chosen.get(bundle))}.yaml"
        for entry in _yaml(path)[0].get("defaults", []) if path.is_file() else []:
            for key, value in (entry.items() if isinstance(entry, dict) else ()):
                if key.startswith("override /"):
                    chosen[key.removeprefix("override /")] = value
    chosen.update(on_command_line)
    known: dict[str, tuple[str, list[str] | None]] = {}
    for group, option in chosen.items():
        path = root / group / f"{option}.yaml"
        if option is None or group not in groups or not path.is_file():
            continue
        data, is_global = _yaml(path)
        known[group] = (str(option), None if is_global else [str(k) for k in data if k != "defaults"])
    used = [g for g in groups if g in chosen]
    top = [str(k) for k in primary if k != "defaults"] + used
    return known, list(dict.fromkeys(top))


def check_keys(line: CommandLine, primary: str = "airl") -> None:
    """Refuse ``GROUP.KEY=VALUE`` for a KEY the group does not have, in one sentence.

    Hydra would advise ``+GROUP.KEY=VALUE``, which adds a key no code reads: the run goes ahead
    and silently ignores it. So ``+GROUP.KEY`` of a key airl does not know is refused too.
    Keys of the experiment and profile groups, which set values across groups, are left to Hydra.

    Raises:
        ConfigError: the sentence (the key, the group's real keys, the closest).
    """
    groups = config_groups()
    values = [o for o in line.tasks if o.sets and not o.prefix.startswith("~") and o.key not in groups]
    if not values:
        return
    known, top = _known_keys(line, primary)
    for o in values:
        name = o.key
        parts = name.split(".")
        adds = " (a leading + would add a key that airl never reads)" if o.prefix.startswith("+") else ""
        if len(parts) == 1:
            if name in top:
                continue
            close = difflib.get_close_matches(name, top, n=1, cutoff=0.7)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise ConfigError(f"'{name}' is not a setting{adds}; {hint}the top-level keys are: {', '.join(top)}")
        group, leaf = parts[0], parts[1]
        if group not in known and group not in top:
            close = difflib.get_close_matches(group, list(known), n=1)
            hint = f"did you mean '{close[0]}'? " if close else ""
            raise ConfigError(f"'{name}' names no setting: '{group}' is not a config group; {hint}the groups are: {', '.join(known)}")
        option, keys = known.get(group, ("", None))
        if keys is None or leaf in keys:
            continue
        close = difflib.get_close_matches(leaf, keys, n=1, cutoff=0.7)
        hint = f"did you mean '{group}.{close[0]}'? " if close else ""
        raise ConfigError(RENAMED_KEYS.get(name) or f"'{name}' is not a key of the config group '{group}' ({group}={option}){adds}; {hint}its keys are: {', '.join(keys)}")


def check_output_folder(line: CommandLine, *, multirun: bool) -> None:
    """Refuse, in one sentence, an output folder that cannot be written (before Hydra makes it)."""
    key = "hydra.sweep.dir" if multirun else "hydra.run.dir"
    named = [o.unquoted for o in line.items if o.sets and o.key == key]
    folder = named[-1] if named else "results"
    problem = writable_problem(folder)
    if problem is not None:
        refuse(f"cannot write the results to {folder} ({problem}); choose a writable folder with {key}=PATH")
