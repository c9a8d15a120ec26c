"""Figure 2 from scheduler.iota, run by `iotad spec run`, gives the trace of the Python-API
scheduler (examples/scheduler.py) for the same inputs, in each of the paper's scenarios."""
import json
import subprocess
import sys
from pathlib import Path

import pytest

from iotad.kernel import trace_jsonl as trace
from iotad import cli
from iotad.esprit import load_file, load_iota
from iotad.kernel.policy import make_policy
from iotad.kernel.input_script import parse_script, run_script

ROOT = Path(__file__).resolve().parents[2]
SPEC = ROOT / "nodes" / "scheduler" / "scheduler.iota"


def req(t, index, priority, epoch=2.0, timeout=5.0, w=0.5):
    return {"t": t, "action": "req", "index": index,
            "value": {"control": {"w": w, "k": 1.0}, "epoch": epoch, "timeout": timeout, "priority": priority}}


SCENARIOS = {
    "commit_after_epoch": [req(0.0, 0, 1, epoch=2.0)],
    "preempt_abort": [req(0.0, 0, 1, epoch=5.0), req(1.0, 1, 5, epoch=1.0)],
    "timeout_reject": [req(0.0, 0, 5, epoch=5.0), req(0.5, 1, 1, timeout=1.0)],
    "lower_waits_then_runs": [req(0.0, 0, 5, epoch=2.0), req(0.5, 1, 1, epoch=1.0, timeout=10.0)],
    "input_sooner_than_switching": [req(0.0, 0, 1), req(0.5, 0, 1)],
    # req[1] takes the motors at 0.4 but its mode waits for mdl_command's switching time (until
    # 1.0), and it times out at 0.7: the motors are free again for the priority-4 request at 8
    "rejected_master_frees_the_motors": [req(0.0, 0, 1, epoch=4.0), req(0.4, 1, 5, timeout=0.3),
                                         req(8.0, 0, 4, epoch=1.0, timeout=1.0)],
}


def spec_run(tmp_path, capsys, inputs, until=20.0, extra=()):
    script = tmp_path / "inputs.jsonl"
    script.write_text("".join(json.dumps(entry) + "\n" for entry in inputs))
    code = cli.main(["spec", "run", str(SPEC), "--inputs", str(script), "--until", str(until), *extra])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    return [json.loads(line) for line in captured.out.splitlines()]


def python_run(inputs, until=20.0, policy="eager", seed=0, **params):
    from scheduler import Scheduler  # examples/ is on sys.path (tests/conftest.py)
    entries = parse_script([json.dumps(e) for e in inputs])
    engine = run_script(Scheduler("scheduler", **params), entries, until, make_policy(policy, seed))
    return [json.loads(trace.dumps(e)) for e in engine.trace]


def events(trace_, action, kind=None):
    return [(e["t"], e["index"], e["value"]) for e in trace_
            if e["action"] == action and (kind is None or e["kind"] == kind)]


@pytest.mark.parametrize("name", sorted(SCENARIOS))
def test_same_trace_as_python_scheduler(name, tmp_path, capsys):
    inputs = SCENARIOS[name]
    assert spec_run(tmp_path, capsys, inputs) == python_run(inputs)


def test_commit_after_epoch(tmp_path, capsys):
    got = spec_run(tmp_path, capsys, SCENARIOS["commit_after_epoch"])
    assert events(got, "mdl_command") == [(0.0, None, {"w": 0.5, "k": 1.0})]
    assert events(got, "commit") == [(2.0, 0, None)]
    assert events(got, "ack") == [(2.0, 0, "COMMIT")]


def test_higher_priority_preempts_the_signalling_one(tmp_path, capsys):
    got = spec_run(tmp_path, capsys, SCENARIOS["preempt_abort"])
    assert events(got, "ack") == [(1.0, 0, "ABORT"), (2.0, 1, "COMMIT")]


def test_request_times_out(tmp_path, capsys):
    got = spec_run(tmp_path, capsys, SCENARIOS["timeout_reject"])
    assert events(got, "reject") == [(1.5, 1, None)]
    assert (1.5, 1, "REJECT") in events(got, "ack")


def test_lower_priority_waits_and_runs_after_commit(tmp_path, capsys):
    got = spec_run(tmp_path, capsys, SCENARIOS["lower_waits_then_runs"])
    assert events(got, "schedule") == [(0.0, 0, None), (2.0, 1, None)]
    assert events(got, "ack") == [(2.0, 0, "COMMIT"), (3.0, 1, "COMMIT")]


def test_a_master_rejected_before_its_mode_went_out_frees_the_motors(tmp_path, capsys):
    # Figure 2 as printed kept current_master on the rejected request: the request at 8 was
    # rejected too, and so was every later one of priority 5 or less
    got = spec_run(tmp_path, capsys, SCENARIOS["rejected_master_frees_the_motors"])
    assert events(got, "ack") == [(0.4, 0, "ABORT"), (0.7, 1, "REJECT"), (9.0, 0, "COMMIT")]
    assert events(got, "mdl_command") == [(0.0, None, {"w": 0.5, "k": 1.0}), (8.0, None, {"w": 0.5, "k": 1.0})]


def test_input_sooner_than_switching_time_is_a_violation(tmp_path, capsys):
    got = spec_run(tmp_path, capsys, SCENARIOS["input_sooner_than_switching"])
    violations = [e for e in got if e["kind"] == "violation"]
    assert [(v["t"], v["action"], v["value"]["violation"]) for v in violations] == [(0.5, "req", "switching_time")]
    assert len(events(got, "req", "input")) == 1


def test_random_policy_same_trace_as_python(tmp_path, capsys):
    inputs = SCENARIOS["preempt_abort"] + [req(6.0, 0, 3, timeout=0.5), req(6.2, 1, 1, timeout=4.0)]
    got = spec_run(tmp_path, capsys, inputs, 30.0, ["--policy", "random", "--seed", "7", "--param", "T=0.5"])
    assert got == python_run(inputs, 30.0, "random", 7, T=0.5)


def test_three_requesters_parameter_n(tmp_path, capsys):
    inputs = [req(0.0, 0, 1), req(0.2, 1, 2), req(0.4, 2, 3, epoch=1.0)]
    got = spec_run(tmp_path, capsys, inputs, extra=["--param", "N=3"])
    assert got == python_run(inputs, N=3)
    # req[1] was still STARTING (mdl_command waits out its switching time) when req[2] took over:
    # it is not ABORTed (that is for a SIGNALING master) but REJECTed after its timeout.
    assert [v for _, i, v in events(got, "ack") if i == 1] == ["REJECT"]


def test_state_matches_python_scheduler():
    from scheduler import Scheduler
    entries = parse_script([json.dumps(e) for e in SCENARIOS["preempt_abort"]])
    esprit = run_script(load_iota(str(SPEC)), entries, 1.5)
    python = run_script(Scheduler("scheduler"), entries, 1.5)
    mine, theirs = esprit.iota("scheduler"), python.iota("scheduler")
    def plain(requests):
        return [(r.status, r.command._type.to_plain(r.command)) for r in requests]
    assert plain(mine.request) == plain(theirs.request)
    assert (mine.current_master, mine.current_priority) == (theirs.current_master, theirs.current_priority)


def test_payload_types_interoperate_with_channel_messages():
    from channels.messages import ACK, MDL_REQ, MODE
    module = load_file(SPEC)
    assert module.structs["mdlReq"].json_schema() == MDL_REQ.json_schema()
    assert module.structs["mode"].json_schema() == MODE.json_schema()
    assert module.enums["ack"].json_schema() == ACK.json_schema()


def test_esprit_scheduler_serves_python_requesters():
    """The .iota scheduler binds to the Python Requester IOTAs: same types on both sides."""
    from requesters import Requester
    from scheduler import Scheduler
    from iotad.kernel.compose import Composite

    def system(scheduler):
        return Composite("figure2", scheduler,
                         Requester("vision", priority=1, epoch=3.0, timeout=4.0, pause=0.5),
                         Requester("manipulation", priority=5, epoch=2.0, timeout=3.0, start=1.0, pause=4.0),
                         bind=[("vision.req", "scheduler.req[0]"), ("manipulation.req", "scheduler.req[1]"),
                               ("scheduler.ack[0]", "vision.ack"), ("scheduler.ack[1]", "manipulation.ack")])
    esprit = run_script(system(load_iota(str(SPEC), T=0.5)), [], 30.0).trace
    python = run_script(system(Scheduler("scheduler", T=0.5)), [], 30.0).trace
    assert esprit == python
    assert any(e["action"] == "ack" and e["value"] == "ABORT" for e in esprit)


def test_spec_run_as_a_process(tmp_path):
    script = tmp_path / "in.jsonl"
    script.write_text(json.dumps(req(0.0, 0, 1)) + "\n")
    done = subprocess.run([sys.executable, "-m", "iotad", "spec", "run", str(SPEC), "--inputs", str(script),
                           "--until", "5"], capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert done.returncode == 0, done.stderr
    lines = [json.loads(line) for line in done.stdout.splitlines()]
    assert lines[-1]["action"] == "ack" and lines[-1]["value"] == "COMMIT"
    bad = subprocess.run([sys.executable, "-m", "iotad", "spec", "run", str(SPEC), "--until", "5", "--param", "N=2.5"],
                         capture_output=True, text=True, cwd=ROOT, timeout=60)
    assert bad.returncode == 2
    assert "Traceback" not in bad.stderr
    assert "scheduler.iota:" in bad.stderr and "parameter N" in bad.stderr and "^" in bad.stderr
