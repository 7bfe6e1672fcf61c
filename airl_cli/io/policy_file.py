"""``policy.npz``, the policy ``airl plan`` writes: the policy graph's arrays and, for a Markov
method, ``markov_policy`` (T, S); ``best_policy.npz``, the bracket's better policy, as a graph."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np

from airl_cli.core.mmdp.baselines import Plan
from airl_cli.core.mmdp.planner import PolicyGraph
from airl_cli.io.files import atomic_write


def save_policy(path: Path, result: Plan | PolicyGraph) -> None:
    """The policy graph's arrays (``PolicyGraph.to_arrays``) and, for a plan of a Markov method,
    ``markov_policy`` (T, S)."""
    graph = result if isinstance(result, PolicyGraph) else result.graph
    arrays = graph.to_arrays()
    if isinstance(result, Plan) and result.policy is not None:
        arrays["markov_policy"] = result.policy

    def write(handle) -> None:
        buf = io.BytesIO()
        np.savez_compressed(buf, **arrays)
        handle.write(buf.getvalue())

    atomic_write(path, write)


def load_policy(path: str | Path) -> PolicyGraph:
    """The policy graph saved by ``airl plan`` (run it on any model with ``graph_returns``)."""
    with np.load(path, allow_pickle=False) as npz:
        return PolicyGraph.from_arrays({k: npz[k] for k in npz.files})
