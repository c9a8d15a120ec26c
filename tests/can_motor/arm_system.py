"""The xArm6 through CAN in one process in virtual time, for the CAN motor node's closed-loop tests:
a trajectory source -> CanMotor -> CanBus -> SimulatedOdrives (PyBullet) and back."""
from __future__ import annotations

import math

from channels.joints import joint_setpoints, joint_states
from iotad.can.virtual_bus import CanBus
from iotad.kernel.api import Input, Iota, Output, Param
from iotad.kernel.compose import Composite
from nodes.can_motor import CanMotor
from sim.odrive_sim import SimulatedOdrives

# The xArm6's joints as its URDF gives them: limits (rad), speed 3.14 rad/s, effort (Nm; the
# simulated axes' torque constant is 1 Nm/A, so Current_Limit in A is the torque limit).
LOWER = (-6.283, -2.059, -3.927, -6.283, -1.693, -6.283)
UPPER = (6.283, 2.094, 0.192, 6.283, 3.142, 6.283)
EFFORT = (50.0, 50.0, 32.0, 32.0, 32.0, 20.0)
XARM6_JOINTS = [{"name": f"joint{k + 1}", "node_id": k + 1, "position_min": LOWER[k], "position_max": UPPER[k],
                 "velocity_limit": 3.14, "current_limit": EFFORT[k], "out_of_range": "clamp"} for k in range(6)]
HOME = (0.0, -0.3, -1.0, 0.0, 1.3, 0.0)


class Trajectory(Iota):
    """Streams setpoints every `period`: the first measured position until `start` (relative to the
    first joint state), then a cosine blend to `target` over `duration`, then `target`."""

    target = Param([0.0] * 6)
    start = Param(0.3)
    duration = Param(2.0)
    period = Param(0.004)
    silent_after = Param(math.inf)

    joint_states = Input(joint_states(6), switching=0)
    setpoints = Output(joint_setpoints(6), switching=0)

    def init(self):
        self.origin = None
        self.k = 0

    @joint_states.input
    def measured(self, value):
        if self.origin is None:
            self.origin = list(value.position)

    @setpoints.action(value=lambda self: self._setpoint(), when=lambda self: self.origin is not None and self.k * self.period < self.silent_after,
                      after="period")
    def sent(self):
        self.k += 1

    def _setpoint(self):
        s = min(max((self.k * self.period - self.start) / self.duration, 0.0), 1.0)
        blend, rate = (1 - math.cos(math.pi * s)) / 2, math.pi / (2 * self.duration) * math.sin(math.pi * s)
        span = [b - a for a, b in zip(self.origin, self.target)]
        return joint_setpoints(6)(position=[a + d * blend for a, d in zip(self.origin, span)],
                                  velocity_ff=[d * rate for d in span], torque_ff=[0.0] * 6)


def arm_system(target, *, motor_params=None, odrive_params=None, **trajectory) -> Composite:
    """trajectory -> motor -> bus station 0; odrives on station 1; joint states back to the source."""
    return Composite(
        "arm",
        Trajectory("trajectory", target=list(target), **trajectory),
        CanMotor("motor", joints=XARM6_JOINTS, **(motor_params or {})),
        CanBus("bus", stations=2),
        SimulatedOdrives("odrives", world="arm", node_ids={f"joint{k}": k for k in range(1, 7)},
                         **(odrive_params or {})),
        bind=[("trajectory.setpoints", "motor.setpoints"), ("motor.joint_states", "trajectory.joint_states"),
              ("motor.can_tx", "bus.tx[0]"), ("bus.rx[0]", "motor.can_rx"),
              ("odrives.can_tx", "bus.tx[1]"), ("bus.rx[1]", "odrives.can_rx")])


def system_toml(target, *, name="arm_can", start=0.3, duration=1.0, polls="{ Get_Error = 0.1, Get_Torques = 0.05 }",
                trajectory_python=None) -> str:
    """The same arm as a system file (what `iotad run --virtual` and `iotad replay` take): the
    joint map as nested TOML tables, a [[can]] bus with the motor and the simulated ODrives."""
    import textwrap
    from pathlib import Path

    python = trajectory_python or f"{Path(__file__).resolve()}:Trajectory"
    joints = "".join(textwrap.dedent(f'''
        [[node.params.joints]]
        name = "joint{k}"
        node_id = {k}
        velocity_limit = 3.14
        current_limit = {effort}
        out_of_range = "clamp"
        ''') for k, effort in zip(range(1, 7), EFFORT))
    return textwrap.dedent(f'''
        [system]
        name = "{name}"
        external = ["motor.estop"]

        [[node]]
        name = "trajectory"
        python = "{python}"
        params = {{ target = {list(target)}, start = {start}, duration = {duration} }}

        [[node]]
        name = "motor"
        python = "nodes.can_motor:CanMotor"

        [node.params]
        polls = {polls}
        ''') + joints + textwrap.dedent('''
        [[node]]
        name = "odrives"
        python = "sim.odrive_sim:SimulatedOdrives"
        params = { world = "arm", node_ids = { joint1 = 1, joint2 = 2, joint3 = 3, joint4 = 4, joint5 = 5, joint6 = 6 } }

        [[can]]
        name = "can0"
        interface = "socketcan"
        channel = "vcan0"
        stations = ["motor", "odrives"]

        [[bind]]
        from = "trajectory.setpoints"
        to = "motor.setpoints"

        [[bind]]
        from = "motor.joint_states"
        to = "trajectory.joint_states"
        ''')
