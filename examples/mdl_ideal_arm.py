"""An ideal six-joint arm for running the MDL interpreter in real time without CAN or physics:
it is where it was last commanded, and says so every `period` (examples/mdl_arm_realtime.toml)."""
from channels.joints import JOINT_SETPOINTS, JOINT_STATES
from iotad import Input, Iota, Output, Param


class IdealArm(Iota):
    start = Param([0.0, -0.3, -1.0, 0.0, 1.3, 0.0])   # the xArm6's home pose in sim/
    period = Param(0.01)                               # s between joint_states
    slack = Param(0.005)                               # s one may come late in real time

    setpoints = Input(JOINT_SETPOINTS)
    joint_states = Output(JOINT_STATES)

    def init(self):
        self.position = list(self.start)

    @setpoints.input
    def commanded(self, x):
        self.position = list(x.position)

    @joint_states.action(value=lambda self: JOINT_STATES(position=self.position, velocity=[0.0] * 6,
                                                         effort=[0.0] * 6, stamp=0.0),
                         within=("period", lambda self: self.period + self.slack))
    def reported(self):
        pass
