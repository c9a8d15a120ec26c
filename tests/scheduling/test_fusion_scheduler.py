"""nodes/scheduler/fusion.iota: overlapping requests are fused into the setpoint of least total
quadratic cost (the weighted mean per joint) for as long as their epochs overlap; acks as in
Figure 2. Exact setpoints in virtual time, random-policy conformance, and the types that let
Python requesters and motor nodes bind to it."""
import json

import pytest

from iotad.cli import main
from iotad.esprit import load_file, load_iota
from iotad.kernel.input_script import parse_script

from scheduling_helpers import EXAMPLES, FUSION, acks, assert_conforms, run, story


def scheduler(**params):
    return load_iota(str(FUSION), **params)


def fuse_req(t, index, position, weight, epoch=2.0, timeout=2.0):
    return {"t": t, "action": "req", "index": index,
            "value": {"position": position, "weight": weight, "epoch": epoch, "timeout": timeout, "priority": 1}}


def setpoints(engine):
    return [(e["t"], e["value"]["position"]) for e in engine.trace if e["action"] == "setpoint"]


def test_overlapping_requests_get_the_weighted_mean_per_joint_while_they_overlap():
    engine = run(scheduler(), [fuse_req(0.0, 0, [0.0, 1.0], [1.0, 1.0], epoch=4.0),
                               fuse_req(1.0, 1, [1.0, 0.0], [3.0, 0.0], epoch=2.0)])
    # joint 0: (1*0 + 3*1) / 4; joint 1: only request 0 weighs it
    assert setpoints(engine) == [(0.0, [0.0, 1.0]), (1.0, [0.75, 1.0]), (3.0, [0.0, 1.0])]
    assert acks(engine) == [(3.0, 1, "COMMIT"), (4.0, 0, "COMMIT")]
    assert story(engine, ("output",))[1] == (1.0, "setpoint", None, {"position": [0.75, 1.0],
                                                                      "velocity_ff": [0.0, 0.0],
                                                                      "torque_ff": [0.0, 0.0]})


def test_the_fused_setpoint_minimises_the_total_cost():
    weights = [[1.0, 2.0], [3.0, 0.5], [0.5, 4.0]]
    positions = [[0.2, -1.0], [1.4, 0.5], [-0.6, 2.0]]
    engine = run(scheduler(N=3), [fuse_req(0.0, k, positions[k], weights[k], epoch=5.0) for k in range(3)])
    [(_, fused)] = setpoints(engine)

    def cost(x):
        return sum(w[j] * (x[j] - p[j]) ** 2 for w, p in zip(weights, positions) for j in range(2))
    assert fused == pytest.approx([sum(w[j] * p[j] for w, p in zip(weights, positions)) / sum(w[j] for w in weights)
                                   for j in range(2)])
    for j in range(2):
        for step in (-1e-3, 1e-3):
            moved = list(fused)
            moved[j] += step
            assert cost(moved) > cost(fused)


def test_a_joint_nobody_weighs_keeps_its_last_setpoint():
    engine = run(scheduler(), [fuse_req(0.0, 0, [0.4, 0.6], [1.0, 1.0], epoch=1.0),
                               fuse_req(2.0, 1, [2.0, 9.0], [1.0, 0.0], epoch=1.0)])
    assert setpoints(engine) == [(0.0, [0.4, 0.6]), (2.0, [2.0, 0.6])]


def test_a_request_the_setpoint_cannot_serve_in_time_is_rejected():
    # setpoint's switching time holds the next setpoint until 1.0; request 1 may wait only 0.25
    engine = run(scheduler(), [fuse_req(0.0, 0, [0.0, 0.0], [1.0, 1.0], epoch=3.0),
                               fuse_req(0.5, 1, [1.0, 1.0], [1.0, 1.0], timeout=0.25)])
    assert story(engine) == [
        (0.0, "fuse", None, None), (0.0, "setpoint", None, {"position": [0.0, 0.0], "velocity_ff": [0.0, 0.0],
                                                            "torque_ff": [0.0, 0.0]}),
        (0.5, "fuse", None, None), (0.75, "reject", 1, None), (0.75, "fuse", None, None),
        (0.75, "ack", 1, "REJECT"),
        (1.0, "setpoint", None, {"position": [0.0, 0.0], "velocity_ff": [0.0, 0.0], "torque_ff": [0.0, 0.0]}),
        (3.0, "commit", 0, None), (3.0, "fuse", None, None), (3.0, "ack", 0, "COMMIT")]


def test_a_request_replaced_while_served_is_aborted():
    engine = run(scheduler(), [fuse_req(0.0, 0, [0.0, 0.0], [1.0, 1.0], epoch=5.0),
                               fuse_req(2.0, 0, [1.0, 2.0], [1.0, 1.0], epoch=1.0)])
    assert setpoints(engine) == [(0.0, [0.0, 0.0]), (2.0, [1.0, 2.0])]
    assert acks(engine) == [(2.0, 0, "ABORT"), (3.0, 0, "COMMIT")]



def test_back_to_back_requests_on_one_index_commit_after_their_epochs():
    engine = run(scheduler(), [fuse_req(0.0, 0, [0.0, 0.0], [1.0, 1.0], epoch=0.9),
                               fuse_req(1.0, 0, [1.0, 1.0], [1.0, 1.0], epoch=0.1)])
    assert [t for t, a, _, _ in story(engine) if a == "commit"] == [0.9, 1.1]
    assert setpoints(engine) == [(0.0, [0.0, 0.0]), (1.0, [1.0, 1.0])]
    assert acks(engine) == [(0.9, 0, "COMMIT"), (1.9, 0, "COMMIT")]  # ack's switching time 1
    assert not [e for e in engine.trace if e["kind"] == "violation"]

def test_the_example_script_with_iotad_spec_run(capsys):
    assert main(["spec", "run", str(FUSION), "--param", "T=0.5", "--inputs", str(EXAMPLES / "fusion-inputs.jsonl"),
                 "--until", "20"]) == 0
    trace = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert [(e["t"], e["value"]["position"]) for e in trace if e["action"] == "setpoint"] == [
        (0.0, [0.0, 1.0]), (1.0, [0.75, 1.0]), (3.0, [0.0, 1.0]), (5.0, [0.5, 0.5]), (6.0, [0.5, 0.5]),
        (7.0, [0.0, 0.0])]
    assert [(e["t"], e["index"], e["value"]) for e in trace if e["action"] == "ack"] == [
        (3.0, 1, "COMMIT"), (4.0, 0, "COMMIT"), (5.75, 1, "REJECT"), (7.0, 0, "ABORT"), (8.0, 0, "COMMIT")]


@pytest.mark.parametrize("seed", [1, 2])
def test_random_policy_runs_conform_to_the_spec(seed, tmp_path, capsys):
    lines = (EXAMPLES / "fusion-inputs.jsonl").read_text().splitlines()
    assert_conforms(lambda: scheduler(T=0.5), parse_script(lines), 20.0, seed, tmp_path)


def test_payload_types_bind_to_python_requesters_and_joint_messages():
    from channels.joints import joint_setpoints
    from fusion_requester import FUSE_REQ
    module = load_file(FUSION)
    assert module.structs["fuseReq"].json_schema() == FUSE_REQ.json_schema()
    assert module.structs["jointSetpoints2"].json_schema() == joint_setpoints(2).json_schema()


def test_fusion_requesters_drive_the_spec_in_one_composite():
    from fusion_requester import FusionRequester
    from iotad.kernel.compose import Composite
    system = Composite("fusion", scheduler(T=0.5),
                       FusionRequester("vision", position=[0.0, 1.0], weight=[1.0, 1.0], epoch=4.0, count=1),
                       FusionRequester("manipulation", position=[1.0, 0.0], weight=[3.0, 0.0], epoch=2.0, start=1.0,
                                       count=1),
                       bind=[("vision.req", "scheduler_fusion.req[0]"), ("manipulation.req", "scheduler_fusion.req[1]"),
                             ("scheduler_fusion.ack[0]", "vision.ack"), ("scheduler_fusion.ack[1]", "manipulation.ack")])
    engine = run(system, [], 10.0)
    assert setpoints(engine) == [(0.0, [0.0, 1.0]), (1.0, [0.75, 1.0]), (3.0, [0.0, 1.0])]
    assert engine.iota("fusion/vision").answers == ["COMMIT"]
    assert engine.iota("fusion/manipulation").answers == ["COMMIT"]


@pytest.mark.parametrize("position, weight, field", [
    ([0.3, 0.5], [float("inf"), 1.0], "fuseReq.weight: [0]: inf outside range [0, 1000000.0]"),
    ([1e308, 0.5], [1e308, 1.0], "fuseReq.position: [0]: 1e+308 outside range [-1000000.0, 1000000.0]"),
])
def test_a_request_whose_sums_could_not_be_finite_is_refused_and_never_acked(position, weight, field):
    # with any float allowed, a weight of inf made the mean NaN (the setpoint was refused, the
    # request still COMMITted) and 1e308 * 1e308 an infinite setpoint
    engine = run(scheduler(), [fuse_req(0.1, 0, position, weight)])
    assert [(e["t"], e["value"]["message"]) for e in engine.trace if e["kind"] == "violation"] == [
        (0.1, f"input req: {field}; rejected")]
    assert setpoints(engine) == [] and acks(engine) == []
