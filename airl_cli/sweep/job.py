"""The job of ``airl sweep``: one point of an experiment's grid, skipped if an earlier run finished it.

The experiment's kind (``airl_cli.kinds``) does the job's work and gives its rows: a fit experiment
runs ``airl fit``'s work into the job folder, one row per dynamics; the alpha-vector experiment
(thesis Figs. 2-3) writes ``alphas.npz`` and one row. ``rows.csv``, the tidy rows for the results
table, is written last, atomically: its presence means done.
Bad input stops the job with ``error.txt`` (one sentence) instead of rows.
"""

from __future__ import annotations

import os

import hydra
from omegaconf import DictConfig, OmegaConf

from airl_cli.errors import AirlError, ResultsUnwritable, interrupted
from airl_cli.experiment_kinds import part
from airl_cli.io.files import describe_os_error, is_unwritable, write_text
from airl_cli.jobs.common import output_dir
from airl_cli.settings import compose_memo
from airl_cli.settings.paths import conf_dir
from airl_cli.sweep import pool
from airl_cli.sweep.code import CODE, fingerprint, made_here
from airl_cli.sweep.folder import same_job
from airl_cli.sweep.spec import ERROR, ROWS


def finished_earlier(cfg: DictConfig, folder) -> bool:
    """Whether this job's rows are there and were made with this very config, by this very code
    (``sweep.code``: airl's sources and the libraries' versions).

    A job folder is named by its swept values only; its ``config.yaml`` holds everything else.
    Rows made with another config (another experiment's folder, a changed setting) are recomputed;
    the other experiment of the same study (fig15 in fig14's folder) differs only in its labels
    and reuses them.
    """
    if not (folder / ROWS).exists():
        return False
    saved = folder / "config.yaml"
    if saved.exists() and made_here(folder):
        text = saved.read_text()
        if text == OmegaConf.to_yaml(cfg, resolve=True):
            return True
        try:
            before = OmegaConf.to_container(OmegaConf.create(text))
        except Exception:  # an unreadable config.yaml: recompute  # noqa: BLE001
            before = None
        if isinstance(before, dict) and same_job(before, OmegaConf.to_container(cfg, resolve=True)):
            return True
    (folder / ROWS).unlink()
    return False


def finished_elsewhere(cfg: DictConfig, folder) -> bool:
    """Whether the same job finished in another sweep folder beside this one (the sweeps root holds
    ``<study>-<profile>[-<overrides>]/<job>/``): if so, its files are copied here, rows last.

    ``airl sweep experiment=fig05 method=airl,mce`` after ``airl sweep experiment=fig05`` ran
    140 jobs that had just finished in ``fig05-full``, because the folder differed. A job is the same
    when its ``config.yaml`` is, as ``finished_earlier`` judges a resumed job (``folder.same_job``),
    and the same code made it (``sweep.code.made_here``).
    """
    import shutil

    from airl_cli.io.files import atomic_write

    plain = OmegaConf.to_container(cfg, resolve=True)
    for rows in sorted(folder.parent.parent.glob(f"*/{folder.name}/{ROWS}")):
        other = rows.parent
        if other == folder or not (other / "config.yaml").is_file() or not made_here(other):
            continue
        try:
            before = OmegaConf.to_container(OmegaConf.create((other / "config.yaml").read_text()))
        except Exception:  # an unreadable config.yaml: not this job  # noqa: BLE001
            continue
        if not (isinstance(before, dict) and same_job(before, plain)):
            continue
        folder.mkdir(parents=True, exist_ok=True)
        for item in sorted(other.iterdir(), key=lambda p: p.name == ROWS):  # rows.csv last: the job's "done"
            if item.is_file() and not item.name.startswith("."):
                data = item.read_bytes()
                atomic_write(folder / item.name, lambda handle, data=data: handle.write(data))
            elif item.is_dir() and not (folder / item.name).exists():
                shutil.copytree(item, folder / item.name)
        return True
    return False


def share_cores() -> None:
    """Use at most the threads the sweep gave this job (``pool.THREADS_ENV``) in the planner's
    parallel backup: with two launcher workers on two cores, one thread each."""
    threads = os.environ.get(pool.THREADS_ENV, "")
    if threads.isdigit():
        import numba

        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))


def main(cfg: DictConfig) -> None:
    pool.watch_parent()
    share_cores()
    compose_memo.install()  # this worker's next jobs compose from what this one loaded
    folder = output_dir()
    if finished_earlier(cfg, folder) or finished_elsewhere(cfg, folder):
        return
    (folder / ERROR).unlink(missing_ok=True)
    try:
        rows = part(cfg.experiment, "rows").rows(cfg, folder)  # the kind's solvers: imported in the job only
    except AirlError as err:
        write_text(folder / ERROR, f"{err}\n")
        return
    write_text(folder / CODE, fingerprint() + "\n")  # what made the rows, before them: reused only by the same code
    write_text(folder / ROWS, rows_csv(rows))


def rows_csv(rows: list[dict]) -> str:
    """The job's rows as the text of ``rows.csv``."""
    import pandas as pd

    return pd.DataFrame(rows).to_csv(index=False)


@hydra.main(version_base="1.3", config_path=conf_dir(), config_name="airl")
def hydra_main(cfg: DictConfig) -> None:
    """One job; a Ctrl-C or a folder that cannot be written stops the sweep, not only this job.

    Hydra would record the SystemError that wraps a Ctrl-C inside a compiled kernel, and an
    ``OSError``, as a failed job and go on; they reach ``airl sweep`` as KeyboardInterrupt and
    ``ResultsUnwritable``.
    """
    try:
        main(cfg)
    except (SystemError, OSError) as err:
        if interrupted(err):
            raise KeyboardInterrupt from None
        if is_unwritable(err):
            raise ResultsUnwritable(describe_os_error(err), str(output_dir())) from None
        raise
