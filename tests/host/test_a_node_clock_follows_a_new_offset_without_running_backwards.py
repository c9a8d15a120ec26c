"""A node clock told a new offset mid-run (its launcher measured the host's clock again) steps
forward at once, slews back at `SLEW` and never reads a time before one it read already. Virtual
time: the monotonic clock under the node clock is a counter the test advances."""
import random

import pytest

from iotad.node_host import wire
from iotad.node_host.clock_correction import SLEW, Correction
from iotad.node_host.host_clock import HostClock
from iotad.node_host.node_config import ConfigError, from_dict
from iotad.kernel import clock as kernel_clock


class FakeMonotonic:
    def __init__(self, start=1000.0):
        self.t = start

    def __call__(self):
        return self.t


@pytest.fixture
def mono(monkeypatch):
    fake = FakeMonotonic()
    monkeypatch.setattr(kernel_clock, "monotonic", fake)
    monkeypatch.setattr(kernel_clock, "wall", lambda: 5000.0 + fake.t)
    return fake


def test_forward_is_a_step_and_backward_a_slew():
    c = Correction()
    assert c.at(10.0) == 0.0
    assert c.aim(0.004, 10.0) == pytest.approx(0.004)  # forward: the whole of it at once
    assert c.at(10.0) == pytest.approx(0.004) and c.at(99.0) == pytest.approx(0.004)
    assert c.aim(0.001, 20.0) == 0.0  # back by 3 ms: no step
    assert c.at(20.0) == pytest.approx(0.004)
    assert c.at(20.5) == pytest.approx(0.004 - SLEW * 0.5)
    assert c.at(20.0 + 0.003 / SLEW) == pytest.approx(0.001)  # all given back, and no further
    assert c.at(1e6) == pytest.approx(0.001)
    # aimed ahead of where a slew has got to: a step from there, not from the old target
    c.aim(-0.010, 30.0)
    assert c.aim(0.0, 31.0) == pytest.approx(0.0 - (0.001 - SLEW))
    with pytest.raises(ValueError):
        Correction(slew=1.5)


def test_a_corrected_reading_never_goes_back_whatever_the_aims():
    c = Correction()
    rng = random.Random(7)
    raw, last = 0.0, -1.0
    for _ in range(5000):
        raw += rng.uniform(0.0, 0.01)
        if rng.random() < 0.05:
            c.aim(rng.uniform(-0.05, 0.05), raw)
        reading = raw + c.at(raw)
        assert reading >= last
        last = reading


def test_a_host_clock_follows_the_hub_origin_its_launcher_publishes(mono):
    # t = 0 at wall 5000 + 1000: the clock starts at t=0
    clock = HostClock(time_unit=0.001, origin=6000.0)
    assert clock.now() == pytest.approx(0.0)
    mono.t += 1.0
    assert clock.now() == pytest.approx(1000.0)  # milliseconds
    # the launcher found the hub 2 ms further ahead: the hub's origin is 2 ms earlier on this clock
    assert clock.follow(6000.0 - 0.002) == pytest.approx(2.0)
    assert clock.now() == pytest.approx(1002.0)
    # then 1 ms back: the clock runs slow until it has given the millisecond back
    before = clock.now()
    assert clock.follow(6000.0 - 0.001) == 0.0
    assert clock.now() == pytest.approx(before)
    mono.t += 0.001 / SLEW / 2  # half the slew
    assert clock.now() == pytest.approx(1000.0 + 0.001 / SLEW / 2 * 1000 + 1.5)
    mono.t += 10.0
    assert clock.now() == pytest.approx((mono.t - 6000.0 + 5000.0) * 1000 + 1.0)


def test_the_key_to_follow_is_a_plain_key_and_needs_an_origin():
    base = {"system": "s", "path": "n", "source": {"kind": "python", "ref": "x.py:X"}, "origin": 1.0}
    assert from_dict({**base, "follow_origin": wire.host_origin_key("s", "arm")}).follow_origin == "iota/s/@origin/arm"
    with pytest.raises(ConfigError, match="follow_origin must be a key without wildcards"):
        from_dict({**base, "follow_origin": "iota/s/@origin/*"})
    with pytest.raises(ConfigError, match="needs an origin"):
        from_dict({**{k: v for k, v in base.items() if k != "origin"}, "follow_origin": "iota/s/@origin/arm"})
