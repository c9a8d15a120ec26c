"""A requester for the fusion scheduler (nodes/scheduler/fusion.iota): a setpoint and its cost.

Each request asks for a position per joint and weighs each joint (a quadratic cost: how much it
minds being elsewhere); the scheduler issues the weighted mean of the requests whose epochs
overlap. `FUSE_REQ` is the value type of fusion.iota's `struct fuseReq` (the same JSON Schema,
so that the two bind).
"""
from iotad import Array, Float, Input, Int, Iota, Output, Param, Struct

from channels.messages import ACK

JOINTS = 2  # fusion.iota's JOINTS
FUSE_REQ = Struct("fuseReq", position=Array(Float(-1e6, 1e6), JOINTS), weight=Array(Float(0, 1e6), JOINTS),
                  epoch=Float(0, None), timeout=Float(0, None), priority=Int)


class FusionRequester(Iota):
    position = Param([0.0, 0.0])   # where it wants each joint
    weight = Param([1.0, 1.0])     # how much it minds each joint being elsewhere
    epoch = Param(2.0)
    timeout = Param(1.0)
    start = Param(0.0)
    pause = Param(1.0)
    count = Param(3)

    req = Output(FUSE_REQ, switching=1)
    ack = Input(ACK, switching=1)

    def init(self):
        self.waiting = False
        self.sent = 0
        self.answers = []

    @req.action(value=lambda self: FUSE_REQ(position=list(self.position), weight=list(self.weight),
                                            epoch=self.epoch, timeout=self.timeout, priority=1),
                when=lambda self: not self.waiting and self.sent < self.count,
                after=lambda self: self.start if self.sent == 0 else self.pause)
    def ask(self):
        self.waiting = True
        self.sent += 1

    @ack.input
    def answered(self, x):
        self.waiting = False
        self.answers.append(x)
