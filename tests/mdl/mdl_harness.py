"""Helpers of the MDL interpreter tests: an interpreter wired to a perfect motor (the joints are
where they were last commanded), inputs posted in virtual time, and trace readers."""
from __future__ import annotations

from channels.joints import JOINT_SETPOINTS, JOINT_STATES
from channels.mdl import MDL_PROGRAM, SENSOR_WIDTH
from iotad import Composite, Engine, Input, Iota, Output, Param
from nodes.mdl_interp import MdlInterpreter

RATE = 100.0        # ticks per second in most tests: exact, and short traces
PERIOD = 1.0 / RATE


class PerfectMotor(Iota):
    """Reports its joints where the last setpoints put them, at once; its start pose first."""

    start = Param([0.0] * 6)
    setpoints = Input(JOINT_SETPOINTS)
    joint_states = Output(JOINT_STATES)

    def init(self):
        self.pending = list(self.start)

    @setpoints.input
    def commanded(self, x):
        self.pending = list(x.position)

    @joint_states.action(value=lambda self: JOINT_STATES(position=self.pending, velocity=[0.0] * 6,
                                                         effort=[0.0] * 6, stamp=0.0),
                         when=lambda self: self.pending is not None)
    def reported(self):
        self.pending = None


def arm(rate=RATE, start=None, **params):
    """An interpreter `mdl` bound to a PerfectMotor `motor` in a composite `arm`; post commands and
    sensor readings to "arm/mdl"."""
    interpreter = MdlInterpreter("mdl", rate=rate, **params)
    motor = PerfectMotor("motor", start=start or [0.0] * 6)
    return Composite("arm", interpreter, motor,
                     bind=[("mdl.setpoints", "motor.setpoints"), ("motor.joint_states", "mdl.joint_states")])


class Run:
    """An engine over a system with an `mdl` interpreter; helpers post inputs and read the trace."""

    def __init__(self, root, path="arm/mdl"):
        self.engine = Engine(root)
        self.path = path

    def command(self, program, t):
        plain = program if isinstance(program, dict) else MDL_PROGRAM.to_plain(program)
        self.engine.post(self.path, "mdl_command", plain, t=t)

    def sensor(self, index, values, t, valid=True):
        padded = list(values) + [0.0] * (SENSOR_WIDTH - len(values))
        self.engine.post(self.path, "sensor", {"valid": valid, "value": padded}, index=index, t=t)

    def run(self, until):
        return self.engine.run(until=until)

    def of(self, action, kind=None):
        return [e for e in self.engine.trace if e["action"] == action and e["iota"] == self.path
                and (kind is None or e["kind"] == kind)]

    def setpoints(self, joint=0):
        """(t, position of `joint`) of every setpoint published."""
        return [(e["t"], e["value"]["position"][joint]) for e in self.of("setpoints", "output")]

    def values(self, action):
        return [e["value"] for e in self.of(action, "output")]

    def violations(self):
        return [e for e in self.engine.trace if e["kind"] == "violation"]

    @property
    def interpreter(self):
        return self.engine.iota(self.path)


def tick_of(t, period=PERIOD):
    return round(t / period)


__all__ = ["PERIOD", "RATE", "PerfectMotor", "Run", "arm", "tick_of"]
