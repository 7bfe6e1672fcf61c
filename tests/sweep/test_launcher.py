"""airl's sweep launcher (hydra/launcher=airl): remembered compositions equal Hydra's own, warm
workers get their share of the cores, and a sweep on two workers gives the in-process table."""

from __future__ import annotations

import os
import re
import signal
from pathlib import Path

import pandas as pd
import pytest
from hydra import compose, initialize_config_dir
from hydra.core.override_parser.overrides_parser import OverridesParser
from omegaconf import OmegaConf
from typer.testing import CliRunner

from airl_cli.cli import app
from airl_cli.settings import compose_memo
from airl_cli.settings.overrides import CommandLine
from airl_cli.settings.paths import conf_dir
from airl_cli.sweep import pool
from airl_cli.sweep.plan import experiment_names, plan
from airl_cli.sweep.run import _expected_workers

runner = CliRunner()


@pytest.fixture(autouse=True)
def in_tmp(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)


def _jobs(name: str, *extra: str) -> list[list[str]]:
    """Every job of an experiment at the quick size: its overrides (the swept values, then the command's)."""
    return [list(job) for job in plan([f"experiment={name}", "profile=quick", *extra]).job_overrides]


def _composed(overrides: list[str]) -> tuple[str, str]:
    """The job's whole config as text (the hydra node included, unresolved), and its task part resolved."""
    with initialize_config_dir(config_dir=conf_dir(), version_base="1.3", job_name="sweep"):
        cfg = compose("airl", overrides=overrides, return_hydra_config=True)
    task = OmegaConf.to_container(cfg, resolve=False)
    del task["hydra"]
    return OmegaConf.to_yaml(cfg), OmegaConf.to_yaml(OmegaConf.create(task), resolve=True)


VARIANTS = [
    pytest.param(experiment_names(), (), marks=pytest.mark.slow, id="every experiment"),  # 48 s on a 2-core machine
    pytest.param(["fig05", "fig09"], ("mdp.transition=sparse", "loss=zero_one", "method=mce"), id="a variant"),
]


@pytest.mark.parametrize("names, extra", VARIANTS)
def test_a_remembered_composition_equals_hydras_for_every_job(names, extra):
    """Quick jobs of every experiment (the first two and the last), and of a variant with group and
    value overrides: the same config, hydra node included, whether Hydra composes it afresh or from
    memory."""
    jobs = [job for name in names for found in [_jobs(name, *extra)] for job in found[: min(2, len(found) - 1)] + found[-1:]]
    assert len(jobs) >= 6
    fresh = [_composed(job) for job in jobs]
    compose_memo.install()
    try:
        remembered = [_composed(job) for job in jobs]
        assert len(compose_memo._config_memo) < len(jobs)  # it did remember
        assert len(compose_memo._parse_memo) < sum(len(job) for job in jobs)
    finally:
        compose_memo.uninstall()
    for job, a, b in zip(jobs, fresh, remembered, strict=True):
        assert a == b, job
    # the seeds differ between jobs: a memory that ignored value overrides would fail above
    assert len({text for _, text in fresh}) == len(jobs)


def test_the_memory_is_gone_after_uninstall():
    from hydra._internal import config_loader_impl
    from hydra.core.override_parser.overrides_parser import OverridesParser

    original = config_loader_impl.create_defaults_list, OverridesParser.parse_rule
    compose_memo.install()
    compose_memo.install()  # idempotent
    assert config_loader_impl.create_defaults_list is not original[0]
    assert OverridesParser.parse_rule is not original[1]
    OverridesParser.create().parse_overrides(["seed=3"])
    assert compose_memo._parse_memo
    compose_memo.uninstall()
    assert (config_loader_impl.create_defaults_list, OverridesParser.parse_rule) == original
    assert not compose_memo._defaults_memo and not compose_memo._parse_memo


def test_a_remembered_parse_is_a_copy_and_function_calls_are_parsed_afresh():
    parser = OverridesParser.create()
    compose_memo.install()
    try:
        first, second = parser.parse_overrides(["seed=3", "seed=3"])
        assert first is not second and first == second and first.input_line == "seed=3"
        parser.parse_overrides(["seed=shuffle(1,2,3)"])
        assert "seed=shuffle(1,2,3)" not in compose_memo._parse_memo
    finally:
        compose_memo.uninstall()


def test_the_workers_a_command_line_asks_for():
    assert _expected_workers(CommandLine.of(["experiment=fig12"])) == pool.workers(-1)
    assert _expected_workers(CommandLine.of(["experiment=fig12", "hydra.launcher.n_jobs=1"])) == 1
    assert _expected_workers(CommandLine.of(["experiment=fig12", "hydra/launcher=basic"])) == 1
    assert _expected_workers(CommandLine.of(["experiment=fig12", "hydra/launcher=joblib"])) == 1
    assert pool.workers(-1) == pool.cores() and pool.workers(-1, n_tasks=1) == 1 and pool.workers(5) == pool.cores()


def _in_worker() -> tuple[int, str, str]:
    return os.getpid(), os.environ.get(pool.THREADS_ENV, ""), os.environ.get("OPENBLAS_NUM_THREADS", "")


@pytest.mark.skipif(pool.cores() < 2, reason="two workers need two cores")
def test_warm_workers_are_other_processes_with_their_share_of_the_cores(monkeypatch):
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    pool.prestart(2)
    try:
        seen = [pool._pool["pool"].submit(_in_worker).result(timeout=120) for _ in range(4)]
    finally:
        pool.shutdown()
    threads = str(pool.cores() // 2)
    assert all(pid != os.getpid() for pid, _, _ in seen)
    assert {(t, b) for _, t, b in seen} == {(threads, threads)}
    assert pool.THREADS_ENV not in os.environ and "OPENBLAS_NUM_THREADS" not in os.environ  # restored
    assert not pool._pool


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
@pytest.mark.skipif(pool.cores() < 2, reason="two workers need two cores")
def test_two_workers_give_the_in_process_table_and_figures(tmp_path, monkeypatch):
    """The table equals basic's; the figures, drawn on the two warm workers (PNG on one, PDF on
    the other), are byte for byte what this process draws from the same folder."""
    import airl_cli.sweep.table as sweep_table
    from airl_cli.readings.plotting import draw

    on_workers = []
    monkeypatch.setattr(sweep_table, "call", lambda targets: on_workers.append(pool.call(targets)) or on_workers[-1])
    tables = {}
    for name, launcher in (("airl", ["hydra/launcher=airl", "hydra.launcher.n_jobs=2"]), ("basic", ["hydra/launcher=basic"])):
        folder = tmp_path / name
        result = runner.invoke(app, ["sweep", "experiment=fig13", "profile=quick", *launcher, f"hydra.sweep.dir={folder}"])
        assert result.exit_code == 0, result.output
        tables[name] = pd.read_csv(folder / "results.csv").drop(columns=["seconds"])
        assert all((folder / job / ".hydra" / "config.yaml").exists() for job in plan(["experiment=fig13", "profile=quick"]).jobs)
    assert len(tables["basic"]) == 12
    pd.testing.assert_frame_equal(tables["airl"], tables["basic"])
    assert on_workers[0] is not None and on_workers[1:] == [None]  # airl's on its workers, basic's here
    folder = tmp_path / "airl" / "figures"
    drawn = {p.name: p.read_bytes() for p in sorted(folder.iterdir())}
    assert [p.name for p in draw(tmp_path / "airl")] == ["fig13_run_bars.png", "fig13_run_bars.pdf"]
    assert drawn == {p.name: p.read_bytes() for p in sorted(folder.iterdir())}
    assert not pool._pool  # the workers are gone


def _boom(message: str) -> None:
    raise (RuntimeError if "runtime" in message else ValueError)(message)


@pytest.mark.skipif(pool.cores() < 2, reason="two workers need two cores")
def test_work_on_kept_workers_returns_in_order_or_raises_and_none_without_workers(monkeypatch):
    assert pool.call([("os:getpid", ())]) is None  # no warm workers
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[2]))  # workers import tests.sweep.test_launcher
    pool.prestart(2)
    try:
        pids = pool.call([("os:getpid", ()), ("os:getpid", ())])
        assert len(pids) == 2 and os.getpid() not in pids
        assert pool.call([("os.path:join", ("a", "b")), ("os.path:join", ("c",))]) == [os.path.join("a", "b"), "c"]
        assert pool.call([("os:getpid", ())] * 3) is None  # more than the workers
        with pytest.raises(ValueError, match="bad figure"):
            pool.call([("tests.sweep.test_launcher:_boom", ("bad figure",))])
        with pytest.raises(RuntimeError, match="a runtime error"):  # raised, not taken for a broken pool
            pool.call([("tests.sweep.test_launcher:_boom", ("a runtime error",))])
        assert pool.call([("os:getpid", ())]) is not None  # and the workers are still there
    finally:
        pool.shutdown()
    assert not pool._pool


@pytest.mark.skipif(pool.cores() < 2, reason="two workers need two cores")
def test_a_worker_that_dies_leaves_no_executor_thread_to_race_the_exit():
    """A worker killed under ``call`` (``launch`` shares the path): None, and the executor's manager
    thread has ended before the call returns. Left running, it closed its wake-up pipe while the
    interpreter's exit hook wrote to it, and a traceback followed the one sentence (seen in CI)."""
    from concurrent.futures import process as futures_process

    pool.prestart(2)
    try:
        assert pool.call([("os:_exit", (9,)), ("time:sleep", (5,))]) is None
        assert not pool._pool
        assert not [t for t in list(futures_process._threads_wakeups) if t.is_alive()]
    finally:
        pool.shutdown()


@pytest.mark.skipif(pool.cores() < 2, reason="two workers need two cores")
def test_workers_that_run_no_job_are_stopped_at_once():
    """A sweep stopped by a bad value does not wait for its warm workers' imports to finish."""
    pool.prestart(2)
    processes = list(pool._pool["pool"]._processes.values())
    assert len(processes) == 2
    pool.shutdown(idle=True)  # at once: a worker's imports take about a second
    assert not any(p.is_alive() for p in processes) and not pool._pool
    assert all(p.exitcode == -signal.SIGTERM for p in processes)  # stopped, not left to finish their imports


# --------------------------------------------------------------------------- Hydra's own launcher tests


@pytest.mark.slow  # end to end, seconds: the slow suite (pytest -m slow, run by CI)
def test_hydras_launcher_test_suite_passes_on_the_airl_launcher():
    """Hydra's test suite for launcher plugins (``hydra.test_utils.launcher_common_tests``), on
    Hydra's own test app (``tests/sweep/hydra_launcher_suite.py``): the airl launcher is a
    self-contained plugin that runs any app's multirun, on warm workers and in-process. In a
    process of its own: an earlier composition of airl's config (``hydra/job_logging: none``) in
    this one changes what Hydra's basic launcher does too."""
    import subprocess
    import sys

    suite = Path(__file__).with_name("hydra_launcher_suite.py")
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(suite)], capture_output=True, text=True, cwd=suite.parent)
    assert done.returncode == 0, done.stdout[-3000:]
    assert re.search(r"\b18 passed\b", done.stdout), done.stdout[-1000:]
