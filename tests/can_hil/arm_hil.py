"""Helpers of the hardware-in-the-loop tests of examples/arm_can.toml: a variant of the system
file, the driver that runs it (and kills its motor node) inside a CAN tier, and readers of what
the recording says about the simulated axes."""
from __future__ import annotations

import re
from pathlib import Path

from iotad.can import odrive
from iotad.can.frame import Frame, FrameError

ROOT = Path(__file__).resolve().parents[2]
EXAMPLE = ROOT / "examples" / "arm_can.toml"
WAYPOINTS = ([0.5, 0.1, -0.8, 0.4, 1.0, 0.5], [-0.3, -0.2, -1.1, -0.3, 1.4, -0.4])
FINAL = WAYPOINTS[-1]
IDLE = odrive.AXIS_STATE["IDLE"]
CLOSED_LOOP = odrive.AXIS_STATE["CLOSED_LOOP_CONTROL"]
WATCHDOG = odrive.AXIS_ERROR["WATCHDOG_TIMER_EXPIRED"]
COMMANDS = {"Set_Input_Pos", "Set_Input_Vel", "Set_Input_Torque", "Set_Axis_State", "Clear_Errors",
            "Set_Controller_Mode", "Set_Limits"}


def mixed_canopen_system(folder: Path) -> Path:
    """examples/arm_canopen.toml on a mixed bus, written into `folder`: joints 1-3 on simulated
    ODrives (node ids 1..3), joints 4-6 on CiA 402 drives (4..6), behind the same motor node."""
    text = (ROOT / "examples" / "arm_canopen.toml").read_text()
    text = text.replace('python = "arm_trajectory.py:', f'python = "{ROOT / "examples" / "arm_trajectory.py"}:')
    text = text.replace("cia402 = { joint1 = 1, joint2 = 2, joint3 = 3, joint4 = 4, joint5 = 5, joint6 = 6 }",
                        "cia402 = { joint4 = 4, joint5 = 5, joint6 = 6 }, node_ids = { joint1 = 1, joint2 = 2, joint3 = 3 }, "
                        "encoder_period = 0.02, watchdog_timeout = 0.08")
    for node in (1, 2, 3):
        text = text.replace(f'protocol = "cia402"\nnode_id = {node}\n', f'protocol = "odrive"\nnode_id = {node}\n')
    system = folder / "mixed.toml"
    system.write_text(text)
    return system


def system_variant(folder: Path, *, segment: float | None = None, odrives: dict | None = None,
                   motor: dict | None = None, port: int | None = None, bus: tuple[str, str] | None = None,
                   backoff: float | None = None) -> Path:
    """examples/arm_can.toml with other leg times and odrives and motor params (key -> TOML
    value text, replacing or adding), another bus (interface, channel: what a tier gives) and
    another wait before the motor node's restart (`backoff`, seconds), written into `folder`;
    the trajectory's file stays where it is."""
    text = EXAMPLE.read_text()
    text = text.replace('python = "arm_trajectory.py:', f'python = "{ROOT / "examples" / "arm_trajectory.py"}:')
    if segment is not None:
        text, n = re.subn(r"segment = [0-9.]+", f"segment = {segment}", text)
        assert n == 1
    head, _, rest = text.partition('params = { world = "arm", ')
    line, _, rest = rest.partition("\n")
    for key, value in (odrives or {}).items():
        line, n = re.subn(rf"\b{key} = [^,]+", f"{key} = {value}", line)
        line = line if n else f"{key} = {value}, {line}"
    text = f'{head}params = {{ world = "arm", {line}\n{rest}'
    head, _, rest = text.partition("[node.params]\n")
    block, _, rest = rest.partition("[[node.params.joints]]")
    for key, value in (motor or {}).items():
        block, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {value}", block)
        block = block if n else f"{key} = {value}\n{block}"
    text = f"{head}[node.params]\n{block}[[node.params.joints]]{rest}"
    if bus is not None:
        text, n = re.subn(r'(?m)^interface = "[^"]*"[^\n]*\n(channel = "[^"]*"\n)?',
                          f'interface = "{bus[0]}"\nchannel = "{bus[1]}"\n', text)
        assert n == 1
    if port is not None:
        text = text.replace("tcp/127.0.0.1:7447", f"tcp/127.0.0.1:{port}")
    if backoff is not None:
        text, n = re.subn(r"(?m)^backoff = [0-9.]+$", f"backoff = {backoff}", text)
        assert n == 1
    path = folder / "arm_can.toml"
    path.write_text(text)
    return path


def frames(trace: list[dict], node: str, action: str) -> list[tuple[float, Frame, object]]:
    """(t, frame, decoded message or None) of a node's can_tx outputs or can_rx inputs."""
    out = []
    for event in trace:
        if event.get("node") != node or event.get("action") != action or event.get("kind") not in ("input", "output"):
            continue
        try:
            frame = Frame.from_value(event["value"])
        except FrameError:
            continue
        try:
            message = odrive.decode(frame)
        except (odrive.UnknownFrame, FrameError):
            message = None
        out.append((float(event["t"]), frame, message))
    return out


def final_positions(trace: list[dict]) -> list[float]:
    states = [e for e in trace if e.get("node") == "motor" and e.get("action") == "joint_states"
              and e.get("kind") == "output"]
    return list(states[-1]["value"]["position"])


def settled_positions(trace: list[dict], since: float, settle: float = 2.0) -> tuple[float, list[float]] | None:
    """The motor node's last joint state after `since` at which every joint had been ARMED for
    `settle` s (by its joint_status events), with its time; None if there is none. In real time a
    stalled motor node (a busy one-vCPU user-mode kernel) can trip the axes' watchdogs at any
    moment; the node re-arms them, and the arm is judged where it stood once armed again."""
    armed_since: dict[int, float | None] = {}
    found = None
    for e in trace:
        if e.get("node") != "motor" or e.get("kind") != "output":
            continue
        t = float(e["t"])
        if e.get("action") == "joint_status":
            joint, armed = e["value"]["joint"], e["value"]["phase"] == "ARMED"
            if not armed:
                armed_since[joint] = None
            elif armed_since.get(joint) is None:
                armed_since[joint] = t
        elif e.get("action") == "joint_states" and t >= since:
            starts = [armed_since.get(j) for j in range(len(e["value"]["position"]))]
            if all(s is not None and t - s >= settle for s in starts):
                found = (t, list(e["value"]["position"]))
    return found


def motor_starts(recording) -> list[float]:
    """When each life of the motor node's engine started (its `start` records)."""
    return [float(e["t"]) for e in recording.trace("motor", starts=True) if e.get("kind") == "start"]


def odrives_log(trace: list[dict]) -> list[tuple[float, str, object, int]]:
    """The simulated axes' frames in the order their engine handled them: (t, "rx" | "tx", decoded
    message or None, steps taken before it). The step count is the axes' own clock: the firmware's
    watchdog counts it, and in real time a busy machine makes it lag the wall clock."""
    out, steps = [], 0
    for event in trace:
        if event.get("node") != "odrives":
            continue
        action = event.get("action")
        if action == "step" and event.get("kind") == "internal":
            steps += 1
        elif action in ("can_rx", "can_tx") and event.get("kind") in ("input", "output"):
            try:
                message = odrive.decode(Frame.from_value(event["value"]))
            except FrameError:
                message = None
            out.append((float(event["t"]), action[4:], message, steps))
    return out


def after_the_kill(recording, step_period: float) -> dict:
    """What the simulated axes recorded between the motor's death and its restart, per node id:
    the last command each received; `idle`, when its heartbeats began to say IDLE with a watchdog
    error for good (until the restart); `sim_delay`, the axis's own time (steps times
    `step_period`) from that last command to that heartbeat; `sim_not_yet`, the same to the
    heartbeat before it, which did not say so yet (the trip lies between the two); `held`, the
    encoder positions (turns) from that heartbeat to the restart, each with the axis's own time (s)
    since the heartbeat; what came after the restart."""
    restart = motor_starts(recording)[1]
    log = odrives_log(recording.trace())
    axes = {}
    for node in range(1, 7):
        mine = [(t, way, m, steps) for t, way, m, steps in log if m is not None and m.node_id == node]
        restarted = next(k for k, (t, way, m, _) in enumerate(mine) if way == "rx" and t >= restart)
        last = max(k for k, (t, way, m, _) in enumerate(mine[:restarted]) if way == "rx" and m.name in COMMANDS)
        beats = [k for k, (t, way, m, _) in enumerate(mine[:restarted]) if way == "tx" and m.name == "Heartbeat"]
        idle = armed = None
        for k in reversed(beats):  # back from the restart while the axis says IDLE + watchdog
            signals = mine[k][2].signals
            if signals["Axis_State"] != IDLE or not signals["Axis_Error"] & WATCHDOG:
                armed = k
                break
            idle = k

        def sim_time(k):
            return max(0.0, step_period * (mine[k][3] - mine[last][3]))

        after = mine[restarted:]
        axes[node] = {"last_command": mine[last][0], "idle": None if idle is None else mine[idle][0],
                      "sim_delay": None if idle is None else sim_time(idle),
                      "sim_not_yet": None if armed is None else sim_time(armed),
                      "held": [(step_period * (steps - mine[idle][3]), m.signals["Pos_Estimate"])
                               for t, way, m, steps in mine[idle or restarted:restarted]
                               if m.name == "Get_Encoder_Estimates"],
                      "first_again": [m.name for t, way, m, _ in after if way == "rx"][:5],
                      "beats_after": [m.signals for t, way, m, _ in after if m.name == "Heartbeat"],
                      "positions_after": [m.signals["Pos_Estimate"] for t, way, m, _ in after
                                          if m.name == "Get_Encoder_Estimates"]}
    return {"restart": restart, "axes": axes}
