"""The ``airl`` sweep launcher: warm worker processes that each run many jobs.

Hydra's joblib launcher ships the whole Hydra state with every job and rebuilds it in the
worker (plugin registry, config repository, master config): on fig12's 90 grid jobs, whose fits
take 0.06 s, that cost more than the fits. Here a worker rebuilds that state once, at its first
job of a sweep, and then composes each job's config itself (through ``compose_memo``, exact) and
runs it with Hydra's own ``run_job``, so a job's folder, ``.hydra/`` files and return value are
what any Hydra launcher gives.

Workers are started with ``spawn`` (a clean interpreter: no inherited threads or locks). ``airl
sweep`` starts them before it plans (``prestart``), so that their imports overlap its own work;
with one job at a time (``n_jobs=1``, or one core) the jobs run in the sweep's own process, like
``hydra/launcher=basic``. Inside ``kept`` the workers outlive the jobs, for more work
(``call``: ``airl sweep`` draws its PNG and PDF figures on two of them at once).
"""

from __future__ import annotations

import gc
import hashlib
import importlib
import multiprocessing
import os
import signal
import socket
import threading
import time
import warnings
from collections.abc import Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager, suppress
from pathlib import Path
from typing import Any

from airl_cli.heap import keep_heap_slack
from airl_cli.io.files import remove_temporaries

#: The environment variable that tells a sweep's jobs which process launched them ("host:pid").
PARENT_ENV = "AIRL_SWEEP_PARENT"
#: The environment variable that tells a sweep's jobs how many threads each may use (the cores
#: divided among the launcher's workers), so that parallel jobs do not oversubscribe the cores.
THREADS_ENV = "AIRL_SWEEP_THREADS"
#: The BLAS thread counts a new worker process reads: two workers on two cores with two BLAS
#: threads each made fig12's jobs 1.4x slower (busy-waiting threads); left alone if already set.
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS")

#: What ``airl sweep`` says when a worker process dies mid-job (killed by the system, out of memory).
WORKER_DIED = (
    "a sweep worker process died (killed by the system, perhaps for lack of memory); the finished jobs "
    "are kept: run the same command again to resume, with a lower hydra.launcher.n_jobs if memory is short"
)


class WorkerDied(BaseException):
    """A worker process died mid-sweep. A BaseException, like KeyboardInterrupt, so that it passes
    Hydra's error report (a traceback) and reaches ``airl sweep``, which says it in one sentence."""

#: In a worker: the Hydra state of the sweep it serves (see ``_serve``).
_worker: dict[str, Any] = {}
#: In the sweep process: the warm pool and its size, if one was started.
_pool: dict[str, Any] = {}
#: In the sweep process, inside ``kept``: the modules idle workers import after the jobs.
_kept: dict[str, tuple[str, ...]] = {}


def cores() -> int:
    """The cores this process may run on."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)


def workers(n_jobs: int, n_tasks: int | None = None) -> int:
    """Jobs at once for ``hydra.launcher.n_jobs`` (joblib's convention: -1 every core, -2 all but one)."""
    n = cores() + 1 + n_jobs if n_jobs < 0 else n_jobs
    return max(1, min(n, cores(), n_tasks if n_tasks is not None else n))


@contextmanager
def environment(n: int) -> Iterator[None]:
    """What the processes started meanwhile read from the environment, for ``n`` workers: this
    process (``PARENT_ENV``) and their share of the cores (``THREADS_ENV``, ``BLAS_THREADS``).
    Restored afterwards."""
    threads = str(max(1, cores() // max(1, n)))
    values = {PARENT_ENV: f"{socket.gethostname()}:{os.getpid()}", THREADS_ENV: threads}
    values.update({name: threads for name in BLAS_THREADS if name not in os.environ})
    saved = {name: os.environ.get(name) for name in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def _warm(preload: tuple[str, ...]) -> None:
    """A new worker imports the job's code (``preload``: numpy, scipy, pandas, the compiled kernels)
    at once, and stops when the sweep process dies, even before its first job (``watch_parent``)."""
    watch_parent()
    keep_heap_slack()  # as the command line does (airl_cli.heap)
    for module in preload:
        importlib.import_module(module)
    gc.freeze()  # what the imports made is never collected: faster collections, and exit in 0.03 s, not 0.3 s


def prestart(n: int, preload: tuple[str, ...] = ()) -> bool:
    """Start ``n`` warm workers now, for the next ``launch`` (a no-op below two), each importing
    the modules ``preload`` names (the jobs' code, which the sweep process itself never imports).

    Returns whether they are there: a system that refuses the pool's semaphores or processes
    (seen for a user who may not start multiprocessing's resource tracker) gets none, and
    ``launch`` then runs the jobs in this process.
    """
    if n < 2 or _pool.get("n") == n:
        return n < 2 or bool(_pool)
    shutdown()
    # multiprocessing relaunches its resource tracker (it holds the pool's semaphores) if that
    # process has died, and warns on stderr in two lines that ask nothing of the user; under load,
    # with workers stopped at once after a bad value, it did, breaking the one-sentence error
    warnings.filterwarnings("ignore", message="resource_tracker: process died unexpectedly", category=UserWarning)
    pool = None
    try:
        _start_resource_tracker()
        context = multiprocessing.get_context("spawn")
        pool = ProcessPoolExecutor(max_workers=n, mp_context=context, initializer=_leave_interrupts_to_the_sweep)
        with environment(n):  # each submit starts a worker, which copies the environment
            warming = [pool.submit(_warm, tuple(preload)) for _ in range(n)]
    except OSError:
        if pool is not None:
            pool.shutdown(wait=False, cancel_futures=True)
        return False
    _pool.update(pool=pool, n=n, warming=warming)
    return True


def _leave_interrupts_to_the_sweep() -> None:
    """A worker ignores Ctrl-C (the terminal sends it to every process of the sweep): the sweep
    process stops it (``shutdown(idle=True)``) at once, where a worker's own KeyboardInterrupt
    would wait for its compiled kernel to return and then end only its job, not its queue."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _start_resource_tracker() -> None:
    """Start multiprocessing's resource tracker (it removes the pool's semaphores if this process
    is killed) without its warning that it did so.

    After a ``kill -9`` of the sweep the tracker removes the semaphores itself and prints
    ``There appear to be 5 leaked semaphore objects to clean up at shutdown``: nothing is left
    behind, so that line asks nothing of the user. The tracker reads its warning filters from the
    environment when it starts; the workers, started later, do not get this one.
    """
    from multiprocessing import resource_tracker

    quiet = "ignore::UserWarning:multiprocessing.resource_tracker"
    saved = os.environ.get("PYTHONWARNINGS")
    os.environ["PYTHONWARNINGS"] = f"{saved},{quiet}" if saved else quiet
    try:
        resource_tracker.ensure_running()
    finally:
        if saved is None:
            os.environ.pop("PYTHONWARNINGS", None)
        else:
            os.environ["PYTHONWARNINGS"] = saved


def shutdown(wait: bool = True, *, idle: bool = False) -> None:
    """Stop the warm workers, if any; ``wait=False`` lets them exit while this process goes on.

    ``idle=True`` terminates them at once, for workers that run no job (still importing, or done)
    or whose jobs are given up (Ctrl-C): a sweep stopped by a bad value then answers in 0.6 s,
    not after the workers' imports, and a Ctrl-C in a second, not after the jobs under way. The
    call returns when they are gone (no semaphore or process is left behind).
    """
    pool = _pool.pop("pool", None)
    _pool.clear()
    if pool is None:
        return
    if idle:
        # the executor's own objects: its result pipe loses this process's write end, so that a
        # worker terminated while it sent a result leaves its manager thread at the end of the
        # pipe instead of waiting forever for the rest of the message (seen on a Ctrl-C)
        writer = getattr(getattr(pool, "_result_queue", None), "_writer", None)
        if writer is not None:
            writer.close()
        for process in list((pool._processes or {}).values()):
            process.terminate()
    pool.shutdown(wait=wait or idle, cancel_futures=True)  # its manager thread reaps them


@contextmanager
def kept(preload: Sequence[str] = ()) -> Iterator[None]:
    """Within: ``launch`` leaves its workers running when the jobs are done (``shutdown`` stops
    them), and each worker imports the modules named in ``preload`` once it has no job left."""
    _kept["preload"] = tuple(preload)
    try:
        yield
    finally:
        _kept.clear()


def _call(target: str, *args: Any) -> Any:
    """``module:function`` called with ``args`` (the sweep process need not import the module);
    ``module:`` only imports it."""
    module, _, name = target.partition(":")
    loaded = importlib.import_module(module)
    if not name:
        gc.freeze()  # as in _warm
        return None
    return getattr(loaded, name)(*args)


def call(targets: Sequence[tuple[str, tuple]]) -> list[Any] | None:
    """Each ``(module:function, args)`` called at once on the warm workers; their results in order.

    None if there are fewer warm workers than targets, or a worker died: then the caller does the
    work itself. An exception raised by a target is raised here.
    """
    pool = _pool.get("pool")
    if pool is None or _pool.get("n", 0) < len(targets):
        return None
    try:
        futures = [pool.submit(_call, target, *args) for target, args in targets]
    except RuntimeError:  # the pool is broken (BrokenProcessPool is one) or shut down
        shutdown(wait=False)
        return None
    try:
        wait(futures)  # all of them, even if one fails: a worker stopped mid-write leaves a temporary file
        return [f.result() for f in futures]
    except BrokenProcessPool:
        shutdown(idle=True)  # as in launch: the manager thread is done before this process exits
        return None


def _start(state: bytes | tuple) -> None:
    """Hydra's state in this process (context, master config, task function, singletons).

    ``state`` comes cloudpickled from the sweep process (Hydra's resolvers and the function that
    ``hydra.main`` wrapped cannot be pickled by name).
    """
    import cloudpickle
    from hydra.core.singleton import Singleton
    from hydra.core.utils import setup_globals

    from airl_cli.jobs.launch import save_hydra_record
    from airl_cli.settings import compose_memo
    from airl_cli.settings.hydra_internals import set_hydra_record_writer

    hydra_context, config, task_function, singleton_state = cloudpickle.loads(state) if isinstance(state, bytes) else state
    setup_globals()
    Singleton.set_state(singleton_state)
    compose_memo.install()
    set_hydra_record_writer(save_hydra_record)  # whole or absent, as in the sweep process
    _worker.update(hydra_context=hydra_context, config=config, task_function=task_function)


def _run(idx: int, overrides: Sequence[str]) -> Any:
    """One job, in the process that holds the sweep's state (``_start``); Hydra's ``JobReturn``."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.core.utils import run_job
    from omegaconf import open_dict

    hydra_context, config = _worker["hydra_context"], _worker["config"]
    sweep_config = hydra_context.config_loader.load_sweep_config(config, list(overrides))
    with open_dict(sweep_config):
        sweep_config.hydra.job.id = f"{sweep_config.hydra.job.name}_{idx}"
        sweep_config.hydra.job.num = idx
    HydraConfig.instance().set_config(sweep_config)
    return run_job(
        hydra_context=hydra_context,
        config=sweep_config,
        task_function=_worker["task_function"],
        job_dir_key="hydra.sweep.dir",
        job_subdir_key="hydra.sweep.subdir",
    )


def _serve(token: str, state: bytes, idx: int, overrides: Sequence[str]) -> bytes:
    """A job in a worker: the sweep's state is rebuilt only when ``token`` (its digest) changes;
    the ``JobReturn`` goes back cloudpickled (it holds Hydra's structured-config nodes)."""
    import cloudpickle

    if _worker.get("token") != token:
        _worker.clear()
        _start(state)
        _worker["token"] = token
    return cloudpickle.dumps(_run(idx, overrides))


def launch(launcher: Any, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> list[Any]:
    """Run the jobs; their ``JobReturn`` in the order given (``Launcher.launch``)."""
    import cloudpickle
    from hydra.core.singleton import Singleton
    from hydra.core.utils import configure_log, setup_globals

    setup_globals()
    configure_log(launcher.config.hydra.hydra_logging, launcher.config.hydra.verbose)
    Path(str(launcher.config.hydra.sweep.dir)).mkdir(parents=True, exist_ok=True)
    state = (launcher.hydra_context, launcher.config, launcher.task_function, Singleton.get_state())
    jobs = [(initial_job_idx + i, list(o)) for i, o in enumerate(job_overrides)]
    n = workers(int(launcher.n_jobs), len(jobs))
    if n == 1 or not prestart(n, (launcher.task_function.__module__,)):
        saved = dict(_worker)
        _start(state)
        try:
            return [_run(idx, o) for idx, o in jobs]
        finally:
            _worker.clear()
            _worker.update(saved)
    shipped = cloudpickle.dumps(state)
    token = hashlib.sha1(shipped).hexdigest()
    futures: list[Future] = []
    done = False
    try:
        futures += [_pool["pool"].submit(_serve, token, shipped, idx, o) for idx, o in jobs]
        for module in _kept.get("preload", ()):  # picked up by workers as they run out of jobs
            for _ in range(n):
                _pool["pool"].submit(_call, f"{module}:")
        results = [cloudpickle.loads(f.result()) for f in futures]
        done = True
        return results
    except BrokenProcessPool:
        # wait for the executor's manager thread, which closes its wake-up pipe on a broken pool:
        # left running, it raced the interpreter's exit hook (concurrent.futures' _python_exit),
        # which then wrote to the closed pipe and printed a traceback under the one sentence
        shutdown(idle=True)
        raise WorkerDied(WORKER_DIED) from None
    except BaseException:
        shutdown(idle=True)  # a Ctrl-C, or a job that stops the sweep: the jobs under way are given up
        with suppress(OSError):  # the error that stopped the sweep is the one to report
            remove_temporaries(launcher.config.hydra.sweep.dir)  # what the terminated workers were writing
        raise
    finally:
        if not (done and _kept):
            shutdown(wait=False)  # the workers exit while the sweep collects its table


_watching = False


def watch_parent(poll: float = 0.5) -> None:
    """Stop this process when the ``airl sweep`` that launched it dies, even by SIGKILL.

    Launcher workers (joblib's loky processes, submitit's local jobs) would otherwise go on
    computing for minutes with no one to collect their rows. ``PARENT_ENV`` names the
    launching process; a worker on the same host runs a daemon thread that checks every ``poll``
    seconds whether that process is gone (or this one was re-parented) and then kills itself. In
    the launching process itself (hydra/launcher=basic) and on other hosts (SLURM) it does nothing.
    """
    global _watching
    parent = os.environ.get(PARENT_ENV, "")
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
