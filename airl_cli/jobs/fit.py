"""``airl fit``: learn reward weights from a dataset file, or from a problem built in-process."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import hydra
import numpy as np
from omegaconf import DictConfig
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from airl_cli.io.dataset import Dataset, read_dataset, write_dataset
from airl_cli.io.fit_folder import write_fit
from airl_cli.jobs.common import Prepared, check_memory, err_console, out_console, output_dir, run_job, save_config, size_note, vector_text, warm_up
from airl_cli.methods import THESIS, learns_reward, plays_game
from airl_cli.plain_progress import PlainProgress
from airl_cli.settings.config import FitSettings
from airl_cli.settings.job import FitJob, fit_job
from airl_cli.settings.overrides import CommandLine
from airl_cli.settings.paths import conf_dir
from airl_cli.usecases.evaluate import identifiability_lines, score_learned
from airl_cli.usecases.fit import check_supported, fit_dataset, learner, with_method_loss
from airl_cli.usecases.learned import Learned
from airl_cli.usecases.problem import build_dataset, loss_kind


def load_dataset(job: FitJob) -> tuple[Dataset, bool, str]:
    """The dataset to learn from (with the loss its method uses: ``usecases.fit.with_method_loss``),
    whether it was built in-process, and the loss the game uses (eq. 5.9's L: what ``loss=auto``
    chose, or ``file`` for the file's own ``loss`` array)."""
    if job.problem is not None:
        dataset, _ = build_dataset(job.problem)
        return dataset, True, loss_kind(job.problem, dataset.features)
    dataset = read_dataset(job.fit.data)
    name = "file" if job.loss == "auto" and dataset.loss is not None else ("zero_one" if job.loss == "auto" else job.loss)
    return with_method_loss(dataset, learner(job.fit), job.loss), False, name


def prepare(cfg: DictConfig, overrides: CommandLine | list[str] = ()) -> Prepared:
    """The job's settings read once (``settings.job.fit_job``) and everything ``main`` would refuse
    before its first result checked, before any folder is made (``launch.preflight``): the
    settings, the memory, and a dataset file with the method.

    Returns the ``FitJob`` for ``main`` and notes on the ``overrides`` that will do nothing (``ignored_settings``)."""
    job = fit_job(cfg)
    check_memory(job)
    if job.problem is None:
        check_supported(load_dataset(job)[0], learner(job.fit))
    return Prepared(job, ignored_settings(cfg, CommandLine.of(overrides), job.fit.method))


#: The groups that configure the thesis's learner alone (method=airl).
LEARNER_GROUPS = ("game", "optim", "pbvi", "variant")
#: The groups that describe a problem airl builds (ignored when the problem comes from data=FILE).
PROBLEM_GROUPS = ("mdp", "dynamics", "demos")


def ignored_settings(cfg: DictConfig, line: CommandLine, method: str) -> list[str]:
    """One sentence per kind of override that this command will not read: the problem's groups
    with data=FILE, the thesis's learner's groups with another method, a map with an environment
    that has none."""
    set_here = [(o.text, o.key.split(".")[0], o.key) for o in line.items if o.sets]
    notes = []
    if cfg.get("data") is not None:
        given = [item for item, group, _ in set_here if group in PROBLEM_GROUPS]
        if given:
            notes.append(f"{', '.join(given)} {'does' if len(given) == 1 else 'do'} nothing with data=FILE: the problem and its demonstrations come from the file")
    if not plays_game(method):
        given = [item for item, group, _ in set_here if group in LEARNER_GROUPS]
        if given:
            notes.append(f"{', '.join(given)} {'does' if len(given) == 1 else 'do'} nothing with method={method}: they configure the thesis's learner (method={THESIS})")
    mdp = cfg.get("mdp") or {}
    if cfg.get("data") is None and mdp.get("name") == "gymnasium" and mdp.get("env") != "FrozenLake":
        given = [item for item, _, key in set_here if key == "mdp.map_name"]
        if given:
            notes.append(f"{given[0]} does nothing with mdp.env={mdp.get('env')}: only FrozenLake has maps")
    return notes


#: How the summary names each loss (eq. 5.9's L; ``metrics.json`` keeps the key).
#: The history-dependent adversary's planners other than PBVI, as the summary names them (pbvi.method).
PLANNER_WORDS = {
    "exact": "exact best responses (every history enumerated)",
    "counts": "exact best responses (the posterior as counts of kinds of move)",
    "mean": "the averaged MDP's best responses",
}
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
        how = f"one shared w, {info['iterations']} iterations"
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


#: Where a comparison method stopped (``usecases.learners.comparison.stop_info``'s ``stopped``), in words.
STOP_WORDS = {
    "tolerance": "converged: its stopping rule met",
    "no_progress": "converged: no further step exists (the projection's mu(w) equals mu_bar)",
    "max_iterations": "NOT converged: stopped at its cap of iterations (method.max_iterations)",
    "line_search": "NOT converged: L-BFGS-B's line search ended short of its tolerance",
}


def stop_sentence(info: dict) -> str:
    """Where a comparison method stopped and what it proves there: its reason, what its rule
    measures at the learned w and, for an objective that is strongly convex (MMP) or concave (MCE
    IRL), the bracket on the objective's optimum (``core.irl.baselines``, eq. (1))."""
    out = f"{STOP_WORDS[info['stopped']]}, {info['stop_measure']} is {info['stop_value']:.2g}"
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
            f"optimum   {info['certified_optimum']:.6g} (certified by optim=exact); f at the learned w is "
            f"{info['objective_at_weights']:.6g} (double oracle to threshold {info['objective_at_weights_tol']:g}), "
            f"{info['above_optimum']:.3g} above it ({100 * info['relative_above_optimum']:.2g}%)"
        )
    if info["oracle_capped_steps"]:
        lines.append(f"note      double oracle reached its iteration cap in {info['oracle_capped_steps']} step(s) (game.max_iterations)")
    return lines


@dataclass(frozen=True)
class FitRun:
    """One finished fit: its data, what was learned, the score rows, the wall time, the summary, the
    loss the game used (as the summary names it) and whether airl built the problem (else a file)."""

    dataset: Dataset
    settings: FitSettings
    learned: Learned
    rows: list[dict]
    seconds: float
    text: str
    loss: str
    generated: bool


def fit_and_write(
    cfg: DictConfig,
    folder: Path,
    job: FitJob,
    on_step: Callable[[dict], None] | None = None,
    on_planner: Callable[[int, int], None] | None = None,
) -> FitRun:
    """Learn as the job's settings (``settings.job.fit_job``, parsed once from ``cfg``) say and
    write every output file of a fit into ``folder`` (``cfg`` itself is saved beside them).

    ``on_step`` gets each iteration's history row, ``on_planner(done, total)`` each time step
    inside a planner call (method=airl).
    """
    settings = job.fit
    check_memory(job)  # before any work: refuse, in one sentence, what will not fit in memory
    dataset, generated, loss = load_dataset(job)
    start = time.perf_counter()
    learned = fit_dataset(dataset, learner(settings), job.seed, callback=on_step, planner_progress=on_planner)
    seconds = time.perf_counter() - start
    rows = score_learned(dataset, learned)
    text = summary_text(dataset, settings, learned, rows, seconds, loss)
    if generated:
        write_dataset(folder / "dataset.npz", dataset)
    metrics = {"method": learned.method, "shared": learned.shared, **learned.info, "scored": dataset.true_weights is not None, "dynamics": rows}
    if plays_game(learned.method):
        metrics["loss"] = loss  # what loss=auto chose (file: the dataset file's own array)
    timing = {"fit_seconds": round(seconds, 6)}
    if "qp_seconds" in learned.history:
        timing["qp_seconds"] = round(float(np.sum(learned.history["qp_seconds"])), 6)
    write_fit(folder, metrics=metrics, timing=timing, summary=text, weights=learned.weights, step_weights=learned.step_weights, policy=learned.policy, history=learned.history)
    save_config(cfg, folder)
    return FitRun(dataset, settings, learned, rows, seconds, text, loss, generated)


def fit_with_progress(cfg: DictConfig, folder: Path, job: FitJob) -> FitRun:
    """``fit_and_write`` under a live display: the learner's iterations, and the current planner call's time steps."""
    settings = job.fit
    exact = settings.optimizer == "exact"
    tol = settings.certified.tol
    columns = (TextColumn("{task.description}"), BarColumn(bar_width=12), TextColumn("{task.fields[info]}"), TimeElapsedColumn())
    name = "fit (exact)" if exact else "fit (gradient)"
    plain, last = PlainProgress(err_console), [""]  # stderr to a file: plain lines, the last step's info
    with Progress(*columns, console=err_console, transient=True, disable=plain.active) as bar:
        fit_task = bar.add_task(name, total=None if exact else settings.options.max_steps, info="")
        # one planner call at S=300, T=30 takes tens of seconds: show which time step it has backed up
        planner_task = bar.add_task("  planner", total=1, info="", visible=False)

        def on_step(row: dict) -> None:
            if "relative_gap" in row:  # an iteration of the exact solve (or of optim.certify's, after the steps)
                bracket = row.get("bracket_upper", np.inf)
                width = f"  bracket [{row['lower']:.6g}, {bracket:.6g}] -> {tol:g}" if np.isfinite(bracket) else ""
                info = (
                    f"{'' if exact else 'certifying: '}iteration {row['iteration']}  gap {row['relative_gap']:.2g}  "
                    f"f in [{row['lower']:.6g}, {row['upper']:.6g}]{width}"
                )
            else:
                info = f"step {int(row['step']) + 1}/{settings.options.max_steps}  objective {row['objective']:.5g}  |grad| {row['grad_norm']:.3g}"
            bar.update(fit_task, advance=1 if exact or "step" in row else 0, info=info)
            last[0] = info
            plain.line(f"{name} {info}")

        def on_planner(done: int, total: int) -> None:
            bar.update(planner_task, completed=done, total=total, visible=done < total, info=f"time step {done}/{total}")
            if done < total:  # a finished call is followed by its iteration's line
                plain.line(f"{name} {last[0] or 'starting'}; planner time step {done}/{total}")

        if settings.optimizer == "gradient" and settings.certify:
            bar.console.print("after the gradient steps, the exact solve certifies the optimum for comparison (optim.certify)")
        return fit_and_write(cfg, folder, job, on_step, on_planner)


def main(cfg: DictConfig, job: FitJob) -> None:
    """Fit as ``job`` (``prepare``'s, read from ``cfg``) says, into Hydra's run folder, and report."""
    folder = output_dir()
    if not plays_game(job.fit.method):
        with err_console.status(f"fitting method={job.fit.method}"):
            run = fit_and_write(cfg, folder, job)
    else:
        if note := size_note(job):
            err_console.print(note, soft_wrap=True)
        with err_console.status("loading the planner (the first run after installing compiles it and the QP solver: about 40 s, once)"):
            warm_up()
        run = fit_with_progress(cfg, folder, job)
    out_console.print(run.text, end="", soft_wrap=True)
    if VERBOSE and plays_game(run.learned.method):
        out_console.print("\n" + "\n".join(verbose_lines(run.learned.info)), soft_wrap=True)
    out_console.print(f"\nwrote {folder} (fit in {run.seconds:.2f} s)", soft_wrap=True)
    for sentence in fit_warnings(run.learned.info):
        err_console.print(f"warning: {sentence}", soft_wrap=True)
        WARNED.append(sentence)
    if plays_game(run.learned.method) and (wide := wide_sentence(run.learned.info)):
        WIDE.append(wide)


#: ``airl fit --verbose``: the summary is followed by ``verbose_lines`` (set by the command line).
VERBOSE: list[bool] = []


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


#: The warnings of the fits run in this process (``airl fit --strict`` exits 3 if there are any).
WARNED: list[str] = []
#: What ``airl fit --strict`` also counts as not converged: a bracket on eq. 5.9's minimum wider than optim.tol.
WIDE: list[str] = []


def wide_sentence(info: dict) -> str | None:
    """The sentence ``--strict`` adds when the fit's certificate, the bracket valid whatever the
    adversary's policy, is wider than optim.tol (or missing, where the fit closes none)."""
    if info.get("optimizer") != "exact" or info.get("converged") or info.get("stopped") in ("max_iterations", "max_seconds"):
        return None  # the gradient steps have no bracket; a fit at a budget warns already (``fit_warnings``)
    return f"not converged: {info['certificate']}"


def fit_warnings(info: dict) -> list[str]:
    """The sentences a fit warns with on stderr: a certified learner stopped at a budget with its
    bracket wider than optim.tol (the width it reached, the setting that narrows it), a degenerate
    optimum (a certificate that says nothing of the reward), a learned reward that is the same
    everywhere (any method's: its policy is a tie-break)."""
    out = []
    if info.get("optimizer") == "exact" and info.get("stopped") in ("max_iterations", "max_seconds") and not info.get("converged"):
        out.append(f"NOT converged: {info['certificate']}")
    if "stop_measure" in info and not info["converged"]:  # a comparison method at its cap
        out.append(f"{stop_sentence(info)}; a larger method.max_iterations goes further")
    if info.get("degenerate"):
        out.append(degenerate_sentence(info))
    if constant := constant_sentence(info):
        out.append(constant)
    return out


@hydra.main(version_base="1.3", config_path=conf_dir(), config_name="airl")
def hydra_main(cfg: DictConfig) -> None:
    """One job of ``airl fit --multirun`` (a single run is composed, prepared and started by ``launch``)."""
    run_job(lambda c: main(c, prepare(c).value), cfg)
