"""Hydra's private API is used in airl_cli/settings/hydra_internals.py only, and each of its functions does
what Hydra itself does on a small case (so a hydra-core upgrade that changes one fails here)."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import hydra
import hydra.core.utils
import pytest
from hydra import compose, initialize_config_dir
from hydra.core.hydra_config import HydraConfig
from hydra.core.override_parser.overrides_parser import OverridesParser
from omegaconf import OmegaConf

import airl_cli
from airl_cli.settings import hydra_internals

PACKAGE = Path(airl_cli.__file__).parent
OWNER = PACKAGE / "settings" / "hydra_internals.py"
#: Source text that reaches into Hydra's private API, whatever the names it is reached through.
PRIVATE_TEXT = ("_save_config", "Singleton._instances", "._internal")


def private_hydra_uses(source: str) -> list[str]:
    """Where this module's source uses Hydra's private API: an import from ``hydra._internal``, an
    underscore attribute (not a dunder) of a name bound to a hydra module or object, or one of
    ``PRIVATE_TEXT``."""
    found = [f"text {text!r}" for text in PRIVATE_TEXT if text in source]
    hydra_names = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "hydra":
                    hydra_names.add(alias.asname or "hydra")
                    if alias.name.startswith("hydra._internal"):
                        found.append(f"line {node.lineno}: import {alias.name}")
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and (node.module or "").split(".")[0] == "hydra":
            hydra_names |= {alias.asname or alias.name for alias in node.names}
            if node.module.startswith("hydra._internal") or any(a.name == "_internal" for a in node.names):
                found.append(f"line {node.lineno}: from {node.module} import ...")
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Attribute) and node.attr.startswith("_") and not node.attr.startswith("__"):
            root = node.value
            while isinstance(root, ast.Attribute):
                root = root.value
            if isinstance(root, ast.Name) and root.id in hydra_names:
                found.append(f"line {node.lineno}: {root.id}...{node.attr}")
    return found


def test_only_hydra_internals_uses_hydras_private_api():
    files = sorted(PACKAGE.rglob("*.py"))
    assert OWNER in files and len(files) > 40
    used = {str(p.relative_to(PACKAGE)): private_hydra_uses(p.read_text()) for p in files if p != OWNER}
    assert not {name: uses for name, uses in used.items() if uses}
    assert private_hydra_uses(OWNER.read_text())  # the check sees the uses where they are


@pytest.mark.parametrize(
    "source",
    [
        "from hydra._internal.config_loader_impl import get_overrides_dirname\n",
        "def f():\n    from hydra._internal import config_loader_impl\n",
        "import hydra._internal.utils as u\n",
        "import hydra.core.utils as hcu\nhcu._save_config = print\n",
        "from hydra.core.singleton import Singleton\nSingleton._instances.clear()\n",
        "from hydra.core import singleton\nx = singleton.Singleton._instances\n",
        "from hydra.plugins.sweeper import Sweeper\nf = Sweeper._private\n",
    ],
)
def test_the_check_finds_a_private_use(source):
    assert private_hydra_uses(source)


def test_the_check_passes_public_uses_and_other_underscores():
    source = (
        "import hydra\nfrom hydra.core.singleton import Singleton\nimport hydra_plugins\n"
        "state = Singleton.get_state()\nhydra_plugins.__path__.append('x')\npool._processes = {}\n"
    )
    assert private_hydra_uses(source) == []


# --------------------------------------------------------------------------- against Hydra itself


def _config(folder: Path, **override_dirname: object) -> Path:
    """A primary config ``cfg.yaml`` with keys a, b, c, and Hydra's override_dirname settings."""
    text = {"a": 1, "b": "x", "c": 0}
    if override_dirname:
        text["hydra"] = {"job": {"config": {"override_dirname": override_dirname}}}
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "cfg.yaml").write_text(OmegaConf.to_yaml(OmegaConf.create(text)))
    return folder


@pytest.mark.parametrize(
    "settings", [{}, {"kv_sep": ":", "item_sep": "__", "exclude_keys": ["c"]}], ids=["Hydra's defaults", "own separators"]
)
def test_overrides_dirname_is_hydras_override_dirname(tmp_path, settings):
    overrides = ["b=y", "c=5", "a=2", "+d=q"]
    with initialize_config_dir(config_dir=str(_config(tmp_path, **settings)), version_base="1.3"):
        cfg = compose("cfg", overrides=overrides, return_hydra_config=True)
    node = cfg.hydra.job.config.override_dirname
    ours = hydra_internals.overrides_dirname(
        OverridesParser.create().parse_overrides(overrides), list(node.exclude_keys), item_sep=node.item_sep, kv_sep=node.kv_sep
    )
    assert ours == cfg.hydra.job.override_dirname
    assert ours == ("+d:q__a:2__b:y" if settings else "+d=q,a=2,b=y,c=5")


def _multirun(folder: Path, overrides: list[str], monkeypatch) -> list[list[str]]:
    """Run a tiny Hydra app with ``--multirun`` and the basic sweeper and launcher, in this
    process; each job's task overrides, in the order the jobs ran."""
    ran: list[list[str]] = []

    @hydra.main(version_base="1.3", config_path=str(folder), config_name="cfg")
    def app(cfg) -> None:
        ran.append(list(HydraConfig.get().overrides.task))

    quiet = ["hydra/job_logging=none", "hydra/hydra_logging=none", f"hydra.sweep.dir={folder / 'multirun'}"]
    monkeypatch.setattr(sys, "argv", ["app", "--multirun", *quiet, *overrides])
    app()
    return ran


def test_split_sweep_overrides_gives_the_jobs_hydras_basic_sweeper_runs(tmp_path, monkeypatch):
    overrides = ["b=y,z", "a=1,2,3", "c=range(0,2)", "+d=q"]
    jobs = hydra_internals.split_sweep_overrides(OverridesParser.create().parse_overrides(overrides))
    assert len(jobs) == 12 and jobs[0] == ["b=y", "a=1", "c=0", "+d=q"] and jobs[1] == ["b=y", "a=1", "c=1", "+d=q"]
    assert jobs == _multirun(_config(tmp_path / "conf"), overrides, monkeypatch)


def test_a_record_writer_gets_every_record_hydra_writes_and_is_put_back(tmp_path, monkeypatch):
    hydras_own = hydra.core.utils._save_config
    written: list[tuple[str, str]] = []

    def writer(cfg, filename, output_dir) -> None:
        written.append((Path(output_dir).parent.name, filename))

    with hydra_internals.atomic_hydra_records(writer):
        assert hydra.core.utils._save_config is writer
        jobs = _multirun(_config(tmp_path / "conf"), ["a=1,2"], monkeypatch)
    assert hydra.core.utils._save_config is hydras_own
    assert len(jobs) == 2
    assert written == [(str(i), name) for i in (0, 1) for name in ("config.yaml", "hydra.yaml", "overrides.yaml")]
    # Hydra wrote no job record itself (the sweeper's own multirun.yaml is not one)
    assert not [p for job in "01" for p in (tmp_path / "conf" / "multirun" / job).rglob("*.yaml")]


def test_the_record_writer_is_put_back_after_an_exception():
    hydras_own = hydra.core.utils._save_config

    def writer(cfg, filename, output_dir) -> None:
        raise AssertionError("never called")

    with pytest.raises(KeyError), hydra_internals.atomic_hydra_records(writer):
        assert hydra.core.utils._save_config is writer
        raise KeyError("stop")
    assert hydra.core.utils._save_config is hydras_own
    assert hydra_internals.set_hydra_record_writer(writer) is hydras_own  # and the plain setter returns it
    assert hydra_internals.set_hydra_record_writer(hydras_own) is writer
    assert hydra.core.utils._save_config is hydras_own


def test_forget_plugin_registry_makes_hydra_scan_its_plugins_again():
    from hydra.core.plugins import Plugins

    before = Plugins.instance()
    assert Plugins.instance() is before
    hydra_internals.forget_plugin_registry()
    after = Plugins.instance()
    assert after is not before
    hydra_internals.forget_plugin_registry()
    hydra_internals.forget_plugin_registry()  # with no registry built: nothing to do
    assert Plugins.instance() is not after


def test_composition_steps_stand_in_for_hydras_and_are_put_back(tmp_path):
    """Stand-ins that call Hydra's own steps compose the config Hydra composes; each is called;
    the defaults-list helpers read what Hydra's steps give."""
    own = hydra_internals.composition_steps()
    seen: dict[str, list] = {"defaults_list": [], "defaults": [], "parsed": []}

    def defaults_list(**kwargs):
        found = own.create_defaults_list(**kwargs)
        seen["defaults_list"].append(found)
        return found

    def compose_from(self, defaults, repo):
        seen["defaults"].append(defaults)
        return own.compose_from_defaults_list(self, defaults=defaults, repo=repo)

    def parse_rule(self, s, rule_name):
        seen["parsed"].append(s)
        return own.parse_rule(self, s, rule_name)

    folder = str(_config(tmp_path))
    with initialize_config_dir(config_dir=folder, version_base="1.3"):
        fresh = compose("cfg", overrides=["a=2", "+d=q"])
    hydra_internals.set_composition_steps(hydra_internals.CompositionSteps(defaults_list, compose_from, parse_rule))
    try:
        assert hydra_internals.composition_steps() == (defaults_list, compose_from, parse_rule)
        with initialize_config_dir(config_dir=folder, version_base="1.3"):
            stood_in = compose("cfg", overrides=["a=2", "+d=q"])
    finally:
        hydra_internals.set_composition_steps(own)
    assert hydra_internals.composition_steps() == own
    assert stood_in == fresh == OmegaConf.create({"a": 2, "b": "x", "c": 0, "d": "q"})
    assert seen["defaults_list"] and seen["defaults"] and set(seen["parsed"]) == {"a=2", "+d=q"}
    found = seen["defaults_list"][0]
    values = [o for o in found.config_overrides if o.key_or_group == "a"]
    copy = hydra_internals.defaults_with_overrides(found, values)
    assert copy.config_overrides == values and copy.defaults is found.defaults and len(found.config_overrides) == 2
    key = hydra_internals.defaults_key(seen["defaults"][0])
    assert key == hydra_internals.defaults_key(list(seen["defaults"][0])) and any(entry[0] == "cfg" for entry in key)


def test_a_single_run_composes_and_runs_as_hydra_main_does(tmp_path, monkeypatch):
    """``single_run`` composes the config ``@hydra.main`` composes for one run and runs the task as
    it does: the same job config, the same three records (but the folder's name), the task's
    exception reported as Hydra reports it; the config without its ``hydra`` node is what the task gets."""
    folder = _config(tmp_path / "conf")
    got: dict[str, object] = {}
    overrides = ["a=7", "+d=q", "hydra/job_logging=none", "hydra/hydra_logging=none"]

    @hydra.main(version_base="1.3", config_path=str(folder), config_name="cfg")
    def app(cfg) -> None:
        got["hydra"] = OmegaConf.to_container(cfg)

    monkeypatch.chdir(tmp_path)
    monkeypatch.setattr(sys, "argv", ["app", *overrides, "hydra.run.dir=by_hydra"])
    app()
    task = "test_hydra_internals"  # @hydra.main's job name: its module's
    with hydra_internals.single_run(str(folder), "cfg", task, [*overrides, "hydra.run.dir=by_us"]) as run:
        assert "hydra" in run.cfg and "hydra" not in run.job_cfg
        assert run.cfg.hydra.job.name == task
        run.start(lambda cfg: got.__setitem__("ours", OmegaConf.to_container(cfg)))
    assert got["ours"] == got["hydra"] == OmegaConf.to_container(run.job_cfg)
    for record in ("config.yaml", "hydra.yaml", "overrides.yaml"):
        ours = (tmp_path / "by_us" / ".hydra" / record).read_text().replace("by_us", "X")
        assert ours == (tmp_path / "by_hydra" / ".hydra" / record).read_text().replace("by_hydra", "X"), record
    monkeypatch.delenv("HYDRA_FULL_ERROR", raising=False)

    def fails(cfg) -> None:
        raise KeyError("stop")

    @hydra.main(version_base="1.3", config_path=str(folder), config_name="cfg")
    def failing_app(cfg) -> None:
        fails(cfg)

    monkeypatch.setattr(sys, "argv", ["app", *overrides, "hydra.run.dir=failed_hydra"])
    with pytest.raises(SystemExit) as by_hydra:
        failing_app()
    with hydra_internals.single_run(str(folder), "cfg", task, [*overrides, "hydra.run.dir=failed_us"]) as run:
        with pytest.raises(SystemExit) as by_us:
            run.start(fails)
    assert by_us.value.code == by_hydra.value.code == 1  # reported as Hydra reports a failed task


def test_hydra_group_options_are_the_choices_hydra_accepts():
    """Each option listed composes; a name outside them is Hydra's MissingConfigException."""
    from hydra import compose, initialize_config_dir
    from hydra.errors import MissingConfigException

    from airl_cli.settings.hydra_internals import hydra_group_options
    from airl_cli.settings.paths import conf_dir

    options = hydra_group_options("hydra/launcher", conf_dir())
    assert {"airl", "basic"} <= set(options) and hydra_group_options("hydra/nothing", conf_dir()) == []
    with initialize_config_dir(config_dir=conf_dir(), version_base="1.3"):
        for option in ("airl", "basic"):
            assert compose("airl", overrides=[f"hydra/launcher={option}"], return_hydra_config=True).hydra.launcher
        with pytest.raises(MissingConfigException):
            compose("airl", overrides=["hydra/launcher=foo"], return_hydra_config=True)
