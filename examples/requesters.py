"""Requesters for the Figure 2 scheduler: a module that asks for the motors now and then.

A vision requester and a manipulation requester are the same IOTA with other parameters:
priority, how long the motion takes (epoch), how long it may wait (timeout), when it first asks
and how long it pauses after each answer.

If the scheduler restarts while a request is in flight, the restarted scheduler knows nothing of
it and would never answer: the node host tells the requester through its `peer_restart` input
(iotad/host/peer_restart.py), and the requester takes that as the ABORT it is (the motors were
taken from it) and goes on with its next request after its pause (docs/failures.md).
"""
from iotad import Input, Iota, Output, Param

from channels.messages import ACK, MDL_REQ, MODE


class Requester(Iota):
    priority = Param(1)
    epoch = Param(2.0)
    timeout = Param(5.0)
    start = Param(0.0)
    pause = Param(1.0)
    count = Param(3)       # how many requests it makes
    setpoint = Param(0.0)  # the MDL control input w it asks for

    req = Output(MDL_REQ, switching=1)
    ack = Input(ACK, switching=1)
    peer_restart = Input()  # fed by the node host: the scheduler restarted (no binding needed)

    def init(self):
        self.waiting = False
        self.sent = 0
        self.answers = []

    @req.action(value=lambda self: MDL_REQ(control=MODE(w=self.setpoint, k=1.0), epoch=self.epoch,
                                           timeout=self.timeout, priority=self.priority),
                when=lambda self: not self.waiting and self.sent < self.count,
                after=lambda self: self.start if self.sent == 0 else self.pause)
    def ask(self):
        self.waiting = True
        self.sent += 1

    @ack.input
    def answered(self, x):
        self.waiting = False
        self.answers.append(x)

    @peer_restart.input
    def scheduler_restarted(self, x):
        if self.waiting:  # our request died with the old scheduler: an ABORT, then our next one
            self.waiting = False
            self.answers.append(ACK.ABORT)
