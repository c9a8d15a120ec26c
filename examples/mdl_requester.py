"""A requester that asks the program scheduler (nodes/scheduler/program_scheduler.iota) to run an
MDL program (channels/mdl.py, docs/mdl.md) on the motors.

It is Figure 2's requester with a program in place of the mode: it asks at `start`; a COMMIT
ends its business; an ABORT (a higher-priority request took the motors) or a REJECT (it waited
past its timeout) makes it ask again after `pause`, up to `count` requests in all. Asking again
sends the same program under the same id, so the MDL interpreter resumes it where it was
preempted instead of starting it over (the paper, section 2). The interpreter's `program_end`
reports, bound to `program_end`, are kept in `ends` (those of its own program).
"""
from iotad import Input, Iota, Output, Param
from iotad.kernel.types import BadValue

from channels.mdl import MDL_PROGRAM, MDL_PROGRAM_REQ, PROGRAM_END
from channels.messages import ACK


class ProgramRequester(Iota):
    program = Param({})     # the program, as plain data (docs/mdl.md): a TOML table in a system file
    priority = Param(1)
    epoch = Param(2.0)      # s the scheduler lets it hold the motors before it commits
    timeout = Param(5.0)    # s it may wait for the motors
    start = Param(0.0)      # s before the first request
    pause = Param(1.0)      # s between an ABORT or REJECT and the next request
    count = Param(3)        # most requests it makes

    req = Output(MDL_PROGRAM_REQ, switching=1)
    ack = Input(ACK, switching=1)
    program_end = Input(PROGRAM_END)
    peer_restart = Input()  # fed by the node host: the scheduler restarted (no binding needed)

    def init(self):
        try:
            self.control = MDL_PROGRAM.from_plain(self.program)
        except BadValue as exc:
            raise ValueError(f"program: {exc}") from None
        self.waiting = False
        self.done = False
        self.sent = 0
        self.answers = []
        self.ends = []

    @req.action(value=lambda self: MDL_PROGRAM_REQ(control=self.control, epoch=self.epoch, timeout=self.timeout,
                                                   priority=self.priority),
                when=lambda self: not self.waiting and not self.done and self.sent < self.count,
                after=lambda self: self.start if self.sent == 0 else self.pause)
    def ask(self):
        self.waiting = True
        self.sent += 1

    @ack.input
    def answered(self, x):
        self.waiting = False
        self.answers.append(x)
        if x == ACK.COMMIT:
            self.done = True

    @program_end.input
    def ended(self, x):
        if x.program == self.control.id:
            self.ends.append(x.end)

    @peer_restart.input
    def scheduler_restarted(self, x):
        if self.waiting:  # our request died with the old scheduler: an ABORT, then ask again
            self.waiting = False
            self.answers.append(ACK.ABORT)
