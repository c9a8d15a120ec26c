"""Links between hosts: zenoh echo round trips between two network namespaces joined by a veth
pair, against the same pair of processes on one host, each over TCP and over TLS with mutual
authentication (prints p50/p99 and ratios; asserts nothing).

    .venv/bin/python bench/hosts.py [--rounds 2000] [--payload 64]

Two "hosts" are network namespaces this benchmark makes and removes (needs root): `brain`
(10.201.0.1) and `arm` (10.201.0.2), with addresses that exist only inside them. The echo process
listens in `arm`; the pinger connects from `brain` as a client and sends one ping at a time. The
baseline is the same two processes in one namespace over its loopback. The certificates for TLS
are made for the run (iotad/host/certificates.py) and removed with it.
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

ADDRESSES = {"brain": "10.201.0.1", "arm": "10.201.0.2"}
PORT = 7631


def ip(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=10)


class Namespaces:
    """brain and arm as namespaces joined by a veth pair; removed on exit, also on failure."""

    def __init__(self):
        tag = os.getpid() % 100000
        self.names = {host: f"iotad-bench-{host}-{tag}" for host in ADDRESSES}
        self._made: list[str] = []

    def __enter__(self) -> "Namespaces":
        try:
            for name in self.names.values():
                result = ip("netns", "add", name)
                if result.returncode:
                    raise SystemExit(f"cannot make network namespaces here ({result.stderr.strip()}): run as root")
                self._made.append(name)
            brain, arm = self.names["brain"], self.names["arm"]
            tag = brain.rsplit("-", 1)[1]
            for step in (("link", "add", f"ibb{tag}", "type", "veth", "peer", "name", f"iba{tag}"),
                         ("link", "set", f"ibb{tag}", "netns", brain), ("link", "set", f"iba{tag}", "netns", arm),
                         ("-n", brain, "addr", "add", f"{ADDRESSES['brain']}/24", "dev", f"ibb{tag}"),
                         ("-n", arm, "addr", "add", f"{ADDRESSES['arm']}/24", "dev", f"iba{tag}"),
                         ("-n", brain, "link", "set", f"ibb{tag}", "up"), ("-n", arm, "link", "set", f"iba{tag}", "up"),
                         ("-n", brain, "link", "set", "lo", "up"), ("-n", arm, "link", "set", "lo", "up")):
                result = ip(*step)
                if result.returncode:
                    raise SystemExit(f"cannot wire the namespaces (ip {' '.join(step)}): {result.stderr.strip()}")
        except BaseException:
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc) -> None:
        for name in self._made:
            ip("netns", "del", name)
        self._made.clear()

    def command(self, host: str, *args: str) -> list[str]:
        return ["ip", "netns", "exec", self.names[host], *args]


def tls_files(certificates_dir: str | None, host: str):
    if not certificates_dir:
        return None
    from iotad.host.certificates import host_files
    return host_files(certificates_dir, host)


def echo(listen: str, certificates_dir: str | None) -> None:
    """The responder: every ping comes back as a pong, until stdin closes."""
    from iotad.host.transport import open_session
    with open_session([listen], [], credentials=False, tls=tls_files(certificates_dir, "arm")) as session:
        publisher = session.declare_publisher("bench/pong", express=True)
        session.declare_subscriber("bench/ping", lambda sample: publisher.put(sample.payload))
        print("ready", flush=True)
        sys.stdin.read()


def ping(connect: str, certificates_dir: str | None, rounds: int, payload: int) -> None:
    """The pinger: `rounds` round trips, one at a time; prints the times (seconds) as JSON."""
    from iotad.host.transport import open_session
    answered = threading.Event()
    with open_session([], [connect], mode="client", connect_timeout=10, credentials=False,
                      tls=tls_files(certificates_dir, "brain")) as session:
        session.declare_subscriber("bench/pong", lambda sample: answered.set())
        publisher = session.declare_publisher("bench/ping", express=True)
        body = bytes(payload)
        for _ in range(200):  # until the route exists both ways
            answered.clear()
            publisher.put(body)
            if answered.wait(0.05):
                break
        times = []
        for _ in range(rounds + 50):
            answered.clear()
            start = time.perf_counter()
            publisher.put(body)
            if not answered.wait(2.0):
                continue
            times.append(time.perf_counter() - start)
        print(json.dumps(times[50:]), flush=True)


def measure(namespaces: Namespaces, two_hosts: bool, certificates_dir: str | None, rounds: int, payload: int) -> list[float]:
    scheme = "tls" if certificates_dir else "tcp"
    address = ADDRESSES["arm"] if two_hosts else "127.0.0.1"
    endpoint = f"{scheme}/{address}:{PORT}"
    extra = ["--certificates", certificates_dir] if certificates_dir else []
    script = [sys.executable, str(Path(__file__).resolve())]
    responder = subprocess.Popen(namespaces.command("arm" if two_hosts else "brain", *script, "--role", "echo",
                                                    "--endpoint", endpoint, *extra),
                                 stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        if responder.stdout.readline().strip() != "ready":
            raise SystemExit("the echo process did not start")
        done = subprocess.run(namespaces.command("brain", *script, "--role", "ping", "--endpoint", endpoint,
                                                 "--rounds", str(rounds), "--payload", str(payload), *extra),
                              capture_output=True, text=True, timeout=120 + rounds * 0.05)
        if done.returncode:
            raise SystemExit(f"the pinger failed: {done.stderr.strip()[-500:]}")
        return json.loads(done.stdout.strip().splitlines()[-1])
    finally:
        responder.stdin.close()
        try:
            responder.wait(10)
        except subprocess.TimeoutExpired:
            responder.kill()
            responder.wait()


def percentile(values: list[float], fraction: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(fraction * len(ordered)))]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=2000, help="round trips per case (default: 2000)")
    parser.add_argument("--payload", type=int, default=64, help="bytes per ping (default: 64)")
    parser.add_argument("--role", choices=["echo", "ping"], help=argparse.SUPPRESS)
    parser.add_argument("--endpoint", help=argparse.SUPPRESS)
    parser.add_argument("--certificates", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role == "echo":
        return echo(args.endpoint, args.certificates)
    if args.role == "ping":
        return ping(args.endpoint, args.certificates, args.rounds, args.payload)

    from iotad.host import certificates
    print(f"zenoh echo round trips, {args.rounds} per case, {args.payload}-byte payload, {os.cpu_count()} cores; "
          f"load average {os.getloadavg()[0]:.1f}")
    with tempfile.TemporaryDirectory(prefix="iotad-bench-certs-") as directory, Namespaces() as namespaces:
        certificates.init_authority(directory)
        for host in ADDRESSES:
            certificates.issue_host(directory, host, [ADDRESSES[host], "127.0.0.1"])
        results = {}
        for tls in (False, True):
            for two_hosts in (False, True):
                times = measure(namespaces, two_hosts, directory if tls else None, args.rounds, args.payload)
                name = f"{'two namespaces' if two_hosts else 'one host      '} {'TLS' if tls else 'TCP'}"
                results[(two_hosts, tls)] = statistics.median(times)
                print(f"  {name}: p50 {percentile(times, 0.5) * 1e6:7.0f} us   p99 {percentile(times, 0.99) * 1e6:7.0f} us"
                      f"   ({len(times)} answered)")
        for tls in (False, True):
            print(f"  {'TLS' if tls else 'TCP'}: two namespaces / one host p50 = "
                  f"{results[(True, tls)] / results[(False, tls)]:.2f}x")
        for two_hosts in (False, True):
            print(f"  {'two namespaces' if two_hosts else 'one host'}: TLS / TCP p50 = "
                  f"{results[(two_hosts, True)] / results[(two_hosts, False)]:.2f}x")


if __name__ == "__main__":
    main()
