"""``airl inspect PATH``: validate a dataset file and describe what it holds (no Hydra, no run folder)."""

from __future__ import annotations

import numpy as np

from airl_cli.core.mdp.sparse import SparseDynamics
from airl_cli.errors import AirlError, refuse
from airl_cli.io.dataset import read_dataset
from airl_cli.jobs.common import err_console, out_console, vector_text
from airl_cli.usecases.evaluate import identifiability_lines


def _form(ds) -> str:
    if isinstance(ds.transitions, SparseDynamics):
        return f", sparse (at most {ds.transitions.next_states.shape[1]} next states per state)"
    return ""


def _kind(ds) -> str:
    """What the features are of, after 'features K=...' ('' for features of a state)."""
    if ds.time_features:
        return " of the step and " + ("a state and an action, phi_t(s, a) (T-1, S, A, K)" if ds.action_features else "a state, phi_t(s) (T, S, K)")
    return " of a state and an action, phi(s, a)" if ds.action_features else ""


def describe(path: str) -> str:
    """A few lines on the dataset at ``path``; raises ``DatasetError`` if it does not validate."""
    ds = read_dataset(path)
    lines = [
        f"{path}: a valid airl dataset",
        f"  states S={ds.n_states}, actions A={ds.n_actions}, features K={ds.n_features}{_kind(ds)}, horizon T={ds.horizon}",
        f"  dynamics: tau and D={ds.n_dynamics} demonstration dynamics" + _form(ds),
    ]
    if ds.n_test:
        names = "test_1" if ds.n_test == 1 else f"test_1..test_{ds.n_test}"
        lines.append(f"  held-out test dynamics: E={ds.n_test}, no demonstration came from them; every method is scored in {'it' if ds.n_test == 1 else 'each'} ({names})")
    if ds.expert == "own":
        how = "hard-optimal" if ds.expert_beta is None else f"soft-optimal, entropy weight beta={ds.expert_beta:g}"
        lines.append(f"  expert: each tau_j's own, {how} in tau_j (the demonstrator is scored so too)")
    if ds.demo_states is not None:
        acts = "with actions" if ds.demo_actions is not None else "states only"
        lines.append(f"  demonstrations: N={ds.n_demos} per dynamics ({acts})")
    if ds.feature_expectations is not None:
        lines.append("  feature expectations: given (used instead of the demonstrations' mean)")
    if ds.true_weights is None:
        lines.append("  true weights: absent, runs cannot be scored")
    elif not np.any(ds.true_weights):
        lines.append("  true weights: all 0: every policy is optimal for the true reward, so every score will be 1 and cos(w, w*) 0")
    else:
        lines.append("  true weights: given, runs will be scored")
    if ds.environment is not None:
        lines.append(f"  environment: {ds.environment}" + (f"; tau_1..tau_D: {ds.perturbation}" if ds.perturbation else ""))
    elif ds.perturbation:
        lines.append(f"  tau_1..tau_D: {ds.perturbation}")
    if ds.goal_states is not None:
        lines.append(f"  goal: {int(ds.goal_states.sum())} state(s); runs report the probability of reaching one within the horizon")
    lines.append("  loss: " + ("given (S, S)" if ds.loss is not None else "absent, the config's loss will be used"))
    if ds.discount < 1.0:
        lines.append(f"  discount: gamma = {ds.discount:g}, step t weighted by gamma^t (optim=gradient refuses it; the certified learner takes it)")
    if ds.allowed_actions is not None:
        lines.append(f"  actions: {int(ds.allowed_actions.sum())} of {ds.allowed_actions.size} (state, action) pairs exist (method=robust_mce only)")
    lines += [f"  {line}" for line in identifiability_lines(ds)]
    lines.append("  feature sums c~_j:")
    for j, row in enumerate(ds.feature_targets(), start=1):
        lines.append(f"    tau_{j}: " + vector_text(row))
    return "\n".join(lines)


def main(path: str) -> None:
    if not path.strip():
        refuse("airl inspect '' names no file: give it a dataset file, airl inspect PATH.npz", err_console)
    try:
        text = describe(path)
    except AirlError as err:
        refuse(err, err_console)
    out_console.print(text, soft_wrap=True)
