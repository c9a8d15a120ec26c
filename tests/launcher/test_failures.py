"""What the launcher does when things go wrong, each the way a robotics engineer expects:
a spec that fails to load in its node, a node that keeps exiting with an error, a node that
floods its receiver, a taken hub port, a recorder killed mid-run, a recording that cannot be
written, a node that ignores SIGINT and SIGTERM. Conditions are waited on, never slept on."""
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.launcher.options import LaunchOptions, RecordingOptions
from iotad.launcher.run.recorder_supervision import RECORDER_MODULE
from iotad.launcher.run.supervision import Launcher
from iotad.recording.mcap_reader import read_recording
from iotad.launcher.system.system_file import load_system
from launcher_helpers import (IOTAS, ROOT, Observer, children_of, free_port, gone, launcher, pair_system,
                              wait_until)

STUB = Path(__file__).resolve().parents[1] / "launcher_stub_node.py"


def stub_argv(*stubbed: str):
    """Node command lines: the stand-in host for the named nodes (all when none), the real one else."""
    def argv(config: str) -> list[str]:
        name = Path(config).stem
        if not stubbed or name in stubbed:
            return [sys.executable, str(STUB), config]
        return [sys.executable, "-m", "iotad.node_host", config]
    return argv


def in_process(tmp_path, system_file: Path, recording: RecordingOptions | None = None,
               **options) -> tuple[Launcher, list]:
    """A launcher in this process whose lines are kept with their time of arrival."""
    options.setdefault("until", 30)
    run = Launcher(load_system(system_file), LaunchOptions(live_table=False, log_dir=str(tmp_path / "logs"), **options),
                   recording)
    lines: list[tuple[float, str]] = []
    run.view.line = lambda text: lines.append((time.monotonic(), text))
    return run, lines


def texts(lines) -> list[str]:
    return [text for _, text in lines]


def write_system(tmp_path, name: str, body: str, **system) -> Path:
    path = tmp_path / f"{name}.toml"
    extra = "".join(f"{key} = {value}\n" for key, value in system.items())
    path.write_text(f'[system]\nname = "{name}"\n{extra}[system.endpoints]\n'
                    f'listen = ["tcp/127.0.0.1:{free_port()}"]\n{body}')
    return path


# ---------------------------------------------------------------------------- a spec that fails to load

BROKEN_AFTER_CHECK = """
from iotad import Input, Int, Iota, Output, Param
class Fine(Iota):
    out = Output(Int, switching=1)
"""


@pytest.mark.parametrize("required", [False, True], ids=["others-keep-running", "required-stops-all"])
def test_spec_that_fails_to_load_in_its_node_gives_up_with_its_stderr(tmp_path, required):
    """The file checked fine when the launcher read it, then broke (edited, or a module missing in
    the node's environment): the node host exits 2 (a configuration error) with the reason on
    stderr. No restart would mend it: one 'failed for good' line shows that stderr. A healthy node
    keeps running, unless the broken one is `required`, in which case everything stops with status 1."""
    spec = tmp_path / "flaky_spec.py"
    spec.write_text(BROKEN_AFTER_CHECK)
    path = write_system(tmp_path, "broken", f"""
[[node]]
name = "good"
python = "{IOTAS}:Source"
[[node]]
name = "bad"
python = "{spec}:Fine"
after = ["good"]
max_restarts = 2
backoff = 0.05
required = {str(required).lower()}
""")
    run, lines = in_process(tmp_path, path)
    spec.write_text(BROKEN_AFTER_CHECK.replace("switching=1)", "switching=1)\n    oops = undefined_name"))
    seen = {}

    def line(text):
        lines.append((time.monotonic(), text))
        if "failed for good" in text and not required:
            seen["good"] = run.runs["good"].state
            run.request_stop("test: seen the give-up")
    run.view.line = line
    assert run.run() == 1, texts(lines)
    giveup = next(text for text in texts(lines) if text.startswith("bad: failed for good: exit 2"))
    assert "cannot load its IOTA" in giveup and "undefined_name" in giveup, giveup
    assert "configuration error" in giveup
    assert run.runs["bad"].state == "failed" and run.runs["bad"].restarts == 0
    if required:
        assert "bad is required and has ended for good: stopping every node" in texts(lines)
        assert run.runs["good"].state == "stopped"
    else:
        assert seen["good"] == "running", texts(lines)
        assert run.runs["good"].restarts == 0


# ---------------------------------------------------------------------------- repeated error exits

def test_repeated_error_exits_back_off_and_honour_max_restarts(tmp_path):
    path = write_system(tmp_path, "crashy", f"""
[[node]]
name = "n"
python = "{IOTAS}:Rogue"
params = {{ exit_code = 3, exit_after = 0.0, stderr = "n: motor driver not found" }}
max_restarts = 3
backoff = 0.1
""")
    run, lines = in_process(tmp_path, path, node_argv=stub_argv())
    assert run.run() == 1, texts(lines)
    exits = [(when, text) for when, text in lines if text.startswith("n: exit 3")]
    starts = [when for when, text in lines if text.startswith("n: started") or text.startswith("n: restarted")]
    assert [text.split("; ")[1].split("\n")[0] for _, text in exits[:3]] == \
        ["restart 1/3 in 0.10 s", "restart 2/3 in 0.20 s", "restart 3/3 in 0.40 s"], texts(lines)
    # its stderr, each time: its own start's, not the earlier ones' again (the log holds them all)
    assert all(text.count("| n: motor driver not found") == 1 for _, text in exits[:3]), texts(lines)
    # each restart waited at least its backoff after the exit it follows (a lower bound: load-proof)
    for (exited, _), restarted, delay in zip(exits, starts[1:], (0.1, 0.2, 0.4)):
        assert restarted - exited >= delay - 0.01
    assert len(starts) == 4 and run.runs["n"].restarts == 3
    giveup = [text for text in texts(lines) if "gave up" in text]
    assert len(giveup) == 1 and "gave up after 3 restarts (max_restarts = 3); last: exit 3" in giveup[0]
    assert "motor driver not found" in giveup[0]


def run_n_beside_a_good_node(tmp_path, name: str, n_lines: str) -> tuple[Launcher, str]:
    """A run of 1.5 s of two stand-in nodes, a healthy one and `n` (its `[[node]]` lines after
    the name and class: `n_lines`); the run must exit 1. The launcher and its summary."""
    path = write_system(tmp_path, name, f"""
[[node]]
name = "n"
python = "{IOTAS}:Rogue"{n_lines}
[[node]]
name = "good"
python = "{IOTAS}:Rogue"
params = {{ token = true, beat = true, exit_after = 60 }}
""")
    run, lines = in_process(tmp_path, path, node_argv=stub_argv(), until=1.5)
    assert run.run() == 1, texts(lines)
    return run, "\n".join(run.summary())


def test_a_run_that_ends_while_a_node_never_went_live_exits_1(tmp_path):
    """The run's --until comes while the restart policy still retries a node that fails at every
    start: the system never ran whole, and the exit status says so (it was 0)."""
    run, summary = run_n_beside_a_good_node(tmp_path, "neverlive", """
params = { exit_code = 3, exit_after = 0.0, stderr = "n: no motor driver yet" }
max_restarts = 100
backoff = 0.2""")
    assert run.runs["n"].state != "failed"  # not given up: still being retried when the run ended
    assert f"n: NEVER LIVE: it failed {run.runs['n'].failures} time(s), last with exit 3" in summary
    assert run.runs["n"].failures >= 2 and "good: NEVER LIVE" not in summary


def test_a_node_down_when_the_run_ends_is_reported_and_the_run_exits_1(tmp_path):
    """A node that went live, crashed and was still waiting for its restart when --until came was
    down for the end of the run: not "stopped", and not a clean run (it exited 0)."""
    run, summary = run_n_beside_a_good_node(tmp_path, "downatend", """
params = { token = true, beat = true, exit_code = 3, exit_after = 0.3 }
backoff = 60""")
    assert run.runs["n"].state == "down" and run.runs["n"].went_live and run.runs["good"].state == "stopped"
    assert "n: DOWN AT THE END: exit 3 " in summary and "its restart still to come" in summary, summary
    assert "NEVER LIVE" not in summary


def test_the_launcher_says_where_its_hub_listens(tmp_path):
    """With `--port 0` the OS picks the port: the launcher's line is the only place it is told."""
    path = write_system(tmp_path, "hubline", f"""
[[node]]
name = "good"
python = "{IOTAS}:Rogue"
params = {{ token = true, beat = true, exit_after = 60 }}
""")
    run, lines = in_process(tmp_path, path, node_argv=stub_argv(), until=0.5)
    assert run.run() == 0, texts(lines)
    hub = run.endpoints[0]
    assert f"hub: {hub} (tools attach with --connect {hub}, e.g. iotad top --connect {hub})" in texts(lines)


# ---------------------------------------------------------------------------- flooding

def test_node_flooding_its_receiver_is_recorded_as_violations_and_the_system_stays_up(tmp_path):
    """A node that does not keep its own switching time (here a stand-in host publishing 500 Hz
    on an output declared one event per second): the receiver rejects the excess, each rejection
    is a switching_time violation on its @trace and in the recording, and nothing restarts."""
    path = write_system(tmp_path, "flood", f"""
[[node]]
name = "rogue"
python = "{IOTAS}:Rogue"
params = {{ token = true, beat = true, flood_hz = 500.0, exit_after = 60 }}
[[node]]
name = "dst"
python = "{IOTAS}:Sink"
[[bind]]
from = "rogue.out"
to = "dst.inp"
""")
    output = tmp_path / "flood.mcap"
    run, lines = in_process(tmp_path, path, RecordingOptions(str(output)), node_argv=stub_argv("rogue"))
    waiter = threading.Thread(target=lambda: wait_until(lambda: run.tally.violations["dst"] >= 300, 30)
                              and run.request_stop("test: enough violations"), daemon=True)
    waiter.start()
    assert run.run() == 0, texts(lines)
    waiter.join(5)
    assert run.runs["dst"].restarts == 0 and run.runs["rogue"].restarts == 0, texts(lines)
    assert not any("stale" in text or "killing" in text for text in texts(lines)), texts(lines)
    recording = read_recording(output)
    assert recording.complete
    rejected = [v for v in recording.violations() if v.get("value", {}).get("violation") == "switching_time"]
    assert len(rejected) >= 300, len(rejected)
    beats = [m.value for m in recording.messages if m.topic == "iota/flood/dst/@heartbeat"]
    assert beats  # the receiver's engine loop kept beating through the flood
    print(f"\nflood at 500 Hz: {len(rejected)} rejected inputs recorded; the receiver's input backlog "
          f"peaked at {max(b['queue'] for b in beats)} (heartbeats)")


# ---------------------------------------------------------------------------- a taken hub port

def test_hub_port_in_use_is_one_clear_line_and_exit_2(tmp_path):
    with socket.socket() as squatter:
        squatter.bind(("127.0.0.1", 0))
        squatter.listen()
        port = squatter.getsockname()[1]
        result = subprocess.run([sys.executable, "-m", "iotad", "run", str(pair_system(tmp_path, port)),
                                 "--no-record", "--plain", "--log-dir", str(tmp_path / "logs")],
                                cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stdout + result.stderr
    assert f"tcp/127.0.0.1:{port} is taken" in result.stderr and "--port" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.stderr
    assert "started" not in result.stdout  # no node ran


# ---------------------------------------------------------------------------- recordings

def signal_the_recorder(proc, observer, signum: int, timeout: float):
    """Send `signum` to the run's recorder; the launcher event saying a new one took over, or None."""
    recorder = next(pid for pid, cmd in children_of(proc.pid).items() if RECORDER_MODULE in cmd)
    os.kill(recorder, signum)
    return observer.wait_event(lambda e: e["event"] == "recorder" and "restarted" in e["message"], timeout)


def test_recorder_killed_mid_run_is_reported_restarted_and_recoverable(tmp_path):
    port = free_port()
    system_file = pair_system(tmp_path, port)
    first = tmp_path / "rec.mcap"
    earlier = tmp_path / "rec_1.mcap"  # an earlier run's second file: kept, the new one goes on in rec_2
    earlier.write_bytes(b"an earlier run")
    observer = Observer("pair", f"tcp/127.0.0.1:{port}")
    try:
        with launcher(system_file, "-o", str(first)) as proc:
            assert observer.wait_all_alive(("src", "dst"), 20), proc.output.read_text()
            event = signal_the_recorder(proc, observer, signal.SIGKILL, 20)
            assert event is not None, proc.output.read_text()
            second = Path(event["file"])
            assert second == tmp_path / "rec_2.mcap"
            assert earlier.read_bytes() == b"an earlier run"
            # the new recorder hears the nodes: wait for their traffic in the growing file
            assert wait_until(lambda: second.exists() and any(
                m.topic.startswith("iota/pair/src/") for m in read_recording(second).messages), 20)
            proc.send_signal(signal.SIGINT)
            assert proc.wait(20) == 130
        output = proc.output.read_text()
    finally:
        observer.close()
    assert f"recorder: killed by SIGKILL" in output and f"'iotad recover {first}' makes it whole" in output, output
    assert f"recording in 2 files (the recorder died): {first}, {second}; what happened between them is lost, " \
           "so the run does not exit 0" in output, output
    recovered = tmp_path / "recovered.mcap"
    assert main(["recover", str(first), "-o", str(recovered)]) == 0
    assert read_recording(recovered).complete and read_recording(recovered).messages
    whole = read_recording(second)
    assert whole.complete
    news = [e for e in whole.launcher_events() if e["event"] == "recorder"]
    assert news and "restarted" in news[0]["message"]


def test_a_frozen_recorder_is_killed_and_replaced(tmp_path):
    """A recorder that stops (SIGSTOP, a write hung on a dead disk) gives no sign of life: after
    RECORDER_STALL s the launcher kills it, says why, and a new recorder takes over."""
    from iotad.launcher.run.supervision import RECORDER_STALL

    port = free_port()
    system_file = pair_system(tmp_path, port)
    first = tmp_path / "rec.mcap"
    observer = Observer("pair", f"tcp/127.0.0.1:{port}")
    try:
        with launcher(system_file, "-o", str(first)) as proc:
            assert observer.wait_all_alive(("src", "dst"), 20), proc.output.read_text()
            event = signal_the_recorder(proc, observer, signal.SIGSTOP, RECORDER_STALL + 2 * 3.0 + 20)  # heartbeat 3 s
            assert event is not None, proc.output.read_text()
            assert Path(event["file"]) == tmp_path / "rec_1.mcap"
            proc.send_signal(signal.SIGINT)
            assert proc.wait(20) == 130
        output = proc.output.read_text()
    finally:
        observer.close()
    assert "recorder: killed by SIGKILL (frozen: no sign of life for" in output, output
    assert read_recording(tmp_path / "rec_1.mcap").complete


def test_a_real_time_run_with_force_replaces_the_recording(tmp_path):
    """`iotad run -o FILE --force` over an earlier recording: the recorder it starts replaces it
    too (what `make demo` does on its second run)."""
    port = free_port()
    system_file = pair_system(tmp_path, port)
    recording = tmp_path / "rec.mcap"
    recording.write_bytes(b"an earlier run")
    with launcher(system_file, "-o", str(recording), "--force", "--until", "2", "--after-live") as proc:
        assert proc.wait(60) == 0, proc.output.read_text()
    replaced = read_recording(recording)
    assert replaced.complete
    assert any(m.topic.startswith("iota/pair/src/") for m in replaced.messages)


@pytest.mark.parametrize("where", ["under-a-file", "a-folder"])
def test_unwritable_recording_path_is_an_error_before_any_node_starts(tmp_path, where):
    (tmp_path / "plain").write_text("a file, not a folder")
    target = tmp_path / "plain" / "rec.mcap" if where == "under-a-file" else tmp_path
    result = subprocess.run([sys.executable, "-m", "iotad", "run", str(pair_system(tmp_path, free_port())),
                             "-o", str(target), "--plain", "--log-dir", str(tmp_path / "logs")],
                            cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert result.returncode == 2, result.stdout + result.stderr
    # said by the launcher's check, or earlier by the command line's own check of -o
    assert str(target) in result.stderr and ("cannot record to" in result.stderr or "is a directory" in result.stderr)
    if where == "under-a-file":
        assert f"{tmp_path / 'plain'} is not a directory" in result.stderr, result.stderr
    assert len(result.stderr.strip().splitlines()) == 1, result.stderr
    assert "Traceback" not in result.stderr and "started" not in result.stdout


def test_full_disk_is_an_error_before_any_node_starts(tmp_path):
    """A 1 MiB file system of our own (a tmpfs in a private mount namespace this test creates)."""
    disk = tmp_path / "disk"
    disk.mkdir()
    system_file = pair_system(tmp_path, free_port())
    script = (f"mount -t tmpfs -o size=1m iotad-test {disk} || exit 77; "
              f"exec {sys.executable} -m iotad run {system_file} -o {disk}/rec.mcap --plain "
              f"--log-dir {tmp_path / 'logs'}")
    try:
        result = subprocess.run(["unshare", "-m", "sh", "-c", script], cwd=ROOT, capture_output=True,
                                text=True, timeout=60)
    except FileNotFoundError:
        pytest.skip("no unshare here")
    if result.returncode == 77 or "unshare:" in result.stderr:
        pytest.skip(f"cannot mount a private tmpfs here: {result.stderr.strip()}")
    assert result.returncode == 2, result.stdout + result.stderr
    assert "MiB free on its file system" in result.stderr and "--no-record" in result.stderr, result.stderr
    assert "started" not in result.stdout


FILL_DURING_RUN = """
mount -t tmpfs -o size=20m iotad-test {disk} || exit 77
{python} -m iotad run {system} -o {disk}/rec.mcap --plain --until 6 --log-dir {logs} > {out} 2>&1 &
launcher=$!
i=0
while ! grep -q "recording to" {out} && [ $i -lt 400 ]; do sleep 0.05; i=$((i+1)); done
dd if=/dev/zero of={disk}/fill bs=1M count=40 2>/dev/null
wait $launcher
status=$?
cp {disk}/rec.mcap {cut}
exit $status
"""


def test_disk_filling_up_mid_run_stops_the_recording_loudly(tmp_path):
    """The recording's file system fills up while the system runs: the recorder exits with the
    reason, the launcher names the cut file, cannot start another (no space), says RECORDING
    STOPPED, keeps the nodes running to the end, and exits 1. The cut file is recoverable."""
    disk, out, cut = tmp_path / "disk", tmp_path / "launcher.out", tmp_path / "cut.mcap"
    disk.mkdir()
    script = FILL_DURING_RUN.format(disk=disk, python=sys.executable, system=pair_system(tmp_path, free_port()),
                                    logs=tmp_path / "logs", out=out, cut=cut)
    try:
        result = subprocess.run(["unshare", "-m", "sh", "-c", script], cwd=ROOT, capture_output=True,
                                text=True, timeout=90)
    except FileNotFoundError:
        pytest.skip("no unshare here")
    if result.returncode == 77 or "unshare:" in result.stderr:
        pytest.skip(f"cannot mount a private tmpfs here: {result.stderr.strip()}")
    output = out.read_text()
    assert result.returncode == 1, output + result.stderr
    assert "No space left on device" in output and f"'iotad recover {disk}/rec.mcap' makes it whole" in output, output
    assert "RECORDING STOPPED: cannot record to" in output and "MiB free" in output, output
    assert "--until 6 s reached" in output and output.count("stopped (exit 0)") == 2, output
    assert "RECORDING INCOMPLETE" in output
    assert main(["recover", str(cut), "-o", str(tmp_path / "recovered.mcap")]) == 0
    assert read_recording(tmp_path / "recovered.mcap").complete


# ---------------------------------------------------------------------------- stopping

def test_node_ignoring_sigint_and_sigterm_is_killed_after_the_timeouts(tmp_path):
    path = write_system(tmp_path, "stubborn", f"""
[[node]]
name = "n"
python = "{IOTAS}:Rogue"
params = {{ ignore_signals = true, exit_after = 60 }}
""")
    run, lines = in_process(tmp_path, path, node_argv=stub_argv(), stop_timeouts=(0.3, 0.3))
    log = tmp_path / "logs" / "n.log"
    threading.Thread(target=lambda: wait_until(lambda: log.exists() and "ready" in log.read_text(), 30)
                     and run.request_stop("test: stop it"), daemon=True).start()
    assert run.run() == 0, texts(lines)
    stopping = next(when for when, text in lines if "stopping every node" in text)
    killed = [(when, text) for when, text in lines if text.startswith("n: stopped (killed by SIGKILL)")]
    assert killed, texts(lines)
    assert "ignored SIGINT (0.3 s) and SIGTERM (0.3 s), so it was killed with SIGKILL" in killed[0][1]
    assert killed[0][0] - stopping >= 0.6
    assert gone(run.runs["n"].child.pid)


LOADS_ONLY_IN_THE_LAUNCHER = '''
import sys
if sys.argv[0].endswith("/iotad/node_host/__main__.py"):  # the node host (python -m iotad.node_host): fails at import
    raise ImportError("no CAN driver in this process")
from iotad import Int, Iota, Output

class Ticker(Iota):
    out = Output(Int, switching=0.2)

    @out.action(value=lambda self: 1, after=0.2)
    def sent(self):
        pass
'''


def test_check_of_a_run_where_a_node_never_ran_is_no_pass(tmp_path, capsys):
    """The node loads where the launcher checks the file, and fails in its own process at every
    start: the recording holds nothing of it. `iotad check` must not pass such a run."""
    (tmp_path / "ticker.py").write_text(LOADS_ONLY_IN_THE_LAUNCHER)
    path = write_system(tmp_path, "never", f"""
[[node]]
name = "tick"
python = "ticker.py:Ticker"
max_restarts = 1
backoff = 0.1
[[node]]
name = "good"
python = "{IOTAS}:FreeSink"
[[bind]]
from = "tick.out"
to = "good.inp"
""")
    out = tmp_path / "never.mcap"
    assert main(["run", str(path), "--until", "3", "--plain", "-o", str(out)]) == 1
    capsys.readouterr()
    assert main(["check", str(out)]) == 1
    report = capsys.readouterr().out
    assert "tick: NOT CHECKED: a node of the recorded system file that never ran" in report, report
    assert "PROBLEMS FOUND (1 node(s) not checked)" in report


def test_a_reader_that_leaves_does_not_stop_the_run(tmp_path):
    """`iotad run ... | head -2`: the pipe breaks after two lines. The system runs on for its
    --until and is recorded; only the lines stop (rich would have ended the program)."""
    out = tmp_path / "piped.mcap"
    run = subprocess.Popen([sys.executable, "-m", "iotad", "run", str(ROOT / "examples" / "figure2.toml"),
                            "--until", "3", "--after-live", "--port", str(free_port()), "--plain", "-o", str(out)],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path)
    try:
        first = run.stdout.readline()
        run.stdout.close()  # the reader leaves
        code = run.wait(timeout=60)
        err = run.stderr.read().decode()
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
        run.stderr.close()
    assert first and code == 0, err
    recording = read_recording(str(out))
    assert recording.complete and [e for e in recording.trace("scheduler") if e["kind"] == "output"]
