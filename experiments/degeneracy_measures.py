"""Why the optimum of eq. 5.9 degenerates on the random MDP as S grows: five measures per size.

    python experiments/degeneracy_measures.py [--sizes 20 50 100 200] [--seeds 0 1 2 3 4 5]
                                              [--sigma-states S0] [--loss auto] [--json FILE]

For the random MDP of ``experiment=degeneracy`` (eq. 7.3's sigma = 0.1, D = 3, T = 10), averaged
over the seeds:

- the total variation between the rows tau(.|s, a) and tau_j(.|s, a);
- the overlap sum_s min(p_tau(t, s), p_tau_j(t, s)) of the expert's state marginals under tau and
  under tau_j, averaged over t = 1..T-1 (1: the same states at the same steps; 0: disjoint);
- the range of the true reward's expected return over all policies under tau_j, R-bar - r-bar of
  thesis §7.2, relative to its range under tau (how much the actions still decide under tau_j);
- the expert's largest state probability under tau, averaged over t = 1..T-1 (how predictable it is);
- the price of imitation: the loss the adversary gives up by playing the expert's own policy,

      Delta = f(0) - min_p p^T L q_E,      f(0) = max_q min_p p^T L q  (the game at w = 0)

  with the loss scaled to a largest entry of 1, as the learner scales it. The expert's policy
  q_E is a Markov policy: every adversary of the game (history-dependent or Markov) may play it,
  and run in tau_j it collects the demonstrated features exactly (per step as well as in sum)
  when the demonstrations are exact. So f* >= min_p p^T L q_E, i.e. f(0) - f* <= Delta for every
  variant of ``conf/variant/`` that keeps the loss: once Delta is below the certificate's
  tolerance, the zero reward is optimal to that tolerance whatever the adversary or the matching.
  f(0) is the game's value at w = 0, T (1 - 1/S) for the zero-one loss when the players can spread
  their state marginals evenly (measured by the fits; printed here as T (1 - 1/S) for that loss);
  the expert's term is exact (the learner's best response by backward induction).

Prints a markdown table. With ``--json FILE`` it also writes the measures per size ("S20") to FILE,
with the commit and the machine (the docs pages' source ``degeneracy_measures``), and the row total
variation, the expert's state overlap and the return range with sigma scaled as 1/S
(``dynamics.sigma_states=20``) beside them (``scaled_tv``, ``scaled_overlap``, ``scaled_return_range``), and
at S = 20 the row total variation for each sigma of fig09 (``sigma_tv``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import airl_cli  # noqa: F401  (first, before numpy: it pins OpenBLAS's kernels, as the commands do)
import numpy as np

from airl_cli import api
from airl_cli.core.irl.game import learner_best_response
from airl_cli.core.irl.game_problem import GameProblem
from airl_cli.core.mdp.planning import backward_induction, state_marginals
from airl_cli.core.mdp.scores import return_bounds


def fig09_sigmas() -> list[float]:
    """Eq. 7.3's noise sigma at the values fig09 sweeps (its config, conf/experiment/fig09.yaml)."""
    import yaml

    return yaml.safe_load((Path(__file__).resolve().parents[1] / "conf" / "experiment" / "fig09.yaml").read_text())["experiment"]["values"]


def measures(S: int, seed: int, extra: list[str]) -> tuple[float, float, float, float, float]:
    """(row total variation, marginal overlap, relative return range, expert's largest state
    probability, expert's loss as the adversary) for one dataset."""
    ds = api.make_dataset(f"mdp.n_states={S}", f"seed={seed}", "demos.n=1", *extra)
    P, p0, T = ds.transitions, ds.initial, ds.horizon
    R = ds.features @ ds.true_weights
    expert, _ = backward_induction(P[0], R, horizon=T)
    under = [state_marginals(P[j], expert, p0) for j in range(P.shape[0])]
    D = range(1, P.shape[0])
    tv = float(np.mean([0.5 * np.abs(P[0] - P[j]).sum(axis=-1).mean() for j in D]))
    shared = float(np.mean([np.minimum(under[0][1:], under[j][1:]).sum(axis=1).mean() for j in D]))
    ranges = [np.subtract(*return_bounds(P[j], R, p0, horizon=T)[::-1]) for j in range(P.shape[0])]
    game = GameProblem(P, ds.features, p0, ds.loss, T).with_scaled_loss(True)
    learner = learner_best_response(game, under[0])  # the learner's best reply to the expert as adversary, under tau
    expert_loss = float(np.sum(game.loss_times(learner) * under[0]))
    return tv, shared, float(np.mean(ranges[1:]) / ranges[0]), float(under[0][1:].max(axis=1).mean()), expert_loss


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[20, 50, 100, 200])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4, 5])
    parser.add_argument("--sigma-states", type=int, default=None, help="dynamics.sigma_states (default: sigma unscaled)")
    parser.add_argument("--loss", default="auto", help="the loss group (auto: zero-one on the random MDP)")
    parser.add_argument("--json", type=Path, default=None, help="also write the measures (and the scaled sigma's row total variation) to FILE")
    args = parser.parse_args()
    extra = [f"loss={args.loss}"] + ([] if args.sigma_states is None else [f"dynamics.sigma_states={args.sigma_states}"])
    zero_one = args.loss in ("auto", "zero_one")
    print(
        "| S | row total variation τ vs τ_j | expert's state overlap τ vs τ_j | return range under τ_j / under τ "
        "| expert's largest state probability | expert as adversary: min_p loss | f(0) = T(1 − 1/S) | price of imitation Δ |"
    )
    print("|---|---|---|---|---|---|---|---|")
    rows = {}
    for S in args.sizes:
        tv, shared, ratio, top, expert_loss = np.mean([measures(S, seed, extra) for seed in args.seeds], axis=0)
        T = api.make_dataset(f"mdp.n_states={S}", "demos.n=1").horizon
        f0 = T * (1 - 1 / S) if zero_one else float("nan")
        delta = f"{f0 - expert_loss:.3f}" if zero_one else "-"
        print(f"| {S} | {tv:.2f} | {shared:.2f} | {ratio:.2f} | {top:.3f} | {expert_loss:.3f} | {f0:.3f} | {delta} |", flush=True)
        rows[f"S{S}"] = {"tv": tv, "overlap": shared, "return_range": ratio, "top": top, "expert_loss": expert_loss,
                         "f0": f0 if zero_one else None, "delta": f0 - expert_loss if zero_one else None}
    if args.json is not None:
        scaled = [f"loss={args.loss}", "dynamics.sigma_states=20"]
        for S in args.sizes:
            tv, shared, ratio, _, _ = np.mean([measures(S, seed, scaled) for seed in args.seeds], axis=0)
            rows[f"S{S}"] |= {"scaled_tv": tv, "scaled_overlap": shared, "scaled_return_range": ratio}
        sigma_tv = {f"{sigma:g}": float(np.mean([measures(20, seed, [f"loss={args.loss}", f"dynamics.sigma={sigma}"])[0] for seed in args.seeds]))
                    for sigma in fig09_sigmas()}
        sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
        from _runs import provenance

        record = {**provenance(sys.argv), "seeds": args.seeds, "sigma_tv": sigma_tv, "rows": {k: {m: float(v) if v is not None else None for m, v in r.items()} for k, r in rows.items()}}
        args.json.write_text(json.dumps(record, indent=1) + "\n")


if __name__ == "__main__":
    main()
