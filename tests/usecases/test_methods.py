"""The method registry (airl_cli.methods) is the one place a method is named: everything else follows it."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
from omegaconf import OmegaConf

from airl_cli import api
from airl_cli.errors import ConfigError
from airl_cli.methods import NAMES, REGISTRY
from airl_cli.readings import plotting, report
from airl_cli.settings.config import fit_settings
from airl_cli.settings.paths import conf_dir
from airl_cli.usecases.fit import learner, learner_class


def test_every_method_has_its_config_file_and_its_learner_and_nothing_else_does():
    files = {p.stem for p in (Path(conf_dir()) / "method").glob("*.yaml")}
    assert files == set(NAMES)
    for name, m in REGISTRY.items():
        yaml = OmegaConf.to_container(OmegaConf.load(Path(conf_dir()) / "method" / f"{name}.yaml"))
        assert yaml.pop("name") == name
        assert set(yaml) == {o.key for o in m.options}, name  # the YAML's keys are the options the registry checks
        cls = learner_class(name)  # found by its import path, a typed object whose fields are the options
        built = learner(fit_settings(api.config(f"method={name}")))
        assert type(built) is cls and callable(built.fit) and callable(built.check), m.learner
        assert built == cls(), name  # the class's defaults are the packaged config's
        fields = {f.name for f in dataclasses.fields(cls)}
        assert {o.key for o in m.options} <= fields, name
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


def test_no_method_name_is_compared_outside_the_registry():
    """Capabilities are the registry's attributes (``Method.plays_game``, ``learns_reward``,
    ``allowed_actions``...): no module outside ``airl_cli/methods.py`` and the learners compares a
    value with a method's name."""
    import re

    package = Path(api.__file__).parent
    names = "|".join(NAMES)
    compared = re.compile(rf"""(==|!=|\bin)\s*\(?\s*["']({names})["']|["']({names})["']\s*(==|!=)""")
    found = []
    for path in sorted(package.rglob("*.py")):
        rel = path.relative_to(package).as_posix()
        if rel == "methods.py" or rel.startswith("usecases/learners/"):
            continue
        found += [f"{rel}:{i}: {line.strip()}" for i, line in enumerate(path.read_text().split("\n"), 1) if compared.search(line)]
    assert not found, "\n".join(found)


def test_the_thesis_learner_is_made_by_the_configs_names():
    """``Airl.exact(tol=..., lam=...)`` is the learner ``airl fit optim.tol=... optim.lam=...`` makes, the
    rest the packaged config's; a value the config refuses is refused (one sentence naming its key)."""
    assert api.Airl.exact() == api.Airl()
    assert api.Airl.exact(tol=1e-2) == api.learner("optim.tol=1e-2")
    assert api.Airl.exact(lam=0.5, weight_sharing=True, max_iterations=50) == api.learner("optim.lam=0.5", "optim.weight_sharing=true", "optim.max_iterations=50")
    assert api.Airl.exact(planner=api.PlannerOptions(method="pbvi")) == api.learner("pbvi.method=pbvi")
    for bad, key in ((dict(tol=0.5), "optim.tol"), (dict(tol=0.0), "optim.tol"), (dict(lam=0.0), "optim.lam"), (dict(max_iterations=0), "optim.max_iterations"), (dict(matching="x"), "game.matching")):
        with pytest.raises(ConfigError, match=key):
            api.Airl.exact(**bad)


def test_the_api_fit_takes_the_loss_and_the_seed_by_name():
    dataset = api.make_dataset("mdp.n_states=6", "mdp.horizon=4", "demos.n=10")
    typed = api.fit(dataset, method=api.Airl.exact(tol=1e-2), loss="squared_features", seed=3)
    spelt = api.fit(dataset, "optim.tol=1e-2", "loss=squared_features", "seed=3")
    assert (typed.weights == spelt.weights).all()
    zero_one = api.fit(dataset, method=api.Airl.exact(tol=1e-2), loss="zero_one", seed=3)
    assert zero_one.info["objective"] != typed.info["objective"]  # the loss was the one named
    with pytest.raises(ConfigError, match="loss='nope' is not a loss airl knows"):
        api.fit(dataset, method=api.Mce(), loss="nope")


def test_behavioural_cloning_without_demonstrated_actions_says_what_a_file_and_a_generated_problem_need():
    """A walk through the commands: its advice for a dataset file was demos=sampled, which a file ignores."""
    dataset = dataclasses.replace(api.make_dataset("mdp.n_states=5", "mdp.n_actions=2", "mdp.horizon=4", "demos.n=3"), demo_actions=None)
    with pytest.raises(ConfigError, match="a dataset file needs the keys 'demo_states' and 'demo_actions', a generated problem demos=sampled"):
        api.fit(dataset, "method=bc")
