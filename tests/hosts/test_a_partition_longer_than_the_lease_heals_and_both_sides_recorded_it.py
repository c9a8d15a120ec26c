"""A partition longer than zenoh's lease (10 s) between the hub's host and another: both sides keep
running on time and recording, the hub reports the host lost (its nodes `down`), and after the
heal the hosts find each other again (`host_back`) and traffic flows both ways.

Brain (the hub) and arm in network namespaces, started as a person would: an agent on arm, one
`iotad run -o` on brain. A pulse on each host feeds a sink on the other, 50 outputs a second. The
link is cut for CUT s. Each host's recording shows its own pulse's outputs in every second of the
cut, received as they were sent: before the fix a process meshed with the other host stopped
receiving once the lease ran out (zenoh closed the cut links on both of its receive threads, each
held up to 10 s by SO_LINGER; iotad/node_host/zenoh_runtime.py), the hub's recorder recorded nothing
for seconds and its launcher killed its own nodes as frozen (the open run; under access control
only the launchers link the hosts, and the test passed before the fix too)."""
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest

from agent_helpers import authority_for
from cut_recording import cut_arm_while_running, per_second, received_after
from launcher_helpers import IOTAS, ROOT
from namespaces import agent, hosts, hosts_header

from iotad.cli import main
from iotad.launcher.processes import interrupt_then_kill
from iotad.recording.mcap_reader import read_recording

# a port of each run's own, so that the two cases can run side by side in other namespaces (an
# open run no longer takes the credentials a secured one advertised for its port:
# tests/launcher/test_an_open_run_takes_no_credentials_another_run_advertised.py)
PORTS = {False: 7661, True: 7663}
CUT = 12.0      # s: just over the lease (10 s), so that zenoh declares the other host gone
PERIOD = 0.02   # s between two outputs of a pulse
AFTER_HEAL = 4.0  # s the run goes on once the hub has the host back: for traffic across the link again


def system_text(hub: str, arm: str, scheme: str, port: int) -> str:
    """tick (a pulse on brain) -> far (on arm); beat (a pulse on arm) -> near (on brain)."""
    nodes = [("tick", "brain", "Pulse", f"params = {{ period = {PERIOD} }}"), ("near", "brain", "FreeSink", ""),
             ("beat", "arm", "Pulse", f"params = {{ period = {PERIOD} }}"), ("far", "arm", "FreeSink", "")]
    # arm measures the hub's clock every 2 s: a measurement falls in the cut, and its warning is a
    # line arm's launcher prints while the hub cannot hear it
    text = hosts_header("long", hub, port, "brain", "arm", arm, scheme).replace(
        'hub_host = "brain"', 'hub_host = "brain"\nclock_period = 2.0')
    for name, host, iota, params in nodes:
        text += f'\n[[node]]\nname = "{name}"\nhost = "{host}"\npython = "{IOTAS}:{iota}"\n{params}\n'
    return text + '\n[[bind]]\nfrom = "tick.out"\nto = "far.inp"\n[[bind]]\nfrom = "beat.out"\nto = "near.inp"\n'


@pytest.mark.parametrize("secure", [False, True], ids=["open", "under access control"])
def test_a_partition_longer_than_the_lease_heals_and_both_sides_recorded_it(tmp_path, secure, capsys):
    """An open run (tcp/, --insecure: every node a peer, meshed across the hosts) and one under
    access control (tls/, --certs: each host's nodes clients of its launcher, one link between)."""
    hub_file, arm_file = tmp_path / "long.mcap", tmp_path / "long.arm.mcap"
    with hosts("brain", "arm", net=213 if secure else 211) as net:
        hub, arm = net.addresses[("brain", "arm")], net.addresses["arm"]
        scheme = "tls" if secure else "tcp"
        path = tmp_path / "long.toml"
        path.write_text(system_text(hub, arm, scheme, PORTS[secure]))
        certs = authority_for(tmp_path / "certs", {"brain": [hub], "arm": [arm]}) if secure else None
        access = ("--certs", str(certs)) if secure else ("--insecure",)
        log = tmp_path / "run.log"
        # a work folder of its own: the run's log file it keeps is this test's alone
        with agent(net, "arm", f"{scheme}/{hub}:{PORTS[secure]}", "--workdir", str(tmp_path / "agent"),
                   *(("--certs", str(certs)) if secure else ())) as arm_agent, \
                log.open("w") as out:
            run = subprocess.Popen(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), *access,
                                            "--plain", "--until", "120", "-o", str(hub_file)),
                                   stdout=out, stderr=subprocess.STDOUT, text=True, cwd=ROOT, start_new_session=True)
            try:
                cut_at, healed_at, code = cut_arm_while_running(net, log, run, 2, [arm_file], CUT, AFTER_HEAL)
            finally:
                interrupt_then_kill(run)
        agent_output = arm_agent.stdout.read()
    output = log.read_text()
    assert code == 130, output[-3000:]
    # the hub reported the host lost, and then back with its part run on; it killed nothing
    assert "host arm LOST: its agent is gone" in output, output[-3000:]
    assert "far: DOWN (host arm lost)" in output and "beat: DOWN (host arm lost)" in output, output[-3000:]
    assert "host arm: exit 130 (stopped by this run; lost 1 time(s), back each time)" in output, output[-3000:]
    assert "no heartbeat" not in output and "restarted" not in output, output[-3000:]
    assert "agent arm: the run exited with 130" in agent_output, agent_output
    # every line arm's run printed reached the hub's console, in order, once: those of the cut
    # (zenoh dropped them) afterwards from its agent, marked late
    kept = re.search(r"agent arm: the run's lines go to the hub and to (\S+)", agent_output)
    assert kept, agent_output
    printed = Path(kept.group(1)).read_text().splitlines()
    relayed = [re.sub(r"^\[arm\] (\(late\) )?", "", line) for line in re.findall(r"\] (\[arm\] .*)", output)]
    assert relayed == printed, (relayed, printed)
    late = [line for line in output.splitlines() if "[arm] (late) " in line]
    assert any("answered no clock query" in line for line in late), output[-3000:]

    hubs, own = read_recording(hub_file), read_recording(arm_file)
    events = hubs.launcher_events()
    assert sorted(e["node"] for e in events if e.get("event") == "down") == ["beat", "far"], events
    assert any(e.get("event") == "host_back" and e.get("host") == "arm" for e in events), events
    for recording in (hubs, own):  # no node of either host was taken for frozen and restarted
        stale = [e for e in recording.launcher_events() if e.get("event") in ("stale", "restart")]
        assert stale == [], stale

    # each side kept running and recording on time through the whole cut: its own pulse's outputs
    # reached its own recorder in every second of it, as in the seconds before it (50 a second; a
    # fifth of that allows for a loaded machine, where the stall gave none for seconds on end)
    nominal = round(1 / PERIOD)
    for recording, pulse in ((hubs, "tick"), (own, "beat")):
        before = per_second(recording, "long", pulse, "output", cut_at - 2.0, cut_at)
        during = per_second(recording, "long", pulse, "output", cut_at, healed_at)
        assert all(n >= nominal // 5 for n in [*before.values(), *during.values()]), (pulse, before, during)
    # after the heal, traffic flows both ways: each host's sink took the other host's pulse again
    assert received_after(hubs, "long", "near", "input", healed_at) > 0, per_second(hubs, "long", "near", "input", cut_at, time.time())
    assert received_after(own, "long", "far", "input", healed_at) > 0, per_second(own, "long", "far", "input", cut_at, time.time())

    # `iotad check` of the hub's file alone: beat is judged up to the stretch the hub never heard,
    # which the report names with its cause, and nothing after it (its counter there is unknown
    # to the file: before the fix every output after the heal was `wrong_value`, the first late)
    code = main(["check", str(hub_file), "--no-delivery", "--all"])
    report = capsys.readouterr().out
    assert code == 1 and "[wrong_value]" not in report and "[expired]" not in report, report
    beat = next(line for line in report.splitlines() if line.startswith("beat: "))
    assert "JUDGED ONLY UP TO A GAP in its trace" in beat, report
    assert "event(s) of its trace are not in this recording (host arm lost: its nodes down at t=" in report, report
