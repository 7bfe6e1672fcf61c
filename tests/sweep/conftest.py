"""One finished quick sweep (``sweep_runs.SWEEP``), made once for the sweep tests and copied by each."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from sweep_runs import sweep_into


@pytest.fixture(scope="session")
def pristine(tmp_path_factory) -> Path:
    """One undamaged quick fig12 sweep (four jobs); a test copies it (``copy``) before changing it."""
    folder = tmp_path_factory.mktemp("pristine") / "fig12"
    result = sweep_into(folder)
    assert result.exit_code == 0, result.output
    return folder


@pytest.fixture
def copy(pristine, tmp_path) -> Path:
    folder = tmp_path / "fig12"
    shutil.copytree(pristine, folder)
    return folder
