"""`BurstCanBus`: the in-process CAN bus of virtual time in recording format 2, where the frames
queued at one instant are arbitrated in one firing and the frames carried are recorded as bursts.

The bus model is `virtual_bus.CanBus`'s, frame for frame: arbitration by identifier among the
heads of the stations' queues whenever the bus goes idle (decided at the end of the SOF bit, so
frames posted at one instant all take part, and one posted during a frame's SOF bit that wins
takes the bus), each frame's exact bit-stuffed duration (`bit_timing`), back to back, FIFO or
priority station queues, the same `queue_limit` refusals and `load` reports. What differs is how
the engine is asked to carry it:

- `tx[k]` inputs queue frames (an input event each, as before). One firing of `burst` at that
  instant (after every station's frames of the instant: `after=0`) computes when each waiting
  frame will start and end, assuming nothing more is posted, and queues each frame for every
  other station at its own wire-end time (`iotad.kernel.wire_delay`): the receivers take it on
  `can_rx` at that time, an input event of theirs, exactly as when the bus fired `rx[k]` there.
  A frame posted later that wins arbitration over a frame not yet started moves it: its
  deliveries are withdrawn and queued again at the new time, so what receivers get is what the
  format 1 bus delivers.
- A station may also queue the frames of one instant as one output (`can_tx_burst`, a list of
  frames, bound to `tx_burst[k]`): one firing and one event of the station instead of one per
  frame, queued in their order exactly as if posted one by one at that instant.
- `rx[k]` fires no event of its own: the outputs are there to be bound; what they carry is in
  the bursts.
- A frame is recorded once its wire times are final (it ended): `burst`'s value is the list of
  frames that ended since the previous burst (possibly none), each with its station, its
  arbitration order on this bus (0, 1, ...), when it was queued, its wire start and end, its bit
  time (`duration`), the frame, and its CAN Simple direction and message name: the bus's frame
  log (`frames` of format 1) and its `rx` outputs folded into one event. A burst also fires as
  the last frame scheduled ends (`drained`: the bus goes idle), and after a `load` report that
  settled frames, so every frame is recorded by the end of its busy period; a frame still on the
  bus when the run ends is not in its recording, as in format 1.

Readers expand a burst into the per-frame events of format 1 (`iotad.recording.bursts`), so
checks, exports and candump see each frame as before.
"""
from __future__ import annotations

from typing import Any

from iotad.esprit.runtime import esprit_now
from iotad.kernel.api import Input, Iota, Output, Param
from iotad.kernel.engine import TIME_GRID, plus
from iotad.kernel.types import Float, Int
from iotad.kernel.wire_delay import deliver_later

from .burst_types import (BURST_FIELDS, CAN_BURST, CAN_FRAMES, CAN_TX_BURST, TX_BURST, TX_BURSTS,  # noqa: F401
                          CanBurstType, CanFramesType)
from .frame import CAN_FRAME, STANDARD_ID_MAX, Frame
from .frame_log import bus_frame
from .virtual_bus import arbitration_key, frame_bits_of

class _Frame:
    """A frame the bus holds: queued, on the wire, or scheduled to follow."""

    __slots__ = ("frame", "station", "queued", "start", "end", "duration", "key", "due", "later")

    def __init__(self, frame: Any, station: int, queued: float, duration: float) -> None:
        self.frame, self.station, self.queued, self.duration = frame, station, queued, duration
        self.start = self.end = 0.0
        self.key = arbitration_key(frame)  # once: it depends on the frame alone, as `duration` does
        self.due = None     # the wire end its deliveries are queued for (None: not queued)
        self.later = None   # their `LaterDelivery`


class BurstCanBus(Iota):
    recording_format = 2  # recordings of a system with this bus are format 2 (iotad.recording.mcap_format)

    stations = Param(2)
    bitrate = Param(1_000_000)
    stuffing = Param("exact")        # "exact", "worst" or "none"
    station_queue = Param("fifo")    # "fifo" (SocketCAN) or "priority" (lowest id of a station first)
    load_period = Param(0.1)         # seconds between `load` reports; 0: no reports
    log_frames = Param(True)         # False: no log ([[can]] log = false): bursts name no direction nor message
    queue_limit = Param(1000)        # frames a station's queue holds; one more is refused (0: no limit)

    tx = Input(CAN_FRAME, size="stations", switching=0)
    # a station's frames of one instant in one event (its `can_tx_burst`), queued in their order,
    # exactly as the same frames posted one by one on `tx[k]` at that instant
    tx_burst = Input(CAN_FRAMES, size="stations", switching=0)
    rx = Output(CAN_FRAME, size="stations", switching=0)  # bound to the receivers; frames go by wire_delay
    burst = Output(CAN_BURST, switching=0)
    load = Output(Float(0, None), switching=0)
    refused = Output(Int(0, None), size="stations", switching=0)

    def init(self):
        if self.stuffing not in ("exact", "worst", "none"):
            raise ValueError(f"CanBus stuffing must be 'exact', 'worst' or 'none', got {self.stuffing!r}")
        if self.station_queue not in ("fifo", "priority"):
            raise ValueError(f"CanBus station_queue must be 'fifo' or 'priority', got {self.station_queue!r}")
        self.waiting = [[] for _ in range(self.stations)]  # per station, _Frames in posting order
        self.current = None           # the _Frame on the wire (its arbitration may still be redone in its SOF bit)
        self.ended = []               # _Frames that ended, not yet in a burst
        self.scheduled = False        # the waiting frames' deliveries are queued as the schedule stands
        self.order = 0                # arbitration order of the next frame to end
        self.busy_time = 0.0
        self.frames = 0
        self.window_busy = 0.0
        self.elapsed = 0.0
        self.busy_time_reported = 0.0
        self.max_waiting = 0
        self.queued = 0
        self.refusals = [0] * self.stations
        self._others = [tuple(k for k in range(self.stations) if k != s) for s in range(self.stations)]
        self._bit_steps = round(TIME_GRID / self.bitrate)
        self.report_due = self.load_period  # when the next load report fires (a run starts at 0)
        self.draining = False         # a burst is due when the frames scheduled have ended
        self.drain_at = 0.0           # then (the last scheduled frame's end)
        self.drain_after = 0.0        # how long after the schedule was computed
        self._last_end = 0.0

    @property
    def average_load(self) -> float:
        """Busy time over elapsed time, as of the last `load` report (0 before the first)."""
        return self.busy_time_reported / self.elapsed if self.elapsed else 0.0

    @tx_burst.input
    def posted_burst(self, i, frames):
        refused = None
        for frame in frames:
            try:
                self.posted(i, frame)
            except Exception as exc:  # noqa: BLE001 - a frame no controller could send: the others go on
                refused = refused or exc
        if refused is not None:
            raise refused  # one violation, naming the first frame refused, as posting it alone would

    @tx.input
    def posted(self, i, frame):
        if not frame.extended and frame.id > STANDARD_ID_MAX:
            Frame.from_value(frame)  # raises FrameError, in the frame module's words
        if self.queue_limit and len(self.waiting[i]) >= self.queue_limit:
            self.refusals[i] += 1
            return
        now = esprit_now()
        current = self.current
        if current is not None and current.end <= now:
            self._settle(now)
        held = _Frame(frame, i, now, frame_bits_of(frame, self.stuffing) / self.bitrate)
        self.waiting[i].append(held)
        self.queued += 1
        if self.queued > self.max_waiting:
            self.max_waiting = self.queued
        if self.current is None:
            self._start(now)
            if not self.queued and not self.ended and not self.draining:
                # a lone frame on an idle bus: its delivery is queued and nothing else is to be
                # scheduled, so no firing is needed now, only the burst as it ends (`drained`)
                self.drain_at = self._last_end = held.end
                self.drain_after = held.end - now
                self.draining = True
                return
        elif round((now - self.current.start) * TIME_GRID) < self._bit_steps:  # in its SOF bit
            self._rearbitrate(now)
        self.scheduled = False
        self.draining = False

    # One firing per instant at which frames were queued (after them all), and one after each
    # load report that settled frames: the frames that ended since the last burst go out, and
    # the deliveries of the frames still waiting are queued at their wire ends.
    @burst.action(value=lambda self: self._record(),
                  when=lambda self: not self.scheduled or bool(self.ended), after=0)
    def carried(self):
        self.ended = []
        self._schedule()
        if self.current is not None:  # the frames' end: a burst then, with what ended until it
            self.drain_at = self._last_end
            self.drain_after = self._last_end - esprit_now()
            self.draining = True

    # When the last frame scheduled ends (the bus goes idle), the frames that ended since the last
    # burst go out: every frame is recorded by the end of its busy period. A post before then
    # computes a new schedule (`draining` false, then true again with a window of its own).
    @burst.action(value=lambda self: self._record_until(self.drain_at), when=lambda self: self.draining,
                  after=lambda self: self.drain_after)
    def drained(self):
        self._settle(esprit_now())
        self.ended = []
        self.draining = False

    def _record_until(self, t: float) -> list:
        self._settle(t)
        return self._record()

    def _record(self) -> list:
        out = []
        log = self.log_frames
        for held in self.ended:
            record = bus_frame(held.frame, held.station, held.duration)
            if log:
                record = self._log_record(record)
            plain = {"station": held.station, "order": 0, "queued": held.queued, "start": held.start,
                     "end": held.end, "duration": held.duration, "id": record.id, "extended": record.extended,
                     "rtr": record.rtr, "dlc": record.dlc, "data": list(record.data),
                     "direction": record.direction if log else None, "message": record.message if log else None}
            out.append(plain)
        first = self.order - len(out)
        for k, plain in enumerate(out):
            plain["order"] = first + k
        return out

    def _log_record(self, record):
        """The log record of a frame (a bus with CANopen stations names it again)."""
        return record

    def frames_at_end(self, now: float) -> list[dict]:
        """The frames a run that stops at `now` leaves unrecorded, each as a burst records a frame
        plus `state`: "ended" (it ended by `now`, its burst still to come), "on the wire" or
        "queued", with the wire start and end it has or would have had had the run gone on
        (nothing more posted). `iotad run --virtual` writes them in the recording's end
        (`iotad.can_at_end`), so that the check can tell a frame cut at the end from one lost.
        Computed on copies: the bus is left as it was."""
        timed = [(held, held.start, held.end) for held in self.ended]
        current = self.current
        if current is not None:
            timed.append((current, current.start, current.end))
        end = current.end if current is not None else now
        saved = self.waiting
        self.waiting = [list(queue) for queue in saved]
        try:
            for _ in range(self.queued):
                station, position = self._winner()
                held = self.waiting[station].pop(position)
                start, end = end, round((end + held.duration) * TIME_GRID) / TIME_GRID  # `plus`, inline
                timed.append((held, start, end))
        finally:
            self.waiting = saved
        first = self.order - len(self.ended)
        records = []
        for k, (held, start, end) in enumerate(timed):
            record = bus_frame(held.frame, held.station, held.duration)
            if self.log_frames:
                record = self._log_record(record)
            state = "ended" if end <= now else "on the wire" if start < now else "queued"
            records.append({"station": held.station, "order": first + k, "queued": held.queued, "start": start,
                            "end": end, "duration": held.duration, "id": record.id, "extended": record.extended,
                            "rtr": record.rtr, "dlc": record.dlc, "data": list(record.data),
                            "direction": record.direction if self.log_frames else None,
                            "message": record.message if self.log_frames else None, "state": state})
        return records

    # -- the bus model, computed lazily: frames start and end between firings
    def _settle(self, now: float) -> None:
        """Every frame that ended by `now` ends (in order), the next starting as each ends."""
        current = self.current
        while current is not None and current.end <= now:
            self._end(current)
            if self.queued:
                self._start(current.end)
                current = self.current
            else:
                current = self.current = None

    def _end(self, held: _Frame) -> None:
        self.ended.append(held)
        self.order += 1
        self.busy_time += held.duration
        self.window_busy += held.duration
        self.frames += 1

    def _start(self, now: float) -> None:
        station, position = self._winner()
        held = self.current = self.waiting[station].pop(position)
        self.queued -= 1
        held.start = now
        held.end = round((now + held.duration) * TIME_GRID) / TIME_GRID  # on the engine's grid (`plus`),
        if held.due != held.end:                                          # as format 1's delivery firing is
            self._deliver(held)

    def _rearbitrate(self, now: float) -> None:
        """A frame posted during the SOF bit: arbitration again, the frame that was winning back
        at the head of its queue; a new winner ends one of its own frame times after the SOF."""
        held = self.current
        self.waiting[held.station].insert(0, held)
        self.queued += 1
        station, position = self._winner()
        if station == held.station and position == 0:
            self.waiting[station].pop(0)  # it still wins
            self.queued -= 1
            return
        start = held.start
        self._start(start)

    def _winner(self) -> tuple:
        """(station, position in its queue) of the frame that wins arbitration now."""
        best = None
        if self.station_queue == "fifo":
            for station, queue in enumerate(self.waiting):
                # the lowest arbitration field wins; equal ids (an error on a real bus): the lower station
                if queue and (best is None or queue[0].key < best[0]):
                    best = (queue[0].key, station)
            return best[1], 0
        for station, queue in enumerate(self.waiting):
            if queue:
                position = min(range(len(queue)), key=lambda k: queue[k].key)
                if best is None or queue[position].key < best[0]:
                    best = (queue[position].key, station, position)
        return best[1], best[2]

    def _schedule(self) -> None:
        """Queue every waiting frame's deliveries at the wire end it will have if nothing more is
        posted (the arbitration of each following frame, computed now on copies of the queues)."""
        self.scheduled = True
        current = self.current
        if current is None:
            return
        self._last_end = current.end
        if not self.queued:
            return
        saved = [list(queue) for queue in self.waiting]
        end = current.end
        try:
            for _ in range(self.queued):
                station, position = self._winner()
                held = self.waiting[station].pop(position)
                held.start = end
                held.end = end = round((end + held.duration) * TIME_GRID) / TIME_GRID  # `plus`, inline
                if held.due != end:
                    self._deliver(held)
            self._last_end = end
        finally:
            self.waiting = saved

    def _deliver(self, held: _Frame) -> None:
        """Queue the frame for every other station at its wire end (again, if that moved)."""
        if held.later is not None:
            held.later.cancel()
        held.due = held.end
        held.later = deliver_later(self, "rx", self._others[held.station], held.frame, held.end)

    # How many frames station i's full queue refused: one report per load period (0.1 s if the
    # reports are off) however many came.
    @refused.action(value=lambda self, i: self.refusals[i], when=lambda self, i: self.refusals[i] > 0,
                    after=lambda self, i: self.load_period or 0.1)
    def reported_refusals(self, i):
        self.refusals[i] = 0

    # The report settles the frames that ended by its time first (its value reads their busy
    # time). An output value may not ask the time (the trace checker evaluates it outside any
    # firing), so the report's time is kept in the state: `report_due`, set as each report fires.
    # The do-block settles again, which changes nothing, so that the engine sees it write.
    @load.action(value=lambda self: self._settled_busy() / self.load_period,
                 when=lambda self: self.load_period > 0, after="load_period")
    def reported(self):
        now = esprit_now()
        self._settle(now)
        self.report_due = plus(now, self.load_period)
        self.elapsed += self.load_period
        self.busy_time_reported = self.busy_time
        self.window_busy = 0.0

    def _settled_busy(self) -> float:
        self._settle(self.report_due)
        return self.window_busy


class BurstCanopenCanBus(BurstCanBus):
    """`BurstCanBus` of a bus with CANopen stations: each frame of its bursts named by family
    (`canopen_frame_log`), the CANopen node ids being `canopen`."""

    canopen = Param(())

    def init(self):
        from .canopen_frame_log import _node_ids
        super().init()
        self.canopen_ids = _node_ids(self.canopen, "CanopenCanBus")

    def _log_record(self, record):
        from .canopen_frame_log import renamed
        return renamed(record, self.canopen_ids)
