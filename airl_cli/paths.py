"""Where the Hydra configs are: inside the installed package, or conf/ of a source checkout."""

from __future__ import annotations

import importlib.util
from pathlib import Path


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
    return str(Path(__file__).resolve().parent.parent / "conf")
