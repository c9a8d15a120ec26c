"""The arm as a system file run by `iotad run --virtual` (trajectory -> can_motor -> [[can]] bus ->
simulated ODrives, an Estop at 1.2 s): the recording holds every frame of the bus, both
directions, on one topic (sender, bit time, bytes, CAN Simple direction and message name, at the
time the frame ended), and `iotad replay --node motor` re-runs can_motor against its recorded
inputs and sends the same frames, byte for byte, at the same times."""
import json
import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest

pytest.importorskip("pybullet")

from arm_system import system_toml  # noqa: E402
from iotad.recording.mcap_reader import read_recording  # noqa: E402
from iotad.recording.replay import replay_node  # noqa: E402

IOTAD = [sys.executable, "-m", "iotad.cli"]
TARGET = [0.2, 0.1, -0.9, -0.3, 1.2, 0.4]
NS = 1e-9


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    folder = tmp_path_factory.mktemp("arm_can")
    system, inputs, output = folder / "arm_can.toml", folder / "estop.jsonl", folder / "arm_can.mcap"
    system.write_text(system_toml(TARGET))
    inputs.write_text(json.dumps({"t": 1.2, "iota": "arm_can/motor", "action": "estop", "value": True}) + "\n")
    run = subprocess.run([*IOTAD, "run", str(system), "--virtual", "--until", "1.4", "-o", str(output), "--plain",
                          "--inputs", str(inputs)], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "0 violations" in run.stdout
    return output


def test_every_frame_of_the_bus_is_on_one_topic_in_bus_order(recording):
    rec = read_recording(recording)
    log = [m for m in rec.messages if m.topic == "iota/arm_can/can0/frames"]
    trace = {node: rec.trace(node) for node in ("motor", "odrives")}
    received = sorted([(e["t"], "odrives", e["value"]) for e in trace["odrives"] if e["action"] == "can_rx"]
                      + [(e["t"], "motor", e["value"]) for e in trace["motor"] if e["action"] == "can_rx"],
                      key=lambda item: item[0])
    # one record per frame the bus carried, when its receiver got it, with the same bytes
    assert len(log) == len(received) > 3000
    for message, (t, receiver, frame) in zip(log, received):
        record = message.value
        assert message.log_time == pytest.approx(t / NS, abs=1)
        assert record["station"] == (0 if receiver == "odrives" else 1)   # [[can]] stations = [motor, odrives]
        assert {k: record[k] for k in ("id", "extended", "rtr", "dlc", "data")} == frame
        assert 40e-6 <= record["duration"] <= 135e-6
    kinds = Counter((m.value["station"], m.value["direction"], m.value["message"]) for m in log)
    for name in ("Clear_Errors", "Set_Controller_Mode", "Set_Limits", "Set_Axis_State", "Set_Input_Pos",
                 "Get_Error", "Get_Torques", "Estop"):
        assert kinds[(0, "TO_AXIS", name)] >= 6, name             # the motor's commands and requests
    for name in ("Heartbeat", "Get_Encoder_Estimates", "Get_Error", "Get_Torques"):
        assert kinds[(1, "FROM_AXIS", name)] >= 6, name           # the axes' answers and cyclic messages
    assert not [k for k in kinds if k[2] in ("UNKNOWN", "MALFORMED")]


def test_iotad_replay_of_can_motor_sends_the_same_frames(recording):
    replay = subprocess.run([*IOTAD, "replay", str(recording), "--node", "motor"], capture_output=True, text=True,
                            timeout=120)
    assert replay.returncode == 0, replay.stdout + replay.stderr
    assert "motor: replay agrees" in replay.stdout and "largest time difference 0 " in replay.stdout
    result = replay_node(read_recording(recording), "motor", tolerance=0.0)
    assert result.ok, result.lines()

    def frames(events):  # the node sends an instant's frames as one can_tx_burst (format 2's bus)
        return [(e["t"], v["id"], v["data"][:v["dlc"]]) for e in events
                for v in ([e["value"]] if e["action"] == "can_tx" else e["value"] if e["action"] == "can_tx_burst" else [])]

    assert {e["action"] for e in result.recorded} & {"can_tx", "can_tx_burst"} == {"can_tx_burst"}
    recorded, replayed = frames(result.recorded), frames(result.replayed)
    assert recorded == replayed and len(recorded) > 1500
    estops = [t for t, ident, _ in recorded if ident & 0x1F == 0x02]
    assert len(estops) >= 6 and min(estops) == pytest.approx(1.2, abs=0.003)
