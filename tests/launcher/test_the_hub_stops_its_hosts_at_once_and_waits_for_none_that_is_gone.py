"""Stopping a run spread over hosts: the hub asks every host's agent to stop its part at once, not
one after another, and stops waiting for a host whose agent is gone (a host cut off: zenoh's
lease ran out and its liveliness token went; its agent stops its part when it finds the hub gone)
or when a second Ctrl-C says hurry. Before, the hub asked each host in turn and waited up to 20 s
for each, a cut-off host's full 20 s included. The hub's side (iotad/launcher/hosts/fleet.py) with its
agents' answers played by the test."""
import threading

import zenoh

from launcher_helpers import ROOT, wait_until
from iotad.launcher.hosts.fleet import Fleet
from iotad.launcher.options import RunOptions
from iotad.launcher.system.system_file import load_system


class TokenGone:
    """The liveliness sample of an agent whose token went."""

    def __init__(self, host: str):
        self.key_expr = f"iota/@agent/{host}"
        self.kind = zenoh.SampleKind.DELETE


def fleet_of(hosts: list[str], answers: dict[str, int]):
    """A fleet whose `hosts` all run their part; an agent in `answers` answers the stop with that
    exit status, the others never (cut off). The stop requests, in the order they were made."""
    fleet = Fleet(load_system(ROOT / "examples" / "figure2.toml", check=False), hosts, ["tcp/127.0.0.1:9"],
                  {host: RunOptions(host=host) for host in hosts})
    fleet._started, fleet._present = set(hosts), set(hosts)
    asked: list[str] = []
    never = threading.Event()  # a cut-off agent's answer: never, until the test ends

    def ask(key: str, payload=None, timeout: float = 10.0, interruptible: bool = False) -> dict:
        host = key.split("/")[2]
        asked.append(host)
        if host in answers:
            return {"ok": True, "code": answers[host]}
        never.wait(timeout)
        return {"ok": False, "error": f"no answer in {timeout:g} s"}

    fleet._ask = ask
    return fleet, asked, never


def stop_in_background(fleet, **kw) -> tuple[threading.Thread, dict]:
    result: dict = {}
    thread = threading.Thread(target=lambda: result.update(fleet.stop(grace=600.0, **kw)), daemon=True)
    thread.start()
    return thread, result


def test_every_host_is_asked_at_once_and_a_host_whose_agent_goes_is_not_waited_for():
    fleet, asked, never = fleet_of(["arm", "base", "camera"], {"base": 130, "camera": 130})
    try:
        thread, result = stop_in_background(fleet)
        # all three asked, though arm's agent has not answered: not one after another
        assert wait_until(lambda: sorted(asked) == ["arm", "base", "camera"], 10), asked
        assert wait_until(lambda: fleet.exits == {"base": 130, "camera": 130}, 10), fleet.exits
        assert thread.is_alive()  # arm may still answer: its agent is there
        fleet._on_agent(TokenGone("arm"))  # the lease ran out: arm's agent is gone
        thread.join(30)
        assert not thread.is_alive(), "the stop still waits for a host whose agent is gone"
        assert result == {"base": 130, "camera": 130}
        assert fleet.outcome("arm") == "no exit status (its agent did not answer)"
        assert fleet.outcome("base") == "exit 130 (stopped by this run)"
    finally:
        never.set()


def test_a_second_ctrl_c_ends_the_wait_for_a_host_that_does_not_answer():
    fleet, asked, never = fleet_of(["arm"], {})
    hurry = threading.Event()
    try:
        thread, result = stop_in_background(fleet, hurry=hurry)
        assert wait_until(lambda: asked == ["arm"], 10), asked
        assert thread.is_alive()
        hurry.set()
        thread.join(30)
        assert not thread.is_alive(), "a second Ctrl-C did not end the wait"
        assert result == {}
    finally:
        never.set()
