"""``airl generate``: build a problem, sample demonstrations, write the dataset file and a summary."""

from __future__ import annotations

import hydra
import numpy as np
from omegaconf import DictConfig
from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

from airl_cli.core.mdp.problems import noise
from airl_cli.envs.named import env_parameter
from airl_cli.io.dataset import Dataset, write_dataset
from airl_cli.io.files import write_text
from airl_cli.jobs.common import Prepared, check_build_memory, err_console, out_console, output_dir, run_job, save_config, vector_text
from airl_cli.plain_progress import PlainProgress
from airl_cli.settings.config import EnvMDPSettings, ProblemSettings, WindyMDPSettings, problem_settings
from airl_cli.settings.paths import conf_dir
from airl_cli.settings.problem_defaults import is_env_id
from airl_cli.usecases.problem import build_dataset, expert_scores, loss_kind


def describe(settings: ProblemSettings, dataset: Dataset) -> list[tuple[str, str]]:
    """(label, text) lines that say what the problem is."""
    mdp, dyn, demos = settings.mdp, settings.dynamics, settings.demos
    sizes = f"S={dataset.n_states}, A={dataset.n_actions}, K={dataset.n_features}, T={dataset.horizon}"
    if mdp.name == "random":
        problem = f"random MDP ({sizes})"
    elif mdp.name == "grid":
        problem = f"grid world {mdp.size}x{mdp.size}, epsilon={mdp.epsilon:g} ({sizes})"
    elif isinstance(mdp, EnvMDPSettings) and is_env_id(mdp.env):
        kind = "one-hot features of (s, a), w* its reward of each state and action" if dataset.action_features else "one-hot state features"
        problem = f"{mdp.env}, made by gymnasium.make with its own defaults, {kind} ({sizes})"
    elif isinstance(mdp, EnvMDPSettings):
        where = f" {mdp.map_name}" if mdp.env == "FrozenLake" else (f" {mdp.width}x{mdp.height}" if mdp.name == "seals" else "")
        problem = f"{mdp.name} {mdp.env}{where}, {env_parameter(mdp.env, mdp.value)}, features={mdp.features} ({sizes})"
    elif isinstance(mdp, WindyMDPSettings):
        reward = (f"their reward rE of seed {settings.seed}: +-1 on {mdp.n_rewarded} (state, action) pairs, one-hot features of (s, a)" if mdp.reward == "theirs"
                  else f"w* +-1 on {mdp.n_rewarded} states, one-hot state features")
        problem = f"windy gridworld {mdp.width}x{mdp.height}, tau's wind {mdp.direction} {mdp.level:g}, {reward} ({sizes})"
    else:
        problem = (
            f"objectworld {mdp.size}x{mdp.size}, {mdp.n_objects} objects of {mdp.n_colours} colours, "
            f"features={mdp.features}, slip={mdp.slip:g} ({sizes})"
        )
    dynamics = f"{dyn.name}, D={dataset.n_dynamics}"
    if dyn.kind == "gaussian":
        sigma = noise(dyn.sigma, dyn.sigma_states, dataset.n_states)
        dynamics += f", sigma={sigma:g}" + ("" if dyn.sigma_states is None else f" ({dyn.sigma:g} at {dyn.sigma_states} states, scaled as 1/S)")
    if isinstance(mdp, EnvMDPSettings):  # the problem's own words (usecases.problem.perturbation_text)
        dynamics += f"; {dataset.perturbation}"
    elif dyn.kind == "slip":
        dynamics += "; slips " + ", ".join(f"tau_{j + 1}: {slip:g}" for j, slip in enumerate(dyn.slips))
    if dyn.kind == "wind":
        dynamics += "; winds " + ", ".join(f"tau_{j + 1}: {d} {v:g}" for j, (d, v) in enumerate(zip(dyn.directions, dyn.values)))
    if dataset.n_test:
        dynamics += f"; {dataset.n_test} held-out test dynamics"
        if dyn.kind == "wind":
            dynamics += " (" + ", ".join(f"test_{e + 1}: {d} {v:g}" for e, (d, v) in enumerate(zip(dyn.test_directions, dyn.test_values))) + ")"
    if dyn.kind == "grid_layouts":
        dynamics += "; crosses " + "; ".join(
            f"tau_{j + 1}: " + (" ".join(f"({r},{c})" for r, c in layout) or "none") for j, layout in enumerate(dyn.layouts)
        )
    what = {
        "sampled": f"sampled, N={demos.n} per dynamics",
        "exact": "exact expected feature sums per dynamics",
        "optimal_path": "the expert's most likely path under tau, as the one demonstration under every tau_j",
    }[demos.kind]
    if demos.expert == "own":
        what += "; each tau_j's own expert, " + (f"soft-optimal (beta={demos.beta:g})" if demos.beta else "optimal") + " in tau_j"
    return [("problem", problem), ("dynamics", dynamics), ("demos", what), ("loss", loss_kind(settings, dataset.features)), ("seed", str(settings.seed))]


def summary_text(settings: ProblemSettings, dataset: Dataset, scores: np.ndarray) -> str:
    """The readable summary written beside the dataset."""
    lines = ["airl generate: dataset summary", ""]
    lines += [f"{label:<10}{text}" for label, text in describe(settings, dataset)]
    lines += ["file      dataset.npz", ""]
    lines += ["true weights w*: " + vector_text(dataset.true_weights), ""]
    who = "optimal for w* under tau" if dataset.expert != "own" else "each dynamics' own expert, " + (
        f"soft-optimal (beta={dataset.expert_beta:g})" if dataset.expert_beta else "optimal") + " there"
    lines += [f"demonstrator ({who}): normalised performance (thesis §7.2)", ""]
    lines += [f"  {'dynamics':<10}{'score':>8}"]
    for j, score in enumerate(scores):
        lines.append(f"  {'tau' if j == 0 else f'tau_{j}':<10}{score:>8.4f}")
    c = dataset.feature_targets()
    lines += ["", "feature sums given to the learner, c~_j (eq. 4.5):"]
    for j, row in enumerate(c, start=1):
        lines.append(f"  tau_{j:<6}" + vector_text(row))
    return "\n".join(lines) + "\n"


def prepare(cfg: DictConfig, overrides: list[str] = ()) -> Prepared:
    """The problem's settings read once (``problem_settings``, for ``main``) and what ``main`` would
    refuse before building anything checked, before any folder is made (``launch.preflight``): the
    settings, and the memory the problem needs. (The learner's groups, which only ``airl fit``
    reads, pass unremarked: a shared list of overrides is common.)"""
    settings = problem_settings(cfg)
    check_build_memory(cfg)
    return Prepared(settings)


def main(cfg: DictConfig, settings: ProblemSettings) -> None:
    """Build the problem and its demonstrations as ``settings`` (``prepare``'s) say, write the dataset file, and report."""
    folder = output_dir()
    plain = PlainProgress(err_console)  # stderr to a file: plain lines, at most every 5 s
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(), console=err_console, transient=True, disable=plain.active) as bar:
        task = bar.add_task("building the problem and the demonstrations", total=3)
        dataset, policy = build_dataset(settings)
        bar.update(task, advance=1, description="scoring the demonstrator")
        plain.line("scoring the demonstrator")
        scores = expert_scores(dataset, policy)
        bar.update(task, advance=1, description="writing the dataset file")
        plain.line("writing the dataset file")
        text = summary_text(settings, dataset, scores)
        write_dataset(folder / "dataset.npz", dataset)
        write_text(folder / "summary.txt", text)
        save_config(cfg, folder)
        bar.update(task, advance=1)
    out_console.print(text, end="", soft_wrap=True)
    out_console.print(f"\nwrote {folder / 'dataset.npz'}", soft_wrap=True)


@hydra.main(version_base="1.3", config_path=conf_dir(), config_name="airl")
def hydra_main(cfg: DictConfig) -> None:
    """One job of ``airl generate --multirun`` (a single run is composed, prepared and started by ``launch``)."""
    run_job(lambda c: main(c, prepare(c).value), cfg)
