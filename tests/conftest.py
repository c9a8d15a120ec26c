"""Shared test set-up for every folder: the examples folder and this folder's helper modules
(launcher_helpers, node_harness, recorded_systems, system_iotas) are importable, and the `hub`
fixture gives a test its own zenoh peer."""
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT / "examples", ROOT / "tests"):
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))


@pytest.fixture
def hub():
    """A node_harness.Hub: the test's own zenoh peer, where nodes connect; closed after the test."""
    from node_harness import Hub

    hub = Hub()
    try:
        yield hub
    finally:
        hub.close()
