"""A sweep's folder: one owner, one configuration.

A sweep folder holds the jobs of one experiment with one set of settings (``sweep.json``), and
one ``airl sweep`` at a time writes into it (an advisory lock). These are the checks that keep a
resumed sweep from mixing its rows with another sweep's (``airl_cli.sweep.run``).
"""

from __future__ import annotations

import fcntl
import json
import os
import socket
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from omegaconf import OmegaConf

from airl_cli.errors import ConfigError
from airl_cli.io.files import writable_problem, write_json
from airl_cli.io.results_table import TABLE
from airl_cli.io.run_folder import EXPERIMENT_FILE, INCOMPLETE
from airl_cli.readings.summaries import summary_of
from airl_cli.sweep.spec import ROWS, SweepPlan  # noqa: F401 (ROWS: part of the interface)

SETTINGS = "sweep.json"
LOCK = ".lock"
#: Keys of an experiment that only label it (titles, axes) or list what it sweeps (the swept values
#: name the job folders): a resumed run need not agree on them.
NOT_COMPARED = frozenset(
    ["experiment.title", "experiment.thesis", "experiment.figures", "experiment.x_label", "experiment.x_log"]
    + ["experiment.runs", "experiment.values", "experiment.methods"]
)


def _flatten(node: Any, prefix: str = "") -> dict[str, Any]:
    if isinstance(node, dict):
        out: dict[str, Any] = {}
        for k, v in node.items():
            out.update(_flatten(v, f"{prefix}{k}."))
        return out
    return {prefix[:-1]: node}


def same_job(saved: dict, config: dict) -> bool:
    """Whether two jobs' plain configs make the same rows: equal but for the experiment's labels
    (``NOT_COMPARED``) and its name, which two experiments of one study (fig14, fig15) share jobs under."""
    ignore = NOT_COMPARED | {"experiment.name"}
    a, b = _flatten(saved), _flatten(config)
    return {k: v for k, v in a.items() if k not in ignore} == {k: v for k, v in b.items() if k not in ignore}


def shared_settings(config: dict, swept: tuple[str, ...]) -> dict[str, Any]:
    """Every leaf setting of a job's plain config (dotted key -> value) but the swept keys and the
    experiment's labels, JSON-normalised (tuples become lists)."""
    flat = _flatten(config)
    keep = {k: v for k, v in sorted(flat.items()) if k not in swept and k not in NOT_COMPARED}
    return json.loads(json.dumps(keep))



@contextmanager
def claim(folder: Path) -> Iterator[Callable[[], None]]:
    """Hold the sweep folder for this process: a second ``airl sweep`` into it is refused.

    An advisory ``flock`` on ``FOLDER/.lock``; the kernel drops it when the process ends, even on
    SIGKILL, so a killed sweep never leaves a stale lock behind. Yields ``own``: called once the
    sweep is accepted, it writes this process into the lock file (which a refused sweep leaves as
    it was: the earlier owner's line).

    Raises:
        ConfigError: another process holds the folder.
    """
    try:
        folder.mkdir(parents=True, exist_ok=True)
        handle = open(folder / LOCK, "a+")  # noqa: SIM115 (held until the sweep ends)
    except OSError as err:
        raise ConfigError(unwritable(folder, err)) from None
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        handle.seek(0)
        owner = handle.read().strip() or "unknown"
        handle.close()
        raise ConfigError(
            f"{folder} is in use by another airl sweep (process {owner}); wait for it to finish, or choose another folder with hydra.sweep.dir=PATH"
        ) from None

    def own() -> None:
        handle.seek(0)
        handle.truncate()
        handle.write(f"{os.getpid()} on {socket.gethostname()}\n")
        handle.flush()

    try:
        yield own
    finally:
        fcntl.flock(handle, fcntl.LOCK_UN)
        handle.close()


def check_writable(folder: Path) -> None:
    """Refuse, before anything is marked or written, a sweep folder whose table or figures cannot be
    written (a refused sweep changes nothing: it used to mark a finished sweep ``INCOMPLETE``).

    Raises:
        ConfigError: naming the folder and why.
    """
    for where in (folder, folder / "figures"):
        problem = writable_problem(where) if where.is_dir() else None
        if problem is not None:
            raise ConfigError(f"cannot write to {where} ({problem}); choose a writable folder with hydra.sweep.dir=PATH")


def unwritable(folder: Path, err: OSError) -> str:
    """One sentence for a folder that cannot be written."""
    reason = (err.strerror or str(err)).lower()
    return f"cannot write to {folder} ({reason}); choose a writable folder with hydra.sweep.dir=PATH"


def _stored_settings(sweep: SweepPlan) -> tuple[dict, str] | None:
    """The settings an earlier run into this folder used, and where they were read from."""
    record = sweep.folder / SETTINGS
    try:
        settings = json.loads(record.read_text())["settings"]
        if isinstance(settings, dict):
            return settings, str(record)
    except (OSError, ValueError, KeyError, TypeError):
        pass  # absent or damaged (this run writes it anew): the jobs' configs tell
    # a folder from before sweep.json: any finished job's config tells
    for job in sorted(p.parent for p in sweep.folder.glob(f"*/{ROWS}")):
        try:
            config = OmegaConf.to_container(OmegaConf.load(job / "config.yaml"), resolve=False)
        except Exception:  # absent or damaged: that job runs again  # noqa: BLE001
            continue
        if isinstance(config, dict):
            return shared_settings(config, sweep.swept), str(job / "config.yaml")
    return None


def check_folder(sweep: SweepPlan) -> None:
    """Refuse to resume into a folder whose finished jobs ran with other settings.

    Job folders are named by the swept values only, so a folder of another experiment (or of the
    same one with another setting) would otherwise pass its rows off as this sweep's.

    Raises:
        ConfigError: naming the first setting that differs.
    """
    stored = _stored_settings(sweep)
    if stored is None:
        check_keeps_the_table(sweep)
        return
    before, source = stored
    before = {k: v for k, v in before.items() if k not in NOT_COMPARED and k not in sweep.swept}
    # a key on one side only was swept there (it names that run's job folders) or is new
    differ = sorted(k for k in before.keys() & sweep.settings.keys() if before[k] != sweep.settings[k])
    if before.get("experiment.study") == sweep.settings.get("experiment.study"):
        differ = [k for k in differ if k != "experiment.name"]  # one study, two figures (fig14 and fig15)
    if not differ:
        check_keeps_the_table(sweep)
        return
    # the experiment's name first, then the settings of the problem and the learner
    key = min(differ, key=lambda k: (k != "experiment.name", k.startswith("experiment."), k))
    was, now = before[key], sweep.settings[key]
    more = f" (and {len(differ) - 1} other setting{'s' if len(differ) > 2 else ''})" if len(differ) > 1 else ""
    raise ConfigError(
        f"{sweep.folder} holds a sweep run with {key}={_show(was)}{more} (see {source}), but this one has {key}={_show(now)}; "
        "choose another folder with hydra.sweep.dir=PATH, or remove that one to start over"
    )


#: The files a sweep writes at the top of its folder (beside its job folders).
SWEEP_FILES = frozenset([SETTINGS, LOCK, INCOMPLETE, TABLE, EXPERIMENT_FILE, "multirun.yaml", "figures", "partial"])


def check_not_foreign(sweep: SweepPlan) -> None:
    """Refuse a folder that holds another kind of run's files (an ``airl generate`` or ``airl fit``
    folder: a dataset, a summary, Hydra's ``.hydra``): a sweep never mixes its files with theirs.

    Raises:
        ConfigError: naming what is there.
    """
    if not sweep.folder.is_dir():
        return
    own = SWEEP_FILES | set(summary_of(sweep.experiment).sweep_files)  # fig02_03's alphas.npz: what its figure draws
    foreign = sorted(p.name for p in sweep.folder.iterdir() if p.name not in own and (not p.is_dir() or p.name == ".hydra"))
    if foreign:
        shown = ", ".join(foreign[:4]) + (f" and {len(foreign) - 4} more" if len(foreign) > 4 else "")
        raise ConfigError(
            f"{sweep.folder} holds {shown}, which no airl sweep writes; a sweep never mixes its files with another run's: "
            "choose another folder with hydra.sweep.dir=PATH"
        )


def check_keeps_the_table(sweep: SweepPlan) -> None:
    """Refuse a sweep whose jobs do not include every job already finished in its folder: its table
    (written from its own jobs) would replace a larger one without a word. The same jobs, or more,
    resume into it; fewer need a folder of their own.

    Raises:
        ConfigError: naming how many finished jobs it would drop, and one of them.
    """
    ours = set(sweep.jobs)
    dropped = sorted(p.parent.name for p in sweep.folder.glob(f"*/{ROWS}") if p.parent.name not in ours)
    if dropped:
        raise ConfigError(
            f"{sweep.folder} holds {len(dropped)} finished job{'s' if len(dropped) != 1 else ''} this sweep does not run "
            f"(such as {dropped[0]}), and its table would drop them: a sweep resumes into a folder only with the same jobs or more; "
            "choose another folder with hydra.sweep.dir=PATH"
        )


def _show(value: Any) -> str:
    return json.dumps(value) if not isinstance(value, str) else value


def record_settings(sweep: SweepPlan) -> None:
    write_json(sweep.folder / SETTINGS, {"experiment": sweep.experiment["name"], "settings": sweep.settings, "swept": list(sweep.swept)})

