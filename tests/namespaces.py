"""Test "hosts" as network namespaces: the first joined to each other one by a veth pair of its
own (a star: 10.<net>.<k>.1 on the first's end toward host k, 10.<net>.<k>.2 on host k's, whose
default route goes to the first). Only
addresses inside namespaces the test makes and removes; never a real interface. A partition is
one end of a pair set down."""
from __future__ import annotations

import os
import subprocess
from contextlib import contextmanager

import pytest


def hosts_header(name: str, hub: str, port: int, hub_host: str, other: str, other_address: str,
                 scheme: str = "tcp") -> str:
    """The `[system]` and `[hosts]` tables of a system spread over `hub_host` (which holds the hub
    at `hub`:`port`) and `other`, each listening on an address of its own namespace."""
    return f"""
[system]
name = "{name}"
hub_host = "{hub_host}"
[system.endpoints]
listen = ["{scheme}/{hub}:{port}"]

[hosts.{hub_host}]
listen = ["{scheme}/{hub}:0"]
[hosts.{other}]
listen = ["{scheme}/{other_address}:0"]
"""


def split_figure2(name: str, hub: str, port: int, hub_host: str, other: str, other_address: str,
                  scheme: str = "tcp", scheduler_on: str | None = None, count: int = 2, pause: float = 1.2,
                  third: tuple[str, str] | None = None) -> str:
    """The Figure 2 scheduler on `hub_host` (which holds the hub at `hub`:`port`) and one
    requester on `other`, bound both ways: the smallest system spread over two hosts.
    `scheduler_on=other` swaps them (the requester, with the hub, on `hub_host`); the requester
    makes `count` requests, `pause` s apart. `third` (name, address): a third host, which holds
    the scheduler, so that the requester on `other` and the scheduler are on two hosts besides
    the hub's (which then holds no node)."""
    scheduler_on = third[0] if third else scheduler_on or hub_host
    requester_on = other if scheduler_on != other else hub_host
    third_host = f'[hosts.{third[0]}]\nlisten = ["{scheme}/{third[1]}:0"]' if third else ""
    from pathlib import Path
    examples = Path(__file__).resolve().parents[1] / "examples"
    return hosts_header(name, hub, port, hub_host, other, other_address, scheme) + f"""{third_host}

[[node]]
name = "scheduler"
host = "{scheduler_on}"
python = "{examples}/scheduler.py:Scheduler"
params = {{ N = 1, T = 0.5 }}

[[node]]
name = "vision"
host = "{requester_on}"
python = "{examples}/requesters.py:Requester"
params = {{ priority = 1, epoch = 1.0, timeout = 2.0, start = 0.5, pause = {pause}, count = {count} }}
after = ["scheduler"]

[[bind]]
from = "vision.req"
to = "scheduler.req[0]"
[[bind]]
from = "scheduler.ack[0]"
to = "vision.ack"
"""


def ip(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=10)


class Hosts:
    """Namespaces by host name; `exec(host, *cmd)` is the command line that runs `cmd` there."""

    def __init__(self, names: dict[str, str], addresses: dict[str, str], links: dict[str, tuple[str, str]]):
        self.names, self.addresses, self.links = names, addresses, links

    def exec(self, host: str, *command: str) -> list[str]:
        return ["ip", "netns", "exec", self.names[host], *command]

    def cut(self, a: str, b: str) -> None:
        """A partition: the link between `a` and `b` down (at `a`'s end)."""
        name, ns = self.links[(a, b)]
        assert ip("-n", ns, "link", "set", name, "down").returncode == 0

    def heal(self, a: str, b: str) -> None:
        name, ns = self.links[(a, b)]
        assert ip("-n", ns, "link", "set", name, "up").returncode == 0

    def limit(self, a: str, b: str, rate: str, burst: str = "2kb", latency: str = "50ms") -> None:
        """What leaves `a` toward `b` shaped by a token bucket (tc tbf: this kernel has no netem):
        at most `rate` on average, `burst` at once; a packet that would wait past `latency` in
        its queue is dropped. A rate below what is sent is delay (the queue) and loss."""
        name, ns = self.links[(a, b)]
        result = subprocess.run(["ip", "netns", "exec", ns, "tc", "qdisc", "add", "dev", name, "root", "tbf",
                                 "rate", rate, "burst", burst, "latency", latency],
                                capture_output=True, text=True, timeout=10)
        if result.returncode != 0:
            pytest.skip(f"cannot shape a link here (tc qdisc add ... tbf: {result.stderr.strip()})")


@contextmanager
def hosts(first: str, *others: str, net: int = 200):
    """`first` joined to each of `others` by its own veth pair (a star around `first`): first is
    10.<net>.<k>.1 toward other k, which is 10.<net>.<k>.2. Skips without root."""
    tag = f"{os.getpid() % 100000}"
    names = {host: f"iotad-{host}-{tag}" for host in (first, *others)}
    made, addresses, links = [], {}, {}
    try:
        for ns in names.values():
            result = ip("netns", "add", ns)
            if result.returncode != 0:
                pytest.skip(f"cannot create network namespaces here (ip netns add: {result.stderr.strip()}); "
                            "this test needs root or CAP_NET_ADMIN")
            made.append(ns)
        ip("-n", names[first], "link", "set", "lo", "up")
        for k, other in enumerate(others, start=1):
            near, far = f"i{k}a{tag}", f"i{k}b{tag}"
            here, there = f"10.{net}.{k}.1", f"10.{net}.{k}.2"
            for step in (("link", "add", near, "type", "veth", "peer", "name", far),
                         ("link", "set", near, "netns", names[first]), ("link", "set", far, "netns", names[other]),
                         ("-n", names[first], "addr", "add", f"{here}/24", "dev", near),
                         ("-n", names[other], "addr", "add", f"{there}/24", "dev", far),
                         ("-n", names[first], "link", "set", near, "up"), ("-n", names[other], "link", "set", far, "up"),
                         ("-n", names[other], "link", "set", "lo", "up"),
                         # every address of the first host is reachable from host k, not only the
                         # one on its own link (the first host does not forward between the others)
                         ("-n", names[other], "route", "add", "default", "via", here)):
                result = ip(*step)
                if result.returncode != 0:
                    pytest.skip(f"cannot wire the namespaces (ip {' '.join(step)}: {result.stderr.strip()})")
            addresses[(first, other)], addresses[other] = here, there
            links[(first, other)] = (near, names[first])
            links[(other, first)] = (far, names[other])
        yield Hosts(names, addresses, links)
    finally:
        for ns in made:
            ip("netns", "del", ns)  # takes its veth ends (and so the pairs) with it


@contextmanager
def agent(net: Hosts, host: str, connect: str, *extra: str, env: tuple[str, ...] = ()):
    """`iotad agent --name HOST --connect CONNECT` in `host`'s namespace, from the repository's
    folder (its output on the Popen's stdout), stopped on the way out as Ctrl-C would."""
    import subprocess
    import sys
    from pathlib import Path

    from iotad.launcher.processes import interrupt_then_kill

    root = Path(__file__).resolve().parents[1]
    prefix = ("env", *env) if env else ()
    process = subprocess.Popen(net.exec(host, *prefix, sys.executable, "-m", "iotad", "agent", "--name", host,
                                        "--connect", connect, *extra),
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=root,
                               start_new_session=True)
    try:
        yield process
    finally:
        interrupt_then_kill(process)
