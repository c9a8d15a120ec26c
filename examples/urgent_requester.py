"""A requester whose need grows urgent: for the preempt-and-resume scheduler (nodes/scheduler/resume.iota).

It is the Figure 2 `Requester` with one more output, `urgency`, bound to the scheduler's
`priority[i]`: once a request of its own has waited `urge_after` without an answer, it raises
that request's priority to `urgent`, once per request. A suspended request raised above the
master takes the motors back and resumes (examples/resume.toml).
"""
from iotad import Int, Output, Param

from requesters import Requester


class UrgentRequester(Requester):
    urgent = Param(9)         # the priority it asks for once its request has waited
    urge_after = Param(2.0)   # how long it waits for an answer before asking

    urgency = Output(Int, switching=1)

    def init(self):
        super().init()
        self.urged = 0  # how many of its requests it has raised

    @urgency.action(value=lambda self: self.urgent, when=lambda self: self.waiting and self.urged < self.sent,
                    after="urge_after")
    def urge(self):
        self.urged = self.sent
