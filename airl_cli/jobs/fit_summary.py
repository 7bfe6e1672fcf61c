"""What ``airl fit`` says about a fit: the summary it prints and writes (``summary_text``), the
sentences it warns with on stderr (``fit_warnings``, which ``--strict`` turns into exit 3) and
``--verbose``'s details (``verbose_lines``), all from the fit's dataset, settings and metrics
``info`` (the learner's ``Learned.info``, as metrics.json keeps it)."""

from __future__ import annotations

import numpy as np

from airl_cli.io.dataset import Dataset
from airl_cli.jobs.common import vector_text
from airl_cli.methods import STOP_WORDS, learns_reward, plays_game
from airl_cli.settings.config import FitSettings
from airl_cli.usecases.evaluate import identifiability_lines
from airl_cli.usecases.learned import Learned

#: The history-dependent adversary's planners other than PBVI, as the summary names them (pbvi.method).
PLANNER_WORDS = {
    "exact": "exact best responses (every history enumerated)",
    "counts": "exact best responses (the posterior as counts of kinds of move)",
    "mean": "the averaged MDP's best responses",
}
#: How the summary names each loss (eq. 5.9's L; ``metrics.json`` keeps the key).
LOSS_WORDS = {"zero_one": "zero-one loss", "squared_features": "squared feature distance", "squared_euclidean": "squared grid distance", "file": "the file's own loss"}


def summary_text(dataset: Dataset, settings: FitSettings, learned: Learned, rows: list[dict], seconds: float, loss: str = "") -> str:
    info = learned.info
    if plays_game(learned.method):
        o = settings.options
        how = f"{'one shared w' if o.weight_sharing else 'one w_j per dynamics'}, lambda={o.lam:g}, {LOSS_WORDS.get(loss, loss)}, "
        if info["optimizer"] == "exact":
            how += f"exact solve of eq. 5.9: {info['iterations']} iterations, {info['planner_calls']} planner calls, "
        else:
            how += f"gradient descent (Table I): {info['steps']} steps (stopped: {info['stopped']}), "
        if o.planner.adversary == "markov":
            how += "Markov adversary (" + ("every Markov policy enumerated" if o.planner.method == "exact" else "CADP best responses") + ")"
        elif info.get("planner", o.planner.method) in PLANNER_WORDS:
            how += PLANNER_WORDS[info.get("planner", o.planner.method)]
        elif info.get("best_responses") == "counts_cut":  # a closing fit answered and bracketed by count programs cut at a layer
            how += (f"best responses from the count program exact over {info['response_cut_layers']} layers (the likeliest models' "
                    f"own policies after them), bracketed by one over {info['bracket_cut_layers']}")
        else:
            grown = f", grown to {info['sharpened_beliefs']} where its policy goes" if info.get("sharpened_beliefs", info["n_beliefs"]) > info["n_beliefs"] else ""
            how += f"PBVI {o.planner.iterations} iterations ({info['n_beliefs']} beliefs{grown})"
            # a closing fit on a grid of beliefs: PBVI plans only the brackets' first policies
            how += " in the bracket; best responses on its grid of beliefs" if info.get("best_responses") == "grid" else ""
        if settings.matching == "per_step":
            how += ", features matched at every step (game.matching=per_step)"
    elif not learns_reward(learned.method):
        how = "action frequencies of the demonstrations"
    else:
        how = f"one shared w, {info['iterations']} iteration{'' if info['iterations'] == 1 else 's'}"
    given = f", N={dataset.n_demos}" if dataset.feature_expectations is None else ", exact feature expectations"
    given += f", discount {dataset.discount:g}" if dataset.discount < 1.0 else ""
    lines = [
        f"airl fit: method={learned.method}",
        f"problem   S={dataset.n_states}, A={dataset.n_actions}, K={dataset.n_features}{f' (features{dataset.features_text()})' if dataset.features_text() else ''}, T={dataset.horizon}, D={dataset.n_dynamics}{given}",
        f"fit       {how}",  # the time is in timing.json: the summary is the same bytes for the same config
    ]
    if dataset.environment is not None:  # an environment's problem says where it and its dynamics come from
        lines.insert(2, f"env       {dataset.environment}" + (f"; tau_j: {dataset.perturbation}" if dataset.perturbation else ""))
    if dataset.expert == "own":  # the field's expert model: can these dynamics identify its reward?
        lines += [f"identify  {line}" for line in identifiability_lines(dataset)]
    if plays_game(learned.method):
        lines += _objective_lines(info)
        if info.get("degenerate"):
            lines.append(f"warning   {degenerate_sentence(info)}")
    elif "stopped" in info:
        lines.append(f"stopped   {stop_sentence(info)}")
    if constant := constant_sentence(info):
        lines.append(f"warning   {constant}")
    if zero := zero_truth_sentence(dataset):
        lines.append(f"warning   {zero}")
    if learned.weights is not None:
        lines += ["", "learned weights:"]
        if learned.step_weights is not None:
            lines.append("  (game.matching=per_step: a reward w_t . phi per step t, all in weights.json; below, their mean over t = 1..T-1)")
        if learned.shared:
            lines.append("  w:   " + vector_text(learned.weights[0]) + "  (shared by every dynamics)")
        else:
            for j, row in enumerate(learned.weights, start=1):
                lines.append(f"  w_{j}: " + vector_text(row))
        if learned.weights.shape[1] > 12:
            lines.append(f"  (all K = {learned.weights.shape[1]} in weights.json)")
    if rows and rows[0]["learner_score"] is not None:
        lines += ["", "normalised performance under the true reward (thesis §7.2):", ""]
        lines += _score_table(rows, held_out=dataset.n_test > 0, returns=dataset.n_test > 0 or dataset.environment is not None)
    else:
        lines += ["", "the dataset has no true weights: nothing to score against"]
    return "\n".join(lines) + "\n"


def stop_sentence(info: dict) -> str:
    """Where a comparison method stopped and what it proves there: its reason, what its rule
    measures at the learned w and, for an objective that is strongly convex (MMP) or concave (MCE
    IRL), the bracket on the objective's optimum (``core.irl.baselines``, eq. (1))."""
    out = f"{STOP_WORDS[info['stopped']][0]}, {info['stop_measure']} is {info['stop_value']:.2g}"
    if info.get("objective_bracket") is not None:
        lo, up = info["objective_bracket"]
        out += (f"; its objective's optimum lies in [{lo:.6g}, {up:.6g}] (relative width {info['objective_relative_width']:.2g}), "
                f"{info['objective']:.6g} at the learned w")
    return out


def constant_sentence(info: dict) -> str | None:
    """One sentence where the learned reward is the same everywhere in some dynamics
    (``usecases.fit.constant_dynamics``: w = 0, say): the learner's policy there is the planner's
    tie-break, whatever its score; None otherwise, and for the thesis's degenerate optimum, which
    ``degenerate_sentence`` says already."""
    names = info.get("constant_reward") or []
    if not names or info.get("degenerate"):
        return None
    return (f"the learned reward w . phi is the same in every state and action ({', '.join(names)}): every policy is optimal "
            "for it, so the learner's policy there and its scores are the planner's tie-break (the lowest action), not a learned reward's")


def degenerate_sentence(info: dict) -> str:
    """One sentence for a certified w that is the zero reward, is it in all but name (it moves the payoff
    by less than the tolerance), or is barely constrained (w = 0 passes the certificate too, ``core.degeneracy``)."""
    if info.get("zero_answer"):
        return (
            "the certified answer is the zero reward: w = 0 is optimal to the tolerance (its upper bound on f(0) is "
            "exact, a plan under tau alone), so the demonstrations do not constrain the reward and the learner's "
            "policy is not learned from them (see the documentation, docs/method.md, 'A degenerate optimum')"
        )
    if info["reward_effect"] <= info["tol"] * max(1.0, abs(info["objective"])):
        return (
            f"the learned reward is indistinguishable from zero: it moves the game's payoff by at most {info['reward_effect']:.2g}, "
            "below the certificate's tolerance, so w = 0 is optimal too and the demonstrations do not constrain the "
            "reward (its direction is noise; see the documentation, docs/method.md, 'A degenerate optimum')"
        )
    # w moves the payoff by more than the tolerance: its direction can carry signal (measured, a
    # median cos(w, w*) of 0.83 on such fits of the degeneracy experiment, 0.47 on the ones above)
    return (
        f"the learned reward is barely constrained: w = 0 passes the certificate too (relative gap "
        f"{info['zero_relative_gap']:.2g} at w = 0, within optim.tol), so the demonstrations hardly tell this "
        f"reward from the zero reward, though it moves the game's payoff by {info['reward_effect']:.2g} and its direction "
        "may still carry signal (see the documentation, docs/method.md, 'A degenerate optimum')"
    )


def _score_table(rows: list[dict], *, held_out: bool, returns: bool) -> list[str]:
    """The summary's score table, one line per dynamics; with ``returns`` (held-out test dynamics, or
    an environment: a return compares across dynamics, and is what the field reports) the expected
    returns too, and where the dataset has a goal the probabilities of reaching it."""
    mixed = rows[0]["equilibrium_score"] is not None
    goal = rows[0]["learner_goal"] is not None
    extra = (f"{'return':>10}{'demo return':>13}" if returns else "") + (f"{'goal':>8}{'demo goal':>11}" if goal else "")
    lines = [f"  {'dynamics':<10}{'learner':>9}{'demonstrator':>14}{'cos(w, w*)':>12}" + (f"{'game p':>9}" if mixed else "") + extra]
    for r in rows:
        cos = "-" if r["cosine_similarity"] is None else f"{r['cosine_similarity']:.3f}"
        p = f"{r['equilibrium_score']:>9.4f}" if mixed else ""
        ret = f"{r['learner_return']:>10.4g}{r['demonstrator_return']:>13.4g}" if returns else ""
        ret += f"{r['learner_goal']:>8.3f}{r['demonstrator_goal']:>11.3f}" if goal else ""
        lines.append(f"  {r['dynamics']:<10}{r['learner_score']:>9.4f}{r['demonstrator_score']:>14.4f}{cos:>12}{p}{ret}")
    notes = ["learner: the optimal policy of the learned reward; game p: the equilibrium's own mixture of policies"] if mixed else []
    notes += ["test_e: held-out dynamics no demonstration came from"] if held_out else []
    notes += ["return: expected return under the true reward"] if returns else []
    notes += ["goal: the probability of reaching the environment's goal within the horizon"] if goal else []
    return lines + [f"  ({'; '.join(notes)})"] if notes else lines


def _objective_lines(info: dict) -> list[str]:
    """The certificate (the exact solve: the bracket on eq. 5.9's minimum, ``usecases.bracket.certificate_line``)
    or where the gradient steps stopped relative to the minimum."""
    if info["optimizer"] == "exact":
        return [f"certified {info['certificate']}"]
    lines = [f"objective {info['objective']:.6g} at the last step, (1/K)|grad|_1 = {info['grad_norm']:.3g}"]
    if "certified_optimum" in info:
        lines.append(
            f"optimum   {info['certified_optimum']:.6g}, the minimum of the game the steps play (against PBVI's best responses, "
            "by the exact solve; eq. 5.9's minimum whatever the adversary's policy is optim=exact's bracket, at or above it); f at the learned w is "
            f"{info['objective_at_weights']:.6g} (double oracle to threshold {info['objective_at_weights_tol']:g}), "
            f"{info['above_optimum']:.3g} above it ({100 * info['relative_above_optimum']:.2g}%)"
        )
    if info["oracle_capped_steps"]:
        lines.append(f"note      double oracle reached its iteration cap in {info['oracle_capped_steps']} step(s) (game.max_iterations)")
    return lines


def verbose_lines(info: dict) -> list[str]:
    """``airl fit --verbose``: what stands behind the certificate, from the fit's metrics ``info``:
    the planner chosen and why, the fit's own gap against it, the bracket's effort, the objective at
    the learned w as the planner sees it."""
    if info.get("optimizer") != "exact":
        return []
    lines = ["details (metrics.json):", f"  planner     pbvi.method={info['planner']}: {info['planner_reason']}"]
    lines.append(f"  gap         {info['planner_certificate']}")
    lines.append(f"  objective   {info['objective']:.6g} at the learned w against those best responses; lower bound {info['lower_bound']:.6g}")
    if "bracket_calls" in info:
        lines.append(
            f"  bracket     {info['bracket_calls']} bracket(s) {_bracket_effort(info)}; {info['close_steps']} closing step(s); "
            f"the bracket's policy bounds the answer {info['planner_resolution']:.2g} (relative) above the planner's"
        )
    elif "planner_resolution" in info:
        lines.append(f"  resolution  PBVI on {info['check_beliefs']} beliefs bounds the answer {info['planner_resolution']:.2g} (relative) higher")
    return lines


def _bracket_effort(info: dict) -> str:
    """What one bracket of the fit planned, from its metrics ``info``: the count program cut at a
    layer (``core.irl.cut_closer``) or PBVI's beliefs backed up, on a grid of beliefs where it has one."""
    if "bracket_cut_layers" in info:
        return f"by the count program exact over {info['bracket_cut_layers']} layers ({info['bracket_cut_nodes']:,} nodes), the likeliest models' own policies after them"
    grid = f", its grid of beliefs at resolution {info['bracket_grid_resolution']}" if info.get("bracket_grid_resolution") else ""
    return f"of {info['bracket_beliefs']:,} beliefs{grid}"


def zero_truth_sentence(dataset: Dataset) -> str | None:
    """The sentence for a dataset whose true weights are all 0 (None otherwise): its scores say nothing."""
    if dataset.true_weights is None or np.any(dataset.true_weights):
        return None
    return "the dataset's true weights are all 0: every policy is optimal for the true reward, so every score is 1 and cos(w, w*) is 0"


def fit_warnings(info: dict, dataset: Dataset | None = None) -> list[str]:
    """The sentences a fit warns with on stderr: a certified learner whose bracket is wider than
    optim.tol (stopped at a budget: "NOT converged"; else held open by its planner, the Markov
    adversary's game or the grid's resolution), with the width it reached and the setting that
    narrows it (the certificate's own words), a degenerate
    optimum (a certificate that says nothing of the reward), a learned reward that is the same
    everywhere (any method's: its policy is a tie-break)."""
    out = []
    if info.get("optimizer") == "exact" and not info.get("converged"):
        budget = info.get("stopped") in ("max_iterations", "max_seconds")
        out.append(f"{'NOT converged' if budget else 'not closed to optim.tol'}: {info['certificate']}")
    if "stop_measure" in info and not info["converged"]:  # a comparison method at its cap
        out.append(f"{stop_sentence(info)}; a larger method.max_iterations goes further")
    if info.get("degenerate"):
        out.append(degenerate_sentence(info))
    if constant := constant_sentence(info):
        out.append(constant)
    if dataset is not None and (zero := zero_truth_sentence(dataset)):
        out.append(zero)
    return out
