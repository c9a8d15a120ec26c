"""`iotad candump`: a recording's CAN frames, one line each, decoded as ODrive CAN Simple by name;
filters by message, axis, node, time and direction; bad input is one line of error."""
import re

import pytest

pytest.importorskip("pybullet")

from arm_hil import EXAMPLE  # noqa: E402
from iotad.can import odrive  # noqa: E402
from iotad.cli import main  # noqa: E402
from iotad.cli.commands.candump import frame_events  # noqa: E402
from iotad.recording.mcap_reader import read_recording  # noqa: E402

LINE = re.compile(r"^(\w+)\s+(\d+\.\d{6})\s+(\S+)\s+([0-9A-F]{3})\s+\[(\d)\]\s+((?:[0-9A-F]{2} ?)*|R)\s+(\S+)(.*)$")


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("candump") / "arm.mcap"
    assert main(["run", str(EXAMPLE), "--virtual", "--until", "0.6", "-o", str(path)]) == 0
    return path


def dump(capsys, *args):
    capsys.readouterr()
    code = main(["candump", *map(str, args)])
    captured = capsys.readouterr()
    return code, captured.out.splitlines(), captured.err


def test_every_frame_sent_is_one_line_decoded_by_name(recording, capsys):
    code, lines, _ = dump(capsys, recording)
    assert code == 0
    sent = frame_events(read_recording(recording), "tx")
    assert len(lines) == len(sent) > 300
    parsed = [LINE.match(line) for line in lines]
    assert all(parsed), [line for line, p in zip(lines, parsed) if not p][:3]
    assert {p.group(1) for p in parsed} == {"motor", "odrives"}
    times = [float(p.group(2)) for p in parsed]
    assert times == sorted(times)
    # the first frames are the motor node arming axis 1, in the order the node sends them
    assert [p.group(7) for p in parsed[:4]] == ["Clear_Errors", "Set_Controller_Mode", "Set_Limits", "Set_Axis_State"]
    for (t, node, action, index, frame), p in zip(sent, parsed):
        assert int(p.group(4), 16) == frame.id and int(p.group(5)) == frame.dlc
        assert p.group(7) == odrive.decode(frame).name
    assert "Axis_State=CLOSED_LOOP_CONTROL" in "\n".join(lines)


def test_filters_by_message_axis_time_node_and_direction(recording, capsys):
    _, beats, _ = dump(capsys, recording, "--message", "Heartbeat", "--axis", "3")
    assert beats and all(" Heartbeat node=3 " in line and line.startswith("odrives") for line in beats)
    assert len(beats) == 6  # every 100 ms for 0.6 s
    _, window, _ = dump(capsys, recording, "--start", "0.3", "--end", "0.31", "--node", "motor")
    assert window and all(line.startswith("motor") and 0.3 <= float(line.split()[1]) <= 0.31 for line in window)
    _, received, _ = dump(capsys, recording, "--rx", "--node", "odrives", "--count", "5")
    assert len(received) == 5 and all(LINE.match(line).group(3) == "can_rx" for line in received)
    _, everything, _ = dump(capsys, recording, "--all", "--start", "0.5")
    assert {LINE.match(line).group(3) for line in everything} >= {"can_tx", "tx[0]", "rx[1]", "can_rx"}


def test_bad_input_is_one_line_of_error(recording, capsys, tmp_path):
    text = tmp_path / "notes.txt"
    text.write_text("not a recording")
    for args, message in (([text], "not an MCAP recording"), ([tmp_path / "none.mcap"], "no such file"),
                          ([recording, "--message", "Hello"], "not a CAN Simple message"),
                          ([recording, "--node", "trajectory"], "no CAN frame events of node(s) trajectory"),
                          ([], "give a recording"), ([recording, "--interface", "virtual"], "are for --live"),
                          (["--live", "--start", "1"], "a live bus has none of them"),
                          ([recording, "--start", "5", "--end", "1"], "--start 5 is after --end 1"),
                          ([recording, "--start", "100"], "no CAN frame events between 100 s and the end (its frames span 0 to"),
                          ([recording, "--axis", "99"], "--axis 99: an ODrive node id is 0 to 63")):
        code, out, err = dump(capsys, *args)
        assert code == 2 and message in err and len(err.strip().splitlines()) == 1, (args, err)


def test_live_reads_a_bus_until_quiet(capsys):
    code, lines, err = dump(capsys, "--live", "--interface", "virtual", "--channel", "iotad-candump-test",
                            "--timeout", "0.2")
    assert code == 0 and lines == [] and "virtual bus on iotad-candump-test" in err


def test_a_recorded_value_that_is_no_frame_is_shown_as_such(tmp_path, capsys):
    """An external can_rx input with id 5000 and extended false: the channel's type takes it (the
    motor node reports it MALFORMED); candump shows the line, it used to drop it in silence."""
    text = EXAMPLE.read_text().replace('arm_trajectory.py', str(EXAMPLE.parent / "arm_trajectory.py"))
    assert 'external = ["motor.estop"]' in text
    text = text.replace('external = ["motor.estop"]', 'external = ["motor.estop", "motor.can_rx"]', 1)
    system = tmp_path / "ext.toml"
    system.write_text(text)
    inputs = tmp_path / "odd.jsonl"
    inputs.write_text('{"t": 0.2, "action": "motor.can_rx", "value": {"id": 5000, "extended": false, '
                      '"rtr": false, "dlc": 8, "data": [0, 0, 0, 0, 0, 0, 0, 0]}}\n')
    out = tmp_path / "odd.mcap"
    assert main(["run", str(system), "--virtual", "--until", "0.3", "--inputs", str(inputs), "-o", str(out)]) == 0
    code, lines, _ = dump(capsys, out, "--rx", "--node", "motor", "--start", "0.2", "--end", "0.2")
    assert code == 0
    assert lines == ["motor  0.200000  can_rx  not a CAN frame: CAN id 0x1388 does not fit a 11-bit standard id "
                     "(0..0x7FF)"]
    code, lines, _ = dump(capsys, out, "--rx", "--node", "motor", "--start", "0.2", "--end", "0.2", "--axis", "1")
    assert lines == []  # a filter by axis or message leaves it out: it has neither
