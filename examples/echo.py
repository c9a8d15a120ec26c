"""Echo IOTAs: the smallest input -> output round trip, for node-host tests and latency benches.

`Echo` answers every input at once (switching time 0). `PacedEcho` declares a switching time of
one time unit on both channels: inputs closer together than that are violations, and its answers
are paced one time unit apart.
"""
from iotad import Input, Int, Iota, Output


class Echo(Iota):
    inp = Input(Int(0, None))
    out = Output(Int(0, None))

    def init(self):
        self.pending = []

    @inp.input
    def got(self, x):
        self.pending.append(x)

    @out.action(value=lambda self: self.pending[0], when=lambda self: len(self.pending) > 0)
    def sent(self):
        del self.pending[0]


class PacedEcho(Iota):
    inp = Input(Int(0, None), switching=1)
    out = Output(Int(0, None), switching=1)

    def init(self):
        self.pending = []

    @inp.input
    def got(self, x):
        self.pending.append(x)

    @out.action(value=lambda self: self.pending[0], when=lambda self: len(self.pending) > 0)
    def sent(self):
        del self.pending[0]
