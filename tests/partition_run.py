"""The arm over CAN split over two namespace hosts, for partitions: the trajectory (the setpoints'
source) on `brain` with the hub, the simulated ODrives, the CAN motor node and their bus on `arm`.
`SplitArm` starts it as a person would (an agent on arm, one `iotad run -o` on brain), records on
the arm host (that host's own recorder, which still hears the arm's nodes while brain is cut
off), watches the motor node's outputs from brain, and cuts and heals the link between them.
`read_partition` reads, from the arm's own recording, how long after a cut each axis was told IDLE.
Shared by tests/hosts/ and bench/hosts.py."""
from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from iotad.can.odrive import AXIS_STATE
from iotad.can.tiers import UDP_GROUP

ROOT = Path(__file__).resolve().parents[1]
SET_AXIS_STATE, SET_INPUT_POS, HEARTBEAT = 0x07, 0x0C, 0x01
IDLE, CLOSED_LOOP = AXIS_STATE["IDLE"], AXIS_STATE["CLOSED_LOOP_CONTROL"]
NODE_IDS = range(1, 7)
START, SEGMENT = 0.5, 3.0  # the trajectory's first leg starts START s after the first joint state


def split_header(name: str, hub: str, port: int, arm: str, settings: str = "") -> str:
    """The [system] and [hosts] tables of a system over brain (the hub at `hub`:`port`) and arm
    (at `arm`), plain TCP; `settings` are more lines of [system]."""
    return f"""
[system]
name = "{name}"
hub_host = "brain"
{settings}
[system.endpoints]
listen = ["tcp/{hub}:{port}"]
[hosts.brain]
listen = ["tcp/{hub}:0"]
[hosts.arm]
listen = ["tcp/{arm}:0"]
"""


def split_arm_system(name: str, hub: str, port: int, arm: str, extra: str = "", legs: int = 3) -> str:
    """examples/arm_can.toml's arm, over two hosts: a long motion (`legs` legs of SEGMENT s, to
    and fro between two poses)."""
    poses = ("[0.5, 0.1, -0.8, 0.4, 1.0, 0.5]", "[-0.3, -0.2, -1.1, -0.3, 1.4, -0.4]")
    waypoints = "[" + ", ".join(poses[k % 2] for k in range(legs)) + "]"
    joints = "\n".join(f'[[node.params.joints]]\nname = "joint{k}"\nnode_id = {k}\nvelocity_limit = 3.14\n'
                       f'current_limit = 50.0\nout_of_range = "clamp"\n' for k in NODE_IDS)
    settings = f'start_timeout = 60.0\nheartbeat_timeout = 10.0\nexternal = ["motor.estop"]\n{extra}'
    return split_header(name, hub, port, arm, settings) + f"""
[[node]]
name = "odrives"
host = "arm"
python = "sim.odrive_sim:SimulatedOdrives"
params = {{ world = "arm", step_period = 0.005, encoder_period = 0.02, watchdog_timeout = 0.08, timing_slack = 0.01, node_ids = {{ joint1 = 1, joint2 = 2, joint3 = 3, joint4 = 4, joint5 = 5, joint6 = 6 }} }}

[[node]]
name = "motor"
host = "arm"
python = "nodes.can_motor:CanMotor"
after = ["odrives"]

[node.params]
encoder_period = 0.02
polls = {{ Get_Error = 0.5 }}
auto_rearm = true
{joints}
[[node]]
name = "trajectory"
host = "brain"
python = "{ROOT}/examples/arm_trajectory.py:ArmTrajectory"
params = {{ waypoints = {waypoints}, segment = {SEGMENT}, start = {START}, period = 0.02 }}

[[can]]
name = "arm_bus"
interface = "udp_multicast"
channel = "{UDP_GROUP}"
stations = ["motor", "odrives"]
# arm's namespace has a veth end (toward brain) besides its loopback; the group is routed to the
# loopback (multicast_on_loopback), and the veth leads only into brain's namespace
options = {{ allow_real_interfaces = true }}

[[bind]]
from = "trajectory.setpoints"
to = "motor.setpoints"
[[bind]]
from = "motor.joint_states"
to = "trajectory.joint_states"
"""


# Run in brain's namespace: a client of the hub that prints each sample on the keys it is given,
# one line each, "<key below iota/SYSTEM/> <value as JSON>", so that a test waits on events.
WATCHER = r"""
import json, sys, threading, time, msgpack, zenoh
from iotad.node_host.transport import open_session
hub, system, keys = sys.argv[1], sys.argv[2], sys.argv[3:]
lock = threading.Lock()  # callbacks come on several threads: one whole line at a time
def show(sample):
    key = str(sample.key_expr).split("/", 2)[2]
    line = key + " " + json.dumps(msgpack.unpackb(sample.payload.to_bytes())) + "\n"
    with lock:
        sys.stdout.write(line)
        sys.stdout.flush()
while True:
    try:
        session = open_session([], [hub], mode="client", connect_timeout=2, credentials=False)
        break
    except zenoh.ZError:
        time.sleep(0.2)
with session:
    for key in keys:
        session.declare_subscriber(f"iota/{system}/{key}", show)
    sys.stdin.read()  # until the test closes it
"""


def multicast_on_loopback(namespace: str) -> None:
    """The CAN tier udp_multicast inside `namespace`: its loopback carries the bus's group."""
    for step in (("link", "set", "lo", "multicast", "on"), ("route", "add", "224.0.0.0/4", "dev", "lo")):
        result = subprocess.run(["ip", "-n", namespace, *step], capture_output=True, text=True, timeout=10)
        assert result.returncode == 0, result.stderr


@dataclass
class SplitRun:
    """A system split over `net`'s hosts brain (the hub) and arm (tests/namespaces.py `hosts("brain",
    "arm")`), started as a person would: an agent on arm, then one `iotad run` on brain; a watcher
    on brain prints what it is told to watch; `cut` and `heal` the link between them."""

    net: object
    folder: Path
    port: int
    name: str
    text: str                      # the system file
    watch: tuple = ()              # keys below iota/<name>/ the watcher prints
    run_args: tuple = ("--no-record",)
    procs: dict = field(default_factory=dict)
    lines: "queue.Queue[tuple]" = field(default_factory=queue.Queue)

    @property
    def hub(self) -> str:
        return self.net.addresses[("brain", "arm")]

    @property
    def endpoint(self) -> str:
        return f"tcp/{self.hub}:{self.port}"

    def start(self) -> None:
        path = self.folder / f"{self.name}.toml"
        path.write_text(self.text)
        iotad = (sys.executable, "-m", "iotad")
        self._switch("up")  # the switch ready before it is needed
        self._spawn("agent", "arm", *iotad, "agent", "--name", "arm", "--connect", self.endpoint)
        self.before_run()
        until = () if "--until" in self.run_args else ("--until", "120")  # a cap: a test stops it sooner
        # tcp/ links: an open run, as it must say (docs/hosts.md)
        self._spawn("run", "brain", *iotad, "run", str(path), "--plain", "--insecure", *until, *self.run_args)
        if self.watch:
            self._spawn("watcher", "brain", sys.executable, "-c", WATCHER, self.endpoint, self.name, *self.watch)
            threading.Thread(target=self._read, daemon=True).start()

    def before_run(self) -> None:
        """What starts after the agent and before the run (nothing here)."""

    def _spawn(self, role: str, host: str, *command: str) -> None:
        watcher = role == "watcher"
        out = subprocess.PIPE if watcher else open(self.folder / f"{role}.out", "w")
        self.procs[role] = subprocess.Popen(self.net.exec(host, *command), stdout=out, stderr=subprocess.STDOUT,
                                            stdin=subprocess.PIPE if watcher else subprocess.DEVNULL, text=True,
                                            cwd=ROOT, start_new_session=True)

    def _read(self) -> None:
        for line in self.procs["watcher"].stdout:
            key, _, value = line.partition(" ")
            self.lines.put((key, json.loads(value)))

    def wait_for(self, wanted, timeout: float, what: str) -> tuple:
        """The first (key, value) the watcher prints for which `wanted(key, value)` holds;
        AssertionError after `timeout` s."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                key, value = self.lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise AssertionError(f"no {what} within {timeout:g} s; the run said:\n{self.output()[-3000:]}") from None
            if wanted(key, value):
                return key, value

    def cut(self) -> int:
        """The link between brain and arm down (brain's end); the wall-clock ns just before."""
        return self._switch("down")

    def heal(self) -> int:
        """The link up again; the wall-clock ns just before (it was down until then)."""
        return self._switch("up")

    def _switch(self, state: str) -> int:
        # one `ip -batch` process, started before, takes each line as it comes: the link changes
        # within a fraction of a millisecond of the time taken, not after a process start (tens
        # of ms on a loaded machine), which would count against the motors' time to safe
        name, namespace = self.net.links[("brain", "arm")]
        if "switch" not in self.procs:
            self.procs["switch"] = subprocess.Popen(["ip", "-n", namespace, "-batch", "-"], stdin=subprocess.PIPE,
                                                    stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        switch = self.procs["switch"]
        now = time.time_ns()
        switch.stdin.write(f"link set {name} {state}\n")
        switch.stdin.flush()
        return now

    def output(self) -> str:
        path = self.folder / "run.out"
        return path.read_text() if path.exists() else ""

    def stop(self) -> None:
        """Every process stopped, the run first (it stops the arm's part through its agent), the
        recorder last; SIGKILL to a group that outlives its patience."""
        for role in ("run", "watcher", "agent", "recorder", "switch"):
            proc = self.procs.get(role)
            if proc is None or proc.poll() is not None:
                continue
            if role in ("watcher", "switch"):
                proc.stdin.close()
            else:
                proc.send_signal(signal.SIGINT)
            try:
                proc.wait(30)
            except subprocess.TimeoutExpired:
                try:
                    os.killpg(proc.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                proc.wait()


class SplitArm(SplitRun):
    """The split arm (`split_arm_system`), recorded by the run (`-o`) and so on the arm host by
    that host's own recorder, which still hears the arm's nodes while brain is cut off; the
    watcher prints the motor node's joint states and status reports."""

    def __init__(self, net, folder: Path, port: int, extra: str = "", legs: int = 3):
        name = "armsplit"
        # each host records its part beside the hub's recording: the arm's is NAME.arm.mcap. (A
        # separate `iotad record` peer on arm, linked to the arm's nodes through the hub's gossip,
        # now and then heard none of them under a loaded suite.)
        super().__init__(net, folder, port, name, split_arm_system(name, net.addresses[("brain", "arm")], port,
                                                                   net.addresses["arm"], extra, legs),
                         watch=("motor/joint_states", "motor/joint_status/*"),
                         run_args=("-o", str(folder / f"{name}.mcap")))

    @property
    def recording(self) -> Path:
        return self.folder / f"{self.name}.arm.mcap"

    def before_run(self) -> None:
        multicast_on_loopback(self.net.names["arm"])

    def wait_recorded(self, timeout: float) -> None:
        """Until the arm's own recorder has written the motor node's frames: it hears the arm's
        nodes, so a cut from now on is in its recording (it links to them through the hub)."""
        from iotad.recording.mcap_reader import RecordingError, read_recording

        def heard() -> bool:
            try:  # a file being written reads as one cut short: what its closed chunks hold
                recording = read_recording(self.recording, salvage=True)
            except (RecordingError, OSError):
                return False
            return any(m.topic == f"iota/{self.name}/motor/can_tx" for m in recording.messages)

        deadline = time.monotonic() + timeout
        while not heard():
            assert time.monotonic() < deadline, f"the arm's recorder wrote no frame of the motor node in {timeout:g} s"
            time.sleep(0.2)

    def wait_moving(self, timeout: float, by: float = 0.1) -> None:
        """Until joint1 is `by` rad away from where the watcher first saw it: the arm is moving."""
        states = "motor/joint_states"
        first = self.wait_for(lambda key, value: key == states, timeout, "joint states")[1]["position"][0]
        self.wait_for(lambda key, value: key == states and abs(value["position"][0] - first) > by, timeout,
                      f"motion of joint1 by {by} rad")

    def wait_all(self, event: str, timeout: float) -> None:
        """Until every joint has reported `event` on joint_status."""
        joints: set = set()
        self.wait_for(lambda key, value: key.startswith("motor/joint_status/") and value["event"] == event
                      and (joints.add(value["joint"]) or len(joints) == len(NODE_IDS)), timeout,
                      f"{event} of every joint")


@dataclass
class Partition:
    """What the arm host's recording says of one cut: per axis, seconds from the cut to the
    Set_Axis_State IDLE frame the motor node sent it (0: it was IDLE at the cut; None: none
    before the heal), and what
    crossed the bus between the last of those and the heal. Frame times are their senders' own
    (the wall clock a node host stamps each `can_tx` with as it sends it on the bus)."""

    safe: dict[int, float | None]
    commands_while_cut: int        # Set_Input_Pos or closed-loop requests after the last IDLE, before the heal
    idle_heartbeats: int           # heartbeats while cut (after the last IDLE + a heartbeat period) saying IDLE
    armed_heartbeats: int          # ... and saying closed loop
    rearmed: set[int]              # axes asked for closed loop after the heal
    commanded_after: set[int]      # axes sent Set_Input_Pos after the heal
    link_events: dict[str, int]    # LINK_LOST / LINK_FOUND reports of the motor node
    silence: float | None          # on the motor node's own clock: from the last setpoint it took to its first IDLE
    # per axis never told safe: what it was told and said, and what the motor node reported of it,
    # from 2 s before the cut to the heal (seconds from the cut): why, when the assertion fails
    story: dict[int, list[str]] = field(default_factory=dict)


def read_partition(recording, system: str, cut_ns: int, heal_ns: int, node_ids=NODE_IDS, motor: str = "motor",
                   drives: str = "odrives") -> Partition:
    """`recording`: a path, or a recording already read (a merge); `motor` and `drives` name the
    motor node and the drives' node, `node_ids` the axes."""
    from iotad.recording.mcap_reader import read_recording

    frames, events, trace, reports = [], {"LINK_LOST": 0, "LINK_FOUND": 0}, [], []
    senders = (f"iota/{system}/{motor}/can_tx", f"iota/{system}/{drives}/can_tx")
    messages = read_recording(recording).messages if isinstance(recording, (str, Path)) else recording.messages
    for message in messages:
        if message.topic == f"iota/{system}/{motor}/@trace" and message.publish_time >= cut_ns - 1_000_000_000:
            trace.append(message.value)
        if message.topic in senders:
            value = message.value
            frames.append((message.publish_time, value["id"] >> 5, value["id"] & 0x1F, bytes(value["data"])))
        elif message.topic.startswith(f"iota/{system}/{motor}/joint_status/"):
            event = message.value["event"]
            if event in events and cut_ns <= message.publish_time:
                events[event] += 1
            if event != "HEARTBEAT" and cut_ns - 2_000_000_000 <= message.publish_time <= heal_ns:
                axis = node_ids[int(message.topic.rsplit("/", 1)[1])]
                reports.append((message.publish_time, axis, f"motor node reports {event}"))
    frames.sort()
    safe: dict[int, float | None] = {}
    for node in node_ids:
        idle = [t for t, n, cmd, data in frames if n == node and cmd == SET_AXIS_STATE and cut_ns <= t < heal_ns
                and data[0] == IDLE]
        states = [data[0] for t, n, cmd, data in frames if n == node and cmd == SET_AXIS_STATE and t < cut_ns]
        # what the axis itself said last before the cut, after the last state it was told
        told_at = max([t for t, n, cmd, data in frames if n == node and cmd == SET_AXIS_STATE and t < cut_ns],
                      default=0)
        said = [data[4] for t, n, cmd, data in frames if n == node and cmd == HEARTBEAT and told_at < t < cut_ns]
        if states and states[-1] == IDLE:
            safe[node] = 0.0  # told IDLE before the cut (a trip of the link watch) and not armed since
        elif said and said[-1] == IDLE:
            # IDLE by itself before the cut, and not armed since: its own watchdog or an error
            # disarmed it (a loaded machine's late setpoint), so there was nothing to tell it
            safe[node] = 0.0
        else:
            safe[node] = (idle[0] - cut_ns) / 1e9 if idle else None
    story = {node: _story(node, frames, reports, cut_ns, heal_ns) for node in node_ids if safe[node] is None}
    last_idle = cut_ns + int(max([s for s in safe.values() if s is not None], default=0.0) * 1e9)
    while_cut = [(n, cmd, data) for t, n, cmd, data in frames if last_idle < t < heal_ns]
    settled = last_idle + 150_000_000  # a heartbeat period (0.1 s) and some for it to be sent
    beats = [data[4] for t, n, cmd, data in frames if cmd == HEARTBEAT and settled < t < heal_ns]
    return Partition(
        safe=safe,
        commands_while_cut=sum(1 for n, cmd, data in while_cut
                               if cmd == SET_INPUT_POS or (cmd == SET_AXIS_STATE and data[0] == CLOSED_LOOP)),
        idle_heartbeats=beats.count(IDLE), armed_heartbeats=beats.count(CLOSED_LOOP),
        rearmed={n for t, n, cmd, data in frames if t > heal_ns and cmd == SET_AXIS_STATE and data[0] == CLOSED_LOOP},
        commanded_after={n for t, n, cmd, data in frames if t > heal_ns and cmd == SET_INPUT_POS},
        link_events=events, silence=silence_of(trace), story=story)


def _story(node: int, frames: list, reports: list, cut_ns: int, heal_ns: int) -> list[str]:
    """What axis `node` was told (Set_Axis_State) and said (its heartbeat's state), and what the
    motor node reported of it, from 2 s before the cut to the heal: seconds from the cut."""
    names = {value: name for name, value in AXIS_STATE.items()}
    lines = []
    for t, n, cmd, data in frames:
        if n == node and cut_ns - 2_000_000_000 <= t <= heal_ns and cmd in (SET_AXIS_STATE, HEARTBEAT):
            state = data[0] if cmd == SET_AXIS_STATE else data[4]
            verb = "told" if cmd == SET_AXIS_STATE else "says"
            lines.append((t, f"{verb} {names.get(state, state)}"
                             + (f" (axis error 0x{int.from_bytes(data[:4], 'little'):x})"
                                if cmd == HEARTBEAT and any(data[:4]) else "")))
    lines += [(t, text) for t, n, text in reports if n == node]
    lines.sort()
    # a heartbeat every 0.1 s: keep each change of what it says, not every beat
    out, said = [], None
    for t, text in lines:
        if text.startswith("says") and text == said:
            continue
        said = text if text.startswith("says") else said
        out.append(f"{(t - cut_ns) / 1e9:+.3f} s: {text}")
    return out


def silence_of(trace: list[dict]) -> float | None:
    """From the last setpoint the motor node took to its first Set_Axis_State IDLE after it, in the
    node's own time (its trace): what its link watch promises, whatever the load does to the wall."""
    taken = None
    for event in sorted(trace, key=lambda e: e["t"]):
        if event["action"] == "setpoints" and event["kind"] == "input":
            taken = event["t"]
        elif event["action"] in ("can_tx", "can_tx_burst") and event["kind"] == "output" and taken is not None:
            # a frame alone, or the frames of one instant as one output (a station that bursts)
            sent = event["value"] if event["action"] == "can_tx_burst" else [event["value"]]
            if any(frame["id"] & 0x1F == SET_AXIS_STATE and frame["data"][0] == IDLE for frame in sent):
                return event["t"] - taken
    return None


def setpoint_gaps(recording: Path, system: str, since_ns: int = 0, until_ns: int = 1 << 62) -> list[float]:
    """Seconds between consecutive setpoints the motor node took (its trace's input times), for the
    trace bursts published between `since_ns` and `until_ns`: what its link watch sees."""
    from iotad.recording.mcap_reader import read_recording

    times = sorted(m.value["t"] for m in read_recording(recording).messages
                   if m.topic == f"iota/{system}/motor/@trace" and since_ns <= m.publish_time <= until_ns
                   and m.value.get("action") == "setpoints" and m.value.get("kind") == "input")
    return [b - a for a, b in zip(times, times[1:])]
