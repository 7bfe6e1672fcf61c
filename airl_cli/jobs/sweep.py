"""The job of ``airl sweep``: one point of an experiment's grid, skipped if an earlier run finished it.

A fit experiment runs ``airl fit``'s work into the job folder and then writes ``rows.csv``, its
tidy rows for the results table; the alpha-vector experiment (thesis Figs. 2-3) writes
``alphas.npz`` and one row. ``rows.csv`` is written last, atomically: its presence means done.
Bad input stops the job with ``error.txt`` (one sentence) instead of rows.
"""

from __future__ import annotations

import os
import signal
import socket
import threading
import time

import hydra
from omegaconf import DictConfig, OmegaConf

from airl_cli import compose_memo, pool, sweep_folder, sweeps
from airl_cli.errors import AirlError, ResultsUnwritable, interrupted
from airl_cli.jobs.common import output_dir
from airl_cli.paths import conf_dir
from airl_cli.results import describe_os_error, is_unwritable, write_text


_watching = False


def watch_parent(poll: float = 0.5) -> None:
    """Stop this process when the ``airl sweep`` that launched it dies, even by SIGKILL.

    Launcher workers (joblib's loky processes, submitit's local jobs) would otherwise go on
    computing for minutes with no one to collect their rows. ``pool.PARENT_ENV`` names the
    launching process; a worker on the same host runs a daemon thread that checks every ``poll``
    seconds whether that process is gone (or this one was re-parented) and then kills itself. In
    the launching process itself (hydra/launcher=basic) and on other hosts (SLURM) it does nothing.
    """
    global _watching
    parent = os.environ.get(pool.PARENT_ENV, "")
    host, _, pid_text = parent.rpartition(":")
    if _watching or not pid_text.isdigit() or host != socket.gethostname() or int(pid_text) == os.getpid():
        return
    pid, ppid = int(pid_text), os.getppid()

    def alive() -> bool:
        if ppid == pid and os.getppid() != pid:
            return False  # re-parented: the sweep process has ended (maybe not yet reaped)
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        except PermissionError:
            return True
        try:
            with open(f"/proc/{pid}/stat") as f:
                return f.read().rsplit(")", 1)[1].split()[0] != "Z"
        except OSError:
            return True

    def watch() -> None:
        while alive():
            time.sleep(poll)
        os.kill(os.getpid(), signal.SIGKILL)

    threading.Thread(target=watch, name="airl-watch-parent", daemon=True).start()
    _watching = True


def finished_earlier(cfg: DictConfig, folder) -> bool:
    """Whether this job's rows are there and were made with this very config.

    A job folder is named by its swept values only; its ``config.yaml`` holds everything else.
    Rows made with another config (another experiment's folder, a changed setting) are recomputed;
    the other experiment of the same study (fig15 in fig14's folder) differs only in its labels
    and reuses them.
    """
    if not (folder / sweeps.ROWS).exists():
        return False
    saved = folder / "config.yaml"
    if saved.exists():
        text = saved.read_text()
        if text == OmegaConf.to_yaml(cfg, resolve=True):
            return True
        try:
            before = OmegaConf.to_container(OmegaConf.create(text))
        except Exception:  # an unreadable config.yaml: recompute  # noqa: BLE001
            before = None
        if isinstance(before, dict) and sweep_folder.same_job(before, OmegaConf.to_container(cfg, resolve=True)):
            return True
    (folder / sweeps.ROWS).unlink()
    return False


def share_cores() -> None:
    """Use at most the threads the sweep gave this job (``pool.THREADS_ENV``) in the planner's
    parallel backup: with two launcher workers on two cores, one thread each."""
    threads = os.environ.get(pool.THREADS_ENV, "")
    if threads.isdigit():
        import numba

        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))


def main(cfg: DictConfig) -> None:
    watch_parent()
    share_cores()
    compose_memo.install()  # this worker's next jobs compose from what this one loaded
    folder = output_dir()
    if finished_earlier(cfg, folder):
        return
    (folder / sweeps.ERROR).unlink(missing_ok=True)
    from airl_cli.jobs.sweep_rows import alpha_rows, fit_rows, rows_csv  # the solvers: in the job only

    try:
        rows = alpha_rows(cfg, folder) if cfg.experiment.kind == "alphas" else fit_rows(cfg, folder)
    except AirlError as err:
        write_text(folder / sweeps.ERROR, f"{err}\n")
        return
    write_text(folder / sweeps.ROWS, rows_csv(rows))


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
