"""Requesters for the Figure 2 scheduler: a module that asks for the motors now and then.

A vision requester and a manipulation requester are the same IOTA with other parameters:
priority, how long the motion takes (epoch), how long it may wait (timeout), when it first asks
and how long it pauses after each answer.

If the scheduler restarts while a request is in flight, the restarted scheduler knows nothing of
it and would never answer: the node host tells the requester through its `peer_restart` input
(iotad/host/peer_restart.py), and the requester takes that as the ABORT it is (the motors were
taken from it) and goes on with its next request after its pause (docs/failures.md).

An answer can also be lost on the way: the network between hosts is cut for longer than it
keeps messages, or a late answer (held up by a partition) arrives sooner after the previous one
than the `ack` input's switching time allows and is refused (a `switching_time` violation). The
scheduler answers every request within its timeout and epoch (and its ack window T), so a
requester that has heard nothing `patience` seconds past `timeout + epoch` takes its request as
aborted too, and goes on: no request is left waiting for ever.
"""
from iotad import Input, Internal, Iota, Output, Param

from channels.messages import ACK, MDL_REQ, MODE


class Requester(Iota):
    priority = Param(1)
    epoch = Param(2.0)
    timeout = Param(5.0)
    start = Param(0.0)
    pause = Param(1.0)
    count = Param(3)       # how many requests it makes
    setpoint = Param(0.0)  # the MDL control input w it asks for
    patience = Param(2.0)  # s past timeout + epoch without an answer before it takes the request as aborted

    req = Output(MDL_REQ, switching=1)
    ack = Input(ACK, switching=1)
    peer_restart = Input()  # fed by the node host: the scheduler restarted (no binding needed)
    no_answer = Internal()

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
        if self.waiting:  # else an answer come after this requester gave its request up: too late
            self.waiting = False
            self.answers.append(x)

    @no_answer.action(when=lambda self: self.waiting, after=lambda self: self.timeout + self.epoch + self.patience)
    def gave_up(self):
        self.waiting = False
        self.answers.append(ACK.ABORT)

    @peer_restart.input
    def scheduler_restarted(self, x):
        if self.waiting:  # our request died with the old scheduler: an ABORT, then our next one
            self.waiting = False
            self.answers.append(ACK.ABORT)
