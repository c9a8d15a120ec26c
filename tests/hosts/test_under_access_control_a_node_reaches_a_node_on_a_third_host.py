"""Under access control, a node on one host besides the hub's reaches a node on another one:
brain holds the hub and the recorder, arm a Figure 2 requester and base its scheduler, bound both
ways, in three network namespaces linked by TLS and started by one `iotad run --certs` on brain
through the agents of arm and base. Each of arm and base has its own router on a private unix
socket; the two cannot link to each other, so everything between them crosses the hub, which
relays between their routers (both it and they zenoh routers: `host_access.zenoh_mode`). The
hub's recording shows every request the scheduler on base was sent received there and every
answer back received on arm (`check_delivery`), and `iotad check` passes.

That the hub still drops what a host's router may not publish, in the same mode, is
tests/launcher/test_the_hub_holds_no_password_of_another_hosts_node.py."""
import re
import subprocess
import sys

from agent_helpers import Lines, authority_for, start
from namespaces import hosts, split_figure2
from recorded_systems import check_of_a_real_run

from iotad.launcher.processes import interrupt_then_kill
from iotad.recording.delivery import check_delivery
from iotad.recording.mcap_reader import read_recording

PORT = 7634


def test_a_node_on_arm_reaches_a_node_on_base_through_the_hub(tmp_path):
    with hosts("brain", "arm", "base", net=214) as net:
        hub, arm, base = net.addresses[("brain", "arm")], net.addresses["arm"], net.addresses["base"]
        # base reaches the hub's address on arm's link through its default route to brain
        certs = authority_for(tmp_path / "certs", {"brain": [hub], "arm": [arm], "base": [base]})
        path = tmp_path / "three.toml"
        path.write_text(split_figure2("three", hub, PORT, "brain", "arm", arm, "tls", count=3, third=("base", base)))
        recording = tmp_path / "three.mcap"
        agents = [start(net.exec(host, sys.executable, "-m", "iotad", "agent", "--name", host,
                                 "--connect", f"tls/{hub}:{PORT}", "--certs", str(certs))) for host in ("arm", "base")]
        agent_lines = [Lines(agent) for agent in agents]
        run = start(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--plain",
                             "--certs", str(certs), "--until", "7", "--after-live", "-o", str(recording)))
        lines = Lines(run)
        try:
            try:  # within the test's time limit, so that a run that never ends fails with its output
                code = run.wait(100)
            except subprocess.TimeoutExpired:
                code = None
            lines.wait_for("join them with: iotad merge", 30)  # the summary's last line, or the end of the output
        finally:
            interrupt_then_kill(run)
            for agent in agents:
                interrupt_then_kill(agent)
    output = lines.text()
    tails = "".join(agent.text()[-2000:] for agent in agent_lines)
    assert code == 0, output[-4000:] + tails
    assert "access control: on (" in output and "access control is OFF" not in output, output[-4000:]

    hub_file = read_recording(recording)
    taken = {node: [e.get("value") for e in hub_file.trace(node) if e["kind"] == "input"] for node in ("vision", "scheduler")}
    # the scheduler on base took arm's requests, and the requester on arm took base's answers
    assert len(taken["scheduler"]) >= 3 and "COMMIT" in taken["vision"], taken
    report = check_delivery(hub_file)
    assert report.checked and report.ok, report.reason or [str(finding) for finding in report.findings]
    bindings = {link.nodes: link for link in report.links if link.kind == "binding"}
    requests, answers = bindings[("vision", "scheduler")], bindings[("scheduler", "vision")]
    # every request arm sent was received on base, and every answer base sent was received on arm
    assert requests.sent >= 3 and requests.delivered == requests.sent, requests
    assert answers.sent >= 1 and answers.delivered == answers.sent, answers
    out = check_of_a_real_run(recording)
    assert re.search(r"scheduler: \d+ events, [1-9]\d* firings checked", out), out[-3000:]
