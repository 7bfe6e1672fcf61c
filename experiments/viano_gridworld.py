"""Viano et al.'s GridWorld table, reproduced: `python experiments/viano_gridworld.py [--learner-epsilon 0|0.05|0.1] [--corner lost|stay] [--all-actions] [--json FILE]`.

Robust MCE IRL (Viano, Huang, Kamalaruban, Weller & Cevher, NeurIPS 2021), their GridWorld
"mode 1" (10 x 10, reward -1, -100 inside, goal (0, 0)), in their setting: the expert soft-optimal
(alpha_E = 1) under noise eps_E, its exact discounted feature expectations (gamma = 0.99, uniform
start), the learner in the grid of noise eps_L (default 0), the infinite-horizon form (value
iteration to 1e-10), w0 = 0 and 200 Adam steps (lr 0.5, betas (0.9, 0.99), eps 1e-7). The metric:
the undiscounted return of the deployed player pi_pl under noise eps_L as their agent draws it
(``viano_grid.evaluation_dynamics``) from every start state (``viano_grid.total_return``, exact).
alpha = 1 is MCE IRL. The published numbers are read from ``conf/experiment/viano_gridworld.yaml``
(their paper's Table at eps_L = 0, their result files at every eps_L), as the sweep reads them.

--corner: what happens to the noise mass their code drops in three corners (see
``airl_cli.core.mdp.viano_grid``); --all-actions: let every action exist everywhere (a move off the
grid stays), instead of their action sets. --json FILE: run the page's five tables instead (eps_L =
0, 0.05, 0.1 in their conventions; corner=stay and every action at eps_L = 0) and write them, with
the published numbers, the seconds and the commit, to FILE (the docs pages' source ``viano``).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from airl_cli.core.irl.robust_mce import discounted_feature_sum, robust_mce_irl, robust_soft_value_iteration
from airl_cli.api import config
from airl_cli.core.mdp.viano_grid import evaluation_dynamics, total_return, viano_grid
from airl_cli.core.mdp.viano_grid import expert_return as viano_expert

GAMMA = 0.99
EPSILONS = (0.0, 0.05, 0.1, 0.15, 0.2)
ALPHAS = (1.0, 0.95, 0.9, 0.85, 0.8)


def published(learner_epsilon: float) -> tuple[dict[float, list[float]], float]:
    """The published rows (alpha -> the return per eps_E) and the expert line at eps_L, from the
    sweep's config; ({}, nan) where none is published."""
    exp = config("experiment=viano_gridworld").experiment
    rows = exp.published.get(str(float(learner_epsilon)), {})
    return {float(a): list(v) for a, v in rows.items()}, float(exp.published_expert.get(str(float(learner_epsilon)), float("nan")))


def learn_and_score(eps_E: float, alpha: float, *, corner: str, all_actions: bool, eps_L: float = 0.0) -> float:
    """The player's total return after learning from the eps_E expert with strength alpha."""
    P_E, allowed, phi, w_star, p0 = viano_grid(epsilon=eps_E, corner=corner)
    P_L = viano_grid(epsilon=eps_L, corner=corner)[0]
    allowed = _actions(allowed, all_actions)
    expert = robust_soft_value_iteration(P_E, phi @ w_star, alpha=1.0, discount=GAMMA, allowed=allowed)[0]
    target = discounted_feature_sum(P_E, expert, p0, phi, GAMMA)
    # transitions[1] is the learner's dynamics for the demonstrations c~_1 (index 0 is not used)
    fit = robust_mce_irl(np.stack([P_E, P_L]), phi, p0, 2, target[None], alpha=alpha, discount=GAMMA, form="infinite",
                         optimizer="adam", lam=0.0, max_iterations=200, lr=0.5, allowed=allowed)
    player = robust_soft_value_iteration(P_L, phi @ fit.weights[0], alpha=alpha, discount=GAMMA, allowed=allowed)[0]
    return total_return(_run_in(P_L, eps_L, all_actions), player, w_star)


def _run_in(P_L: np.ndarray, eps_L: float, all_actions: bool) -> np.ndarray:
    """The dynamics the metric runs in: their agent's noise among the moves that exist (with every
    move existing, the learner's own dynamics)."""
    return P_L if all_actions else evaluation_dynamics(epsilon=eps_L, n_states=P_L.shape[0])


def _actions(allowed: np.ndarray, all_actions: bool) -> np.ndarray:
    """Their action sets, or every action on the grid (the extra state keeps its single action)."""
    if not all_actions:
        return allowed
    out = np.ones_like(allowed)
    out[100:] = allowed[100:]
    return out


def expert_return(*, corner: str, all_actions: bool, eps_L: float = 0.0) -> float:
    """Their "expert" line: the optimal (hard) policy of the true reward in the learner's grid."""
    P_L, allowed, phi, w_star, _ = viano_grid(epsilon=eps_L, corner=corner)
    return viano_expert(P_L, _actions(allowed, all_actions), phi @ w_star, w_star, GAMMA, P_eval=_run_in(P_L, eps_L, all_actions))


def table(*, eps_L: float, corner: str, all_actions: bool) -> dict:
    """One table: ours per alpha (rows: alpha -> the return per eps_E), the published rows and the
    expert line at eps_L (where published), the expert's return, and the seconds it took."""
    rows, expert_published = published(eps_L)
    start = time.perf_counter()
    ours = {f"{a:g}": [learn_and_score(e, a, corner=corner, all_actions=all_actions, eps_L=eps_L) for e in EPSILONS] for a in ALPHAS}
    expert = expert_return(corner=corner, all_actions=all_actions, eps_L=eps_L)
    return {"eps_L": eps_L, "corner": corner, "all_actions": all_actions, "epsilons": list(EPSILONS), "rows": ours,
            "published": {f"{a:g}": rows[a] for a in ALPHAS if a in rows}, "expert": expert,
            "expert_published": None if expert_published != expert_published else expert_published,
            "seconds": time.perf_counter() - start}


#: the page's tables: name -> (eps_L, corner, all_actions)
TABLES = {"eps0": (0.0, "lost", False), "eps0.05": (0.05, "lost", False), "eps0.1": (0.1, "lost", False),
          "stay": (0.0, "stay", False), "all_actions": (0.0, "lost", True)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--learner-epsilon", type=float, default=0.0, help="eps_L (published: 0, 0.05, 0.1)")
    parser.add_argument("--corner", choices=("lost", "stay"), default="lost")
    parser.add_argument("--all-actions", action="store_true")
    parser.add_argument("--json", type=Path, default=None, help="run the page's five tables and write them to FILE")
    args = parser.parse_args()
    if args.json is not None:
        sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
        from _runs import provenance

        tables = {}
        for name, (eps_L, corner, all_actions) in TABLES.items():
            tables[name] = table(eps_L=eps_L, corner=corner, all_actions=all_actions)
            print(f"{name}: {tables[name]['seconds']:.1f} s", flush=True)
        args.json.write_text(json.dumps({**provenance(sys.argv), "tables": tables}, indent=1) + "\n")
        return
    eps_L = args.learner_epsilon
    t = table(eps_L=eps_L, corner=args.corner, all_actions=args.all_actions)
    print(f"eps_L={eps_L:g} corner={args.corner} all_actions={args.all_actions}; columns eps_E = {', '.join(map(str, EPSILONS))}")
    print("| learner | " + " | ".join(f"eps_E = {e:g}" for e in EPSILONS) + " |")
    print("| --- |" + " --- |" * len(EPSILONS))
    for alpha, ours in t["rows"].items():
        pub = t["published"].get(alpha)
        cells = [f"{v:.1f}" if pub is None else f"{v:.1f} ({pub[j]:.1f}, {100 * (v - pub[j]) / abs(pub[j]):+.1f}%)" for j, v in enumerate(ours)]
        name = "MCE IRL (alpha = 1)" if alpha == "1" else f"alpha = {alpha}"
        print(f"| {name} | " + " | ".join(cells) + " |", flush=True)
    e, theirs = t["expert"], t["expert_published"]
    theirs = "" if theirs is None else f" ({theirs:.1f}, {100 * (e - theirs) / abs(theirs):+.1f}%)"
    print(f"| expert (optimal in eps_L = {eps_L:g}) | {e:.1f}{theirs} |")
    print(f"({t['seconds']:.1f} s)")


if __name__ == "__main__":
    main()
