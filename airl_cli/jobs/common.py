"""What every job shares: the output folder, the consoles, and turning bad input into one sentence."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf
from rich.console import Console
from rich.markup import escape

from airl_cli.core.mmdp.budget import Estimate, estimate_fit, refusal
from airl_cli.errors import AirlError, ConfigError, ResultsUnwritable, error_line, interrupt_status, interrupted
from airl_cli.io.files import describe_os_error, is_unwritable, write_text
from airl_cli.io.run_folder import INCOMPLETE, discard, holds_no_results, mark_complete, mark_incomplete

#: Progress and errors go to stderr; the final "where it went" line to stdout.
err_console = Console(stderr=True, highlight=False)
out_console = Console(highlight=False)


def output_dir() -> Path:
    """The run folder Hydra made for this job (``hydra.run.dir`` or the sweep's job folder)."""
    return Path(HydraConfig.get().runtime.output_dir)


def warm_up() -> None:
    """Load (or, on the first run after installing, compile) the planner's kernels: a PBVI solve of
    a tiny problem, which runs the kernels of both ``airl fit`` and ``airl plan``."""
    from airl_cli.core.mmdp.planner import solve  # numba: only in the jobs that plan

    P = np.full((2, 2, 1, 2), 0.5)
    solve(P, np.zeros((2, 2, 2)), np.array([1.0, 0.0]), iterations=2)


def save_config(cfg: DictConfig, folder: Path) -> None:
    """The resolved config beside the results, as ``config.yaml``."""
    write_text(folder / "config.yaml", OmegaConf.to_yaml(cfg, resolve=True))


def run_job(main: Callable[[DictConfig], object], cfg: DictConfig) -> object:
    """Run ``main(cfg)`` into the run folder; a run that does not finish says why in one sentence.

    The folder holds ``INCOMPLETE`` while the job runs (``results.mark_incomplete``). Bad input
    and a results folder that cannot be written (read-only, a full disk) exit with status 2,
    Ctrl-C with 130 (SIGTERM 143), after one sentence on stderr (``stop``). Other errors (a bug)
    keep their traceback and the marker.
    """
    try:
        folder: Path | None = output_dir()
    except ValueError:  # no Hydra context (called directly)
        folder = None
    fresh = folder is not None and holds_no_results(folder)
    try:
        if folder is not None:
            mark_incomplete(folder)
        result = main(cfg)
        if folder is not None:
            mark_complete(folder)  # the last act: the folder is complete
        return result
    except BaseException as err:
        stop(err, folder, fresh=fresh)
        raise


def stop(err: BaseException, folder: Path | None, *, fresh: bool) -> None:
    """Say in one sentence why a run stopped and exit, if it is bad input, an unwritable folder or
    an interrupt; return (for the caller to re-raise) otherwise.

    Nothing half-written stays behind: the run folder is removed if this run made it (``fresh``:
    it held nothing but Hydra's records when the job started); a folder that held an earlier
    run's files keeps the ``INCOMPLETE`` marker instead, and the sentence says so.

    Raises:
        SystemExit: status 2 (bad input, unwritable), 130 (Ctrl-C) or 143 (SIGTERM).
    """
    if interrupted(err):
        status, sentence = interrupt_status(), "[bold yellow]interrupted[/]"
        removed, marked = ": nothing was kept (the run folder {} is removed)", ": {} is marked INCOMPLETE"
    else:
        if isinstance(err, ResultsUnwritable) or is_unwritable(err):
            reason = err.reason if isinstance(err, ResultsUnwritable) else describe_os_error(err)  # type: ignore[arg-type]
            err = AirlError(f"cannot write the results ({reason}); choose a writable folder with hydra.run.dir=PATH")
        if not isinstance(err, AirlError):
            return
        status, sentence = 2, error_line(err)
        removed, marked = "", "; {} is marked INCOMPLETE"
    if folder is not None and fresh and discard(folder):
        sentence += removed.format(escape(str(folder)))
    elif folder is not None and (folder / INCOMPLETE).exists():
        sentence += marked.format(escape(str(folder)))
    err_console.print(sentence, soft_wrap=True)
    raise SystemExit(status) from None


def available_memory() -> int:
    """Bytes this process can still get: free memory, or the container's limit if lower."""
    free = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    free = int(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        used = int(Path("/sys/fs/cgroup/memory.current").read_text())
        if limit != "max":
            free = min(free if free is not None else 1 << 62, int(limit) - used)
    except (OSError, ValueError):
        pass
    if free is None:  # not Linux: physical memory
        try:
            free = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (OSError, ValueError):
            free = 1 << 62
    return free


def fit_sizes(cfg: DictConfig) -> dict | None:
    """S, A, T, D and N of the fit this config asks for, known without building or reading it all.

    None when they cannot be known cheaply (a dataset file that will fail its own check).
    """
    from airl_cli.config import problem_settings

    data = cfg.get("data")
    if data is None:
        problem = problem_settings(cfg)
        mdp = problem.mdp
        if mdp.name == "random":
            S, A = mdp.n_states, mdp.n_actions
        elif mdp.name in ("gymnasium", "seals"):
            from airl_cli.envs import env_sizes

            S, A = env_sizes(mdp.name, mdp.env, map_name=mdp.map_name, width=mdp.width, height=mdp.height)
        else:  # the grid world and the objectworld: size x size cells
            from airl_cli.core.mdp.objectworld import OBJECTWORLD_ACTIONS
            from airl_cli.core.mdp.problems import GRID_ACTIONS

            S, A = mdp.size**2, len(OBJECTWORLD_ACTIONS if mdp.name == "objectworld" else GRID_ACTIONS)
        n = problem.demos.n if problem.demos.kind == "sampled" else 1
        # the most next states a state reaches: a grid cell its neighbours and itself
        R = None if mdp.name in ("random", "gymnasium", "seals") else 5
        if mdp.name == "random" and mdp.transition == "sparse":
            R = mdp.n_next * mdp.n_actions * (problem.dynamics.n_dynamics + 1)
        return {"n_states": S, "n_actions": A, "horizon": mdp.horizon, "n_dynamics": problem.dynamics.n_dynamics, "n_demos": n, "n_next": R}
    try:
        with np.load(str(data), allow_pickle=False) as npz:
            if "transition_probs" in npz.files:  # the sparse form: (M, S, A, R)
                M, S, A, R = npz["transition_probs"].shape
            else:
                P = npz["transitions"]
                M, S, A, _ = P.shape
                R = int(np.max(np.sum(np.any(P != 0, axis=(0, 2)), axis=1))) if P.size else None
            T = int(npz["horizon"])
            n = npz["demo_states"].shape[1] if "demo_states" in npz.files else 0
    except Exception:  # noqa: BLE001 (read_dataset names what is wrong)
        return None
    return {"n_states": S, "n_actions": A, "horizon": T, "n_dynamics": M - 1, "n_demos": n, "n_next": R}


def memory_estimate(cfg: DictConfig) -> tuple[Estimate, int | None] | None:
    """The fit's memory estimate and its PBVI iterations (None if it does not run PBVI)."""
    from airl_cli.config import fit_settings

    sizes = fit_sizes(cfg)
    if sizes is None:
        return None
    settings = fit_settings(cfg)
    planner = settings.options.planner
    estimate = estimate_fit(**sizes, method=settings.method, planner=planner.method, iterations=planner.iterations)
    pbvi = settings.method == "airl" and planner.method == "pbvi"
    return estimate, (planner.iterations if pbvi else None)


def _shrink(cfg: DictConfig) -> str:
    """The settings that size the problem, for the refusal to name: the grids have mdp.size."""
    if cfg.get("data") is None and OmegaConf.select(cfg, "mdp.name") in ("grid", "objectworld"):
        return "mdp.size, mdp.horizon"
    return "mdp.n_states, mdp.horizon"


def check_memory(cfg: DictConfig, *, workers: int = 1) -> Estimate | None:
    """Refuse, before any work, a fit that will not fit in memory (one sentence: what to lower).

    Raises:
        ConfigError: the estimate (times ``workers`` fits at once) exceeds the free memory.
    """
    found = memory_estimate(cfg)
    if found is None:
        return None
    estimate, iterations = found
    sentence = refusal(estimate, available_memory(), iterations=iterations, workers=workers, shrink=_shrink(cfg))
    if sentence is not None:
        raise ConfigError(sentence)
    return estimate


def size_note(cfg: DictConfig) -> str | None:
    """A line to print before a fit whose steps will be long (a large belief set or over 1 GB)."""
    found = memory_estimate(cfg)
    if found is None or found[1] is None:
        return None
    estimate, iterations = found
    if estimate.total < 2**30 and estimate.n_beliefs <= 1024:
        return None
    if refusal(estimate, available_memory(), iterations=iterations) is not None:
        return None  # check_memory will refuse it
    from airl_cli.config import fit_settings

    # the planner is called once per gradient step, or up to once per iteration of the exact solve
    each = "gradient step" if fit_settings(cfg).optimizer == "gradient" else "iteration of the exact solve"
    return (
        f"note: pbvi.iterations={iterations} allows up to {estimate.n_beliefs:,} belief points and about "
        f"{estimate.total / 2**30:,.1f} GB of memory; each {each} may take minutes"
    )
