"""``airl plan``: solve a multi-model MDP with the chapter-6 planner or a published heuristic.

Reads a CSV folder or an ``.npz`` (``airl_cli.io.mmdp_files``), plans over ``plan.horizon`` decisions,
and writes to the run folder: ``plan.json`` (objective on the training models, mean return on the
test models, time, the bracket on the optimum whatever the planner), ``policy.npz`` (the policy graph's arrays, and ``markov_policy`` (T, S) for
Markov methods; ``airl_cli.io.policy_file.load_policy`` reads it back), ``best_policy.npz`` where the
bracket's lower side is a policy that earns more than the plan's (the same arrays), and ``config.yaml``.
"""

from __future__ import annotations

from typing import NamedTuple

import hydra
import numpy as np
from omegaconf import DictConfig

from airl_cli.core.numerics.magnitude import MAX_SUM, largest_sum
from airl_cli.errors import ConfigError
from airl_cli.io.files import write_json
from airl_cli.io.mmdp_files import MMDPProblem, input_path, read_problem
from airl_cli.io.policy_file import save_policy
from airl_cli.jobs.common import Prepared, err_console, out_console, output_dir, run_job, save_config, warm_up
from airl_cli.plain_progress import PlainProgress
from airl_cli.settings.config import PlanSettings, plan_settings
from airl_cli.settings.paths import conf_dir
from airl_cli.usecases.memory import plan_refusal
from airl_cli.usecases.plan import bracket_optimum, check_exact, mean_test_return, run_plan


class PlanInput(NamedTuple):
    """What one plan reads (``prepare``): its settings and the problem of its input files."""

    settings: PlanSettings
    problem: MMDPProblem


def prepare(cfg: DictConfig, overrides: list[str] = ()) -> Prepared:
    """The plan's settings and input files read once (a ``PlanInput``, for ``main``) and what
    ``main`` would refuse before planning checked, before any folder is made
    (``launch.preflight``): the settings, the input's files, a horizon that surely does not fit in
    memory, and an exact enumeration of too many histories."""
    settings = plan_settings(cfg)
    problem = read_problem(settings.input)
    M, S, _ = problem.shape
    n_next = int(np.count_nonzero(problem.transitions, axis=-1).max())
    sentence = plan_refusal(M, S, n_next, settings.horizon)
    if sentence is not None:
        raise ConfigError(sentence)
    for name, rewards in (("rewards", problem.rewards), ("test rewards", problem.test_rewards)):
        if rewards is not None and largest_sum(rewards, settings.horizon) > MAX_SUM:
            raise ConfigError(
                f"the {name} reach {np.max(np.abs(rewards)):.3g}: their sums over plan.horizon = {settings.horizon} decisions "
                f"(up to {largest_sum(rewards, settings.horizon):.3g}) are beyond {MAX_SUM:.0e}, where the planners' values overflow; scale them down"
            )
    check_exact(problem, settings)
    return Prepared(PlanInput(settings, problem))


def main(cfg: DictConfig, plan: PlanInput) -> dict:
    """Plan as ``plan`` (``prepare``'s) says, write plan.json and policy.npz, and report."""
    settings, problem = plan
    M, S, A = problem.shape
    folder = output_dir()
    what = f"planning with {settings.method} (M={M}, S={S}, A={A}, T={settings.horizon})"
    plain = PlainProgress(err_console)  # stderr to a file: plain lines, at most every 5 s
    if settings.method == "pbvi" and (beliefs := 2 ** (settings.iterations - 1)) > 1024:  # the set at most doubles per expansion
        err_console.print(f"note: plan.iterations={settings.iterations} allows up to {beliefs:,} belief points: growing them, and "
                          f"each of the {settings.horizon} backups, may take minutes", soft_wrap=True)
    with err_console.status(what) as status:
        warm_up()

        def progress(done: int, total: int) -> None:
            status.update(f"{what}: time step {done}/{total} backed up")
            plain.line(f"{what}: time step {done}/{total} backed up")

        result, discount, test, seconds = run_plan(problem, settings, progress)
        status.update(f"{what}: bracketing the optimum")
        br = bracket_optimum(problem, settings, result, discount)
    record = {
        "input": str(input_path(settings.input).resolve()),
        "method": settings.method,
        "horizon": settings.horizon,
        "discount": discount,
        "models": M, "states": S, "actions": A,
        "test_models": None if problem.test_transitions is None else int(problem.test_transitions.shape[0]),
        "objective": result.objective,
        "test_return": test,
        "seconds": seconds,
        "pbvi_iterations": settings.iterations if settings.method == "pbvi" else None,
        "beliefs": result.n_beliefs,
        "nodes": int(result.graph.n_nodes.sum()),
        "cadp_sweeps": result.sweeps if settings.method == "cadp" else None,
        "optimum_bracket": [result.objective] * 2 if settings.method == "counts" else None if br is None else [br.lower, br.upper],
        "each_model_known": None if br is None else br.corner,
        "bracket_beliefs": None if br is None else br.beliefs,
        "bracket_count_layers": None if br is None else br.count_layers,
        "bracket_tol": settings.bracket_tol,
        "best_policy": None,
    }
    better = br is not None and br.better_policy(result.objective)
    if better:  # the bracket's lower side is a policy that earns more than the plan's: written beside it
        record["best_policy"] = {"file": "best_policy.npz", "objective": br.policy_value, "source": br.policy_source,
                                 "test_return": mean_test_return(problem, settings, br.policy, discount)}
        save_policy(folder / "best_policy.npz", br.policy)
    save_policy(folder / "policy.npz", result)
    write_json(folder / "plan.json", record)
    save_config(cfg, folder)
    lines = [
        f"{settings.method}: M={M} training models, S={S}, A={A}, T={settings.horizon}, discount={discount:g}",
        f"  objective on the training models (prior-weighted mean return): {result.objective:.4f}",
        f"  mean return on the {record['test_models']} test models: {test:.4f}" if test is not None else "  no test models",
        f"  planning time: {seconds:.2f} s; policy graph: {record['nodes']:,} nodes",
    ]
    if settings.method == "counts":
        lines.append("  this is the optimum on the training models: exact, the posterior over the models being a count of kinds of move")
    if br is not None:
        how = [f"{br.beliefs:,} beliefs backed up"] if br.beliefs else []
        how += [f"the count program exact over {br.count_layers} of {settings.horizon + 1} layers"] if br.count_layers else []
        how += [f"with each model known: {br.corner:.4f}"] if br.corner is not None else []
        within = f"within plan.bracket_tol = {settings.bracket_tol:g}" if br.width <= settings.bracket_tol else f"wider than plan.bracket_tol = {settings.bracket_tol:g}"
        lines.append(f"  the optimum on the training models lies in [{br.lower:.4f}, {br.upper:.4f}] whatever the planner (relative width {br.width:.2g}, {within}; {'; '.join(how)})")
        if better:
            best = record["best_policy"]
            on_test = f", {best['test_return']:.4f} on the test models" if best["test_return"] is not None else ""
            if br.policy_source == "count":
                what = f"the count program's (exact over {br.count_layers} layers, then the likeliest models' own policies)"
            else:
                what = f"{'this plan' if settings.method == 'pbvi' else 'PBVI'}'s graph with a node for each belief the bracket backed up"
            lines.append(f"  a better policy, the bracket's lower side, {what}: {best['objective']:.4f} on the training models{on_test}; "
                         "written to best_policy.npz")
        if br.width > settings.bracket_tol and br.spent:
            lines.append(f"  the bracket stopped at its budget of beliefs (plan.bracket_beliefs = {settings.bracket_beliefs:,} per state and decision): a larger plan.bracket_beliefs narrows it")
    out_console.print("\n".join(lines), soft_wrap=True)
    written = f"{folder / 'plan.json'}, {folder / 'policy.npz'} and {folder / 'best_policy.npz'}" if better else f"{folder / 'plan.json'} and {folder / 'policy.npz'}"
    out_console.print(f"wrote {written}", soft_wrap=True)
    return record


@hydra.main(version_base="1.3", config_path=conf_dir(), config_name="airl_plan")
def hydra_main(cfg: DictConfig) -> None:
    """One job of ``airl plan --multirun`` (a single run is composed, prepared and started by ``launch``)."""
    run_job(lambda c: main(c, prepare(c).value), cfg)
