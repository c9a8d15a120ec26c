"""`CanBus`: the in-process CAN bus of virtual time, an IOTA timed by the engine's clock.

Stations post frames on `tx[k]` and receive every other station's frames on `rx[k]` (never their
own). The bus models a classic CAN bus at `bitrate`:

- A frame occupies the bus for its bit time (`bit_timing.frame_bits`: stuff bits counted exactly,
  or worst case with `stuffing="worst"`), intermission included: an 8-byte standard frame takes
  111-135 us at 1 Mbit/s. It is delivered to every other station at the end of that time.
- Arbitration: when the bus goes idle, the frames waiting (the head of each station's queue) take
  part, and the lowest arbitration field wins: the lowest id; a data frame beats a remote frame of
  the same id, a standard id beats an extended id of the same base. Each station's own queue is
  FIFO, as a SocketCAN socket sends (`station_queue="priority"` models a controller that sends
  its lowest id first). Arbitration is decided at the end of the start-of-frame bit, so frames
  posted at the same instant all take part whatever the order of the components' actions; the
  frame still ends exactly one frame time after it started. A frame starts as it is posted to
  an idle bus, or as the frame before it ends (the bus reads the time with `now()`); one posted
  before the SOF bit is over and that wins takes the bus then (`rearbitrated`, rare), and the
  deliveries' windows open again for its end. A frame thus costs the engine its deliveries and
  its log, not one more firing for its arbitration.
- Log: with `log_frames` (the default), every frame the bus carried goes out on `frames` as it
  ends, a `CAN_BUS_FRAME` (`frame_log.py`: sender station, bit time, the frame, its direction
  and its CAN Simple message name; `canopen_frame_log.CanopenCanBus`, the bus of a system with
  CiA 402 stations, names CANopen families instead), so a recording holds the bus's frames on
  one topic.
- Load: `busy_time` (seconds the bus carried frames), `frames`; every `load_period` seconds the
  output `load` reports the fraction of that period the bus was busy (frames counted when they end;
  0 switches it off: the reports never stop, so `engine.run()` needs `until`) and `average_load` is
  busy time over elapsed time as of that report.
  `bus_summary(trace, ...)` gives the exact figures over any span from a trace.

- Queues: a station's queue holds at most `queue_limit` frames (1000; 0: no limit). A frame
  posted to a full one is refused, as a controller's full transmit queue refuses it (SocketCAN:
  ENOBUFS): it never reaches the bus, and `refused[k]` reports how many were refused, one event
  per `load_period` at most. A station that floods the bus (a cyclic period shorter than its
  frames take) then costs the run a count, not memory without bound.

Bind station k's `can_tx` to `tx[k]` and `rx[k]` to its `can_rx`. The bus does not model error
frames, bus-off or acknowledgement: every frame it takes onto the bus is delivered.
"""
from __future__ import annotations

from iotad.esprit.runtime import esprit_now
from iotad.kernel.api import Input, Internal, Iota, Output, Param
from iotad.kernel.engine import TIME_GRID
from iotad.kernel.types import Float, Int

from .bit_timing import frame_bits
from .frame import CAN_FRAME, STANDARD_ID_MAX, Frame
from .frame_log import CAN_BUS_FRAME, bus_frame


def arbitration_key(frame) -> tuple:
    """The arbitration field as CAN compares it, dominant (0) first: lower wins."""
    if frame.extended:
        return (frame.id >> 18, 1, 1, frame.id & 0x3FFFF, int(frame.rtr))  # SRR and IDE recessive
    return (frame.id, int(frame.rtr), 0, 0, 0)


def frame_bits_of(frame, stuffing: str = "exact") -> int:
    """Bits a CAN_FRAME value occupies the bus for (its first `dlc` data bytes)."""
    return frame_bits(frame.id, frame.extended, frame.rtr, bytes(frame.data[:frame.dlc]), stuffing,
                      dlc=frame.dlc)


class CanBus(Iota):
    recording_format = 1  # a recording of a system with this bus is format 1 (iotad.recording.mcap_format)

    stations = Param(2)
    bitrate = Param(1_000_000)
    stuffing = Param("exact")        # "exact", "worst" or "none"
    station_queue = Param("fifo")    # "fifo" (SocketCAN) or "priority" (lowest id of a station first)
    load_period = Param(0.1)         # seconds between `load` reports; 0: no reports
    log_frames = Param(True)         # every frame carried out on `frames` (one recorded topic per bus)
    queue_limit = Param(1000)        # frames a station's queue holds; one more is refused (0: no limit)

    tx = Input(CAN_FRAME, size="stations", switching=0)
    rx = Output(CAN_FRAME, size="stations", switching=0)
    load = Output(Float(0, None), switching=0)
    frames = Output(CAN_BUS_FRAME, switching=0)
    refused = Output(Int(0, None), size="stations", switching=0)  # frames a full queue refused, per report
    rearbitrated = Internal(CAN_FRAME, switching=0)  # its value: the frame that won late
    finish = Internal(CAN_FRAME, switching=0)        # its value: the frame that ended unheard

    def init(self):
        if self.stuffing not in ("exact", "worst", "none"):
            raise ValueError(f"CanBus stuffing must be 'exact', 'worst' or 'none', got {self.stuffing!r}")
        if self.station_queue not in ("fifo", "priority"):
            raise ValueError(f"CanBus station_queue must be 'fifo' or 'priority', got {self.station_queue!r}")
        self.waiting = [[] for _ in range(self.stations)]  # per station, in posting order
        self.current = None           # the frame on the bus
        self.sender = None            # its station
        self.receivers = set()        # stations it is still to be delivered to
        self.frame_time = 0.0         # its bit time, seconds
        self.start = 0.0              # when its start-of-frame bit began
        self.finish_delay = 0.0       # from when the deliveries' windows opened to its end
        self.late_winner = False      # a frame won during the SOF bit: the windows open again
        self.busy_time = 0.0
        self.frames = 0
        self.window_busy = 0.0
        self.elapsed = 0.0
        self.busy_time_reported = 0.0
        self.max_waiting = 0
        self.queued = 0               # frames waiting, all stations
        self.log = []                 # CAN_BUS_FRAME records of frames that ended, not yet out
        self.refusals = [0] * self.stations  # frames each station's full queue refused, not yet reported
        self._others = [frozenset(range(self.stations)) - {k} for k in range(self.stations)]
        self._bit_steps = round(TIME_GRID / self.bitrate)  # the SOF bit, in steps of the engine's time grid

    @property
    def average_load(self) -> float:
        """Busy time over elapsed time, as of the last `load` report (0 before the first)."""
        return self.busy_time_reported / self.elapsed if self.elapsed else 0.0

    @tx.input
    def posted(self, i, frame):
        # canFrame's field ranges cannot say that a standard id ends at 0x7FF: a frame no
        # controller could send is refused here, once (a runtime_error naming it), and never
        # queued; taken onto the bus it would fail at every delivery and stop the bus
        if not frame.extended and frame.id > STANDARD_ID_MAX:
            Frame.from_value(frame)  # raises FrameError, in the frame module's words
        if self.queue_limit and len(self.waiting[i]) >= self.queue_limit:
            # a controller's transmit queue is finite (SocketCAN says ENOBUFS): the frame is lost,
            # and a flood costs the run a count, not memory without bound
            self.refusals[i] += 1
            return
        self.waiting[i].append(frame)
        self.queued += 1
        if self.queued > self.max_waiting:
            self.max_waiting = self.queued
        now = esprit_now()
        if self.current is None:
            self._start(now)
        elif round((now - self.start) * TIME_GRID) < self._bit_steps:  # on the engine's grid:
            self._rearbitrate(now)  # start + 1 bit in floats may land either side of that instant

    # The start-of-frame bit: a frame posted before its end takes part in arbitration, so frames
    # posted at one instant all do, whatever the order of the components' actions. The frame
    # that was winning goes back to the head of its queue, and the deliveries' windows open
    # again (this action, at once) for the new winner's end.
    @rearbitrated.action(value=lambda self: self.current, when=lambda self: self.late_winner, after=0)
    def reopened(self):
        self.late_winner = False

    @rx.action(value=lambda self, i: self.current,
               when=lambda self, i: self.current is not None and i in self.receivers and not self.late_winner,
               after=lambda self, i: self.finish_delay)
    def delivered(self, i):
        self.receivers.discard(i)
        if not self.receivers:
            self._free()

    # Only a frame nobody receives (a bus with one station) ends here; otherwise the last delivery ends it.
    @finish.action(value=lambda self: self.current,
                   when=lambda self: self.current is not None and not self.receivers and not self.late_winner,
                   after=lambda self: self.finish_delay)
    def finished(self):
        self._free()

    def _start(self, now: float) -> None:
        """The next frame starts now: the frame that wins arbitration among the queue heads."""
        station, position, _ = self._winner()
        self.current = frame = self.waiting[station].pop(position)
        self.queued -= 1
        self.sender = station
        self.frame_time = frame_bits_of(frame, self.stuffing) / self.bitrate
        self.receivers = set(self._others[station])
        self.start = now
        self.finish_delay = self.frame_time

    def _rearbitrate(self, now: float) -> None:
        """A frame posted during the SOF bit: arbitration again, with the frame that was winning
        back in its queue (at its head: it was the head, or, with `priority`, the lowest)."""
        self.waiting[self.sender].insert(0, self.current)
        self.queued += 1
        station, position, frame = self._winner()
        if station == self.sender and position == 0:
            self.waiting[station].pop(0)  # it still wins
            self.queued -= 1
            return
        start = self.start
        self._start(now)
        self.start = start
        self.finish_delay = self.frame_time - (now - start)  # it ends one frame time after the SOF
        self.late_winner = True

    def _winner(self) -> tuple:
        """(station, position in its queue, frame) of the frame that wins arbitration now."""
        stations = [station for station, queue in enumerate(self.waiting) if queue]
        if len(stations) == 1 and self.station_queue == "fifo":  # the usual case: no contest
            return stations[0], 0, self.waiting[stations[0]][0]
        heads = []
        for station, queue in enumerate(self.waiting):
            if queue:
                position = (0 if self.station_queue == "fifo"
                            else min(range(len(queue)), key=lambda k: arbitration_key(queue[k])))
                heads.append((arbitration_key(queue[position]), station, position))
        _, station, position = min(heads)  # equal ids (an error on a real bus): the lower station
        return station, position, self.waiting[station][position]

    # How many frames station i's full queue refused: one report per load period (0.1 s if the
    # reports are off) however many came, so that a flood is not one event per frame.
    @refused.action(value=lambda self, i: self.refusals[i], when=lambda self, i: self.refusals[i] > 0,
                    after=lambda self, i: self.load_period or 0.1)
    def reported_refusals(self, i):
        self.refusals[i] = 0

    @frames.action(value=lambda self: self.log[0], when=lambda self: bool(self.log), after=0)
    def logged(self):
        self.log.pop(0)

    def _free(self):
        if self.log_frames:
            self.log.append(bus_frame(self.current, self.sender, self.frame_time))
        self.busy_time += self.frame_time
        self.window_busy += self.frame_time
        self.frames += 1
        self.current = None
        if self.queued:  # back to back: the next SOF follows the intermission at once
            self._start(esprit_now())
        else:
            self.sender = None

    @load.action(value=lambda self: self.window_busy / self.load_period,
                 when=lambda self: self.load_period > 0, after="load_period")
    def reported(self):
        self.elapsed += self.load_period
        self.busy_time_reported = self.busy_time
        self.window_busy = 0.0


def bus_summary(trace, bus: str, bitrate: float = 1_000_000, stuffing: str = "exact",
                start: float = 0.0, until: float | None = None) -> dict:
    """Exact figures of a bus from a trace: frames, busy time and load over [start, until]
    (until: the last event of the bus). `bus` is the bus's path in the trace ("iota" field). A
    frame ends when it is delivered (its `rx` events, one per receiver, all at that instant) or,
    on a bus with one station, with its `finish` event; it began its bit time before that. A
    frame still on the bus where the trace ends is not in the trace's account, so not in these
    figures (the bus's own `busy_time` counts it once it ends)."""
    events = [e for e in trace if e.get("iota") == bus]
    span_end = until if until is not None else max((e["t"] for e in events), default=start)
    ended = {}  # end time -> frame: one frame ends at a time
    for event in events:
        if event["action"] in ("rx", "finish") and event["kind"] in ("output", "internal"):
            ended[event["t"]] = event["value"]
    frames, busy = 0, 0.0
    for end, frame in ended.items():
        duration = frame_bits(frame["id"], frame["extended"], frame["rtr"], bytes(frame["data"][:frame["dlc"]]),
                              stuffing, dlc=frame["dlc"]) / bitrate
        overlap = min(end, span_end) - max(end - duration, start)
        if overlap > 0:
            busy += overlap
            frames += 1
    elapsed = span_end - start
    return {"frames": frames, "busy_time": busy, "elapsed": elapsed,
            "load": busy / elapsed if elapsed > 0 else 0.0, "bitrate": bitrate}
