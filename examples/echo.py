"""Echo IOTAs: the smallest input -> output round trip, for node-host tests and latency benches.

`Echo` answers every input at once (switching time `S`, default 0). `PacedEcho` is the same with
a switching time of one time unit on both channels: inputs closer together than that are
violations, and its answers are paced one time unit apart.
"""
from iotad import Input, Int, Iota, Output, Param


class Echo(Iota):
    S = Param(0.0)  # switching time of both channels, in time units
    inp = Input(Int(0, None), switching="S")
    out = Output(Int(0, None), switching="S")

    def init(self):
        self.pending = []

    @inp.input
    def got(self, x):
        self.pending.append(x)

    @out.action(value=lambda self: self.pending[0], when=lambda self: len(self.pending) > 0)
    def sent(self):
        del self.pending[0]


class PacedEcho(Echo):
    S = Param(1.0)
