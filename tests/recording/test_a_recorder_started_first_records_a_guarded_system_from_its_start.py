"""README's "Record" step: `iotad record` started before `iotad run` waits for the system's hub
and records every node from its start, so that `iotad check` can check them all. The hub that
`iotad run` guards (access control, on by default) lets the recorder in only with the
credentials the run writes as it starts: the recorder looks for them every 0.2 s, not once a
second, and so is in before the nodes start. With 1 s it came in after them and every node was
NOT CHECKED."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from iotad.node_host.wire import START_KIND
from iotad.recording.mcap_reader import read_recording
from launcher_helpers import free_port
from node_harness import wait_for
from recorded_systems import check_of_a_real_run

ROOT = Path(__file__).resolve().parents[2]


def test_a_recorder_started_before_the_run_records_every_node_from_its_start(tmp_path):
    port, output, err = free_port(), tmp_path / "mine.mcap", tmp_path / "record.err"
    with open(err, "w") as sink:
        recorder = subprocess.Popen(
            [sys.executable, "-m", "iotad.cli", "record", "-o", str(output), "--system-file",
             str(ROOT / "examples" / "figure2.toml"), "--connect", f"tcp/127.0.0.1:{port}", "--duration", "60"],
            cwd=ROOT, stderr=sink, text=True)
    try:
        wait_for(lambda: "waiting for a hub" in err.read_text() or recorder.poll() is not None, 20,
                 what="the recorder to wait")
        run = subprocess.run([sys.executable, "-m", "iotad.cli", "run", str(ROOT / "examples" / "figure2.toml"),
                              "--port", str(port), "--until", "4", "--after-live", "--no-record"],
                             cwd=ROOT, capture_output=True, text=True, timeout=120)
        assert run.returncode == 0, run.stdout + run.stderr
        assert "access control" in run.stdout + run.stderr and "OFF" not in run.stdout + run.stderr
    finally:
        recorder.send_signal(2)  # SIGINT: the recorder finishes its file
        recorder.wait(30)
    assert recorder.returncode == 0, err.read_text()
    recording = read_recording(output)
    for node in ("scheduler", "vision", "manipulation"):  # each engine's start record is in the file
        assert [e for e in recording.process_trace(node) if e["kind"] == START_KIND], node
    check_of_a_real_run(output)  # every message delivered as sent; a node late only under load
