"""A system over three namespace hosts (brain with the hub, arm with the CAN motor node, the
simulated drives and their bus, camera), secured (TLS, access control), run in real time through
the hosts' agents while a schedule of faults (tests/fault_schedule.py) is made real
(tests/fault_injection.py); every process it started stopped afterwards, also on Ctrl-C or a
failure, and what was left in the namespaces killed and reported. Shared by bench/bad_day.py (the
conveyor) and its short campaign in tests/hosts/ (the arm of examples/arm_can.toml, lighter)."""
from __future__ import annotations

import re

import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

from agent_helpers import authority_for
from fault_injection import Injector, kill_leftovers
from fault_schedule import Fault
from partition_run import multicast_on_loopback, split_arm_system

from iotad.can.tiers import UDP_GROUP
from iotad.launcher.processes import interrupt_then_kill

ROOT = Path(__file__).resolve().parents[1]
HOSTS = ("brain", "arm", "camera")


@dataclass(frozen=True)
class Machine:
    """What a campaign needs to know of its system: its name, where each node runs, which node
    sends the motors' setpoints, the motor node, the drives' node and the axes' CAN node ids."""

    name: str
    nodes: dict[str, str]
    setpoints_from: str
    motor: str
    drives: str
    node_ids: tuple[int, ...]


def conveyor_over_three_hosts(hub: str, port: int, arm: str, camera: str,
                              seconds: float = 140.0, traces_home: bool = True) -> tuple[str, Machine]:
    """examples/conveyor.toml over brain (the hub, the scheduler, the MDL interpreter, planning,
    manipulation), arm (the world with its simulated drives, the motor node, their bus: a CAN
    bus is local to its machine) and camera (vision: what a smart camera computes beside its
    sensor). The camera's images come from the world on arm, as a camera's frames would come
    over its own link; the motors' setpoints cross from brain to arm. The belt brings cubes for
    all of `seconds` (the example's 20 last 140 s): cubes placed then measure the whole run, not
    how soon the 20 were done.

    `traces_home`: arm and camera keep their nodes' traces on their own recordings, as a robot
    whose arm and camera reach the brain over radio links would: the arm's traces (about 3.5
    Mbit/s, its CAN bus's frames among them) fill a link slowed to 1 Mbit/s, and its outputs
    queued behind them arrived 1.1 s late (7 s at 256 kbit/s), so vision saw a belt that had
    moved on. The merge joins every host's file (docs/hosts.md, "A slowed link")."""
    hosts = {"sim": "arm", "motor": "arm", "vision": "camera", "interpreter": "brain", "scheduler": "brain",
             "planning": "brain", "manipulation": "brain"}
    text = (ROOT / "examples" / "conveyor.toml").read_text()
    text = text.replace('listen = ["tcp/127.0.0.1:7447"]\n',
                        f'listen = ["tls/{hub}:{port}"]\n[hosts.brain]\nlisten = ["tls/{hub}:0"]\n'
                        f'[hosts.arm]\nlisten = ["tls/{arm}:0"]\n[hosts.camera]\nlisten = ["tls/{camera}:0"]\n', 1)
    text = text.replace("[system]\n", '[system]\nhub_host = "brain"\n', 1)
    if traces_home:
        for host in ("arm", "camera"):
            text = text.replace(f"[hosts.{host}]\n", f'[hosts.{host}]\ntraces = "home"\n', 1)
    interval = float(re.search(r"cube_interval = ([\d.]+)", text).group(1))
    text = text.replace("cube_count = 20,", f"cube_count = {max(20, int(seconds / interval) + 1)},", 1)
    for name, host in hosts.items():
        text = text.replace(f'[[node]]\nname = "{name}"\n', f'[[node]]\nname = "{name}"\nhost = "{host}"\n', 1)
    text = text.replace('"conveyor/', f'"{ROOT}/examples/conveyor/')
    # arm's namespace has a veth end besides its loopback; the bus's group is routed to the loopback
    text = text.replace('interface = "env"', f'interface = "udp_multicast"\nchannel = "{UDP_GROUP}"', 1)
    text = text.replace('stations = ["motor", "sim"]', 'stations = ["motor", "sim"]\n'
                        'options = { allow_real_interfaces = true }', 1)
    return text, Machine("conveyor", hosts, "interpreter", "motor", "sim", tuple(range(1, 8)))


def arm_over_three_hosts(hub: str, port: int, arm: str, camera: str, seconds: float) -> tuple[str, Machine]:
    """The arm of examples/arm_can.toml (tests/partition_run.py) with its trajectory on brain and
    its drives, motor node and bus on arm, moving to and fro for `seconds` and more; and on
    camera a source of 10 outputs a second that a sink on brain takes: each host has nodes of its
    own, at a fraction of the conveyor's load."""
    legs = int(seconds / 3) + 40
    text = split_arm_system("badday", hub, port, arm, legs=legs).replace('"tcp/', '"tls/')
    iotas = ROOT / "tests" / "system_iotas.py"
    text += f"""
[hosts.camera]
listen = ["tls/{camera}:0"]

[[node]]
name = "seen"
host = "camera"
python = "{iotas}:Pulse"
params = {{ period = 0.1 }}

[[node]]
name = "sink"
host = "brain"
python = "{iotas}:FreeSink"

[[bind]]
from = "seen.out"
to = "sink.inp"
"""
    hosts = {"odrives": "arm", "motor": "arm", "trajectory": "brain", "seen": "camera", "sink": "brain"}
    return text, Machine("badday", hosts, "trajectory", "motor", "odrives", tuple(range(1, 7)))


@dataclass
class Done:
    """A fault as it was made: its wall-clock ns at the start and at the end (a kill: both its
    instant), the pid it hit, and what could not be done (no such process then)."""

    fault: Fault
    start_ns: int
    end_ns: int
    pid: int | None = None
    missed: str = ""


@dataclass
class Campaign:
    """One real-time run of `text` (a system over HOSTS, its Machine `machine`) in `net`, files in
    `folder`, the hub on `port`, with `schedule` made real from when every host's start gate is
    open, for `length` s; then Ctrl-C on the hub's run. `start()` ... `stop()`; `stop` is safe to
    call at any point and more than once."""

    net: object
    folder: Path
    port: int
    text: str
    machine: Machine
    schedule: list[Fault]
    length: float
    restart_agent_after: float = 1.0  # s: the agents' supervisor (systemd's Restart=on-failure)
    procs: dict = field(default_factory=dict)
    done: list[Done] = field(default_factory=list)
    agent_restarts: list[tuple[str, int]] = field(default_factory=list)
    began_ns: int = 0
    orphans: dict = field(default_factory=dict)
    run_code: int | None = None

    def __post_init__(self):
        self.injector = Injector(self.net)
        self.certs = None

    @property
    def hub(self) -> str:
        return self.net.addresses[("brain", "arm")]

    @property
    def recording(self) -> Path:
        return self.folder / f"{self.machine.name}.mcap"

    def start(self, timeout: float = 240.0) -> None:
        """Certificates, the agents of arm and camera, the hub's `iotad run`; returns once every
        host's start gate is open (AssertionError with the run's output if not within `timeout`)."""
        self.certs = authority_for(self.folder / "certs", {"brain": [self.hub], "arm": [self.net.addresses["arm"]],
                                                          "camera": [self.net.addresses["camera"]]})
        path = self.folder / f"{self.machine.name}.toml"
        path.write_text(self.text)
        multicast_on_loopback(self.net.names["arm"])
        for host in ("arm", "camera"):
            self._agent(host)
        self.procs["run"] = self._spawn("run", "brain", sys.executable, "-m", "iotad", "run", str(path), "--plain",
                                        "--certs", str(self.certs), "--until", f"{self.length + 600:g}",
                                        "-o", str(self.recording))
        deadline = time.monotonic() + timeout
        while self.output().count("start gate open") < len(HOSTS):
            # a host whose part failed to start says so in one line; the hub would wait for it
            # (issue 46: "a failed start waited out"): the campaign cannot begin, say why at once
            if time.monotonic() > deadline or self.procs["run"].poll() is not None or "] iotad: error:" in self.output():
                raise AssertionError(f"the run did not open every host's start gate within {timeout:g} s:\n"
                                     + self.output()[-4000:])
            time.sleep(0.2)
        self.began_ns = time.time_ns()

    def _agent(self, host: str) -> None:
        self.procs[f"agent-{host}"] = self._spawn(f"agent-{host}", host, sys.executable, "-m", "iotad", "agent",
                                                  "--name", host, "--connect", f"tls/{self.hub}:{self.port}",
                                                  "--certs", str(self.certs))

    def _spawn(self, role: str, host: str, *command: str) -> subprocess.Popen:
        out = open(self.folder / f"{role}.out", "a")
        return subprocess.Popen(self.net.exec(host, *command), stdout=out, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, text=True, cwd=ROOT, start_new_session=True)

    def output(self) -> str:
        path = self.folder / "run.out"
        return path.read_text(errors="replace") if path.exists() else ""

    def seconds(self, ns: int) -> float:
        """Seconds into the campaign of the wall-clock time `ns`."""
        return (ns - self.began_ns) / 1e9

    def play(self, say=lambda line: None) -> None:
        """The schedule, each fault at its time from the campaign's start; then the rest of `length`.
        `say(line)` is told each fault as it is made."""
        begin = time.monotonic()
        for fault in self.schedule:
            time.sleep(max(0.0, begin + fault.at - time.monotonic()))
            done = self._make(fault, lambda: max(0.0, begin + fault.end - time.monotonic()))
            self.done.append(done)
            say(f"  t={self.seconds(done.start_ns):6.1f} s  {fault.describe()}"
                + (f"  (not made: {done.missed})" if done.missed else ""))
        time.sleep(max(0.0, begin + self.length - time.monotonic()))

    def _make(self, fault: Fault, left) -> Done:
        injector = self.injector
        if fault.kind == "partition":
            start = injector.cut(fault.host)
            time.sleep(left())
            return Done(fault, start, injector.heal(fault.host))
        if fault.kind == "slow":
            start = injector.slow(fault.host, fault.rate)
            time.sleep(left())
            return Done(fault, start, injector.unslow(fault.host))
        role = fault.target
        if role == "agent":
            proc = self.procs[f"agent-{fault.host}"]
            pid = proc.pid
        else:
            pid = injector.find(fault.host, role)
        if pid is None:
            now = time.time_ns()
            return Done(fault, now, now, None, f"no {role} on {fault.host} then")
        if fault.kind == "stop":
            start = injector.stop(pid)
            time.sleep(left())
            return Done(fault, start, injector.cont(pid), pid)
        start = injector.kill(pid)
        if role == "agent":
            proc.wait()
            time.sleep(self.restart_agent_after)
            self._agent(fault.host)
            self.agent_restarts.append((fault.host, time.time_ns()))
        return Done(fault, start, start, pid)

    def stop(self) -> None:
        """Every link healed and process continued, Ctrl-C to the hub's run (which stops every
        host's part through its agent), then the agents; whatever is still in a namespace 10 s
        later is an orphan (`orphans`), killed."""
        self.injector.close()
        run = self.procs.get("run")
        if run is not None:
            self.run_code = interrupt_then_kill(run, patience=60)
        for role, proc in self.procs.items():
            if role.startswith("agent-"):
                interrupt_then_kill(proc, patience=20)
        self.orphans = kill_leftovers(self.net)
        self.procs.clear()
        if self.began_ns:
            self.save()

    def save(self) -> Path:
        """What was made, as JSON beside the recordings (`faults.json`): the campaign's start and each
        fault as made, so that its readings can be made again from the kept folder (`load`)."""
        import dataclasses
        import json

        path = self.folder / "faults.json"
        path.write_text(json.dumps({"began_ns": self.began_ns, "length": self.length,
                                    "agent_restarts": self.agent_restarts,
                                    "done": [{**dataclasses.asdict(d), "fault": dataclasses.asdict(d.fault)}
                                             for d in self.done]}, indent=1))
        return path

    def load(self) -> None:
        """What `save` wrote in `folder`, back into this campaign."""
        import json

        saved = json.loads((self.folder / "faults.json").read_text())
        self.began_ns, self.agent_restarts = saved["began_ns"], [tuple(a) for a in saved["agent_restarts"]]
        self.length = saved["length"]
        self.done = [Done(**{**d, "fault": Fault(**d["fault"])}) for d in saved["done"]]

    def files(self) -> list[Path]:
        """Every recording the run's hosts wrote: the hub's, each host's, and those their
        recorders and launchers began again."""
        stem = self.machine.name
        return sorted(path for path in self.folder.glob(f"{stem}*.mcap") if ".merged" not in path.name)
