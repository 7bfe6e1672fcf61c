"""An alpha-vector job's row (``airl_cli.experiment_kinds``), thesis Figs. 2-3: every exact alpha-vector at one
(t, s) of two random MDPs (Theorem 6.3.1's enumeration) and those modified PBVI computes, written to
``alphas.npz``, with their counts and the largest gap between the two value functions."""

from __future__ import annotations

import io
import time

import numpy as np
from omegaconf import DictConfig

from airl_cli.core.mmdp.planner import exact_alpha_vectors, expand_beliefs, pbvi_graph
from airl_cli.io.files import atomic_write
from airl_cli.jobs.common import save_config
from airl_cli.readings.alpha_values import largest_gap, upper_envelope_1d
from airl_cli.settings.config import plain
from airl_cli.usecases.problem import streams


def rows(cfg: DictConfig, folder) -> list[dict]:
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
    gap = largest_gap(exact[envelope], pbvi, x)
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
