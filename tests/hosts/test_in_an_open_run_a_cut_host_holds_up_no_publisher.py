"""In an open run (`--insecure`: every node a zenoh peer, meshed directly across the hosts), a cut of
one host (arm) longer than zenoh's lease (10 s) holds up no publisher of the other hosts: a node on
brain whose output also goes to arm keeps firing on time and its other readers, on brain and on
base, keep taking it, every message, through the whole cut.

brain, arm and base in network namespaces (a star around brain), started as a person would: an
agent on arm and on base, one `iotad run --insecure` on brain. `tick` on brain sends PERIOD s apart
to `far` on arm, `low` on base and `near` on brain. arm's link is cut for CUT s.

Before the fix the nodes published with congestion control BLOCK toward every peer, the other
hosts' too: cut off, the link's queue toward arm filled (an express output takes a batch of its
own, and a queue holds two a priority, behind the socket's send buffer), and `tick`'s put waited
on it, on its engine's thread, until zenoh closed the link (`wait_before_close`, 5 s) or the lease
did: `tick` fired late for seconds, and neither `near` on its own host nor `low` on base heard
anything meanwhile. Now each node's session sends what goes to another host with DROP, and keeps
BLOCK toward its own host's sessions (iotad/node_host/open_run_qos.py), so that its host's recorder
still loses nothing."""
import subprocess
import sys

from cut_recording import cut_arm_while_running, per_second
from launcher_helpers import IOTAS, ROOT
from namespaces import agent, hosts, hosts_header

from iotad.launcher.processes import interrupt_then_kill
from iotad.recording.delivery import check_delivery
from iotad.recording.mcap_reader import read_recording
from iotad.recording.merge import merge

PORT, NET = 7671, 221
CUT = 12.0        # s: just over the lease (10 s)
AFTER_HEAL = 3.0  # s of traffic once the hub has arm back
PERIOD = 0.004    # s between two of tick's outputs: 250 a second, enough to fill the cut link's queue
NODES = [("tick", "brain", "Pulse"), ("near", "brain", "FreeSink"), ("far", "arm", "FreeSink"),
         ("low", "base", "FreeSink")]


def system_text(hub: str, arm: str, base: str) -> str:
    text = hosts_header("open3", hub, PORT, "brain", "arm", arm) + f'[hosts.base]\nlisten = ["tcp/{base}:0"]\n'
    for name, host, iota in NODES:
        params = f"params = {{ period = {PERIOD} }}" if iota == "Pulse" else ""
        text += f'\n[[node]]\nname = "{name}"\nhost = "{host}"\npython = "{IOTAS}:{iota}"\n{params}\n'
    for sink in ("near", "far", "low"):
        text += f'\n[[bind]]\nfrom = "tick.out"\nto = "{sink}.inp"\n'
    return text


def test_in_an_open_run_a_cut_host_holds_up_no_publisher(tmp_path):
    files = {host: tmp_path / (f"open3.{host}.mcap" if host != "brain" else "open3.mcap") for host in ("brain", "arm", "base")}
    with hosts("brain", "arm", "base", net=NET) as net:
        hub, arm, base = net.addresses[("brain", "arm")], net.addresses["arm"], net.addresses["base"]
        path = tmp_path / "open3.toml"
        path.write_text(system_text(hub, arm, base))
        log = tmp_path / "run.log"
        connect = f"tcp/{hub}:{PORT}"
        with agent(net, "arm", connect, "--workdir", str(tmp_path / "arm-agent")), \
                agent(net, "base", connect, "--workdir", str(tmp_path / "base-agent")), log.open("w") as out:
            run = subprocess.Popen(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--insecure",
                                            "--plain", "--until", "120", "-o", str(files["brain"])),
                                   stdout=out, stderr=subprocess.STDOUT, text=True, cwd=ROOT, start_new_session=True)
            try:
                cut_at, healed_at, code = cut_arm_while_running(net, log, run, 3, [files["arm"], files["base"]],
                                                                CUT, AFTER_HEAL)
            finally:
                interrupt_then_kill(run)
    output = log.read_text()
    assert code == 130, output[-3000:]
    assert "host arm LOST" in output and "host base LOST" not in output, output[-3000:]

    recordings = {host: read_recording(file) for host, file in files.items()}
    # through the whole cut tick fired on time, and its readers on brain and on base took it, on
    # their receipt times, in every second of it as in the 2 s before it (250 a second; a fifth of
    # that allows for a loaded machine): before the fix none of the three for 5 s on end
    nominal = round(1 / PERIOD)
    for host, node, kind in (("brain", "tick", "output"), ("brain", "near", "input"), ("base", "low", "input")):
        before = per_second(recordings[host], "open3", node, kind, cut_at - 2.0, cut_at)
        during = per_second(recordings[host], "open3", node, kind, cut_at, healed_at)
        assert all(n >= nominal // 5 for n in [*before.values(), *during.values()]), (host, node, before, during)
    # and nothing of what tick sent them was lost (not judged: what was in flight at the end)
    report = check_delivery(merge(files.values()).recording)
    links = {link.nodes: link for link in report.links if link.kind == "binding"}
    for pair in (("tick", "near"), ("tick", "low")):
        assert links[pair].delivered > 0 and links[pair].lost == 0, links[pair]
    # what went to arm while its links were closed is lost, not late: the cut was real
    assert links[("tick", "far")].lost > 0, links[("tick", "far")]
