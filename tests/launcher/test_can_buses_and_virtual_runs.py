"""`[[can]]` in system files (every check trips on a file and passes on its twin), and `iotad run
--virtual`: the file's nodes and its CAN buses in one process in virtual time, recorded in the
format every reading command takes."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from iotad.can.frame import Frame
from iotad.cli import main
from iotad.launcher.system.system_file import SystemFileError, load_system
from iotad.recording.mcap_reader import read_recording
from system_iotas import PINGPONG_BUS, pingpong_system

ROOT = Path(__file__).resolve().parents[2]

GOOD_BUS = PINGPONG_BUS


def write(tmp_path: Path, bus: str = GOOD_BUS, pinger: str = "CanPinger") -> Path:
    path = tmp_path / "pingpong.toml"
    path.write_text(pingpong_system(0.01, bus=bus, pinger=pinger))
    return path


def errors(tmp_path: Path, **kw) -> str:
    with pytest.raises(SystemFileError) as caught:
        load_system(write(tmp_path, **kw))
    return "\n".join(caught.value.errors)


def test_a_bus_binds_its_stations_and_tells_each_node_host_what_to_open(tmp_path):
    system = load_system(write(tmp_path))
    bus = system.buses["can0"]
    assert (bus.interface, bus.channel, bus.bitrate, bus.stations) == ("socketcan", "vcan0", 1_000_000,
                                                                      ["pinger", "echo"])
    # can_rx is fed by the bus (no [[bind]] needed); each station's host is told what to open
    for node in ("pinger", "echo"):
        config = system.node_config(node, 0.0, ["tcp/127.0.0.1:7447"])
        assert config["can"] == {"bus": "can0", "interface": "socketcan", "channel": "vcan0",
                                 "bitrate": 1_000_000, "options": {}}


@pytest.mark.parametrize("bus, expected", [
    (GOOD_BUS + '\nspeed = 3', "unknown key 'speed'"),
    (GOOD_BUS.replace('name = "can0"', 'name = "can 0"'), "name must be one key chunk"),
    (GOOD_BUS.replace('name = "can0"', 'name = "echo"'), "already taken by another bus or a node"),
    (GOOD_BUS.replace('interface = "socketcan"', 'interface = ""'), "interface must name a python-can interface"),
    (GOOD_BUS.replace('channel = "vcan0"', 'channel = 0'), "channel must be a string"),
    (GOOD_BUS + "\nbitrate = 5", "bitrate must be an integer from 10000 to 1000000"),
    (GOOD_BUS + "\noptions = 3", "options must be a table"),
    (GOOD_BUS.replace('["pinger", "echo"]', '[]'), "stations must be a non-empty list"),
    (GOOD_BUS.replace('["pinger", "echo"]', '["pinger", "motor"]'), "station 'motor' is not a node"),
    (GOOD_BUS.replace('["pinger", "echo"]', '["pinger", "pinger"]'), "listed twice"),
])
def test_a_bad_bus_entry_is_named_with_what_is_wrong(tmp_path, bus, expected):
    message = errors(tmp_path, bus=bus)
    assert "[[can]] #1" in message and expected in message


def test_a_station_needs_plain_canframe_channels(tmp_path):
    message = errors(tmp_path, pinger="NotAStation")
    assert "'pinger' needs a plain input channel 'can_rx' of type canFrame" in message
    assert "pinger.can_tx carries" in message and "not canFrame" in message


def test_a_node_cannot_sit_on_two_buses(tmp_path):
    bus = GOOD_BUS + '\n[[can]]\nname = "can1"\ninterface = "socketcan"\nstations = ["echo"]'
    assert "node 'echo' is already a station of bus 'can0'" in errors(tmp_path, bus=bus)


def test_a_node_may_start_after_a_bus_logger_and_is_told_when_the_bus_has_none(tmp_path):
    path = tmp_path / "pingpong.toml"
    path.write_text(pingpong_system(0.01, echo='after = ["can0"]'))
    assert load_system(path).nodes["echo"].after == ["can0"]  # the logger of can0 is a node
    path.write_text(pingpong_system(0.01, echo='after = ["can0"]', bus=GOOD_BUS + "\nlog = false"))
    with pytest.raises(SystemFileError) as caught:
        load_system(path)
    assert "after names unknown node 'can0' (bus 'can0' has no logger node: it says log = false)" in str(caught.value)


def test_iotad_run_check_accepts_the_bus(tmp_path, capsys):
    assert main(["run", "--check", str(write(tmp_path))]) == 0
    assert "ok: system" in capsys.readouterr().out


def frames(recording, node, action):
    return [(round(e["t"], 9), Frame.from_value(e["value"])) for e in recording.trace(node)
            if e["kind"] in ("output", "input") and e["action"] == action and e["value"] is not None]


def test_virtual_run_carries_frames_over_the_modelled_bus_and_records_them(tmp_path, capsys):
    out = tmp_path / "pingpong.mcap"
    assert main(["run", str(write(tmp_path)), "--virtual", "--until", "0.1", "-o", str(out)]) == 0
    assert main(["check", str(out)]) == 0
    recording = read_recording(out)
    pings = frames(recording, "pinger", "can_tx")
    answers = frames(recording, "echo", "can_tx")
    heard = frames(recording, "pinger", "can_rx")
    assert [f.data[0] for _, f in pings] == list(range(len(pings))) and len(pings) >= 9
    # every ping answered by 0x11 with its data; each answer heard by the pinger, in order
    assert [(f.id, f.data) for _, f in answers] == [(0x11, f.data) for _, f in pings][:len(answers)]
    assert [f for _, f in heard] == [f for _, f in answers][:len(heard)]
    # the bus holds each frame for its bit time (1-byte standard frame at 1 Mbit/s: ~65-75 us)
    for (t_ping, _), (t_answer, _) in zip(pings, answers):
        assert 50e-6 < t_answer - t_ping < 100e-6
    for (t_answer, _), (t_heard, _) in zip(answers, heard):
        assert 50e-6 < t_heard - t_answer < 100e-6
    # the frames the echo never sees are its own: the bus does not deliver a frame to its sender
    assert not any(f.id == 0x11 for _, f in frames(recording, "echo", "can_rx"))


@pytest.mark.parametrize("log", [True, False])
def test_a_virtual_bus_logs_its_frames_as_the_can_entry_says(tmp_path, log):
    path = tmp_path / "pingpong.toml"
    path.write_text(pingpong_system(0.01, bus=GOOD_BUS + ("" if log else "\nlog = false")))
    out = tmp_path / "pingpong.mcap"
    assert main(["run", str(path), "--virtual", "--until", "0.05", "-o", str(out)]) == 0
    recording = read_recording(out)
    logged = [e for e in recording.trace("can0") if e["action"] == "frames" and e["kind"] == "output"]
    carried = [e for e in recording.trace("can0") if e["action"] == "rx" and e["kind"] == "output"]
    assert len(carried) >= 8
    # one log entry per frame carried, at the frame's end, or none at all with log = false
    assert [e["t"] for e in logged] == ([e["t"] for e in carried] if log else [])
    assert main(["check", str(out)]) == 0


def test_virtual_runs_are_deterministic_for_a_seed(tmp_path):
    path = write(tmp_path)
    traces = []
    for k in range(2):
        out = tmp_path / f"run{k}.mcap"
        assert main(["run", str(path), "--virtual", "--until", "0.05", "--seed", "7", "-o", str(out)]) == 0
        traces.append([(e["t"], e["iota"], e["action"], str(e.get("value"))) for e in read_recording(out).trace()])
    assert traces[0] == traces[1] and len(traces[0]) > 10


def test_virtual_run_of_figure2_passes_check_and_shows_the_scheduler_at_work(tmp_path, capsys):
    out = tmp_path / "fig2.mcap"
    assert main(["run", str(ROOT / "examples/figure2.toml"), "--virtual", "--until", "20", "-o", str(out)]) == 0
    summary = capsys.readouterr().out
    assert main(["check", str(out)]) == 0
    trace = read_recording(out).trace()
    acks = {e["value"] for e in trace if e["iota"] == "scheduler" and e["action"] == "ack" and e["kind"] == "output"}
    assert "COMMIT" in acks
    # the summary's counts are the recording's: firings are outputs and internal actions; inputs are events
    kinds = {kind: sum(1 for e in trace if e["kind"] == kind) for kind in ("output", "internal", "input")}
    assert (f"{kinds['output'] + kinds['internal']} firings ({kinds['output']} outputs, {kinds['internal']} internal), "
            f"{kinds['input']} inputs, 0 violations") in summary


@pytest.mark.parametrize("args, expected", [
    (["--virtual"], "--virtual needs --until"),
    (["--virtual", "--until", "1", "--port", "7999"], "--port is for processes over zenoh"),
    (["--virtual", "--until", "1", "--inputs", "/nonexistent.jsonl"], "/nonexistent.jsonl"),
])
def test_virtual_run_refuses_what_it_cannot_do_with_a_clear_message(tmp_path, capsys, args, expected):
    assert main(["run", str(write(tmp_path))] + args) != 0
    captured = capsys.readouterr()
    assert expected in captured.err and "Traceback" not in captured.err


def test_an_input_script_names_a_node_as_the_system_file_does(tmp_path, capsys):
    request = {"control": {"w": 0.2, "k": 1.0}, "epoch": 1.0, "timeout": 1.0, "priority": 9}
    for name in ("scheduler", "figure2/scheduler"):  # the node's name, or its full path
        script = tmp_path / "in.jsonl"
        script.write_text(json.dumps({"t": 1.5, "iota": name, "action": "req", "index": 1, "value": request}) + "\n")
        out = tmp_path / f"{name.replace('/', '-')}.mcap"
        assert main(["run", str(ROOT / "examples/figure2.toml"), "--virtual", "--until", "3", "-o", str(out),
                     "--inputs", str(script)]) == 0
        inputs = [e for e in read_recording(out).trace("scheduler") if e["kind"] == "input" and e["t"] == 1.5]
        assert [(e["action"], e["index"], e["value"]["priority"]) for e in inputs] == [("req", 1, 9)], name
    script.write_text(json.dumps({"t": 1.0, "iota": "ghost", "action": "req", "index": 0, "value": request}) + "\n")
    assert main(["run", str(ROOT / "examples/figure2.toml"), "--virtual", "--until", "3", "--no-record",
                 "--inputs", str(script)]) == 2
    assert "no node 'ghost' in this system (nodes: manipulation, scheduler, vision" in capsys.readouterr().err


def test_two_identical_virtual_runs_write_the_same_bytes(tmp_path):
    # in two processes, with two string-hash seeds: a module name made with hash() made the
    # recordings' spec attachments differ though every message was the same
    files = []
    for seed in ("1", "2"):
        out = tmp_path / f"run{seed}.mcap"
        done = subprocess.run([sys.executable, "-m", "iotad.cli", "run", str(ROOT / "examples/figure2.toml"),
                               "--virtual", "--until", "10", "-o", str(out)],
                              cwd=ROOT, capture_output=True, text=True, timeout=120,
                              env=dict(os.environ, PYTHONHASHSEED=seed))
        assert done.returncode == 0, done.stderr
        files.append(out.read_bytes())
    assert files[0] == files[1]


def test_a_virtual_run_closes_the_worlds_its_nodes_opened(capsys):
    # as each node's process would at its end: a second run in this process (a test, a notebook)
    # found the first one's PyBullet world still open under its key
    from sim.worlds import find_world

    assert main(["run", str(ROOT / "examples" / "buggy.toml"), "--virtual", "--until", "0.5", "--no-record"]) == 0
    assert find_world("body") is None
