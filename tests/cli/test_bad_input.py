"""Bad input to every `iotad` command is one line on stderr (`iotad: error: ...`), exit status 2,
never a Python traceback and never a hang. Each row: argv (with placeholders for files made by
the fixture) and a fragment the error line must contain."""
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from iotad.cli import main
from iotad.kernel.compose import Composite
from iotad.recording.engine_sink import EngineRecorder, record_run
from iotad.recording.mcap_sink import McapSink
from requesters import Requester
from scheduler import Scheduler

ROOT = Path(__file__).resolve().parents[2]
SPEC = "nodes/scheduler/scheduler.iota"
SYSTEM = "examples/figure2.toml"
DEAD = "tcp/127.0.0.1:9"  # discard port: nothing listens there
FAST = ["--connect", DEAD, "--connect-timeout", "0.3"]


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """Bad files of every kind, and one good in-process recording."""
    d = tmp_path_factory.mktemp("bad")
    (d / "empty.mcap").write_bytes(b"")
    (d / "empty.iota").write_text("")
    (d / "types.iota").write_text("// only types\nstruct s { int x; };\n")
    (d / "empty.toml").write_text("")
    (d / "nospec.toml").write_text("[system]\nname = 'x'\n[[node]]\nname = 'a'\n[[node]]\nname = 'b'\n")
    (d / "garbage.bin").write_bytes(bytes(range(256)) * 8)
    (d / "text.mcap").write_text("hello, not a recording\n")
    (d / "bad.toml").write_text("[system\nname = 'x'\n")
    (d / "bad.iota").write_text("iota x(\n")
    (d / "bad.jsonl").write_text('{"t": \n')
    (d / "back.jsonl").write_text('{"t": 2, "action": "req"}\n{"t": 1, "action": "req"}\n')
    (d / "deep.jsonl").write_text("[" * 100_000 + "]" * 100_000 + "\n")
    (d / "bom.toml").write_bytes(b"\xef\xbb\xbf[system]\nname = 'x'\n")
    (d / "folder").mkdir()
    # Python turns no more than 4300 digits into an int: each reader says what that means here
    huge = "9" * 5000
    (d / "huge.iota").write_text(f"iota a: go()/0 -> {{ states int x = 0; actions go() do x = {huge}; }}\n")
    (d / "huge.jsonl").write_text(f'{{"t": 0, "action": "req", "value": {huge}}}\n')
    (d / "huge.toml").write_text(f"[system]\nname = 'x'\nstart_timeout = {huge}\n")
    (d / "deep.toml").write_text("[system]\nname = 'x'\n[[node]]\nname = 'a'\nparams = { n = "
                                 + "[" * 600 + "]" * 600 + " }\n")
    (d / "nofolder.toml").write_text("[system]\nname = 'x'\n[[node]]\nname = 'a'\nspec = 'nope.iota'\n")
    good = d / "good.mcap"
    record_run(Composite(
        "figure2", Scheduler("scheduler", N=2, T=0.5),
        Requester("vision", priority=1, epoch=3.0, timeout=4.0, start=0.0, pause=0.5, setpoint=0.2),
        Requester("manipulation", priority=5, epoch=2.0, timeout=3.0, start=1.0, pause=4.0, setpoint=1.5),
        bind=[("vision.req", "scheduler.req[0]"), ("manipulation.req", "scheduler.req[1]"),
              ("scheduler.ack[0]", "vision.ack"), ("scheduler.ack[1]", "manipulation.ack")]), good, until=10)
    # specs and not one message: what `iotad recover` makes of a virtual run killed before it
    # wrote its first chunk
    sink = McapSink(d / "nomessages.mcap")
    EngineRecorder(sink, Scheduler("scheduler", N=2, T=0.5))
    sink.finish()
    return d


CASES = [
    # the command line itself
    (["nosuch"], "invalid choice: 'nosuch'"),
    (["spec", "nosuch"], "invalid choice"),
    (["run"], "required: SYSTEM.toml"),
    # iotad spec
    (["spec", "check", "missing.iota"], "cannot read missing.iota: no such file"),
    (["spec", "check", "{d}/folder"], "is a directory"),
    (["spec", "check", "{d}/empty.iota"], "the file is empty"),
    (["spec", "check", "{d}/types.iota"], "the file declares no iota (only comments, types or constants)"),
    (["spec", "check", "{d}/garbage.bin"], "not UTF-8 text"),
    (["spec", "check", "{d}/bad.iota"], "1 error(s)"),
    (["spec", "check", "examples/scheduler.py"], "is Python"),
    (["spec", "show", "{d}/empty.iota"], "declares no iota"),
    (["spec", "show", SPEC, "--iota", "nosuch"], "no iota nosuch"),
    (["spec", "run", SPEC], "required: --until"),
    (["spec", "run", SPEC, "--until", "-1"], "--until: expected a number >= 0, got '-1'"),
    (["spec", "run", SPEC, "--until", "nan"], "--until: expected a number >= 0"),
    # a parameter off by powers of ten: refused at once, not minutes of building (nor a hang)
    (["spec", "run", SPEC, "--until", "1", "--param", "N=2", "--param", "N=3"], "--param N is given twice"),
    (["spec", "run", SPEC, "--until", "1", "--param", "N=20000"], "size of req is 20000; a channel family has at most 10000"),
    (["spec", "run", SPEC, "--until", "1", "--param", "N=100000000"], "array length 100000000 is past the limit of 1000000"),
    (["spec", "run", SPEC, "--until", "abc"], "--until: expected a number >= 0, got 'abc'"),
    (["spec", "run", SPEC, "--until", "1", "--seed", "abc"], "--seed: expected a whole number from 0 to 18446744073709551615"),
    (["spec", "run", SPEC, "--until", "1", "--seed", "-1"], "--seed: expected a whole number from 0 to"),
    (["run", SYSTEM, "--virtual", "--until", "1", "--seed", "99999999999999999999999"],
     "--seed: expected a whole number from 0 to 18446744073709551615, got '99999999999999999999999'"),
    # a device named as a file would be read for ever
    (["spec", "check", "/dev/zero"], "cannot read /dev/zero: not a regular file (a device, a FIFO or a socket)"),
    (["run", "--check", "/dev/zero"], "/dev/zero: cannot read: not a regular file"),
    (["run", SYSTEM, "--virtual", "--until", "1", "--no-record", "--inputs", "/dev/zero"],
     "--inputs /dev/zero: cannot read: not a regular file"),
    (["spec", "run", SPEC, "--until", "1", "--inputs", "/dev/zero"], "cannot read input script /dev/zero: not a regular"),
    (["run", SYSTEM, "--virtual", "--until", "1", "--no-record", "-o", "{d}/x.mcap"],
     "--no-record says there is none: give one of them"),
    (["replay", "{d}/good.mcap", "--live", "--rate", "1e-300"], "--rate 1e-300: give a speed factor from 1e-06 to 1e+06"),
    (["replay", "{d}/good.mcap", "--node", "scheduler", "--rate", "2"], "--rate, --start and --loop are the pace of --live"),
    (["spec", "run", SPEC, "--until", "1", "--policy", "lazy"], "invalid choice: 'lazy'"),
    (["spec", "run", SPEC, "--until", "1", "--param", "X=1"], "has no parameter X (it has N, T)"),
    (["spec", "run", SPEC, "--until", "1", "--param", "N=abc"], "parameter N: expected int"),
    (["spec", "run", SPEC, "--until", "1", "--param", "N"], "expected NAME=VALUE"),
    (["spec", "run", SPEC, "--until", "1", "--inputs", "missing.jsonl"], "cannot read input script missing.jsonl"),
    (["spec", "run", SPEC, "--until", "1", "--inputs", "{d}/bad.jsonl"], "bad.jsonl:1: not JSON"),
    (["spec", "run", SPEC, "--until", "1", "--inputs", "{d}/back.jsonl"], "must not go backwards"),
    (["spec", "run", SPEC, "--until", "1", "--inputs", "{d}/garbage.bin"], "not UTF-8 text"),
    (["spec", "run", SPEC, "--until", "1", "--inputs", "{d}/deep.jsonl"], "deep.jsonl:1: nested too deeply"),
    (["run", SYSTEM, "--virtual", "--until", "1", "--no-record", "--inputs", "{d}/deep.jsonl"],
     "--inputs {d}/deep.jsonl:1: nested too deeply"),
    (["run", SYSTEM, "--virtual", "--until", "1", "--no-record", "--inputs", "{d}/bad.jsonl"],
     "--inputs {d}/bad.jsonl:1: not JSON"),
    (["run", SYSTEM, "--virtual", "--until", "1", "--no-record", "--inputs", "{d}/garbage.bin"], "not UTF-8 text"),
    (["spec", "run", "{d}/bad.iota", "--until", "1"], "bad.iota:1:"),
    (["spec", "run", SYSTEM, "--until", "1"], "not an ESPRIT spec"),
    # iotad run (only checks: nothing starts)
    (["run", "--check", "missing.toml"], "missing.toml: cannot read"),
    (["run", "--check", "{d}/folder"], "Is a directory"),
    (["run", "--check", "{d}/empty.toml"], "the system has no nodes"),
    (["run", "--check", "{d}/garbage.bin"], "not UTF-8 text"),
    (["run", "--check", "{d}/bad.toml"], "not valid TOML"),
    (["run", "--check", SPEC], "not valid TOML"),
    (["run", "--check", "{d}/nofolder.toml"], "nope.iota"),
    (["run", SYSTEM, "--until", "-1"], "--until: expected a number > 0"),
    (["run", SYSTEM, "--until", "nan"], "--until: expected a number > 0"),
    (["run", SYSTEM, "--port", "70000"], "--port: expected a port number 0-65535"),
    (["run", SYSTEM, "--view", "99999"], "--view: expected a port number 0-65535"),  # before anything starts
    (["view", "--port", "99999"], "--port: expected a port number 0-65535"),
    (["run", SYSTEM, "--host", "nosuch"], "no node has host = 'nosuch'"),
    (["run", SYSTEM, "-o", "{d}/folder"], "is a directory"),
    (["run", SYSTEM, "--log-dir", "{d}/empty.toml/logs"], "--log-dir"),
    (["demo", "--until", "0"], "--until: expected a number > 0"),
    (["demo", "--virtual", "--until", "abc"], "--until: expected a number > 0"),
    # recordings: info, check, replay, plot, export, recover
    *[([command, path, *extra], message)
      for command, extra in (("info", []), ("check", []), ("replay", ["--node", "scheduler"]),
                             ("plot", ["-o", "{d}/out.png"]), ("export", ["-o", "{d}/out.mcap", "--json"]),
                             ("recover", ["-o", "{d}/out.mcap"]))
      for path, message in (("missing.mcap", "missing.mcap: no such file"),
                            ("{d}/folder", "is a directory"),
                            ("{d}/empty.mcap", "empty file"),
                            ("{d}/garbage.bin", "not an MCAP recording"),
                            ("{d}/text.mcap", "not an MCAP recording"))],
    (["info", "{d}/good.mcap", "--violations", "-1"], "--violations: expected a whole number >= 0"),
    (["check", "{d}/good.mcap", "--node", "nosuch"], "no spec of node 'nosuch'"),
    (["check", "{d}/good.mcap", "--tolerance", "-1"], "--tolerance: expected a number >= 0"),
    (["check", "{d}/good.mcap", "--budget", "0"], "--budget: expected a whole number > 0"),
    (["check", "{d}/good.mcap", "--param", "N=1"], "--iota and --param apply to --spec"),
    (["check", "{d}/good.mcap", "--spec", SPEC], "--spec needs --node"),
    (["check", "{d}/good.mcap", "--node", "scheduler", "--spec", "missing.iota"], "no such file"),
    (["check", "{d}/good.mcap", "--node", "scheduler", "--spec", "{d}/bad.iota"], "bad.iota:1:"),
    (["check", "{d}/good.mcap", "--node", "scheduler", "--spec", SPEC, "--param", "X=1"], "no parameter X"),
    (["check", "{d}/good.mcap", "--node", "scheduler", "--spec", SYSTEM], "expected an ESPRIT file"),
    (["check", "{d}/good.mcap", "--node", "scheduler", "--spec", "examples/scheduler.py:Nope"], "has no Nope"),
    (["replay", "{d}/good.mcap"], "one of the arguments --node --live is required"),
    (["replay", "{d}/good.mcap", "--node", "nosuch"], "node 'nosuch' is not in"),
    (["replay", "{d}/good.mcap", "--node", "scheduler", "--tolerance", "-1"], "--tolerance: expected a number >= 0"),
    (["replay", "{d}/good.mcap", "--live", "--rate", "0"], "--rate: expected a number > 0"),
    (["replay", "{d}/good.mcap", "--live", "--start", "1000"], "--start 1000: past the end of the recording"),
    (["replay", "{d}/good.mcap", "--live", "--start", "-3"], "--start: expected a number >= 0"),
    (["replay", "{d}/good.mcap", "--live", "--connect", "garbage"], "expected a zenoh endpoint"),
    (["replay", "{d}/good.mcap", "--live", "--connect", DEAD], "cannot open a zenoh session"),
    (["plot", "{d}/good.mcap", "-o", "{d}/out.txt"], "the image format follows the extension"),
    (["plot", "{d}/good.mcap", "-o", "{d}/empty.toml/out.png"], "is not a directory"),
    (["plot", "{d}/good.mcap", "-o", "{d}/out.png", "--node", "nosuch"], "no node 'nosuch'"),
    (["run", SYSTEM, "--virtual", "--until", "1e400"], "expected a number > 0, got '1e400' (infinite)"),
    (["run", "--check", "{d}/bom.toml"], "the file starts with a byte-order mark, which TOML does not allow"),
    (["plot", "{d}/good.mcap", "-o", "{d}/out.png", "--node", "vision"],
     "vision never fired 'schedule': it is no motion scheduler (here: scheduler)"),
    (["export", "{d}/good.mcap", "-o", "{d}/folder", "--json"], "is a directory"),
    (["export", "{d}/good.mcap", "-o", "{d}/good.mcap", "--json"], "another file than the recording"),
    (["export", "{d}/good.mcap", "-o", "{d}/x.mcap"], "one of the arguments --json --ros2 is required"),
    (["recover", "{d}/good.mcap", "-o", "{d}/empty.toml/x.mcap"], "is not a directory"),
    # iotad record (fails before subscribing)
    (["record", "-o", "{d}/r.mcap"], "nothing to record"),
    (["record", "iota/x/**", "-o", "{d}/folder"], "is a directory"),
    (["record", "iota/x/**", "-o", "{d}/empty.toml/r.mcap"], "empty.toml is not a directory"),
    (["record", "bad//key", "-o", "{d}/r.mcap"], "not a key expression"),
    (["record", "iota/x/**", "-o", "{d}/r.mcap", "--duration", "-1"], "--duration: expected a number > 0"),
    (["record", "iota/x/**", "-o", "{d}/r.mcap", "--duration", "nan"], "--duration: expected a number > 0"),
    (["record", "iota/x/**", "-o", "{d}/r.mcap", "--flush-period", "0"], "--flush-period: expected a number > 0"),
    (["record", "iota/x/**", "-o", "{d}/r.mcap", "--connect", "garbage"], "expected a zenoh endpoint"),
    (["record", "iota/x/**", "-o", "{d}/r.mcap", "--listen", "tcp/127.0.0.1:99999"], "port out of range"),
    (["record", "-o", "{d}/r.mcap", "--system-file", "missing.toml"], "--system-file missing.toml: no such file"),
    (["record", "-o", "{d}/r.mcap", "--system-file", "{d}/bad.toml"], "not valid TOML"),
    (["record", "-o", "{d}/r.mcap", "--system-file", "{d}/empty.toml"], "the system has no nodes"),
    (["record", "-o", "{d}/r.mcap", "--system-file", "{d}/nospec.toml"],
     "give exactly one of spec = \"file.iota\" or python = \"file.py:Class\" (and 1 more: 'iotad run --check"),
    (["record", "-o", "{d}/r.mcap", "--system-file", "{d}/garbage.bin"], "not UTF-8 text"),
    # live tools: bad options, and nothing running at the peer
    (["ls", *FAST], "no zenoh peer at tcp/127.0.0.1:9"),
    (["ls", "--connect", "garbage"], "expected a zenoh endpoint"),
    (["ls", "--timeout", "0"], "--timeout: expected a number > 0"),
    (["export", "{d}/good.mcap", "-o", "{d}/x.mcap"], "iotad: error: export: one of the arguments --json --ros2 is required (see 'iotad export --help')"),
    (["echo", "iota/**", *FAST], "is a system running?"),
    (["echo", "bad//key"], "not a key expression"),
    (["echo", "iota/**", "--count", "-1"], "--count: expected a whole number > 0"),
    (["echo", "iota/**", "--timeout", "-1"], "--timeout: expected a number > 0"),
    (["pub", "iota/x/y", "{bad"], "value is not JSON"),
    (["pub", "iota/x/y", "1", "--rate", "0"], "--rate: expected a number > 0"),
    (["pub", "iota/x/y", "1", "--count", "-1"], "--count: expected a whole number >= 0"),
    (["pub", "iota/x/y", "{\"n\": 99999999999999999999999}"], "value cannot be sent: Integer value out of range"),
    (["pub", "iota/x/*", "1"], "no wildcards"),
    (["check", "{d}/nomessages.mcap"], "holds no events at all, only 1 spec(s): nothing to check"),
    (["pub", "iota/x/y", "9" * 5000], "value holds an integer of thousands of digits, past 64 bits"),
    (["spec", "check", "{d}/huge.iota"], "huge.iota:1:59: an integer literal of 5000 digits: past 64 bits"),
    (["spec", "run", SPEC, "--inputs", "{d}/huge.jsonl", "--until", "1"],
     "huge.jsonl:1: an integer of thousands of digits, past 64 bits"),
    (["spec", "run", SPEC, "--until", "1", "--param", "N=" + "9" * 5000], "an integer past 64 bits"),
    (["run", "--check", "{d}/huge.toml"], "huge.toml: an integer of thousands of digits, past 64 bits"),
    (["run", "--check", "{d}/deep.toml"], "deep.toml: a value is nested too deeply to read"),
    (["pub", "iota/x/y", "@{d}/missing.json"], "@{d}/missing.json: no such file"),
    (["pub", "iota/x/y", "@{d}"], "is a directory, not a JSON file"),
    (["pub", "iota/x/y", "@{d}/garbage.bin"], "garbage.bin: not UTF-8 text"),
    (["pub", "iota/x/y", "@{d}/bad.jsonl"], "{d}/bad.jsonl is not JSON: Expecting value (line 2, column 1)"),
    (["pub", "iota/x/y", "@{d}/deep.jsonl"], "deep.jsonl is nested too deeply"),
    (["pub", "iota/x/y", "[" * 100_000], "value is nested too deeply"),
    (["pub", "iota/x/y", "1", *FAST], "no zenoh peer"),
    (["hz", "iota/**", "--window", "1"], "--window must be at least 2"),
    (["hz", "iota/**", "--every", "0"], "--every: expected a number > 0"),
    (["hz", "iota/**", *FAST], "no zenoh peer"),
]


def _ids():
    return [" ".join(argv)[:60] for argv, _ in CASES]


@pytest.mark.parametrize("argv, message", CASES, ids=_ids())
def test_bad_input_is_one_line_exit_2(argv, message, files, capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    argv = [a.replace("{d}", str(files)) for a in argv]
    code = main(argv)
    captured = capsys.readouterr()
    err = captured.err
    assert code == 2, (code, err)
    assert "Traceback" not in err + captured.out
    lines = err.strip().splitlines()
    # one error line; a spec error may add its source line and a caret (and `spec check` lists
    # its diagnostics first, compiler style, then the error line)
    assert any(line.startswith("iotad: error:") for line in lines) and len(lines) <= 5, err
    if argv[:2] != ["spec", "check"]:
        assert lines[0].startswith("iotad: error:"), err
    assert message.replace("{d}", str(files)) in err, err


def test_good_input_still_works(files, capsys, monkeypatch):
    """The twin of the table: the same commands on the good recording and spec succeed."""
    monkeypatch.chdir(ROOT)
    good = str(files / "good.mcap")
    assert main(["info", good]) == 0
    assert main(["check", good]) == 0
    assert main(["replay", good, "--node", "scheduler"]) == 0
    assert main(["spec", "check", SPEC]) == 0
    assert main(["run", "--check", SYSTEM]) == 0
    assert "Traceback" not in capsys.readouterr().err


def test_unexpected_errors_are_one_line_too(monkeypatch, capsys):
    """A bug in a command still prints one line (and the traceback with IOTAD_DEBUG=1)."""
    from iotad.cli.commands import info

    def broken(args):
        raise RuntimeError("something inside broke\nsecond line")

    monkeypatch.setattr(info, "run", broken)
    monkeypatch.delenv("IOTAD_DEBUG", raising=False)
    assert main(["info", "x.mcap"]) == 1
    err = capsys.readouterr().err
    assert err.strip() == ("iotad: error: unexpected RuntimeError: something inside broke "
                           "(IOTAD_DEBUG=1 shows the traceback; please report it)")


def _iotad(*argv, **kw):
    return subprocess.Popen([sys.executable, "-m", "iotad", *argv], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, **kw)


# a tool started with SIGINT ignored, as a background job of a non-interactive shell is: exec keeps
# the ignoring, and Python then installs no KeyboardInterrupt of its own
IGNORING = ("import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_IGN); "
            "os.execv(sys.executable, [sys.executable, '-m', 'iotad', *sys.argv[1:]])")


@pytest.mark.parametrize("started", ["plainly", "with SIGINT ignored"])
def test_ctrl_c_exits_130_without_traceback(started):
    """Ctrl-C (SIGINT) in a command that waits: exit 130, no traceback, no hang; also when the
    command was started with SIGINT ignored (it then waited for ever)."""
    hub = subprocess.Popen([sys.executable, "-c", "import sys, time\nfrom iotad.node_host.transport import open_session\n"
                            f"s = open_session(['tcp/127.0.0.1:{_port()}'])\nprint('up', flush=True)\n"
                            "sys.stdin.read()\ns.close()"],
                           cwd=ROOT, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    tools = []
    try:
        assert hub.stdout.readline().strip() == "up"
        endpoint = f"tcp/127.0.0.1:{_PORT[0]}"
        if started == "plainly":
            tools = [_iotad("echo", "iota/**", "--connect", endpoint),
                     _iotad("hz", "iota/**", "--connect", endpoint)]
        else:
            tools = [subprocess.Popen([sys.executable, "-c", IGNORING, tool, "iota/**", "--connect", endpoint],
                                      cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                     for tool in ("echo", "hz")]
        time.sleep(3)
        for tool in tools:
            tool.send_signal(signal.SIGINT)
        for tool in tools:
            out, err = tool.communicate(timeout=15)
            assert tool.returncode == 130, err
            assert "Traceback" not in err
    finally:
        for tool in tools:  # one that did not stop (a shell that ignores SIGINT passes that on) is killed
            if tool.poll() is None:
                tool.kill()
                tool.wait(10)
        hub.stdin.close()
        hub.wait(10)


_PORT = []


def _port():
    from iotad.node_host.transport import free_port
    _PORT[:] = [free_port()]
    return _PORT[0]


def test_record_status_and_clean_stop(tmp_path):
    """`iotad record` says what it records and, at the end, what it wrote (stderr); SIGINT: exit 0."""
    out = tmp_path / "r.mcap"
    recorder = _iotad("record", "iota/nobody/**", "-o", str(out), "--duration", "0.5")
    stdout, stderr = recorder.communicate(timeout=30)
    assert recorder.returncode == 0, stderr
    assert f"-> {out}" in stderr and f"recorded 0 messages to {out}" in stderr
    assert out.exists() and stdout == ""
    assert os.path.getsize(out) > 0


def test_run_view_on_a_taken_port_is_refused_before_anything_starts(tmp_path, capsys, monkeypatch):
    import socket

    monkeypatch.chdir(tmp_path)
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["run", str(ROOT / "examples" / "figure2.toml"), "--until", "1", "--view", str(port),
                     "--plain"]) == 2
    captured = capsys.readouterr()
    assert f"iotad: error: --view {port}: cannot serve there: Address already in use" in captured.err
    assert "started" not in captured.out and not (tmp_path / "recordings").exists()
