"""CAN benchmark, on the best CAN tier this host has (vcan, user-mode Linux, udp_multicast).

1. Baseline: the raw python-can round trip between two processes on the same bus (a frame out,
   an echo process sends it back); then the same through iotad's bus (`open_env_bus`) and the ratio.
2. The CAN motor node as a process (`iotad run`, six joints, its [[can]] bus on the tier's bus),
   fed setpoints over zenoh at 500 Hz for `--seconds` (default 10; the issue's figure is 60),
   while this process plays six ODrives on the bus: heartbeats every 100 ms, encoder estimates
   at 500 Hz per axis. Setpoint published -> its Set_Input_Pos frame on the bus: p50/p99; control
   cycles missed (a setpoint whose six frames did not all reach the bus within one cycle, 2 ms,
   or never); bus load (bits of every frame over the run's bus time, of 1 Mbit/s).
3. The same with six CiA 402 drives (protocol = "cia402"): this process plays them with the
   simulated drive's model (sim/cia402_drive.py: NMT, SDO start-up, TPDOs at SYNC, heartbeats);
   setpoint published -> its RPDO on the bus: p50/p99; SYNC cycles missed (a gap between two of
   the node's SYNCs longer than 1.5 cycles counts each cycle it skipped); bus load.
   In both parts the node's own reports (joint_status, over zenoh) say when an axis left ARMED:
   a setpoint published while an axis was not armed has no frame by design (the node sends none
   to a drive that is not enabled) and is counted apart ("not armed"), never as missed. (The
   96.76 % of an earlier run was that: the drives' watchdogs, the heartbeat consumer, tripped
   under load, the node took the axes out of ARMED as it must, and the bench counted every later
   setpoint as a frame that never came.) The CiA 402 joints' TPDO timeout is `--tpdo-timeout`
   SYNCs (25: 50 ms; the default 3 is 6 ms at 500 Hz, which this process, playing six drives
   in Python on a loaded machine, does not keep).
4. Fault to safe, both families: `--faults` faults (20), one axis at a time, each a drive's own
   account (CiA 402: its EMCY and FAULT statusword, the simulated drive's `fault`; ODrive: a
   Heartbeat with an axis error and IDLE): the time from the fault's first frame on the bus to
   the node's report that the axis is no longer ARMED (its joint_status, over zenoh), p50/max.
   The node re-arms it (auto_rearm, arm_retry 0.05 s) before the next.
5. examples/arm_can.toml in virtual time, in this process: its speed as a multiple of real time.

    .venv/bin/python bench/can_bus.py [--count 2000] [--seconds 10] [--faults 20] [--tier uml]

The host side picks the tier and runs parts 1 and 2 inside it (`--inside`); inside, the echo
peer is a second process (`--echo`). Prints the tier first. Figures only, no pass/fail on timings.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

ECHO_ID, REQUEST_ID, READY_ID, STOP_ID = 0x101, 0x100, 0x7F0, 0x7F1


def raw_bus():
    import can

    interface, channel = os.environ["IOTAD_CAN_INTERFACE"], os.environ["IOTAD_CAN_CHANNEL"]
    extra = {"port": 43113, "hop_limit": 1, "fd": False} if interface == "udp_multicast" else {}
    return can.Bus(interface=interface, channel=channel, **extra)


def echo() -> None:
    """The peer: answers every request frame with the same data under ECHO_ID (raw python-can)."""
    import can

    bus = raw_bus()
    bus.send(can.Message(arbitration_id=READY_ID, data=b"", is_extended_id=False))
    try:
        while True:
            message = bus.recv(timeout=30)
            if message is None or message.arbitration_id == STOP_ID:
                return
            if message.arbitration_id == REQUEST_ID:
                bus.send(can.Message(arbitration_id=ECHO_ID, data=message.data, is_extended_id=False))
            elif message.arbitration_id == READY_ID + 2:  # ping during start-up
                bus.send(can.Message(arbitration_id=READY_ID, data=b"", is_extended_id=False))
    finally:
        bus.shutdown()


def percentiles(samples: list[float]) -> dict:
    ordered = sorted(samples)
    pick = lambda q: ordered[min(len(ordered) - 1, int(q * len(ordered)))]  # noqa: E731
    return {"n": len(ordered), "p50_us": pick(0.50) * 1e6, "p99_us": pick(0.99) * 1e6,
            "mean_us": statistics.fmean(ordered) * 1e6, "max_us": ordered[-1] * 1e6}


def raw_round_trips(count: int) -> dict:
    import can

    bus = raw_bus()
    samples = []
    try:
        for k in range(count):
            data = k.to_bytes(4, "little") + b"\x00" * 4
            start = time.perf_counter()
            bus.send(can.Message(arbitration_id=REQUEST_ID, data=data, is_extended_id=False))
            while True:
                reply = bus.recv(timeout=2.0)
                if reply is None:
                    raise SystemExit(f"raw round trip {k}: no echo within 2 s")
                if reply.arbitration_id == ECHO_ID and bytes(reply.data) == data:
                    break
            samples.append(time.perf_counter() - start)
    finally:
        bus.shutdown()
    return percentiles(samples)


def iotad_round_trips(count: int) -> dict:
    from iotad.can.bus import open_env_bus
    from iotad.can.frame import Frame

    samples = []
    with open_env_bus() as bus:
        for k in range(count):
            frame = Frame(REQUEST_ID, k.to_bytes(4, "little") + b"\x00" * 4)
            start = time.perf_counter()
            bus.send_frame(frame)
            while True:
                got = bus.recv_frame(timeout=2.0)
                if got is None:
                    raise SystemExit(f"iotad round trip {k}: no echo within 2 s")
                if got[1].id == ECHO_ID and got[1].data == frame.data:
                    break
            samples.append(time.perf_counter() - start)
    return percentiles(samples)


def wait_for_echo(timeout: float = 20.0) -> None:
    import can

    bus = raw_bus()
    try:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            bus.send(can.Message(arbitration_id=READY_ID + 2, data=b"", is_extended_id=False))
            reply = bus.recv(timeout=0.2)
            if reply is not None and reply.arbitration_id == READY_ID:
                return
        raise SystemExit("the echo process did not come up")
    finally:
        bus.shutdown()


MOTOR_SYSTEM = """
[system]
name = "canbench"
time_unit = 1.0
external = ["motor.setpoints", "motor.estop"]

[system.endpoints]
listen = ["tcp/127.0.0.1:{port}"]

[[node]]
name = "motor"
python = "nodes.can_motor:CanMotor"
params = {{ encoder_period = {period}, state_period = {state_period}, polls = {polls},{extra} joints = [{joints}] }}

[[can]]
name = "bench_bus"
interface = "{interface}"
channel = "{channel}"
stations = ["motor"]
log = false  # no bus logger process: the bench measures the motor node alone (this process watches the bus)
"""
JOINTS, RATE, SCALE = 6, 500.0, 1e-4   # setpoint k carries position k * SCALE rad (mod WRAP)
WRAP = 60000  # setpoints told apart: a 60 s run at 500 Hz (30,000) fits, within the joints' 6.3 rad


def motor_pid() -> int:
    """The motor node's process (the launcher's child running its node host)."""
    for entry in Path("/proc").iterdir():
        try:
            argv = (entry / "cmdline").read_bytes().split(b"\0")
        except OSError:
            continue
        if b"iotad.node_host" in argv and any(a.endswith(b"motor.json") for a in argv):
            return int(entry.name)
    raise SystemExit("the motor node's process is not to be found")


def cpu_seconds(pid: int) -> float:
    """User and system CPU time of a process, every thread."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def motor_loop(seconds: float, rate: float = RATE, port: int = 7447, protocol: str = "odrive", faults: int = 0,
               tpdo_timeout: int = 25) -> dict:
    """Part 2 (protocol odrive): the motor node fed at `rate`, this process as its six ODrives;
    part 3 (cia402): the same with six CiA 402 drives, the node's tick (a SYNC) at `rate`;
    part 4: then `faults` faults, one axis at a time, each timed to the node's report."""
    import math
    import tempfile
    import threading

    from iotad.can import odrive
    from iotad.can.bit_timing import frame_bits
    from iotad.node_host import wire
    from iotad.node_host.transport import open_tool_session
    from iotad.launcher.processes import interrupt_then_kill

    interface, channel = os.environ["IOTAD_CAN_INTERFACE"], os.environ["IOTAD_CAN_CHANNEL"]
    cia402 = protocol == "cia402"
    joints = ", ".join(f'{{ name = "j{k}", node_id = {k + 1}, position_min = -6.3, position_max = 6.3, '
                       f'protocol = "{protocol}"' + (f", tpdo_timeout = {tpdo_timeout}" if cia402 else "") + " }"
                       for k in range(JOINTS))
    folder = Path(tempfile.mkdtemp(prefix="canbench-"))
    system = folder / "canbench.toml"
    system.write_text(MOTOR_SYSTEM.format(port=port, period=1.0 / rate, joints=joints, interface=interface,
                                          channel=channel, state_period=1.0 / rate if cia402 else 0.01,
                                          polls="{}" if cia402 else "{ Get_Error = 0.1 }",
                                          # velocity every 5th SYNC: 19 frames a cycle would not fit 1 Mbit/s at 500 Hz;
                                          # auto_rearm with a short retry: the faults of part 4 come one after another
                                          extra=(" velocity_every = 5," if cia402 else "")
                                          + " auto_rearm = true, arm_retry = 0.05, rearm_limit = 1000,"))
    # --insecure: this process publishes the setpoints from outside the system, which access
    # control (on by default) would refuse; bench/access_control.py measures what it costs
    # the launcher's own words go to a log, shown if the node does not come up (the bench's
    # output stays the figures), and removed with the folder after a run that worked
    log_path = folder / "launcher.log"
    log = log_path.open("w")
    launcher = subprocess.Popen([str(Path(sys.executable).with_name("iotad")), "run", str(system), "--no-record",
                                 "--plain", "--insecure"], cwd=ROOT, stdout=log, stderr=subprocess.STDOUT,
                                start_new_session=True)
    log.close()
    bus = raw_bus()
    stop = threading.Event()
    frames_seen: list[tuple[float, int, bytes, bool]] = []   # (time, id, data, rtr) of every frame on the bus
    arrivals: dict[tuple[int, int], float] = {}              # (setpoint k, node id) -> Set_Input_Pos time
    syncs: list[float] = []                                  # CiA 402: the node's SYNC times
    reports: list[tuple[float, int, str, str, bool]] = []    # the node's joint_status: (time, joint, event, phase, lost)
    faulted: dict[int, float] = {}                           # ODrive: node -> until when its heartbeat says IDLE + error
    lock = threading.Lock()
    models = {}
    if cia402:
        from iotad.can import canopen as co
        from iotad.can.frame import Frame
        from sim.cia402_drive import Cia402Drive
        models = {node: Cia402Drive(node) for node in range(1, JOINTS + 1)}
    t0 = time.perf_counter()

    # python-can's udp_multicast hands every frame back to its sender, so listen() already sees
    # this process's own frames there; counting them here too would count them twice
    own_frames_come_back = interface == "udp_multicast"

    def send(message):
        bus.send(message)
        if not own_frames_come_back:
            frames_seen.append((time.time(), message.arbitration_id, bytes(message.data), message.is_remote_frame))

    def drain():
        for model in models.values():
            for frame in model.outbox:
                send(frame.to_can_message())
            model.outbox.clear()

    def odrives():
        """Six axes, always in closed loop: heartbeats at 10 Hz, encoder estimates at rate each;
        or six CiA 402 drives' control steps at 100 Hz (their heartbeats; their TPDOs go at SYNC)."""
        beat = odrive.AXIS_STATE["CLOSED_LOOP_CONTROL"]
        start, n = time.perf_counter(), 0
        while cia402 and not stop.is_set():
            with lock:
                for model in models.values():
                    model.update(0.0, 0.0, time.perf_counter() - t0, 0.01)
                drain()
            time.sleep(0.01)
        while not stop.is_set():
            for node in range(1, JOINTS + 1):
                frame = odrive.encode(node, "Get_Encoder_Estimates", Pos_Estimate=0.0, Vel_Estimate=0.0)
                send(frame.to_can_message())
                if n % max(1, int(rate / 10)) == 0:
                    send(odrive_heartbeat(node))
            n += 1
            delay = start + n / rate - time.perf_counter()
            if delay > 0:
                time.sleep(delay)

    def odrive_heartbeat(node):
        if faulted.get(node, 0.0) > time.time():  # part 4: a watchdog error, the axis IDLE
            return odrive.encode(node, "Heartbeat", Axis_Error=odrive.AXIS_ERROR["WATCHDOG_TIMER_EXPIRED"],
                                 Axis_State=odrive.AXIS_STATE["IDLE"], Procedure_Result=0,
                                 Trajectory_Done_Flag=1).to_can_message()
        return odrive.encode(node, "Heartbeat", Axis_Error=0, Axis_State=odrive.AXIS_STATE["CLOSED_LOOP_CONTROL"],
                             Procedure_Result=0, Trajectory_Done_Flag=1).to_can_message()

    def on_status(sample):
        value = wire.decode(bytes(sample.payload))
        if isinstance(value, dict) and "event" in value:
            with lock:
                reports.append((time.time(), value["joint"], value["event"], value["phase"], value["lost"]))

    def listen():
        while not stop.is_set():
            message = bus.recv(timeout=0.1)
            if message is None or message.is_error_frame:
                continue
            frames_seen.append((message.timestamp, message.arbitration_id, bytes(message.data),
                                message.is_remote_frame))
            if cia402:
                ident = message.arbitration_id
                if ident == co.SYNC:
                    syncs.append(message.timestamp)
                elif ident & 0x780 == co.RPDO[0] and len(message.data) == 6:
                    counts = int.from_bytes(bytes(message.data[2:6]), "little", signed=True)
                    k = round(counts / 65536 * 2 * math.pi / SCALE)
                    with lock:
                        arrivals.setdefault((k, ident & 0x7F), message.timestamp)
                if own_frames_come_back and ident & 0x780 in (co.TPDO[0], co.TPDO[1], co.HEARTBEAT, co.EMCY, co.TSDO) \
                        and ident & 0x7F in models:
                    continue  # our own drives' frames, handed back
                with lock:
                    for model in models.values():
                        model.handle(Frame.from_can_message(message), time.perf_counter() - t0)
                    drain()
                continue
            if message.arbitration_id & 0x1F == odrive.MESSAGES["Set_Input_Pos"].cmd_id and not message.is_remote_frame:
                turns = odrive.decode(odrive.Frame.from_can_message(message)).signals["Input_Pos"]
                k = round(turns * 2 * math.pi / SCALE)
                with lock:
                    arrivals.setdefault((k, message.arbitration_id >> 5), message.timestamp)

    def inject_faults(count, publisher, setpoint, k):
        """Part 4: `count` faults, axis 1, 2, ... in turn, each once the previous one is armed again;
        the time from the fault's frame to the node's first report of that axis not ARMED."""
        times = []
        for i in range(count):
            node = i % JOINTS + 1
            with lock:
                mark = len(reports)
            if cia402:
                with lock:
                    models[node].fault(0x2310)  # an over-current: its EMCY goes out now, FAULT at the next SYNC
                    at = time.time()
                    drain()
            else:
                faulted[node] = time.time() + 0.2
                at = time.time()
                send(odrive_heartbeat(node))
            safe = armed = None
            deadline = time.time() + 5.0
            while time.time() < deadline and armed is None:
                publisher.put(setpoint(k), attachment=wire.encode_attachment(k))  # the source goes on
                k += 1
                time.sleep(1.0 / rate)
                with lock:
                    for t, joint, event, phase, lost in reports[mark:]:
                        if joint == node - 1 and safe is None and phase != "ARMED":
                            safe = t
                        if joint == node - 1 and safe is not None and event == "ARM_DONE":
                            armed = t
            if safe is not None:
                times.append(safe - at)
        return times

    threads = [threading.Thread(target=odrives, daemon=True), threading.Thread(target=listen, daemon=True)]
    for thread in threads:
        thread.start()
    session = publisher = None
    published: dict[int, float] = {}
    worked = False
    try:
        session = open_tool_session([f"tcp/127.0.0.1:{port}"], timeout=60.0)
        status_subscriber = session.declare_subscriber("iota/canbench/motor/joint_status/**", on_status)
        publisher = session.declare_publisher("iota/canbench/motor/setpoints")
        deadline = time.monotonic() + 120
        while not publisher.matching_status.matching and time.monotonic() < deadline:
            time.sleep(0.05)
        if not publisher.matching_status.matching:
            raise SystemExit("the motor node did not come up within 120 s")

        def setpoint(k):
            q = (k % WRAP) * SCALE
            return wire.encode({"position": [q] * JOINTS, "velocity_ff": [0.0] * JOINTS, "torque_ff": [0.0] * JOINTS})

        # warm-up: until every axis is armed and gets setpoints (start-up, arming)
        k, warm_end = 0, time.monotonic() + 120
        while time.monotonic() < warm_end:
            publisher.put(setpoint(k), attachment=wire.encode_attachment(k))
            time.sleep(1.0 / rate)
            k += 1
            with lock:
                if len({node for (kk, node) in arrivals if kk == (k - 50) % WRAP}) == JOINTS:
                    break
        else:
            raise SystemExit("the motor node did not arm its six axes within 120 s of warm-up")
        with lock:
            arrivals.clear()
        first, begin = k, time.time()
        syncs.clear()
        node_cpu = cpu_seconds(motor_pid())
        frames_seen.clear()
        start = time.perf_counter()
        late_publish = 0
        n = 0
        while time.perf_counter() - start < seconds:
            published[(first + n) % WRAP] = time.time()
            publisher.put(setpoint(first + n), attachment=wire.encode_attachment(first + n))
            n += 1
            delay = start + n / rate - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
            elif delay < -1.0 / rate:
                late_publish += 1
        end = time.time()
        node_cpu = cpu_seconds(motor_pid()) - node_cpu
        time.sleep(0.5)   # the last frames
        fault_times = inject_faults(faults, publisher, setpoint, first + n)
        worked = True
    finally:
        stop.set()
        for thread in threads:
            thread.join(2)
        if publisher is not None:
            publisher.undeclare()
            status_subscriber.undeclare()
        if session is not None:
            session.close()
        interrupt_then_kill(launcher, 20)
        bus.shutdown()
        if worked:
            shutil.rmtree(folder, ignore_errors=True)
        else:
            tail = log_path.read_text(errors="replace").splitlines()[-25:]
            print(f"the motor node's launcher said (last lines of {log_path}):", *tail, sep="\n  ", file=sys.stderr)
    fault_times = fault_times if worked else []
    latencies, last_frames, spreads, missed, not_armed = [], [], [], 0, 0
    period = 1.0 / rate
    # when each axis was not ARMED by the node's own reports: a setpoint then has no frame by design
    windows, since = [], {}
    for t, joint, event, phase, lost in sorted(reports):
        if phase != "ARMED" and joint not in since:
            since[joint] = t
        elif phase == "ARMED" and joint in since:
            windows.append((since.pop(joint), t))
    windows += [(t, float("inf")) for t in since.values()]
    events = [(joint, event) for t, joint, event, phase, lost in reports if begin <= t <= end and event != "HEARTBEAT"]
    for k, sent in list(published.items()):
        if any(a <= sent <= b + period for a, b in windows):
            not_armed += 1
            del published[k]
            continue
        got = [arrivals.get((k, node)) for node in range(1, JOINTS + 1)]
        if got[0] is not None:
            latencies.append(got[0] - sent)
        if all(t is not None for t in got):
            # the hop to the node (first frame) and the node's own sending (first to last frame)
            last_frames.append(max(got) - sent)
            spreads.append(max(got) - min(got))
        if any(t is None or t - sent > period for t in got):
            missed += 1
    bits = sum(frame_bits(i, False, rtr, data) for t, i, data, rtr in frames_seen if begin <= t <= end)
    span = end - begin
    ticks = [t for t in syncs if begin <= t <= end]
    sync_missed = sum(max(0, round((b - a) / period) - 1) for a, b in zip(ticks, ticks[1:]) if b - a > 1.5 * period)
    return {"setpoint_to_frame": percentiles(latencies) if latencies else None,
            "setpoint_to_last_frame": percentiles(last_frames) if last_frames else None,
            "first_to_last_frame": percentiles(spreads) if spreads else None, "setpoints": len(published),
            "missed": missed, "missed_pct": 100.0 * missed / max(1, len(published)),
            "lost": sum(1 for k in published if arrivals.get((k, 1)) is None), "late_publish": late_publish,
            "frames": sum(1 for t, *_ in frames_seen if begin <= t <= end), "seconds": span,
            "bus_load_pct": 100.0 * bits / (span * 1e6), "node_cpu_pct": 100.0 * node_cpu / span,
            "syncs": len(ticks), "sync_missed": sync_missed,
            "sync_missed_pct": 100.0 * sync_missed / max(1, len(ticks) + sync_missed),
            "not_armed": not_armed, "axis_events": sorted(set(events)),
            "fault_to_safe": percentiles(fault_times) if fault_times else None, "faults": faults,
            "tpdo_timeout": tpdo_timeout if cia402 else None}


def print_axes(figures: dict) -> None:
    """What the node said of its axes during the measured seconds: setpoints it had no armed axis for."""
    events = ", ".join(f"joint {joint} {event}" for joint, event in figures.get("axis_events", [])[:12]) or "none"
    print(f"  setpoints while an axis was not armed (no frame by design, not counted above): {figures['not_armed']}; "
          f"the node's axis events: {events}")


def virtual_arm(seconds: float = 5.0) -> dict:
    """Part 3: examples/arm_can.toml in one process in virtual time."""
    from iotad.kernel.engine import Engine
    from iotad.launcher.system.in_process import compose
    from iotad.launcher.system.system_file import load_system

    engine = Engine(compose(load_system(ROOT / "examples" / "arm_can.toml")))
    try:
        start = time.perf_counter()
        engine.run(until=seconds)
        wall = time.perf_counter() - start
    finally:
        for iota in ("arm_can/odrives",):
            engine.iota(iota).close()
    return {"virtual_s": seconds, "wall_s": wall, "speed": seconds / wall, "events": len(engine.trace)}


BUSY = "while True: pass"  # one core's worth of other work: a robot's vision or planning beside the node


def busy_processes(count: int) -> list[subprocess.Popen]:
    return [subprocess.Popen([sys.executable, "-c", BUSY]) for _ in range(count)]


def stop_all(processes: list[subprocess.Popen]) -> None:
    for process in processes:
        process.kill()
    for process in processes:
        process.wait()


def inside(count: int, seconds: float, rate: float = RATE, faults: int = 20, tpdo_timeout: int = 25,
           busy: int = 0, protocols: tuple[str, ...] = ("odrive", "cia402")) -> None:
    """The measuring side, inside the tier: start the echo peer, measure, stop it."""
    import can

    peer = subprocess.Popen([sys.executable, __file__, "--echo"])
    try:
        wait_for_echo()
        raw_round_trips(min(200, count))  # warm-up
        raw = raw_round_trips(count)
        wrapped = iotad_round_trips(count)
        stop = raw_bus()
        stop.send(can.Message(arbitration_id=STOP_ID, data=b"", is_extended_id=False))
        stop.shutdown()
        peer.wait(timeout=10)
    finally:
        if peer.poll() is None:
            peer.kill()
            peer.wait()
    others = busy_processes(busy)  # beside the motor loops only: the round trips above are the baseline
    try:
        motor = motor_loop(seconds, rate, faults=faults) if seconds > 0 and "odrive" in protocols else None
        cia402 = (motor_loop(seconds, rate, protocol="cia402", faults=faults, tpdo_timeout=tpdo_timeout)
                  if seconds > 0 and "cia402" in protocols else None)
    finally:
        stop_all(others)
    print("RESULT " + json.dumps({"raw": raw, "iotad": wrapped, "motor": motor, "cia402": cia402,
                                  "tier": os.environ.get("IOTAD_CAN_TIER")}))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--count", type=int, default=2000, help="round trips per measurement (2000)")
    parser.add_argument("--seconds", type=float, default=10.0,
                        help="seconds of the 6-joint 500 Hz motor loop (default 10; 0 skips it)")
    parser.add_argument("--rate", type=float, default=RATE,
                        help=f"setpoints and encoder estimates per second and axis (default {RATE:.0f})")
    parser.add_argument("--faults", type=int, default=20, help="part 4: faults per family, timed to the axis marked safe (20)")
    parser.add_argument("--tpdo-timeout", type=int, default=25,
                        help="the CiA 402 joints' TPDO timeout, SYNCs (25: 50 ms at 500 Hz; the node's default is 3)")
    parser.add_argument("--tier", help="vcan | uml | udp_multicast (default: the best here)")
    parser.add_argument("--busy", type=int, default=0,
                        help="processes that each keep a core busy beside the motor loops (0), as a robot's "
                             "vision and planning would")
    parser.add_argument("--protocols", default="odrive,cia402",
                        help="the motor loops to run: odrive, cia402 or both (default odrive,cia402)")
    parser.add_argument("--inside", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--echo", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    unknown = set(args.protocols.split(",")) - {"odrive", "cia402"}
    if unknown:
        parser.error(f"--protocols: unknown {', '.join(sorted(unknown))}; choose odrive, cia402 or both")
    if args.echo:
        echo()
        return 0
    if args.inside:
        inside(args.count, args.seconds, args.rate, args.faults, args.tpdo_timeout, args.busy,
               tuple(args.protocols.split(",")))
        return 0
    from iotad.can.tiers import TierBus

    bus = TierBus(args.tier)
    print(f"CAN tier: {bus.describe()}  (interface {bus.interface}, channel {bus.channel})", flush=True)
    result = bus.run([sys.executable, __file__, "--inside", "--count", str(args.count), "--seconds", str(args.seconds),
                      "--rate", str(args.rate), "--faults", str(args.faults), "--tpdo-timeout", str(args.tpdo_timeout),
                      "--busy", str(args.busy), "--protocols", args.protocols],
                     timeout=600 + args.seconds, cwd=str(ROOT))
    result.check()
    report = json.loads(next(l for l in result.output.splitlines() if l.startswith("RESULT "))[7:])
    raw, wrapped = report["raw"], report["iotad"]
    print(f"{'round trip, two processes':34} {'n':>6} {'p50 us':>9} {'p99 us':>9} {'mean us':>9} {'max us':>9}")
    for name, figures in (("raw python-can (baseline)", raw), ("iotad.can.bus (send/recv_frame)", wrapped)):
        print(f"{name:34} {figures['n']:6d} {figures['p50_us']:9.1f} {figures['p99_us']:9.1f} "
              f"{figures['mean_us']:9.1f} {figures['max_us']:9.1f}")
    print(f"iotad.can.bus / raw: p50 x{wrapped['p50_us'] / raw['p50_us']:.2f}, "
          f"p99 x{wrapped['p99_us'] / raw['p99_us']:.2f}   (run took {result.seconds:.1f} s, tier {bus.name})")
    if args.busy:
        print(f"\nbeside the motor loops: {args.busy} busy process(es), each spinning on a core "
              f"(this machine has {os.cpu_count()} cores)")
    motor = report["motor"]
    if motor:
        print(f"\nmotor node, {JOINTS} joints at {args.rate:g} Hz for {motor['seconds']:.1f} s "
              f"(setpoints over zenoh, this process as the ODrives), tier {bus.name}:")
        hop = motor["setpoint_to_frame"]
        if hop:
            print(f"  setpoint published -> Set_Input_Pos on the bus: p50 {hop['p50_us'] / 1000:.3f} ms, "
                  f"p99 {hop['p99_us'] / 1000:.3f} ms, max {hop['max_us'] / 1000:.1f} ms "
                  f"(x{hop['p50_us'] / raw['p50_us']:.1f} / x{hop['p99_us'] / raw['p99_us']:.1f} the raw round trip)")
        last, spread = motor.get("setpoint_to_last_frame"), motor.get("first_to_last_frame")
        if last and spread:
            print(f"  ... to the last of its {JOINTS} frames: p50 {last['p50_us'] / 1000:.3f} ms, "
                  f"p99 {last['p99_us'] / 1000:.3f} ms; first to last frame: p50 {spread['p50_us'] / 1000:.3f} ms, "
                  f"p99 {spread['p99_us'] / 1000:.3f} ms (the node's own sending)")
        print(f"  control cycles missed: {motor['missed']} of {motor['setpoints']} = {motor['missed_pct']:.2f} % "
              f"(a setpoint whose {JOINTS} frames were not all on the bus within a cycle, {1000 / args.rate:g} ms; {motor['lost']} never came; "
              f"{motor['late_publish']} published more than a cycle late)")
        print(f"  bus load: {motor['bus_load_pct']:.1f} % of 1 Mbit/s ({motor['frames']} frames, "
              f"{motor['frames'] / motor['seconds']:.0f} frames/s)")
        print(f"  motor node CPU: {motor['node_cpu_pct']:.0f} % of one core (every thread of its process)")
        print_axes(motor)
    co = report.get("cia402")
    if co:
        print(f"\nmotor node, {JOINTS} CiA 402 joints, SYNC and setpoints at {args.rate:g} Hz for {co['seconds']:.1f} s "
              f"(this process as the drives), tier {bus.name}:")
        hop = co["setpoint_to_frame"]
        if hop:
            print(f"  setpoint published -> RPDO on the bus: p50 {hop['p50_us'] / 1000:.3f} ms, "
                  f"p99 {hop['p99_us'] / 1000:.3f} ms, max {hop['max_us'] / 1000:.1f} ms "
                  f"(beside the ODrive's Set_Input_Pos above)")
        print(f"  SYNC cycles missed: {co['sync_missed']} of {co['syncs'] + co['sync_missed']} = "
              f"{co['sync_missed_pct']:.2f} %; control cycles missed: {co['missed']} of {co['setpoints']} = "
              f"{co['missed_pct']:.2f} % ({co['lost']} never came)")
        print(f"  bus load: {co['bus_load_pct']:.1f} % of 1 Mbit/s ({co['frames']} frames, "
              f"{co['frames'] / co['seconds']:.0f} frames/s); motor node CPU: {co['node_cpu_pct']:.0f} % of one core")
        print(f"  TPDO timeout of the joints: {co['tpdo_timeout']} SYNCs")
        print_axes(co)
    for name, figures in (("ODrive", motor), ("CiA 402", co)):
        timed = figures and figures.get("fault_to_safe")
        if timed:
            print(f"\nfault to safe, {name}: {timed['n']} of {figures['faults']} faults: the drive's fault frame -> the "
                  f"node's report of the axis not ARMED: p50 {timed['p50_us'] / 1000:.2f} ms, max {timed['max_us'] / 1000:.2f} ms")
    arm = virtual_arm()
    print(f"\nexamples/arm_can.toml in virtual time, one process (this host, no tier): {arm['virtual_s']:.0f} s "
          f"in {arm['wall_s']:.2f} s wall = {arm['speed']:.1f}x real time ({arm['events']} trace events)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
