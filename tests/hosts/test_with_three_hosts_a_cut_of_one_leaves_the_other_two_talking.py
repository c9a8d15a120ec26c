"""With three hosts under access control, a partition of one of them (arm) longer than zenoh's
lease (10 s) leaves the two others (brain, the hub's host, and base) talking, and after the heal
arm's node reaches base again through the hub.

brain, arm and base in network namespaces (a star around brain: arm and base reach each other
only through the hub, which with two hosts besides its own runs as a zenoh router, as do their
routers: `host_access.zenoh_mode`), started as a person would: `iotad certs`, an agent on arm and
on base, one `iotad run --certs` on brain. Three pulses, 10 outputs a second each: `beat` on arm
feeds `far` on base (across the hub), `tock` on base feeds `near` on brain and `tick` on brain
feeds `low` on base. arm's link is cut for CUT s. The recordings show, in every second of the cut,
base's outputs taken on brain and brain's taken on base; arm reported lost (its node alone down:
base's are not) and back; `far` taking `beat`'s outputs again after the heal. The merge of the three
recordings conforms to every node's spec, and its delivery check finds only `beat`'s messages
lost, those from the cut until its messages got through again: what arm sent while its links were
closed is lost, not late (docs/hosts.md, section 8), and nothing between brain and base is.

At 50 outputs a second each as at 10: before the hub forwarded to other hosts with congestion
control DROP (`host_access.across_hosts_settings`), the hub stalled at 50 a second on the queue toward
the cut host, heard nothing for 10 s, and killed its own host's nodes as frozen."""
import subprocess
import sys
import time

import pytest

from agent_helpers import authority_for
from cut_recording import cut_arm_while_running, per_second, received_after
from launcher_helpers import IOTAS, ROOT
from namespaces import agent, hosts, hosts_header
from recorded_systems import check_of_a_real_run

from iotad.launcher.processes import interrupt_then_kill
from iotad.recording.delivery import check_delivery
from iotad.recording.mcap_reader import read_recording
from iotad.recording.merge import merge, write_merged

# a port and a network of each case's own, so that the two can run side by side
PORTS, NETS = {0.1: 7665, 0.02: 7667}, {0.1: 216, 0.02: 217}
CUT = 12.0        # s: just over the lease (10 s), so that zenoh declares arm gone
AFTER_HEAL = 4.0  # s the run goes on once the hub has arm back: for arm's traffic to reach base again
NODES = [("beat", "arm", "Pulse"), ("far", "base", "FreeSink"),
         ("tock", "base", "Pulse"), ("near", "brain", "FreeSink"),
         ("tick", "brain", "Pulse"), ("low", "base", "FreeSink")]
BINDINGS = [("beat", "far"), ("tock", "near"), ("tick", "low")]


# The hub forwards to arm's router everything that arm's launcher and nodes subscribe to: every
# node's heartbeats and traces, of every host, and what arm's nodes take. Cut off, that link's queue
# fills (about 7 s into the cut with three pulses at 50 a second), before the lease closes it. The
# nodes publish with congestion control BLOCK, and zenoh keeps it on every hop: the hub's receive
# task of the link a message came in on waited on the full queue, and everything behind it (gdb on
# the hub 7.5 s into the cut: route_data -> Mux::send_push -> StageIn::push_network_message), so the
# hub heard nothing from its own host's nodes nor from base for 10 s and killed its nodes as
# frozen. The hub and the hosts' routers now forward to other hosts with DROP: what does not fit
# in the cut link's queue is dropped, as it would have been lost once the lease closed the link.


def system_text(hub: str, arm: str, base: str, period: float) -> str:
    text = hosts_header("tri", hub, PORTS[period], "brain", "arm", arm, "tls") + f'[hosts.base]\nlisten = ["tls/{base}:0"]\n'
    for name, host, iota in NODES:
        params = f"params = {{ period = {period} }}" if iota == "Pulse" else ""
        text += f'\n[[node]]\nname = "{name}"\nhost = "{host}"\npython = "{IOTAS}:{iota}"\n{params}\n'
    for source, sink in BINDINGS:
        text += f'\n[[bind]]\nfrom = "{source}.out"\nto = "{sink}.inp"\n'
    return text


@pytest.mark.parametrize("period", [0.1, 0.02], ids=["10 a second", "50 a second"])
def test_with_three_hosts_a_cut_of_one_leaves_the_other_two_talking(tmp_path, period):
    """Each pulse sends `period` s apart."""
    files = {host: tmp_path / (f"tri.{host}.mcap" if host != "brain" else "tri.mcap") for host in ("brain", "arm", "base")}
    with hosts("brain", "arm", "base", net=NETS[period]) as net:
        hub, arm, base = net.addresses[("brain", "arm")], net.addresses["arm"], net.addresses["base"]
        # base reaches the hub's address on arm's link through its default route to brain
        certs = authority_for(tmp_path / "certs", {"brain": [hub], "arm": [arm], "base": [base]})
        path = tmp_path / "tri.toml"
        path.write_text(system_text(hub, arm, base, period))
        log = tmp_path / "run.log"
        connect = f"tls/{hub}:{PORTS[period]}"
        with agent(net, "arm", connect, "--certs", str(certs)) as arm_agent, \
                agent(net, "base", connect, "--certs", str(certs)) as base_agent, log.open("w") as out:
            run = subprocess.Popen(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--certs", str(certs),
                                            "--plain", "--until", "120", "-o", str(files["brain"])),
                                   stdout=out, stderr=subprocess.STDOUT, text=True, cwd=ROOT, start_new_session=True)
            try:
                cut_at, healed_at, code = cut_arm_while_running(net, log, run, 3, [files["arm"], files["base"]],
                                                                CUT, AFTER_HEAL)
            finally:
                interrupt_then_kill(run)
        agents = {"arm": arm_agent.stdout.read(), "base": base_agent.stdout.read()}
    output = log.read_text()
    assert code == 130, output[-3000:]
    # the hub lost arm alone, its node alone down, and had it back; base was never lost
    assert "host arm LOST: its agent is gone" in output and "beat: DOWN (host arm lost)" in output, output[-3000:]
    assert "host base LOST" not in output and "DOWN (host base" not in output, output[-3000:]
    assert "host arm: exit 130 (stopped by this run; lost 1 time(s), back each time)" in output, output[-3000:]
    assert "host base: exit 130 (stopped by this run)\n" in output, output[-3000:]
    assert "no heartbeat" not in output and "restarted" not in output, output[-3000:]
    for host, text in agents.items():
        assert f"agent {host}: the run exited with 130" in text, text

    recordings = {host: read_recording(file) for host, file in files.items()}
    events = recordings["brain"].launcher_events()
    assert [e["node"] for e in events if e.get("event") == "down"] == ["beat"], events
    assert [e.get("host") for e in events if e.get("event") == "host_back"] == ["arm"], events
    for host, recording in recordings.items():  # no node of any host was taken for frozen and restarted
        stale = [e for e in recording.launcher_events() if e.get("event") in ("stale", "restart")]
        assert stale == [], (host, stale)

    # through the whole cut, brain and base kept talking through the hub: base's outputs reached
    # brain's sink, and brain's base's, in every second of it as in the seconds before it (1 / period a
    # second; a fifth of that allows for a loaded machine); arm kept running on its own
    nominal = round(1 / period)
    for host, node, kind in (("brain", "near", "input"), ("base", "low", "input"), ("arm", "beat", "output")):
        before = per_second(recordings[host], "tri", node, kind, cut_at - 2.0, cut_at)
        during = per_second(recordings[host], "tri", node, kind, cut_at, healed_at)
        assert all(n >= nominal // 5 for n in [*before.values(), *during.values()]), (host, node, before, during)
    # after the heal arm's node reaches base again, through the hub
    assert received_after(recordings["base"], "tri", "far", "input", healed_at) > 0, \
        per_second(recordings["base"], "tri", "far", "input", cut_at, time.time())

    merged = merge(files.values())
    write_merged(merged, tmp_path / "merged.mcap")
    # every node conforms to its spec over the whole run, the cut included (the hub's file alone
    # lacks beat's outputs of the cut, and judged alone would find the outputs after it wrong)
    check_of_a_real_run(tmp_path / "merged.mcap", "--no-delivery")
    # the merge marks a gap for arm, none for base
    assert [g["host"] for g in merged.gaps] == ["arm"], merged.gaps
    report = check_delivery(merged.recording)
    assert report.checked, report.reason
    links = {link.nodes: link for link in report.links if link.kind == "binding"}
    # nothing between brain and base went missing (not judged: what tick sent before low's engine
    # started, base's nodes starting after brain's, and what was in flight at the end)
    for pair in (("tock", "near"), ("tick", "low")):
        link = links[pair]
        assert link.delivered > 0 and link.lost == 0 and link.delivered + link.unjudged == link.sent, link
    # what beat sent from the cut until its messages got through again (after the lease closed
    # its links, and until the hub had routed to base again after the heal) is lost, not late,
    # and that is the only problem: run times (s) of the senders' firings. One stretch: from its
    # first lost message to the first that got through after it, every one is lost. It begins at
    # the cut: nothing beat sent is lost while arm's link could still carry it. What the link
    # carried is in the hub's own file: beat sends each output before the trace that records it,
    # and arm's router forwards both on its one link to the hub, the output (priority DATA) no
    # later than the trace (DATA_LOW), so every output whose trace the hub heard before the heal
    # had crossed the link, and none of them may be lost. (Not the latency of beat's messages in
    # the 2 s before the cut, as this test once assumed: a message still in arm's router when the
    # link went down is lost with the rest however long before the cut it was sent, and on a loaded
    # machine the router may not run for tens of ms. With the router stopped for 150 ms just
    # before the cut, the message sent 91 ms before it was lost, 82 ms sooner than that bound
    # allowed, and the test failed on a run that did everything right.)
    beat = "beat.out -> far.inp"
    cut, healed = (at - merged.recording.info["run"]["origin"] for at in (cut_at, healed_at))
    delivered = [(t, latency) for label, t, latency, _ in report.deliveries if label == beat]
    crossed = max(m.value["t"] for m in recordings["brain"].messages
                  if m.topic == "iota/tri/beat/@trace" and m.value.get("kind") == "output" and m.log_time / 1e9 < healed_at)
    problems = [f for f in report.findings if f.problem]
    assert links[("beat", "far")].lost > 0 and all(f.code == "lost" and f.link == beat for f in problems), \
        [str(f) for f in problems if f.code != "lost" or f.link != beat][:5]
    first_lost = min(f.t for f in problems)
    resumed = min(t for t, _ in delivered if t > first_lost)
    assert crossed < first_lost < healed < resumed, (cut, crossed, first_lost, healed, resumed)
    assert all(f.t < resumed for f in problems), ([str(f) for f in problems if f.t >= resumed][:5], resumed)
