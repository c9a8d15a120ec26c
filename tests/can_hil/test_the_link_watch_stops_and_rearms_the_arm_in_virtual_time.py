"""The motor node's link watch on the whole arm in one process in virtual time, for both drive
families (examples/arm_can.toml's ODrives, examples/arm_canopen.toml's CiA 402 drives): the
trajectory's setpoints stop reaching the motor node for a second mid-motion (a partition between
their hosts) with `link_timeout` 0.06 s. Every drive is stopped (ODrive: IDLE; CiA 402: quick
stop, out of OPERATION ENABLED) within link_timeout and a tick of the last setpoint, stays so while
the setpoints are missing, and is enabled again after they return, the arm then following the
trajectory to its last waypoint."""
import pytest

pytest.importorskip("pybullet")

from arm_hil import ROOT  # noqa: E402
from arm_trajectory import ArmTrajectory  # noqa: E402
from channels.joints import joint_setpoints  # noqa: E402
from iotad.can.virtual_bus import CanBus  # noqa: E402
from iotad.kernel.api import Input, Internal, Iota, Output, Param  # noqa: E402
from iotad.kernel.compose import Composite  # noqa: E402
from iotad.kernel.engine import Engine  # noqa: E402
from iotad.launcher.system.system_file import load_system  # noqa: E402
from nodes.can_motor import CanMotor  # noqa: E402

CUT, HEAL, END = 1.2, 2.2, 6.0  # s; the trajectory's last leg ends at 3.5


class Gap(Iota):
    """The network between the trajectory's host and the motor's: setpoints pass, except from
    `cut` until `heal` (s after the start), when they are lost."""

    cut = Param(1.0)
    heal = Param(2.0)
    inp = Input(joint_setpoints(6), switching=0)
    out = Output(joint_setpoints(6), switching=0)
    down = Internal()
    up = Internal()

    def init(self):
        self.open, self.queue, self.cuts = True, [], 0

    @inp.input
    def got(self, value):
        if self.open:
            self.queue.append(value)

    @out.action(value=lambda self: self.queue[0], when=lambda self: bool(self.queue))
    def passed(self):
        self.queue.pop(0)

    @down.action(after="cut", when=lambda self: self.cuts == 0)
    def went_down(self):
        self.open, self.queue, self.cuts = False, [], 1

    @up.action(after=lambda self: self.heal - self.cut, when=lambda self: not self.open)
    def came_up(self):
        self.open = True


def nodes(example: str) -> dict:
    return {node.name: (node.source["ref"], dict(node.params)) for node in load_system(ROOT / "examples" / example).nodes.values()}


def run(example: str, drives_name: str):
    from iotad.kernel.python_loader import iota_factory
    declared = nodes(example)
    ref, drive_params = declared[drives_name]
    motor = CanMotor("motor", **dict(declared["motor"][1], link_timeout=0.06))
    trajectory = ArmTrajectory("trajectory", **declared["trajectory"][1])
    drives = iota_factory(ref)(drives_name, **drive_params)
    system = Composite(
        "arm", trajectory, Gap("net", cut=CUT, heal=HEAL), motor, CanBus("bus", stations=2), drives,
        bind=[("trajectory.setpoints", "net.inp"), ("net.out", "motor.setpoints"),
              ("motor.joint_states", "trajectory.joint_states"),
              ("motor.can_tx", "bus.tx[0]"), ("bus.rx[0]", "motor.can_rx"),
              (f"{drives_name}.can_tx", "bus.tx[1]"), ("bus.rx[1]", f"{drives_name}.can_rx")])
    engine = Engine(system)
    sim = engine.iota(f"arm/{drives_name}")
    states = {}
    try:
        for t in (CUT + 0.1, HEAL - 0.01, END):
            engine.run(until=t)
            states[t] = enabled(sim)
    finally:
        sim.close()
    return engine.trace, states, engine.iota("arm/motor")


def enabled(sim) -> list[bool]:
    if hasattr(sim, "drives"):
        return [drive.state == "OPERATION ENABLED" for drive in sim.drives]
    return [axis.armed for axis in sim.axes]


@pytest.mark.parametrize("example, drives", [("arm_can.toml", "odrives"), ("arm_canopen.toml", "drives")])
def test_the_drives_stop_within_the_link_timeout_and_come_back_after_the_heal(example, drives):
    trace, states, motor = run(example, drives)
    taken = [e["t"] for e in trace if e["iota"] == "arm/motor" and e["action"] == "setpoints" and e["kind"] == "input"]
    last = max(t for t in taken if t < CUT)
    lost = [e for e in trace if e["iota"] == "arm/motor" and e["action"] == "joint_status"
            and e["value"]["event"] == "LINK_LOST"]
    assert len(lost) == 6 and all(last + 0.06 <= e["t"] <= last + 0.06 + motor.period + 0.004 for e in lost), \
        (last, [e["t"] for e in lost])
    assert states[CUT + 0.1] == [False] * 6 and states[HEAL - 0.01] == [False] * 6  # stopped while cut
    assert states[END] == [True] * 6  # enabled again after the heal
    found = [e["t"] for e in trace if e["iota"] == "arm/motor" and e["action"] == "joint_status"
             and e["value"]["event"] == "LINK_FOUND"]
    assert len(found) == 6 and all(HEAL <= t < HEAL + 0.05 for t in found), found
    final = [e["value"]["position"] for e in trace if e["iota"] == "arm/motor" and e["action"] == "joint_states"][-1]
    target = nodes(example)["trajectory"][1]["waypoints"][-1]
    assert max(abs(p - q) for p, q in zip(final, target)) < 0.05, (final, target)
