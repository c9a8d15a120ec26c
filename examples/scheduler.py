"""The motion scheduler of the paper's Figure 2, in iotad's Python API.

Fixes to the figure's typos (also in nodes/scheduler/scheduler.iota):
- `current.status == SIGNALING` / `request[master]` mean the current master's request.
- `command.mode` is the field the figure's struct calls `control`.
- `request[i].timeout` is `request[i].command.timeout`.
- `current_master` is NULL (None) when nobody holds the motors, so mdl_command is guarded by it.
"""
from iotad import Enum, Input, Internal, Iota, Output, Param, Struct

from channels.messages import ACK, MDL_REQ, MODE

Status = Enum("status", "NULL", "PENDING", "STARTING", "SIGNALING", "COMMITTED", "ABORTED", "REJECTED")
Request = Struct("request", status=Status, command=MDL_REQ)
NULL, PENDING, STARTING, SIGNALING = Status.NULL, Status.PENDING, Status.STARTING, Status.SIGNALING
COMMITTED, ABORTED, REJECTED = Status.COMMITTED, Status.ABORTED, Status.REJECTED


class Scheduler(Iota):
    N = Param(2)
    T = Param(1.0)

    req = Input(MDL_REQ, size="N", switching=1)
    ack = Output(ACK, size="N", switching=1)
    mdl_command = Output(MODE, switching=1)
    schedule = Internal(size="N", switching=1)
    commit = Internal(size="N", switching=1)
    reject = Internal(size="N", switching=1)

    def init(self):
        self.request = [Request(status=NULL, command=None) for _ in range(self.N)]
        self.current_master = None
        self.current_priority = 0

    @req.input
    def on_req(self, i, x):
        self.request[i].status = PENDING
        self.request[i].command = x

    @schedule.action(when=lambda self, i: self.request[i].status == PENDING
                     and self.request[i].command.priority > self.current_priority)
    def on_schedule(self, i):
        if self.current_master is not None and self.request[self.current_master].status == SIGNALING:
            self.request[self.current_master].status = ABORTED
        self.request[i].status = STARTING
        self.current_master = i
        self.current_priority = self.request[i].command.priority

    @commit.action(when=lambda self, i: self.request[i].status == SIGNALING,
                   after=lambda self, i: self.request[i].command.epoch)
    def on_commit(self, i):
        self.request[i].status = COMMITTED
        self.current_master = None
        self.current_priority = 0

    @reject.action(when=lambda self, i: self.request[i].status in (PENDING, STARTING),
                   after=lambda self, i: self.request[i].command.timeout)
    def on_reject(self, i):
        self.request[i].status = REJECTED
        if self.current_master == i:  # a STARTING request is the master: the motors are free again
            self.current_master = None
            self.current_priority = 0

    @mdl_command.action(value=lambda self: self.request[self.current_master].command.control,
                        when=lambda self: self.current_master is not None
                        and self.request[self.current_master].status == STARTING)
    def on_mdl_command(self):
        self.request[self.current_master].status = SIGNALING

    @ack.action(value=ACK.ABORT, when=lambda self, i: self.request[i].status == ABORTED, within=(0, "T"))
    def on_abort(self, i):
        self.request[i].status = NULL

    @ack.action(value=ACK.COMMIT, when=lambda self, i: self.request[i].status == COMMITTED, within=(0, "T"))
    def on_commit_ack(self, i):
        self.request[i].status = NULL

    @ack.action(value=ACK.REJECT, when=lambda self, i: self.request[i].status == REJECTED, within=(0, "T"))
    def on_reject_ack(self, i):
        self.request[i].status = NULL
