"""Replay of one node of a virtual-time system run: an input that arrived at the same instant as
the node's own firings goes in where the recording has it, after the firings that came before it.

In one process the system fires its actions in one order (components in declaration order); a
node declared before its sender fires what is due at an instant before the sender's output
reaches it. Replayed alone, the node would take the input first ("inputs first at an instant")
and diverge from a recording that is right."""
from pathlib import Path

import pytest

from iotad.kernel.api import Iota, Output
from iotad.kernel.compose import Composite, flatten
from iotad.kernel.types import Int
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_reader import read_recording
from iotad.recording.replay import replay_node
from system_iotas import Ticker

ROOT = Path(__file__).resolve().parents[2]


class Sender(Iota):
    """Sends 10, 20, 30... every time unit, at the same instants as the ticker's ticks."""
    out = Output(Int, switching=0)

    def init(self):
        self.n = 0

    @out.action(value=lambda self: 10 * (self.n + 1), after=1.0)
    def sent(self):
        self.n += 1


def test_an_input_at_the_instant_of_a_tick_is_replayed_after_the_tick(tmp_path):
    path = tmp_path / "tick.mcap"
    record_run(Composite("sys", Ticker("ticker"), Sender("sender"), bind=[("sender.out", "ticker.inp")]),
               path, until=3.5)
    recording = read_recording(path)
    events = [(e["t"], e["kind"], e["action"], e.get("value")) for e in recording.trace("ticker")
              if e["kind"] in ("input", "output")]
    # the ticker is declared first: at t=1 it ticks (0 inputs seen), then the input arrives, then its echo
    assert events[:3] == [(1.0, "output", "tick", 0), (1.0, "input", "inp", 10), (1.0, "output", "echo", 10)]
    result = replay_node(recording, "ticker", tolerance=0.0)
    assert result.ok, "\n".join(result.lines())
    assert [e["value"] for e in result.replayed] == [0, 10, 1, 20, 2, 30]


def test_every_node_of_the_can_arm_example_replays_its_recording(tmp_path):
    pytest.importorskip("pybullet")
    from iotad.launcher.system.in_process import compose
    from iotad.launcher.system.system_file import load_system
    system = load_system(ROOT / "examples" / "arm_can.toml")
    path = tmp_path / "arm.mcap"
    root = compose(system)
    try:
        record_run(root, path, until=1.0, system=system.name)
    finally:
        for leaf in flatten(root).leaves:  # the simulated arm's PyBullet client
            getattr(leaf.iota, "close", lambda: None)()
    recording = read_recording(path)
    for node in recording.specs:
        result = replay_node(recording, node, tolerance=1e-9)
        assert result.ok, "\n".join(result.lines())
        assert result.recorded, node
