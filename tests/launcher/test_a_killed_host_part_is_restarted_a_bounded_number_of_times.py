"""An agent starts its killed run again a bounded number of times, backing off, and never a run
that was asked to stop or that exited with a status of its own (iotad/launcher/hosts/agent.py).

The agent's decision alone, on real processes that exit as a killed launcher, a configuration
error and a stopped run do; the whole path over hosts is
tests/hosts/test_a_killed_host_part_is_started_again_by_its_agent.py."""
import signal
import subprocess
import sys
import time

from iotad.launcher.hosts.agent import PART_RESTARTS, Agent

SLEEPER = [sys.executable, "-c", "import time; time.sleep(60)"]


def exited(agent: Agent, argv: list[str], kill: bool = True) -> tuple[subprocess.Popen, int]:
    """A child of `agent` (its run in progress) and its exit status: killed with SIGKILL, or as it exits."""
    child = subprocess.Popen(argv)
    child.started_at = time.monotonic()
    agent.child = child
    if kill:
        child.send_signal(signal.SIGKILL)
    return child, child.wait(30)


def agent_with_a_run() -> Agent:
    agent = Agent("camera", [], say=lambda text: None)
    agent._launch = (SLEEPER, {}, "digest", "system.toml")
    return agent


def test_a_killed_run_is_restarted_with_backoff_until_its_restarts_are_spent():
    agent = agent_with_a_run()
    restarts = []
    for _ in range(PART_RESTARTS.max_restarts + 1):
        child, code = exited(agent, SLEEPER)
        assert code == -signal.SIGKILL
        restarts.append(agent._restart_after(child, code))
        assert agent._running() == (restarts[-1] is not None)  # the hub's session kept while one is due
    assert restarts[:-1] == [{"attempt": k + 1, "of": 3, "in_s": delay}
                             for k, delay in enumerate([0.5, 1.0, 2.0])], restarts
    assert restarts[-1] is None  # its restarts are spent: an exit the hub takes as the part's end


def test_a_run_asked_to_stop_or_ending_with_its_own_status_is_not_restarted():
    agent = agent_with_a_run()
    child, code = exited(agent, [sys.executable, "-c", "raise SystemExit(2)"], kill=False)
    assert code == 2 and agent._restart_after(child, code) is None  # a configuration error: the same again
    child, code = exited(agent, SLEEPER)
    agent._asked_stop = True  # as _stop_child marks it before its SIGINT
    assert agent._restart_after(child, code) is None


def test_a_restart_due_is_dropped_when_the_run_is_stopped_meanwhile():
    agent = agent_with_a_run()
    child, code = exited(agent, SLEEPER)
    assert agent._restart_after(child, code) is not None
    assert agent._stop_child("the hub asked") == code  # the stop comes during the backoff
    agent._respawn(child)
    assert agent.child is child and not agent._running()  # nothing started again
