"""The `can_bus` fixture: a CAN bus in the best tier this host has (vcan in a private network
namespace, else user-mode Linux, else udp_multicast), named in the test output.

    def test_something(can_bus):                      # a iotad.can.tiers.TierBus
        result = can_bus.run_python(SCRIPT, timeout=60)   # SCRIPT opens iotad.can.bus.open_env_bus()
        result.check()                                # RuntimeError with tier, status and output
        assert "..." in result.output
    can_bus.name / .interface / .channel              # "uml" / "socketcan" / "vcan0"
    can_bus.run([cmd, ...], timeout=60)               # any command, with the bus in its environment

IOTAD_CAN_TIER=vcan|uml|udp_multicast forces a tier. Without any tier the test is skipped, saying why.
"""
import pytest

from iotad.can.tiers import TierBus, TierUnavailable



@pytest.fixture(scope="session")
def can_tier(request):
    """The session's TierBus (one choice of tier per session), announced once on the terminal."""
    try:
        bus = TierBus()
    except TierUnavailable as exc:
        pytest.skip(f"no CAN bus tier: {exc}")
    reporter = request.config.pluginmanager.get_plugin("terminalreporter")
    capture = request.config.pluginmanager.get_plugin("capturemanager")
    if reporter is not None and capture is not None:  # past pytest's capture: the run's output names the tier
        with capture.global_and_fixture_disabled():
            reporter.write_line(f"\ncan_bus fixture: CAN tier {bus.describe()}")
    return bus


@pytest.fixture
def can_bus(request, can_tier):
    """The session's TierBus, with the tier in this test's report (user_properties: can_tier)."""
    request.node.user_properties.append(("can_tier", can_tier.name))
    return can_tier
