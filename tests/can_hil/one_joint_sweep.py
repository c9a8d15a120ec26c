"""`Sweep`: setpoints for one position joint, for the tests against third-party drives: where the
joint is until `start`, then a ramp of `span` rad over `duration`, then held."""
from __future__ import annotations

from channels.joints import joint_setpoints, joint_states
from iotad.kernel.api import Input, Iota, Output, Param


class Sweep(Iota):
    span = Param(1.0)
    start = Param(0.5)
    duration = Param(1.0)
    period = Param(0.05)

    joint_states = Input(joint_states(1), switching=0)
    setpoints = Output(joint_setpoints(1), switching=0)

    def init(self):
        self.origin = None
        self.k = 0

    @joint_states.input
    def measured(self, value):
        if self.origin is None:
            self.origin = value.position[0]

    @setpoints.action(value=lambda self: self._setpoint(), when=lambda self: self.origin is not None, after="period")
    def sent(self):
        self.k += 1

    def _setpoint(self):
        s = min(max((self.k * self.period - self.start) / self.duration, 0.0), 1.0)
        return joint_setpoints(1)(position=[self.origin + self.span * s], velocity_ff=[0.0], torque_ff=[0.0])
