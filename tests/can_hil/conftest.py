"""The CAN tier fixtures of tests/can/conftest.py (`can_tier`, `can_bus`), here too: one choice of
tier per session, named on the terminal. `system_can_tier`: the tier for whole systems run in
real time (launcher, nodes, recorder): the kernel's own vcan where it has one (SocketCAN at native
speed), else udp_multicast, which also runs at native speed in a private network namespace;
user-mode Linux runs every process on one emulated vCPU, which took a minute and more per system
on the 2 cores CI has. SocketCAN itself keeps its tests on the best tier (tests/can)."""
import importlib.util
from pathlib import Path

import pytest

from iotad.can.tiers import TierBus, TierUnavailable

_spec = importlib.util.spec_from_file_location("can_tier_fixtures", Path(__file__).parents[1] / "can" / "conftest.py")
_fixtures = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(_fixtures)

can_tier, can_bus = _fixtures.can_tier, _fixtures.can_bus


@pytest.fixture(scope="session")
def system_can_tier(request):
    for tier in ("vcan", "udp_multicast"):
        try:
            return TierBus(tier)
        except TierUnavailable:
            continue
    return request.getfixturevalue("can_tier")
