"""Estop over CAN: the motor node sends Estop, both axes go IDLE, and Buggy stops (its brake)
within half a second, rather than coasting across the arena; it stays where it stopped, and the
Buggy picture marks the estop."""
import json
import math

from buggy_runs import outputs, run_virtual

from iotad.can.odrive import AXIS_STATE
from sim.worlds.buggy_plot import buggy_data
from iotad.recording.mcap_reader import read_recording

ESTOP_AT = 8.0


def test_estop_stops_buggy_within_half_a_second(tmp_path):
    inputs = tmp_path / "estop.jsonl"
    inputs.write_text(json.dumps({"t": ESTOP_AT, "action": "motor.estop", "value": True}) + "\n")
    recording = run_virtual("buggy.toml", ESTOP_AT + 3, tmp_path / "estop.mcap", "--inputs", str(inputs))
    poses = [(t, v) for t, node, _, v in outputs(recording, "pose") if node == "body"]

    def moved(start: float, end: float) -> float:
        span = [v for t, v in poses if start <= t <= end]
        return math.hypot(span[-1]["x"] - span[0]["x"], span[-1]["y"] - span[0]["y"])

    assert moved(ESTOP_AT - 1.0, ESTOP_AT) > 0.1  # it was driving (0.3 m/s at full speed)
    assert moved(ESTOP_AT + 0.5, ESTOP_AT + 3) < 1e-3  # and stopped within 0.5 s
    states = [v for t, node, channel, v in outputs(recording) if node == "motor" and channel.startswith("joint_status")
              and t > ESTOP_AT + 0.2]
    assert len(states) >= 2 and all(s["axis_state"] == AXIS_STATE["IDLE"] for s in states), states

    # the picture marks it: the estop input, on the path and over time
    assert buggy_data(read_recording(str(recording)))["estops"] == [(ESTOP_AT, True)]
