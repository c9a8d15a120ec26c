"""Links between hosts: zenoh echo round trips between two network namespaces joined by a veth
pair, against the same pair of processes on one host, each over TCP and over TLS with mutual
authentication; the time from a partition to the motors safe; the conveyor arm split over two
hosts in real time (prints figures; asserts nothing).

    .venv/bin/python bench/hosts.py [--rounds 2000] [--payload 64] [--only links|partition|conveyor]
    .venv/bin/python bench/hosts.py --only partition [--cuts 8] [--quiet 30] [--load 2]

Two "hosts" are network namespaces this benchmark makes and removes (needs root): `brain`
(10.201.0.1) and `arm` (10.201.0.2), with addresses that exist only inside them. The echo process
listens in `arm`; the pinger connects from `brain` as a client and sends one ping at a time. The
baseline is the same two processes in one namespace over its loopback. The certificates for TLS
are made for the run (iotad/machine/certificates.py) and removed with it.
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
from contextlib import nullcontext
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
    from iotad.machine.certificates import host_files
    return host_files(certificates_dir, host)


def echo(listen: str, certificates_dir: str | None) -> None:
    """The responder: every ping comes back as a pong, until stdin closes."""
    from iotad.node_host.transport import open_session
    with open_session([listen], [], credentials=False, tls=tls_files(certificates_dir, "arm")) as session:
        publisher = session.declare_publisher("bench/pong", express=True)
        session.declare_subscriber("bench/ping", lambda sample: publisher.put(sample.payload))
        print("ready", flush=True)
        sys.stdin.read()


def ping(connect: str, certificates_dir: str | None, rounds: int, payload: int) -> None:
    """The pinger: `rounds` round trips, one at a time; prints the times (seconds) as JSON."""
    from iotad.node_host.transport import open_session
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


def partition_figures(cuts: int, quiet: float, load: int) -> None:
    """The arm split over brain and arm (tests/partition_run.py): first `quiet` s of motion with no
    cut, under `load` busy processes beside it, for how far apart the motor node takes its
    setpoints (what its link watch judges) and whether it trips; then `cuts` partitions of 1 s
    mid-motion, each healed and the arm re-armed before the next: from each cut to the last
    axis told IDLE, on the frames the arm host recorded."""
    sys.path.insert(0, str(ROOT / "tests"))
    from namespaces import hosts
    from partition_run import SplitArm, read_partition, setpoint_gaps

    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(load)]
    marks = []
    with tempfile.TemporaryDirectory(prefix="iotad-bench-partition-") as folder, hosts("brain", "arm", net=209) as net:
        # legs of 3 s: the quiet part, then about 4 s per cut (1 s cut, re-arming, motion seen)
        arm = SplitArm(net, Path(folder), 7619, legs=int(quiet / 3 + cuts * 2.5) + 4)
        try:
            arm.start()
            arm.wait_moving(timeout=180)
            arm.wait_recorded(timeout=30)
            quiet_from = time.time_ns()
            time.sleep(quiet)  # the motion goes on uncut: the part whose setpoint gaps are measured
            quiet_to = time.time_ns()
            for _ in range(cuts):
                arm.wait_moving(timeout=60, by=0.02)
                cut = arm.cut()
                time.sleep(1.0)
                marks.append((cut, arm.heal()))
                arm.wait_all("LINK_FOUND", 60)
                arm.wait_all("ARM_DONE", 60)
        finally:
            arm.stop()
            for proc in busy:
                proc.kill()
                proc.wait()
        gaps = setpoint_gaps(arm.recording, arm.name, quiet_from, quiet_to)
        from iotad.recording.mcap_reader import read_recording
        false_trips = sum(1 for m in read_recording(arm.recording).messages
                          if m.topic.startswith(f"iota/{arm.name}/motor/joint_status/") and quiet_from <= m.publish_time
                          <= quiet_to and m.value["event"] == "LINK_LOST")
        partitions = [read_partition(arm.recording, arm.name, cut, heal) for cut, heal in marks]
    print(f"partition of the arm's host, {load} busy process(es) beside it, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.1f}")
    if gaps:
        print(f"  setpoints at the motor node over {quiet:g} s uncut ({len(gaps)} gaps, sent every 20 ms): "
              f"p50 {percentile(gaps, 0.5) * 1e3:.1f} ms  p99 {percentile(gaps, 0.99) * 1e3:.1f} ms  "
              f"max {max(gaps) * 1e3:.1f} ms; link watch trips without a cut: {false_trips}")
    worst = [max(s if s is not None else float("inf") for s in p.safe.values()) for p in partitions]
    every = [s for p in partitions for s in p.safe.values() if s is not None]
    if worst:
        print(f"  cut to every axis told IDLE, {len(worst)} cuts: p50 {percentile(worst, 0.5) * 1e3:.0f} ms  "
              f"max {max(worst) * 1e3:.0f} ms (each axis: p50 {percentile(every, 0.5) * 1e3:.0f} ms); "
              f"commands while cut: {sum(p.commands_while_cut for p in partitions)}; "
              f"re-armed after every heal: {all(len(p.rearmed) == 6 for p in partitions)}")


def conveyor_figures(until: float, keep: str | None) -> None:
    """examples/conveyor.toml over two hosts in real time: sim, motor and their bus on arm, the rest
    (scheduler, interpreter, planning, vision, manipulation) and the hub on brain; against the same
    file on one host (one namespace), run just before it. `keep`: a folder that keeps each run's
    system file, recording and output."""
    sys.path.insert(0, str(ROOT / "tests"))
    from namespaces import hosts

    text = (ROOT / "examples" / "conveyor.toml").read_text()
    for split in (False, True):
        place = tempfile.TemporaryDirectory(prefix="iotad-bench-conveyor-") if keep is None \
            else nullcontext(str(Path(keep) / ("split" if split else "one")))
        with place as folder, (hosts("brain", "arm", net=210) if split else hosts("one", net=212)) as net:
            Path(folder).mkdir(parents=True, exist_ok=True)
            placed, took, violations = conveyor_run(net, Path(folder), text, split, until)
        where = "two hosts (sim, motor, bus on arm)" if split else "one host                          "
        print(f"conveyor arm on {where}, real time, {until:g} s after every node was live ({took:.0f} s in all): "
              f"placed {placed['placed']}/{placed['spawned']} ({placed['missed']} missed, {placed['dropped']} "
              f"dropped); {violations}")


def conveyor_run(net, folder: Path, text: str, split: bool, until: float) -> tuple[dict, float, str]:
    """One real-time run of the conveyor in `net`: (its metrics, seconds in all, its violations line)."""
    from partition_run import SplitRun, multicast_on_loopback
    sys.path.insert(0, str(ROOT / "examples"))
    from conveyor.conveyor_metrics import conveyor_metrics
    from iotad.recording.mcap_reader import read_recording

    recording = folder / "conveyor.mcap"
    args = ("--until", f"{until:g}", "--after-live", "--plain", "-o", str(recording))
    started = time.monotonic()
    if split:
        hub, port = net.addresses[("brain", "arm")], 7620
        run = SplitRun(net, folder, port, "conveyor", split_conveyor(text, hub, port, net.addresses["arm"]),
                       run_args=args)
        multicast_on_loopback(net.names["arm"])
        try:
            run.start()
            run.procs["run"].wait(until + 300)
        finally:
            run.stop()
        output = run.output()
    else:
        multicast_on_loopback(net.names["one"])
        path = folder / "conveyor.toml"
        path.write_text(text.replace('"conveyor/', f'"{ROOT}/examples/conveyor/'))
        done = subprocess.run(net.exec("one", sys.executable, "-m", "iotad", "run", str(path), *args),
                              capture_output=True, text=True, timeout=until + 300, cwd=ROOT)
        output = done.stdout + done.stderr
        (folder / "run.out").write_text(output)
    took = time.monotonic() - started
    violations = next((line.strip() for line in output.splitlines() if "violations:" in line and "[arm]" not in line), "")
    return conveyor_metrics(read_recording(recording)), took, violations


def split_conveyor(text: str, hub: str, port: int, arm: str) -> str:
    """examples/conveyor.toml with hosts: sim and motor (and so the bus) on arm, the rest on brain;
    its relative code paths made absolute (the file is written elsewhere)."""
    text = text.replace('listen = ["tcp/127.0.0.1:7447"]\n', f'listen = ["tcp/{hub}:{port}"]\n'
                        f'[hosts.brain]\nlisten = ["tcp/{hub}:0"]\n[hosts.arm]\nlisten = ["tcp/{arm}:0"]\n', 1)
    text = text.replace('[system]\n', '[system]\nhub_host = "brain"\n', 1)
    for name in ("sim", "motor", "interpreter", "scheduler", "planning", "vision", "manipulation"):
        host = "arm" if name in ("sim", "motor") else "brain"
        text = text.replace(f'[[node]]\nname = "{name}"\n', f'[[node]]\nname = "{name}"\nhost = "{host}"\n', 1)
    text = text.replace('"conveyor/', f'"{ROOT}/examples/conveyor/')
    # arm's namespace has a veth end besides its loopback; the bus's group is routed to the loopback
    return text.replace('stations = ["motor", "sim"]', 'stations = ["motor", "sim"]\n'
                        'options = { allow_real_interfaces = true }', 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=2000, help="round trips per case (default: 2000)")
    parser.add_argument("--payload", type=int, default=64, help="bytes per ping (default: 64)")
    parser.add_argument("--only", choices=["links", "partition", "conveyor"],
                        help="one part: the links' round trips, partitions of the arm's host, or the conveyor arm "
                             "over two hosts (default: all three)")
    parser.add_argument("--cuts", type=int, default=8, help="partitions to time (default: 8)")
    parser.add_argument("--quiet", type=float, default=30.0,
                        help="s of motion with no cut first, for the setpoints' gaps (default: 30)")
    parser.add_argument("--load", type=int, default=2, help="busy processes beside the partitioned arm (default: 2)")
    parser.add_argument("--until", type=float, default=160.0,
                        help="s the conveyor runs once every node is live (default: 160, 20 cubes)")
    parser.add_argument("--keep", metavar="DIR", help="keep the conveyor's system file, recording and output in DIR")
    parser.add_argument("--role", choices=["echo", "ping"], help=argparse.SUPPRESS)
    parser.add_argument("--endpoint", help=argparse.SUPPRESS)
    parser.add_argument("--certificates", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.role == "echo":
        return echo(args.endpoint, args.certificates)
    if args.role == "ping":
        return ping(args.endpoint, args.certificates, args.rounds, args.payload)

    if args.only in (None, "links"):
        links(args)
    if args.only in (None, "partition"):
        partition_figures(args.cuts, args.quiet, args.load)
    if args.only in (None, "conveyor"):
        conveyor_figures(args.until, args.keep)


def links(args: argparse.Namespace) -> None:
    from iotad.machine import certificates
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
