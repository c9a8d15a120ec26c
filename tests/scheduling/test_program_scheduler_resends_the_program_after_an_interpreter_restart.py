"""The program scheduler (nodes/scheduler/program_scheduler.iota, Figure 2 carrying MDL programs)
takes restart notices: when the node that reads mdl_command (the MDL interpreter) restarts, it
starts empty and the program it ran for the master is gone, so the master's program goes again,
once mdl_command's switching time allows; the master still commits when Figure 2 says. A notice
while nobody signals, or one whose master stopped signalling before the re-send, sends nothing.
In virtual time (the notice as an input) and through the node host's enum filtering."""
import json

from iotad.esprit import load_iota
from iotad.node_host.node_config import parse
from iotad.node_host.peer_restart import notice_values, peers_of
from iotad.launcher.system.system_file import load_system

from scheduling_helpers import ROOT, acks, req, run, story, violations

PROGRAMS = ROOT / "nodes" / "scheduler" / "program_scheduler.iota"


def restart(t):
    return {"t": t, "action": "peer_restart", "value": "mdl_command"}


def sent(engine):
    """(t, w) of each program sent: a request's mode {w, k} is the program `mode w=W k=1.0`."""
    return [(t, float(value["id"].split()[1][2:])) for t, action, _, value in story(engine)
            if action == "mdl_command"]


def test_an_interpreter_restart_sends_the_masters_program_again():
    engine = run(load_iota(str(PROGRAMS)), [req(0.0, 0, 1, epoch=5.0, w=0.1), restart(2.0)])
    assert sent(engine) == [(0.0, 0.1), (2.0, 0.1)]
    assert acks(engine) == [(5.0, 0, "COMMIT")]          # Figure 2's epoch: not lengthened
    assert not violations(engine)


def test_a_restart_within_the_switching_time_resends_once_it_allows():
    engine = run(load_iota(str(PROGRAMS)), [req(0.0, 0, 1, epoch=5.0, w=0.1), restart(0.4)])
    assert sent(engine) == [(0.0, 0.1), (1.0, 0.1)]
    assert acks(engine) == [(5.0, 0, "COMMIT")]
    assert not violations(engine)


def test_a_notice_while_nothing_signals_sends_nothing():
    quiet = run(load_iota(str(PROGRAMS)), [restart(1.0), req(2.0, 0, 1, epoch=2.0, w=0.3), restart(6.0)])
    assert sent(quiet) == [(2.0, 0.3)]
    assert acks(quiet) == [(4.0, 0, "COMMIT")]


def test_a_master_preempted_before_its_resend_is_not_sent_again_nor_is_its_successor_twice():
    # the notice at 0.4 waits for the switching time (until 1.0); at 0.6 a higher request takes
    # the motors: its own program goes at 1.0, once, and the aborted master's never again
    engine = run(load_iota(str(PROGRAMS)), [req(0.0, 0, 1, epoch=5.0, w=0.1), restart(0.4),
                                            req(0.6, 1, 5, epoch=2.0, w=0.9)])
    assert sent(engine) == [(0.0, 0.1), (1.0, 0.9)]
    assert acks(engine) == [(0.6, 0, "ABORT"), (3.0, 1, "COMMIT")]
    assert not violations(engine)


def test_in_the_mdl_systems_the_node_host_passes_it_the_interpreters_restart_only():
    peer = load_iota(str(PROGRAMS)).iota_spec.channels["peer_restart"].type
    for example in ("mdl_arm_realtime.toml", "mdl_arm.toml"):
        config = parse(json.dumps(load_system(ROOT / "examples" / example).node_config("scheduler", origin=0.0, hub=[])))
        peers = peers_of(config.system, config.path, config.inputs, config.readers)
        notices = {name: notice_values(peer, channels) for name, channels in peers.items()}
        assert notices.pop("mdl") == ["mdl_command"], (example, peers)     # the interpreter
        assert notices and all(v == [] for v in notices.values()), (example, notices)  # requesters: nothing
