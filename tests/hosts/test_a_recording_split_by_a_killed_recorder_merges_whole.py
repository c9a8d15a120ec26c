"""A recorder killed (-9) mid-run on the hub and on a host: each launcher restarts it, and the
recording goes on in a numbered file beside the first (`split_1.mcap`, `split.arm_1.mcap`). The
run's `join them with:` line names all four files, and `iotad merge` of exactly what it says
joins them: every event of the requester's and the scheduler's traces that any of the four files
holds is in the merged file, and the stretch between each killed recorder's last message and its
successor's first is a gap named with its cause (its recorder was restarted). Before, the line
named only `split.mcap split.arm.mcap` (merging as told lost both later files), and `iotad merge`
refused two files of the hub."""
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

from agent_helpers import Lines, start
from launcher_helpers import ROOT
from namespaces import agent, hosts, split_figure2
from iotad.launcher.processes import interrupt_then_kill
from iotad.recording.mcap_format import RecordingError
from iotad.recording.mcap_reader import read_recording
from iotad.recording.merge import merged_gaps

PORT = 7683


def traced(recording) -> set:
    return {(m.topic, m.publish_time, m.sequence, m.data) for m in recording.messages if m.topic.endswith("/@trace")}


def recorder_pid(lines: Lines, prefix: str, path: Path) -> int:
    assert lines.wait_for(f"recording to {path} (recorder pid", 90), lines.text()[-4000:]
    found = re.search(rf"{re.escape(prefix)}\[ *[\d.]+\] recording to {re.escape(str(path))} \(recorder pid (\d+)\)",
                      lines.text())
    assert found, lines.text()[-4000:]
    return int(found.group(1))


def holds_events(path: Path, timeout: float = 30.0) -> bool:
    """Whether the recording being written at `path` holds an event of vision's trace, within
    `timeout` s (read as `iotad recover` would: up to its last whole chunk)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            if any(m.topic == "iota/split/vision/@trace" for m in read_recording(path).messages):
                return True
        except RecordingError:
            pass  # nothing whole in it yet
        time.sleep(0.2)
    return False


def test_the_join_line_names_every_part_and_their_merge_holds_every_event_with_the_restart_named(tmp_path):
    with hosts("brain", "arm", net=231) as net:
        hub, arm = net.addresses[("brain", "arm")], net.addresses["arm"]
        system = tmp_path / "split.toml"
        system.write_text(split_figure2("split", hub, PORT, "brain", "arm", arm, count=30, pause=0.3))
        recording, arm_path = tmp_path / "split.mcap", tmp_path / "split.arm.mcap"
        with agent(net, "arm", f"tcp/{hub}:{PORT}"):
            run = start(net.exec("brain", sys.executable, "-m", "iotad", "run", str(system), "--insecure", "--plain",
                                 "--until", "14", "--after-live", "-o", str(recording)))
            lines = Lines(run)
            try:
                assert lines.wait_for("vision: live (on another host)", 90), lines.text()[-4000:]
                hub_recorder, arm_recorder = recorder_pid(lines, "", recording), recorder_pid(lines, "[arm] ", arm_path)
                # killed once each file holds the requester's events (what a recorder wrote is on disk)
                assert holds_events(recording) and holds_events(arm_path), lines.text()[-4000:]
                os.kill(hub_recorder, signal.SIGKILL)
                os.kill(arm_recorder, signal.SIGKILL)  # one pid namespace: the arm's namespace is only its network
                assert lines.wait_for(f"recording continues in {tmp_path / 'split_1.mcap'}", 60), lines.text()[-4000:]
                assert lines.wait_for(f"recording continues in {tmp_path / 'split.arm_1.mcap'}", 60), \
                    lines.text()[-4000:]
                run.wait(150)
                lines.wait_for("join them with: iotad merge", 30)  # the summary's last line, or the end
            finally:
                interrupt_then_kill(run)
    output = lines.text()
    joined = re.search(r"join them with: (iotad merge .*)$", output, re.M)
    assert joined, output[-4000:]
    command = shlex.split(joined.group(1))
    files = [Path(f) for f in command[2:command.index("-o")]]
    assert files == [recording, tmp_path / "split_1.mcap", arm_path, tmp_path / "split.arm_1.mcap"], joined.group(0)

    merged_path = tmp_path / "merged.mcap"
    command[command.index("-o") + 1] = str(merged_path)
    done = subprocess.run([sys.executable, "-m", "iotad", *command[1:]], capture_output=True, text=True, timeout=120,
                          cwd=ROOT)
    assert done.returncode == 0, done.stdout + done.stderr
    merged = read_recording(merged_path)
    events = traced(merged)
    for path in files:  # every event each file holds, counted per file
        held = traced(read_recording(path))
        assert held, path
        assert len(held - events) == 0, (path, len(held), len(held - events))
    gaps = merged_gaps(merged)
    for host, cut, following in (("brain", "split.mcap", "split_1.mcap"), ("arm", "split.arm.mcap", "split.arm_1.mcap")):
        named = [g for g in gaps if g["host"] == host and g["reason"].startswith(
            f"its recorder was restarted: {cut} was cut short (killed by SIGKILL")
            and f"goes on in {following} from t=" in g["reason"]]
        assert len(named) == 1 and named[0]["from_ns"] < named[0]["to_ns"], gaps
    assert "its recorder was restarted" in done.stdout, done.stdout
