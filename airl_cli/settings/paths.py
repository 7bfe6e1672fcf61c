"""Where the Hydra configs are: inside the installed package, or conf/ of a source checkout."""

from __future__ import annotations

import importlib.util
from pathlib import Path

from omegaconf import OmegaConf

# hydra.run.dir of conf/airl.yaml. Composing a config (sweep plans, tests) only names the folder;
# launch.run_hydra swaps in io.run_folder.new_run_folder, which makes it, for the one run it starts.
OmegaConf.register_new_resolver("airl.new_run_folder", lambda path: path, replace=True)


def conf_dir() -> str:
    """Absolute path of the config folder.

    An installed ``airl_cli`` carries ``conf/`` as the subpackage ``airl_cli.conf``; code run from
    a source checkout without installing finds ``conf/`` beside the package.
    """
    try:
        spec = importlib.util.find_spec("airl_cli.conf")
    except ModuleNotFoundError:
        spec = None
    if spec is not None and spec.submodule_search_locations:
        return str(Path(next(iter(spec.submodule_search_locations))).resolve())
    return str(Path(__file__).resolve().parents[2] / "conf")
