"""The experiments shipped in ``conf/experiment/``: their names, and each one's ``experiment`` section.

Read by ``airl sweep``'s plan and by ``airl report``, which needs each experiment's own settings (its
kind, its summary, its claim) without planning its sweep.
"""

from __future__ import annotations

from pathlib import Path

from hydra import compose, initialize_config_dir
from omegaconf import DictConfig, OmegaConf

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


def study_of(name: str) -> str:
    """An experiment's study (its sweep folder's stem: fig14 and fig15 share ``fig14_15``), read from
    its config file without composing it; the experiment's own name where it has none."""
    node = OmegaConf.load(Path(conf_dir()) / "experiment" / f"{name}.yaml")
    return str(OmegaConf.select(node, "experiment.study", default=None) or name)


def study_siblings(recorded: dict) -> list[dict]:
    """The other experiments of the study a sweep ran (``recorded``: its experiment.json; fig15's
    for a sweep of fig14, which runs the same jobs), each as that sweep ran it: ``recorded`` with
    the keys in which the sibling's config differs from the experiment's own (its name, title,
    figures, summary, claim) taken from the sibling's. [] for a study of one experiment, or an
    experiment.json of no shipped experiment."""
    name, study = recorded.get("name"), recorded.get("study")
    if name not in experiment_names() or not study:
        return []
    names = [n for n in experiment_names() if n != name and study_of(n) == study]
    if not names:
        return []
    own = experiment_section(name)
    out = []
    for other in names:
        section = experiment_section(other)
        differ = {k: v for k, v in section.items() if own.get(k) != v}
        out.append({**recorded, **differ})
    return out
