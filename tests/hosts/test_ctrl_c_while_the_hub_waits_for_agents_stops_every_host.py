"""Ctrl-C while the hub's `iotad run` still waits for an agent (here: host base has none) ends the
wait at once, not when the agent timeout runs out, and stops the hosts it had already started
(host arm, whose agent took its part as soon as it was there). In network namespaces."""
import re
import signal
import subprocess
import sys

from launcher_helpers import ROOT, wait_until
from namespaces import hosts, split_figure2
from iotad.launcher.processes import interrupt_then_kill

AGENT_TIMEOUT = 300  # the run is stopped long before this: a wait that ignored Ctrl-C fails the test


def three_hosts(hub: str, arm: str, base: str) -> str:
    """The split Figure 2 (scheduler on brain with the hub, requester on arm) and an echo on base."""
    # a top-level key comes before the first table
    return 'external = ["dock.inp"]\n' + split_figure2("three", hub, 7635, "brain", "arm", arm) + f"""
[hosts.base]
listen = ["tcp/{base}:0"]

[[node]]
name = "dock"
host = "base"
python = "{ROOT}/examples/echo.py:Echo"
"""


def test_ctrl_c_while_waiting_for_an_agent_stops_at_once_and_stops_the_started_hosts(tmp_path):
    with hosts("brain", "arm", "base", net=207) as net:
        hub = net.addresses[("brain", "arm")]
        path = tmp_path / "three.toml"
        path.write_text(three_hosts(hub, net.addresses["arm"], net.addresses["base"]))
        agent = subprocess.Popen(net.exec("arm", sys.executable, "-m", "iotad", "agent", "--name", "arm",
                                          "--connect", f"tcp/{hub}:7635"),
                                 stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=ROOT,
                                 start_new_session=True)
        log = tmp_path / "run.log"
        with log.open("w") as out:
            run = subprocess.Popen(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--insecure", "--plain",
                                            "--no-record", "--agent-timeout", str(AGENT_TIMEOUT)),
                                   stdout=out, stderr=subprocess.STDOUT, text=True, cwd=ROOT, start_new_session=True)
        try:
            # arm's part runs (its launcher has measured its clock against the hub's); base has no agent
            started = wait_until(lambda: re.search(r"\[arm\] .*host arm: clock", log.read_text()), 90)
            assert started, log.read_text()[-3000:]
            assert "host base" not in log.read_text()
            run.send_signal(signal.SIGINT)
            code = run.wait(60)  # far sooner than the agent timeout
        finally:
            interrupt_then_kill(run)
            agent_code = interrupt_then_kill(agent)
            agent_output = agent.stdout.read()
        output = log.read_text()
        assert code == 130, output[-3000:]
        assert "Ctrl-C: stopping every node" in output, output[-3000:]
        assert "no agent answered" not in output and "Traceback" not in output, output[-3000:]
        assert "host arm: exit 130 (stopped by this run)" in output, output[-3000:]
        assert "agent arm: stopping the run (the hub asked)" in agent_output, agent_output
        assert "agent arm: the run exited with 130" in agent_output, agent_output
        assert agent_code == 0, agent_output
