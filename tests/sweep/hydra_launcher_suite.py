"""Hydra's test suite for launcher plugins, on the airl launcher (run by ``test_launcher.py`` in a
process of its own; the file name keeps pytest from collecting it with the other tests)."""

import pytest
from hydra.test_utils.launcher_common_tests import LauncherTestSuite


@pytest.fixture(autouse=True)
def _airl_launcher_discoverable():
    from airl_cli.settings.hydra_internals import launcher_discoverable

    launcher_discoverable()  # an editable install only maps the plugin's import


@pytest.mark.parametrize("launcher_name, overrides", [("airl", []), ("airl", ["hydra.launcher.n_jobs=1"])])
class TestHydrasLauncherSuite(LauncherTestSuite):
    """Warm workers (every core) and n_jobs=1 (the launching process)."""
