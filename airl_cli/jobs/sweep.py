"""The job of ``airl sweep``: one point of an experiment's grid, skipped if an earlier run finished it.

A fit experiment runs ``airl fit``'s work into the job folder and then writes ``rows.csv``, its
tidy rows for the results table; the alpha-vector experiment (thesis Figs. 2-3) writes
``alphas.npz`` and one row. ``rows.csv`` is written last, atomically: its presence means done.
Bad input stops the job with ``error.txt`` (one sentence) instead of rows.
"""

from __future__ import annotations

import io
import json
import os
import signal
import socket
import threading
import time

import hydra
import numpy as np
import pandas as pd
from omegaconf import DictConfig, OmegaConf

from airl_cli import compose_memo, pool, sweep_folder, sweeps
from airl_cli.build import resolved_loss, streams
from airl_cli.config import plain, problem_settings
from airl_cli.core.multimodel import exact_alpha_vectors, expand_beliefs, pbvi_graph, upper_envelope_1d
from airl_cli.errors import AirlError
from airl_cli.jobs.common import output_dir, save_config
from airl_cli.jobs.fit import fit_and_write
from airl_cli.paths import conf_dir
from airl_cli.results import atomic_write, write_text


def fit_rows(cfg: DictConfig, folder) -> list[dict]:
    """Run the fit of this job; one row per dynamics: ``sweeps.FIT_COLUMNS``, then every setting."""
    run = fit_and_write(cfg, folder)
    c = plain(cfg)
    exp = c["experiment"]
    ds = run.dataset
    base = {
        "experiment": exp["name"],
        "method": run.settings.method,
        "seed": c["seed"],
        "run": c["seed"],
        "x": float(OmegaConf.select(cfg, exp["x_key"])),
        "x_name": exp["x"],
        "mdp": c["mdp"]["name"],
        "dynamics_kind": c["dynamics"]["name"],
        "n_dynamics": ds.n_dynamics,
        "n_features": ds.n_features,
        "n_demos": ds.n_demos if ds.feature_expectations is None else 0,
        "demos": c["demos"]["kind"],
        "sigma": float(c["dynamics"].get("sigma", 0.0)),
        "weight_sharing": run.settings.options.weight_sharing,
        "loss": resolved_loss(problem_settings(cfg)),
    }
    info = run.learned.info
    certified = run.settings.method == "airl" and info.get("optimizer") == "exact"
    fit_facts = {
        "optimizer": info.get("optimizer", "") if run.settings.method == "airl" else "",
        "objective": info.get("objective", np.nan) if run.settings.method == "airl" else np.nan,
        "relative_gap": info["relative_gap"] if certified else np.nan,
        "converged": info["converged"] if certified else np.nan,
    }
    settings = setting_columns(c)
    out = []
    for row in run.rows:
        out.append(
            {
                **base,
                "dynamics": row["dynamics"],
                "learner_score": row["learner_score"],
                "demonstrator_score": row["demonstrator_score"],
                "cosine_similarity": row["cosine_similarity"],
                "seconds": run.seconds,
                **fit_facts,
                **settings,
            }
        )
    return out


#: The config groups whose every setting becomes a column of the results table.
SETTING_GROUPS = ("mdp", "dynamics", "demos", "loss", "method", "pbvi", "game", "optim")


def setting_columns(config: dict) -> dict[str, object]:
    """Every setting of the problem and learner groups as a column (``optim.lam``, ``mdp.transition``...).

    A variant's table (say ``mdp.transition=dirichlet``) thus says what it ran, row by row. Lists
    (grid cells) are written as JSON text.
    """
    out: dict[str, object] = {}
    for group in SETTING_GROUPS:
        for key, value in sweep_folder.shared_settings({group: config.get(group) or {}}, ()).items():
            out[key] = json.dumps(value) if isinstance(value, (list, dict)) else value
    return out


def alpha_rows(cfg: DictConfig, folder) -> list[dict]:
    """Thesis Figs. 2-3: every exact alpha-vector at one (t, s) of two random MDPs, and PBVI's."""
    exp = plain(cfg)["experiment"]
    seed = int(cfg.seed)
    rng = streams(seed)["mdp"]
    S, A, T, t, s = exp["n_states"], exp["n_actions"], exp["horizon"], exp["t"], exp["s"]
    start = time.perf_counter()
    P = rng.dirichlet(np.ones(S), size=(2, S, A))
    R = rng.normal(size=(2, T, S))
    exact = exact_alpha_vectors(P, R, t=t, s=s)
    envelope = upper_envelope_1d(exact)
    beliefs = expand_beliefs(P, iterations=exp["pbvi_iterations"], rng=streams(seed)["fit"])
    graph = pbvi_graph(P, R, beliefs)
    pbvi = graph.alpha[t][graph.offsets[t][s] : graph.offsets[t][s + 1]]
    x = np.linspace(0.0, 1.0, 2001)
    curve = lambda a: np.max(np.outer(1 - x, a[:, 0]) + np.outer(x, a[:, 1]), axis=1)  # noqa: E731
    gap = float(np.max(curve(exact[envelope]) - curve(pbvi)))
    buf = io.BytesIO()
    np.savez(buf, exact=exact, exact_envelope=envelope, pbvi=pbvi, t=t, s=s)
    atomic_write(folder / "alphas.npz", lambda h: h.write(buf.getvalue()))
    save_config(cfg, folder)
    return [
        {
            "experiment": exp["name"],
            "seed": seed,
            "n_exact": len(exact),
            "n_envelope": len(envelope),
            "n_pbvi": len(pbvi),
            "n_beliefs": len(beliefs),
            "max_value_gap": gap,
            "seconds": time.perf_counter() - start,
        }
    ]


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
    try:
        rows = alpha_rows(cfg, folder) if cfg.experiment.kind == "alphas" else fit_rows(cfg, folder)
    except AirlError as err:
        write_text(folder / sweeps.ERROR, f"{err}\n")
        return
    write_text(folder / sweeps.ROWS, pd.DataFrame(rows).to_csv(index=False))


@hydra.main(version_base="1.3", config_path=conf_dir(), config_name="airl")
def hydra_main(cfg: DictConfig) -> None:
    main(cfg)
