"""The experiments shipped in ``conf/experiment/``: their names, and each one's ``experiment`` section.

Read by ``airl sweep``'s plan and by ``airl report``, which needs each experiment's own settings (its
kind, its summary, its claim) without planning its sweep.
"""

from __future__ import annotations

from pathlib import Path

from hydra import compose, initialize_config_dir
from omegaconf import DictConfig

from airl_cli.settings import compose_memo
from airl_cli.settings.config import plain
from airl_cli.settings.hydra_internals import launcher_discoverable
from airl_cli.settings.paths import conf_dir


def experiment_names() -> list[str]:
    """Every experiment config shipped in conf/experiment/, sorted."""
    return sorted(p.stem for p in (Path(conf_dir()) / "experiment").glob("*.yaml") if not p.name.startswith("_"))


def compose_airl(overrides: list[str]) -> DictConfig:
    """``conf/airl.yaml`` composed with these overrides, the ``hydra`` node included, as a sweep's job sees it."""
    with initialize_config_dir(config_dir=conf_dir(), version_base="1.3", job_name="sweep"):
        return compose("airl", overrides=overrides, return_hydra_config=True)


def experiment_section(name: str) -> dict:
    """``experiment=NAME``'s ``experiment`` section as plain Python values (what the sweep's plan records)."""
    launcher_discoverable()  # before Hydra's plugin registry is first built
    with compose_memo.active():
        return plain(compose_airl([f"experiment={name}"]).experiment)
