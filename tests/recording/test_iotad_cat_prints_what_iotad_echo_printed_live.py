"""`iotad cat REC.mcap KEYEXPR` prints a recording's values line for line as `iotad echo KEYEXPR`
printed them live during the same run (key, #sequence number, value as JSON); `--since` and
`--until` cut by the run's seconds; `iotad.open_recording` gives the same samples to Python, and
the reader's `Recording(path)`, which would read nothing, is refused."""
import json
import signal
import subprocess
import sys
from pathlib import Path

import pytest

import iotad
from iotad.cli import main
from iotad.node_host.transport import free_port
from iotad.recording.mcap_reader import Recording

ROOT = Path(__file__).resolve().parents[2]
KEYS = "iota/figure2/**"


def test_cat_prints_exactly_the_lines_echo_printed_of_the_same_run(tmp_path, capsys):
    port = free_port()
    out = tmp_path / "fig2.mcap"
    # the run first, echo once its hub is up: an echo started before it gives up after its
    # --connect-timeout, and on a loaded machine the hub came up later than that (echo heard nothing)
    run = subprocess.Popen([sys.executable, "-m", "iotad", "run", "examples/figure2.toml", "--until", "6",
                            "--after-live", "--port", str(port), "--insecure", "-o", str(out), "--plain"],
                           cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    echo = None
    try:
        said = []
        for line in run.stdout:
            said.append(line)
            if " hub: " in line:
                break
        assert any(" hub: " in line for line in said), "".join(said)
        echo = subprocess.Popen([sys.executable, "-m", "iotad", "echo", KEYS, "--connect", f"tcp/127.0.0.1:{port}",
                                 "--connect-timeout", "60"],
                                cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        rest, _ = run.communicate(timeout=120)
        assert run.returncode == 0, "".join(said) + rest
    finally:
        if run.poll() is None:
            run.kill()
            run.communicate()
        if echo is not None:
            echo.send_signal(signal.SIGINT)
            live, _ = echo.communicate(timeout=20)
    live = live.splitlines()
    assert main(["cat", str(out), KEYS]) == 0
    recorded = capsys.readouterr().out.splitlines()
    assert any("/scheduler/ack/" in line for line in live), live  # echo heard the run
    # key by key, the same lines in the same order (messages on different keys may cross on
    # their way to two subscribers); echo may have joined after a key's first message
    def by_key(lines):
        keys: dict[str, list[str]] = {}
        for line in lines:
            keys.setdefault(line.split()[0], []).append(line)
        return keys

    live_keys, recorded_keys = by_key(live), by_key(recorded)
    assert set(live_keys) == set(recorded_keys)
    for key, lines in live_keys.items():
        whole = recorded_keys[key]
        assert whole[whole.index(lines[0]):] == lines, key
    assert {line.split()[0] for line in recorded} >= {"iota/figure2/scheduler/ack/0", "iota/figure2/vision/req"}


def test_cat_cuts_by_time_and_open_recording_gives_the_same_samples(tmp_path, capsys):
    out = tmp_path / "fig2.mcap"
    assert main(["run", str(ROOT / "examples/figure2.toml"), "--virtual", "--until", "8", "-o", str(out),
                 "--plain"]) == 0
    capsys.readouterr()
    recording = iotad.open_recording(out)
    acks = recording.values("iota/figure2/scheduler/ack/*")
    assert [s.value for s in acks] and all(s.key.startswith("iota/figure2/scheduler/ack/") for s in acks)
    assert main(["cat", str(out), "iota/figure2/scheduler/ack/*", "--json", "--since", "1", "--until", "4"]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert lines == [{"key": s.key, "seq": s.seq, "send_ns": s.send_ns, "value": s.value, "t": s.t}
                     for s in acks if 1 <= s.t <= 4]
    assert lines and len(lines) < len(acks)
    # traces by node: each ack the scheduler sent is one of its output events
    sent = [e for e in recording.events("scheduler", kind="output") if e["action"] == "ack"]
    assert [(e["index"], e["value"]) for e in sent] == [(int(s.key.rsplit("/", 1)[1]), s.value) for s in acks]
    assert recording.series("iota/figure2/scheduler/ack/0") == [
        (s.t, s.value) for s in acks if s.key.endswith("/ack/0")]
    with pytest.raises(KeyError, match="no node 'nobody'"):
        recording.events("nobody")


def test_a_recording_built_by_hand_is_refused_not_empty(tmp_path, capsys):
    with pytest.raises(TypeError, match=r"reads nothing: open a recording with iotad.open_recording"):
        Recording(str(tmp_path / "x.mcap"))
    assert main(["cat", str(tmp_path / "none.mcap")]) == 2
    assert "no such file" in capsys.readouterr().err
