"""What a sweep is, below every module that runs one: its file names, its quick profile, its plan.

The ``airl.sweep`` resolver (``${airl.sweep:runs|values|methods|variants|problems}`` in ``conf/experiment/*.yaml``)
is registered on import, in the sweep process and in every worker that composes a job's config.
Nothing here imports another module of ``airl_cli``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from omegaconf import DictConfig, OmegaConf

from airl_cli.io.run_folder import JOB_ERROR, JOB_ROWS

#: A job's rows for the results table (written last, so its presence means the job is done), and its
#: one-sentence error when it stopped on bad input (its rows are then absent): ``io.run_folder``'s.
ROWS, ERROR = JOB_ROWS, JOB_ERROR

#: Quick profile: this many runs at most, the first and last swept value (or the experiment's
#: ``quick_values``), the first two methods (or variants).
QUICK_RUNS = 2
QUICK_METHODS = 2


def _sweep_values(what: str, *, _root_: DictConfig) -> str:
    """``${airl.sweep:runs|values|methods|variants|problems}``: the sweep of the experiment under the current profile."""
    exp = _root_.experiment
    quick = _root_.profile.name == "quick"
    if what == "runs":
        n = min(int(exp.runs), QUICK_RUNS) if quick else int(exp.runs)
        return f"range(0,{n})"
    if what == "values":
        values = list(exp["values"])
        if quick:
            # an experiment whose swept values are the problem's size shrinks them (quick_values)
            values = list(exp.get("quick_values") or dict.fromkeys([values[0], values[-1]]))
        return ",".join(str(v) for v in values)
    if what == "problems":  # conf/problem/ bundles, each a problem with its dynamics: every one, quick or not
        return ",".join(exp[what])
    if what in ("methods", "variants"):  # variants: conf/variant/ bundles, each a method and its settings
        names = list(exp[what])
        return ",".join(names[:QUICK_METHODS] if quick else names)
    raise ValueError(f"airl.sweep takes runs, values, methods, variants or problems, not {what!r}")


OmegaConf.register_new_resolver("airl.sweep", _sweep_values, replace=True)


@dataclass(frozen=True)
class SweepPlan:
    """What ``airl sweep`` will run.

    Attributes:
        experiment: the experiment's settings (the ``experiment`` node, plain).
        folder: the sweep folder.
        jobs: the job folder names, in launch order.
        settings: every setting the jobs share (dotted key -> value), the swept keys left out:
            what a resumed run must agree with (see ``check_folder``).
        swept: the keys the sweep varies (they name the job folders).
        workers: how many jobs the launcher runs at once on this machine.
        job_overrides: each job's overrides (the swept values), in the order of ``jobs``.
    """

    experiment: dict
    folder: Path
    jobs: tuple[str, ...]
    settings: dict = field(default_factory=dict)
    swept: tuple[str, ...] = ()
    workers: int = 1
    job_overrides: tuple[tuple[str, ...], ...] = ()

    def done(self) -> list[str]:
        return [j for j in self.jobs if (self.folder / j / ROWS).exists()]

    def failed(self) -> dict[str, str]:
        """Job -> its error sentence, for jobs that stopped on bad input."""
        out = {}
        for j in self.jobs:
            err = self.folder / j / ERROR
            if not (self.folder / j / ROWS).exists() and err.exists():
                out[j] = err.read_text().strip()
        return out
