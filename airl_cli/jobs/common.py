"""What every job shares: the output folder, the consoles, and turning bad input into one sentence."""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

from hydra.core.hydra_config import HydraConfig
from omegaconf import DictConfig, OmegaConf
from rich.console import Console

from airl_cli.errors import AirlError
from airl_cli.results import UNWRITABLE, describe_os_error, write_text


#: Progress and errors go to stderr; the final "where it went" line to stdout.
err_console = Console(stderr=True, highlight=False)
out_console = Console(highlight=False)


def output_dir() -> Path:
    """The run folder Hydra made for this job (``hydra.run.dir`` or the sweep's job folder)."""
    return Path(HydraConfig.get().runtime.output_dir)


def save_config(cfg: DictConfig, folder: Path) -> None:
    """The resolved config beside the results, as ``config.yaml``."""
    write_text(folder / "config.yaml", OmegaConf.to_yaml(cfg, resolve=True))


def run_job(main: Callable[[DictConfig], object], cfg: DictConfig) -> object:
    """Run ``main(cfg)``; on bad input print one sentence and exit with status 2.

    A results folder that cannot be written (read-only, full disk) is bad input too. Nothing
    half-written stays behind: a run folder that holds only Hydra's own records is
    removed when the job fails on bad input.
    """
    try:
        return main(cfg)
    except (AirlError, OSError) as err:
        if isinstance(err, OSError):
            if err.errno not in UNWRITABLE:
                raise
            err = AirlError(f"cannot write the results ({describe_os_error(err)}); choose a writable folder with hydra.run.dir=PATH")
        err_console.print(f"[bold red]error:[/] {err}", soft_wrap=True)
        try:
            folder = output_dir()
            if folder.is_dir() and {p.name for p in folder.iterdir()} <= {".hydra"}:
                shutil.rmtree(folder)
        except ValueError:  # no Hydra context (called directly)
            pass
        raise SystemExit(2) from None
