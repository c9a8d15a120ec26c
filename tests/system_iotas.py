"""Tiny IOTAs for the system-file and launcher tests: just enough channels to bind; and the
ping-pong system over a CAN bus that many of them run."""
from pathlib import Path

from iotad import Float, Input, Int, Internal, Iota, Output, Param
from iotad.can.burst_bus import CAN_FRAMES
from iotad.can.frame import CAN_FRAME, Frame

from channels.messages import MODE

PINGPONG_BUS = 'name = "can0"\ninterface = "socketcan"\nchannel = "vcan0"\nstations = ["pinger", "echo"]'


def pingpong_system(period: float, *, system: str = "", pinger: str = "CanPinger", echo: str = "",
                    bus: str = PINGPONG_BUS) -> str:
    """A system file's text: `pinger` (CanPinger: a frame every `period`) and CanEcho (answers
    each) on the bus can0. `system` and `echo` add lines to the [system] table and the echo's
    [[node]]; `bus` is the whole [[can]] table, which ends the text (more may be appended)."""
    here = Path(__file__).resolve()
    return f"""[system]
name = "pingpong"
{system}
[[node]]
name = "pinger"
python = "{here}:{pinger}"
params = {{ period = {period} }}
[[node]]
name = "echo"
python = "{here}:CanEcho"
{echo}
[[can]]
{bus}
"""


class Source(Iota):
    period = Param(1.0)
    out = Output(Int, switching=1)

    def init(self):
        self.n = 0

    @out.action(value=lambda self: self.n, after="period")
    def sent(self):
        self.n += 1


class Pulse(Iota):
    """An output every `period` s, at any rate (switching 0): a node's periodic output whose count
    per second shows whether it kept its timing."""
    period = Param(0.02)
    out = Output(Int, switching=0)

    def init(self):
        self.n = 0

    @out.action(value=lambda self: self.n, after="period")
    def sent(self):
        self.n += 1


class FastSource(Iota):
    out = Output(Int, switching=0.5)


class Sink(Iota):
    inp = Input(Int, switching=1)

    @inp.input
    def got(self, x):
        pass


class FreeSink(Iota):
    """Takes inputs at any rate: several senders may feed it."""
    inp = Input(Int, switching=0)

    @inp.input
    def got(self, x):
        pass


class FloatSink(Iota):
    inp = Input(Float, switching=1)

    @inp.input
    def got(self, x):
        pass


class Fan(Iota):
    N = Param(2)
    inp = Input(Int, size="N", switching=1)

    @inp.input
    def got(self, i, x):
        pass


class Sources(Iota):
    N = Param(2)
    out = Output(Int, size="N", switching=1)


class Stub(Iota):
    """Stands for a node that the stub host (launcher_stub_node.py) makes exit on cue."""
    exit_code = Param(0)
    exit_after = Param(0.1)


class Rogue(Iota):
    """Stands for a node that the stub host plays badly: a token but no heartbeat, signals
    ignored, an output flooded past its switching time (see launcher_stub_node.py)."""
    exit_code = Param(0)
    exit_after = Param(0.1)
    stderr = Param("")
    token = Param(False)
    beat = Param(False)
    ignore_signals = Param(False)
    flood_hz = Param(0.0)
    out = Output(Int, switching=1)


class CanPinger(Iota):
    """A CAN station: sends frame 0x10 with a counter every `period`, keeps what it receives."""
    period = Param(0.01)
    can_tx = Output(CAN_FRAME, switching=0)
    can_rx = Input(CAN_FRAME, switching=0)

    def init(self):
        self.n = 0
        self.received = []

    @can_tx.action(value=lambda self: Frame(0x10, bytes([self.n % 256])).to_value(), after="period")
    def ping(self):
        self.n += 1

    @can_rx.input
    def heard(self, frame):
        self.received.append(Frame.from_value(frame))


class _CanTicker(Iota):
    """Every `period`, four frames (0x13, 0x10, 0x12, 0x11, with a counter) to send at once."""
    period = Param(0.01)
    tick = Internal(switching=0)
    can_rx = Input(CAN_FRAME, switching=0)

    def init(self):
        self.n = 0
        self.outbox = []
        self.received = []

    @tick.action(after="period")
    def ticked(self):
        self.outbox += [Frame(ident, bytes([self.n % 256, ident])).to_value() for ident in (0x13, 0x10, 0x12, 0x11)]
        self.n += 1

    @can_rx.input
    def heard(self, frame):
        self.received.append(Frame.from_value(frame))


class CanRowPinger(_CanTicker):
    """A CAN station that sends four frames at once every `period`, one `can_tx` firing each."""
    can_tx = Output(CAN_FRAME, switching=0)

    @can_tx.action(value=lambda self: self.outbox[0], when=lambda self: bool(self.outbox), after=0)
    def sent(self):
        self.outbox.pop(0)


class CanBurstPinger(_CanTicker):
    """CanRowPinger's frames, the four of an instant in one `can_tx_burst` output (recording
    format 2's bus takes them on `tx_burst[k]`); its `can_tx` sends nothing."""
    can_tx = Output(CAN_FRAME, switching=0)
    can_tx_burst = Output(CAN_FRAMES, switching=0)

    @can_tx_burst.action(value=lambda self: self.outbox, when=lambda self: bool(self.outbox), after=0)
    def sent_all(self):
        self.outbox = []


class CanTwinPinger(Iota):
    """A CAN station that sends the same frame (0x10, one zero byte) every `period`, as an
    ODrive's unchanging heartbeat does: frames told apart only by their order."""
    period = Param(0.01)
    can_tx = Output(CAN_FRAME, switching=0)
    can_rx = Input(CAN_FRAME, switching=0)

    @can_tx.action(value=lambda self: Frame(0x10, bytes(1)).to_value(), after="period")
    def ping(self):
        pass

    @can_rx.input
    def heard(self, frame):
        pass


class CanEcho(Iota):
    """A CAN station: answers every frame id with id + 1 and the same data."""
    can_tx = Output(CAN_FRAME, switching=0)
    can_rx = Input(CAN_FRAME, switching=0)

    def init(self):
        self.pending = []

    @can_rx.input
    def heard(self, frame):
        self.pending.append(Frame.from_value(frame))

    @can_tx.action(value=lambda self: Frame(self.pending[0].id + 1, self.pending[0].data).to_value(),
                   when=lambda self: len(self.pending) > 0)
    def answered(self):
        del self.pending[0]


class NotAStation(Iota):
    """Has can_tx and can_rx, but of the wrong type and shape."""
    period = Param(0.01)
    can_tx = Output(Int, switching=0)
    can_rx = Input(CAN_FRAME, size=2, switching=0)


class Ticker(Iota):
    """Ticks every time unit with how many inputs it has had; echoes each input at once."""
    inp = Input(Int, switching=0)
    echo = Output(Int, switching=0)
    tick = Output(Int, switching=0)

    def init(self):
        self.seen, self.pending = 0, []

    @inp.input
    def got(self, value):
        self.seen += 1
        self.pending.append(value)

    @echo.action(value=lambda self: self.pending[0], when=lambda self: bool(self.pending))
    def echoed(self):
        self.pending.pop(0)

    @tick.action(value=lambda self: self.seen, after=1.0)
    def ticked(self):
        pass


class CommandReader(Iota):
    """Takes the resume scheduler's mdl_command (a Figure 2 mode) and keeps it: a stand-in for
    the MDL interpreter that a test can kill."""
    mdl_command = Input(MODE, switching=1)

    def init(self):
        self.commands = []

    @mdl_command.input
    def got(self, mode):
        self.commands.append(mode)
