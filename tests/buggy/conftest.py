import sys
from pathlib import Path

import pytest

pytest.importorskip("pybullet")
sys.path.insert(0, str(Path(__file__).resolve().parent))

from buggy_runs import run_virtual  # noqa: E402


@pytest.fixture(scope="session")
def buggy_run(tmp_path_factory):
    """examples/buggy.toml, 90 s of virtual time."""
    return run_virtual("buggy.toml", 90, tmp_path_factory.mktemp("buggy") / "buggy.mcap")


@pytest.fixture(scope="session")
def hungry_run(tmp_path_factory):
    """examples/buggy-hungry.toml, 90 s of virtual time."""
    return run_virtual("buggy-hungry.toml", 90, tmp_path_factory.mktemp("hungry") / "hungry.mcap")
