"""The files of a robot `iotad new` makes, from its plan: `robot.toml` (the system: behaviours,
the program scheduler, the MDL interpreter, the CAN motor node and simulated drives on a URDF
world), `robot.urdf`, `behaviours.py`, `test_robot.py` and a `README.md`."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

from iotad.kernel.package_files import is_package_ref

from .robot_plan import SHIPPED, BehaviourPlan, JointPlan, RobotPlan, urdf_path

TEMPLATES = Path(__file__).resolve().parent / "templates"
RUN_SECONDS = 12  # virtual seconds the robot's own tests run: every behaviour has had the motors by then


class FolderTaken(Exception):
    """The robot's folder exists and is not empty."""


def write_robot(plan: RobotPlan, where: Path) -> Path:
    """Write the robot's folder `where / plan.name` (which must not hold anything); its path."""
    folder = where / plan.name
    if folder.exists() and (not folder.is_dir() or any(folder.iterdir())):
        raise FolderTaken(f"{folder}: exists and is not empty; choose another name or folder")
    folder.mkdir(parents=True, exist_ok=True)
    urdf = "robot.urdf"
    if plan.urdf is None:
        (folder / urdf).write_text(chain_urdf(plan.name, plan.joints))
    elif meshes_of(urdf_path(plan.urdf)):
        # its meshes lie beside it: the robot names the URDF where it is, not a copy without them
        urdf = SHIPPED.get(plan.urdf) or (plan.urdf if is_package_ref(plan.urdf) else str(urdf_path(plan.urdf)))
    else:
        shutil.copyfile(urdf_path(plan.urdf), folder / urdf)
    (folder / "robot.toml").write_text(system_file(plan, urdf))
    (folder / "behaviours.py").write_text((TEMPLATES / "behaviours.py.tmpl").read_text())
    (folder / "test_robot.py").write_text(test_file(plan))
    (folder / "README.md").write_text(readme(plan))
    return folder


# ---------------------------------------------------------------------------- robot.toml

def meshes_of(path: Path) -> list[str]:
    """The mesh files a URDF names (relative to it, or package://): a copy elsewhere would lose them."""
    import re

    return re.findall(r'<mesh[^>]*filename="([^"]+)"', path.read_text(errors="replace"))


def system_file(plan: RobotPlan, urdf: str = "robot.urdf") -> str:
    joints, family = plan.joints, plan.family
    names = [j.name for j in joints]
    n = len(plan.behaviours)
    lines = [
        f"# {plan.name}: a robot made by `iotad new` (README.md says what is here and how to change it).",
        "#",
        "#   iotad run robot.toml --virtual --until 12 -o run.mcap     # one process, virtual time",
        "#   iotad check run.mcap                                     # every node kept to its spec",
        "#   iotad export --json run.mcap -o run-foxglove.mcap       # open it in Foxglove: the robot in 3D",
        "#   python -m iotad.can.tiers run -- iotad run robot.toml --until 12 --after-live -o rt.mcap",
        "#   IOTAD_CAN_INTERFACE=socketcan IOTAD_CAN_CHANNEL=can0 iotad run robot.toml --view   # live, in Foxglove",
        "",
        "[system]",
        f'name = "{plan.system_name}"',
        "time_unit = 1.0",
        "start_timeout = 60.0     # s a node may take to go live (PyBullet and imports on a busy machine)",
        "heartbeat_timeout = 10.0",
        "# fed from outside (iotad pub): the paper's mode and the interpreter's sensors, the motors' estop",
        'external = ["mdl.mode_command", "mdl.sensor[0]", "mdl.sensor[1]", "mdl.sensor[2]", "motor.estop"]',
        "",
        "[system.endpoints]",
        'listen = ["tcp/127.0.0.1:7447"]',
        "",
        "[[node]]",
        'name = "scheduler"',
        'spec = "nodes.scheduler:program_scheduler.iota"   # Figure 2 carrying MDL programs',
        f"params = {{ N = {n}, T = 0.5 }}",
        "",
    ]
    for k, behaviour in enumerate(plan.behaviours):
        lines += behaviour_node(behaviour, k, joints)
    lower = ", ".join(_num(j.lower) for j in joints)
    upper = ", ".join(_num(j.upper) for j in joints)
    lines += [
        "[[node]]",
        'name = "mdl"',
        'python = "nodes.mdl_interp:mdl_interpreter"',
        f"params = {{ rate = 250.0, joints = [{', '.join(_q(x) for x in names)}], lower = [{lower}], "
        f"upper = [{upper}], max_velocity = 2.0 }}",
        "",
        "[[node]]",
        'name = "motor"',
        'python = "nodes.can_motor:CanMotor"',
        'after = ["drives"]',
        "",
        "[node.params]",
        "encoder_period = 0.01",
        "polls = {}",
        "auto_rearm = true",
        "",
    ]
    for joint in joints:
        lines += ["[[node.params.joints]]", f"name = {_q(joint.name)}"]
        if family == "cia402":
            lines.append('protocol = "cia402"')
        lines += [f"node_id = {joint.node_id}", f"position_min = {_num(joint.lower)}",
                  f"position_max = {_num(joint.upper)}", "velocity_limit = 3.0", "current_limit = 10.0",
                  'out_of_range = "clamp"', ""]
    ids = ", ".join(f"{_key(j.name)} = {j.node_id}" for j in joints)
    world = f'world = "urdf", world_options = {{ urdf = {_q(urdf)} }}'
    if family == "odrive":
        lines += ["[[node]]", 'name = "drives"', 'python = "sim.odrive_sim:SimulatedOdrives"',
                  f"params = {{ {world}, node_ids = {{ {ids} }} }}", ""]
    else:
        lines += ["[[node]]", 'name = "drives"', 'python = "sim.cia402_sim:SimulatedCia402Drives"',
                  f"params = {{ {world}, cia402 = {{ {ids} }} }}", ""]
    lines += [
        "[[can]]",
        'name = "can0"',
        'interface = "env"     # the CAN tier\'s bus, or IOTAD_CAN_INTERFACE/IOTAD_CAN_CHANNEL (docs/can.md)',
        'stations = ["motor", "drives"]',
        "",
    ]
    binds = []
    for k, behaviour in enumerate(plan.behaviours):
        binds += [(f"{behaviour.name}.req", f"scheduler.req[{k}]"), (f"scheduler.ack[{k}]", f"{behaviour.name}.ack"),
                  ("mdl.program_end", f"{behaviour.name}.program_end")]
    binds += [("scheduler.mdl_command", "mdl.mdl_command"), ("mdl.setpoints", "motor.setpoints"),
              ("motor.joint_states", "mdl.joint_states")]
    for source, target in binds:
        lines += ["[[bind]]", f"from = {_q(source)}", f"to = {_q(target)}", ""]
    return "\n".join(lines)


def behaviour_node(behaviour: BehaviourPlan, k: int, joints: list[JointPlan]) -> list[str]:
    """A behaviour's node: the first sweeps every joint between a quarter and three quarters of
    its range, again and again; each other one glances: its first joint (then the next...) to the
    far end of its range and back, a few times, starting later."""
    lines = ["[[node]]", f"name = {_q(behaviour.name)}", 'python = "behaviours.py:Behaviour"', 'after = ["scheduler"]',
             "", "[node.params]", f"priority = {behaviour.priority}"]
    if k == 0:
        lines += ["epoch = 2.0", "timeout = 20.0", "start = 0.5", "pause = 0.2", "repeat = true"]
        poses = [{j.name: _at(j, 0.25) for j in joints}, {j.name: _at(j, 0.75) for j in joints}]
        atoms = [("minimum_jerk", pose, 1.5) for pose in poses]
    else:
        joint = joints[(k - 1) % len(joints)]
        lines += ["epoch = 0.8", "timeout = 6.0", f"start = {_num(1.5 * k)}", "pause = 3.0", "count = 3"]
        atoms = [("minimum_jerk", {joint.name: _at(joint, 0.9 if k % 2 else 0.1)}, 0.6),
                 ("hold", {}, 0.3)]
    lines += ["", "[node.params.program]", f"id = {_q(behaviour.name)}", "",
              "[[node.params.program.behaviours]]", f"name = {_q(behaviour.name)}", ""]
    for kind, target, seconds in atoms:
        lines.append("[[node.params.program.behaviours.atoms]]")
        if target:
            pose = ", ".join(f"{_key(name)} = {_num(value)}" for name, value in target.items())
            lines.append(f'u = {{ kind = "{kind}", target = {{ {pose} }} }}')
        else:
            lines.append(f'u = {{ kind = "{kind}" }}')
        lines += [f"T = {_num(seconds)}", ""]
    return lines


def _at(joint: JointPlan, fraction: float) -> float:
    return round(joint.lower + fraction * (joint.upper - joint.lower), 4)


def _num(value: float) -> str:
    text = repr(float(value))
    return text[:-2] if text.endswith(".0") and "e" not in text else text


def _key(name: str) -> str:
    """A TOML key: bare where it can be (a URDF's joint names may hold dots or spaces)."""
    import re

    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else _q(name)


def _q(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


# ---------------------------------------------------------------------------- robot.urdf

def chain_urdf(name: str, joints: list[JointPlan]) -> str:
    """A serial chain for the joints: a base, then one link per joint, the joints turning about
    z and y in turn; plain boxes, light enough for small drives, so any URDF viewer draws it."""
    parts = [f'<?xml version="1.0"?>\n<!-- {name}: a chain of {len(joints)} joints made by `iotad new`; '
             "replace it with your robot's URDF (same joint names) -->", f'<robot name="{name}">',
             _link("base", (0.12, 0.12, 0.04), (0, 0, 0.02), 1.0)]
    parent = "base"
    for k, joint in enumerate(joints):
        child = f"{joint.name}_link"
        parts.append(_link(child, (0.04, 0.04, 0.12), (0, 0, 0.06), 0.2))
        axis = "0 0 1" if k % 2 == 0 else "0 1 0"
        z = 0.04 if k == 0 else 0.12
        parts.append(f'  <joint name="{joint.name}" type="revolute">\n    <parent link="{parent}"/><child link="{child}"/>\n'
                     f'    <origin xyz="0 0 {z}"/><axis xyz="{axis}"/>\n'
                     f'    <limit lower="{_num(joint.lower)}" upper="{_num(joint.upper)}" effort="5" velocity="4"/>\n  </joint>')
        parent = child
    parts.append("</robot>\n")
    return "\n".join(parts)


def _link(name: str, size: tuple, xyz: tuple, mass: float) -> str:
    sx, sy, sz = size
    ixx, iyy, izz = (mass * (sy * sy + sz * sz) / 12, mass * (sx * sx + sz * sz) / 12, mass * (sx * sx + sy * sy) / 12)
    box = f'<geometry><box size="{sx} {sy} {sz}"/></geometry><origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}"/>'
    return (f'  <link name="{name}">\n    <visual>{box}</visual>\n    <collision>{box}</collision>\n'
            f'    <inertial><mass value="{mass}"/><origin xyz="{xyz[0]} {xyz[1]} {xyz[2]}"/>\n'
            f'      <inertia ixx="{ixx:.3g}" ixy="0" ixz="0" iyy="{iyy:.3g}" iyz="0" izz="{izz:.3g}"/></inertial>\n  </link>')


# ---------------------------------------------------------------------------- tests and README

def test_file(plan: RobotPlan) -> str:
    text = (TEMPLATES / "test_robot.py.tmpl").read_text()
    return (text.replace("__JOINTS__", repr([j.name for j in plan.joints]))
            .replace("__BEHAVIOURS__", repr([b.name for b in plan.behaviours]))
            .replace("__SECONDS__", str(RUN_SECONDS)).replace("__SYSTEM__", plan.system_name))


def readme(plan: RobotPlan) -> str:
    family = "simulated ODrives (CAN Simple)" if plan.family == "odrive" else "simulated CiA 402 drives (CANopen)"
    joints = "\n".join(f"| `{j.name}` | {_num(j.lower)} .. {_num(j.upper)} rad | {j.node_id} |" for j in plan.joints)
    behaviours = "\n".join(f"| `{b.name}` | {b.priority} |" for b in plan.behaviours)
    source = ("a chain made for its joints" if plan.urdf is None else
              f"the shipped `{plan.urdf}`" if "/" not in plan.urdf and not plan.urdf.endswith(".urdf")
              else f"a copy of `{plan.urdf}`")
    return f"""# {plan.name}

A robot made by `iotad new`: {len(plan.joints)} joints on {family} on one CAN bus, driving the
URDF `robot.urdf` ({source}) in PyBullet; {len(plan.behaviours)} behaviour(s) asking the program
scheduler for the motors with MDL programs; the MDL interpreter turning the winner's program into
setpoints; the CAN motor node turning setpoints into CAN frames.

| joint | range | CAN node id |
|---|---|---|
{joints}

| behaviour | priority (the higher wins) |
|---|---|
{behaviours}

## Run it

```sh
iotad run robot.toml --check                                   # the wiring, before anything runs
iotad run robot.toml --virtual --until 12 -o run.mcap          # one process, virtual time
iotad check run.mcap                                           # every node kept to its spec
iotad cat run.mcap 'iota/{plan.system_name}/scheduler/ack/*'   # who got the motors, when
iotad export --json run.mcap -o run-foxglove.mcap               # open it in Foxglove: the robot in 3D
python -m iotad.can.tiers run -- iotad run robot.toml --until 12 --after-live -o rt.mcap   # real time, a CAN bus
pytest test_robot.py                                           # its tests: extend them as it grows
```

`--strict` (or `strict = true` in `[system]`) makes any violation, exception or node that never
went live fail the run. In real time every node is a process and the bus is the CAN tier's
(`interface = "env"`); on a machine with a CAN card (or a vcan0 of its own),
`IOTAD_CAN_INTERFACE=socketcan IOTAD_CAN_CHANNEL=can0 iotad run robot.toml --view` runs it and
serves it live to Foxglove (`iotad view`, ws://127.0.0.1:8765). A run inside a CAN tier is in a
private network namespace: watch it from there (docs/first-robot.md, "Watching inside a CAN tier").

## Change it

- **Behaviours** are `behaviours.py:Behaviour` nodes in `robot.toml`: change a behaviour's
  `priority`, its times, or its MDL `program` (docs/mdl.md: atoms `u` with targets by joint
  name, `T`, interrupts `xi`); add one with a `[[node]]`, a `scheduler.req[k]`/`ack[k]` pair of
  `[[bind]]`s and `N` one more on the scheduler.
- **Joints** are named alike in `robot.urdf`, the motor node's joint map (`[[node.params.joints]]`)
  and the drives' node ids: rename them in all three. A joint on a CAN node id no drive serves is
  refused by `iotad run --check`.
- **Your robot's URDF**: replace `robot.urdf` (its movable joints by name are what the drives
  drive and what `iotad view` and `iotad export` show).
- **Real drives**: remove the `drives` node and its station, and run on the drives' bus.
"""
