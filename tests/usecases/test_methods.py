"""The method registry (airl_cli.methods) is the one place a method is named: everything else follows it."""

from __future__ import annotations

from pathlib import Path

import pytest
from omegaconf import OmegaConf

from airl_cli import api
from airl_cli.errors import ConfigError
from airl_cli.methods import NAMES, REGISTRY
from airl_cli.readings import plotting, report
from airl_cli.settings.config import fit_settings
from airl_cli.settings.paths import conf_dir
from airl_cli.usecases import fit as learners


def test_every_method_has_its_config_file_and_its_learner_and_nothing_else_does():
    files = {p.stem for p in (Path(conf_dir()) / "method").glob("*.yaml")}
    assert files == set(NAMES)
    for name, m in REGISTRY.items():
        yaml = OmegaConf.to_container(OmegaConf.load(Path(conf_dir()) / "method" / f"{name}.yaml"))
        assert yaml.pop("name") == name
        assert set(yaml) == {o.key for o in m.options}, name  # the YAML's keys are the options the registry checks
        assert callable(getattr(learners, m.learner)), m.learner
    assert report.ORDER == list(NAMES)
    assert [plotting.METHOD_LABELS[n] for n in NAMES] == [REGISTRY[n].label for n in NAMES]
    assert len({m.colour for m in REGISTRY.values()}) == len(REGISTRY)


@pytest.mark.parametrize("name", [n for n in NAMES if REGISTRY[n].options])
def test_a_method_option_out_of_range_is_one_sentence(name):
    option = REGISTRY[name].options[0]
    cfg = api.config(f"method={name}", f"method.{option.key}=-1")
    with pytest.raises(ConfigError, match=f"method.{option.key}"):
        fit_settings(cfg)


@pytest.mark.parametrize("name", NAMES)
def test_every_method_learns_through_the_registry(name):
    dataset = api.make_dataset("mdp.n_states=6", "mdp.horizon=4", "demos.n=20", "dynamics.n_dynamics=2")
    learned = api.fit(dataset, f"method={name}", "mdp.n_states=6", "mdp.horizon=4", "demos.n=20", "dynamics.n_dynamics=2")
    assert learned.method == name
    assert (learned.weights is not None) == REGISTRY[name].learns_reward
