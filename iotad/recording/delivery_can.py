"""The delivery checks of CAN buses, each a function from the accounts (`delivery_accounts.py`)
to report rows: every station's `can_tx` frames against the `can_rx` of each other station
(`check_bus`), and against the bus's own log of the frames it carried, where the recording has
one (`check_bus_log`). Frames are matched by content and per-sender order (a CAN controller
sends in FIFO order), in time linear in the frames: each sender's unmatched frames wait in one
queue per content.
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from iotad.node_host import wire
from iotad.kernel.ports import Port
from iotad.recording.delivery_accounts import CAN_RX, CAN_TX, Accounts, Life, last_at_or_before
from iotad.recording.delivery_report import Link, Rows

BUS_LOG = "frames"  # a bus's log of every frame it carried (iotad.can.frame_log), if the recording has one
Frames = dict[str, list[tuple[float, tuple]]]  # station -> (t, frame) of each frame it sent, in order


def sent_frames(acc: Accounts, stations: list[str]) -> Frames:
    """What each station sent on the bus: its can_tx outputs, but those its port could not send."""
    sent: Frames = {}
    for s in stations:
        events = acc.events.get(s, [])
        refused = {e.t for e in events if e.kind == "violation" and e.action == CAN_TX
                   and (e.raw.get("value") or {}).get("violation") == "can_send_failed"}
        frames = []
        for e in events:
            if e.kind == "output" and e.action == CAN_TX:
                t = e.t
                if t in refused:  # the port could not send it (recorded): nobody could receive it
                    refused.discard(t)
                    continue
                frames.append((t, _frame(e.value)))
        sent[s] = frames
    return sent


@dataclass
class _Matching:
    """How the frames senders sent are matched to what one receiver (or the bus log) got: per
    sender, its link, the sends taken (delivered) and altered, and the latest one taken."""

    sent: Frames
    links: dict[str, Link]
    taken: dict[str, set[int]] = field(default_factory=dict)
    altered: dict[str, set[int]] = field(default_factory=dict)
    last_taken: dict[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.taken = {s: set() for s in self.links}
        self.altered = {s: set() for s in self.links}

    def take(self, s: str, k: int) -> bool:
        """Take send `k` of `s`; whether it came after a later one of `s` (out of order)."""
        self.taken[s].add(k)
        overtaken = k < self.last_taken.get(s, -1)
        self.last_taken[s] = max(k, self.last_taken.get(s, -1))
        return overtaken

    def alter(self, rows: Rows, s: str, k: int, what: str) -> None:
        """Send `k` of `s` arrived changed: `what` says how."""
        self.altered[s].add(k)
        self.links[s].altered += 1
        rows.finding(self.links[s], "altered", self.sent[s][k][0],
                     f"{s} sent frame {_frame_text(self.sent[s][k][1])}, {what}")

    def unmatched(self) -> list[tuple[str, int, float, tuple]]:
        """(sender, k, t sent, frame) of every send neither taken nor altered."""
        return [(s, k, t_sent, frame) for s in self.links for k, (t_sent, frame) in enumerate(self.sent[s])
                if k not in self.taken[s] and k not in self.altered[s]]


# ------------------------------------------------------------------------------ station to station
def check_bus(acc: Accounts, bus: str, stations: list[str], sent: Frames) -> Rows:
    """Frames each station sent (can_tx outputs) against the frames each other station received
    (can_rx inputs), by content and per-sender order."""
    rows = Rows()
    for receiver in stations:
        senders = [s for s in stations if s != receiver]
        links = {s: rows.link(f"can {bus}: {s} -> {receiver}", "can", (s, receiver), sent=len(sent[s]))
                 for s in senders}
        matching = _Matching(sent, links)
        foreign = _receive(acc, rows, receiver, matching)
        _foreign_frames(acc, rows, bus, receiver, matching, foreign)
        _unreceived(acc, rows, receiver, matching)
    return rows


def _receive(acc: Accounts, rows: Rows, receiver: str, matching: _Matching) -> list[tuple[float, tuple]]:
    """Match each frame `receiver` received to the earliest send of it that it can be; returns
    (t, frame) of those no station sent."""
    sent, senders = matching.sent, list(matching.links)
    window = acc.can_window()  # a frame may wait behind others on a busy bus
    got = [(e.t, _frame(e.value)) for e in acc.events.get(receiver, []) if e.kind == "input" and e.action == CAN_RX]
    waiting = _frame_queues(sent, senders)
    life = acc.life.get(receiver)
    if life is not None:
        _unheard_before_start(waiting, sent, got, life)
    foreign: list[tuple[float, tuple]] = []
    heard_until = -math.inf  # the latest send time among the frames it received so far
    starts = [run[0] for run in life.runs] if life is not None and life.seen and life.virtual_end is None else []

    def run_start(t: float) -> float:
        # the engine start of the receiver's process at t, if a restart: the twins sent before its
        # first start are trimmed by `_unheard_before_start`, which keeps as many as the receiver
        # heard; its socket may have opened any time before (a slow start on a loaded machine)
        k = last_at_or_before(starts, t)
        return starts[k] if k >= 1 else -math.inf
    for t, frame in got:
        best = None
        for s in senders:
            queue = waiting[s].get(frame)
            if not queue:
                continue
            # an older twin was lost if the receiver already got a frame its sender sent
            # after it (per-sender FIFO), or one any station sent well after it (the bus
            # is one FIFO): a receiver that was frozen drains its backlog in order, late
            while len(queue) > 1 and sent[s][queue[-2]][0] <= t + acc.tolerance and (
                    queue[-1] < matching.last_taken.get(s, -1)
                    or sent[s][queue[-1]][0] + window < heard_until
                    or sent[s][queue[-1]][0] + window < run_start(t)):
                queue.pop()
            k = queue[-1]
            if sent[s][k][0] <= t + acc.tolerance and (best is None or sent[s][k][0] < sent[best[0]][best[1]][0]):
                best = (s, k)
        if best is None:
            foreign.append((t, frame))
            continue
        s, k = best
        waiting[s][frame].pop()
        t_sent = sent[s][k][0]
        heard_until = max(heard_until, t_sent)
        if matching.take(s, k):
            rows.finding(matching.links[s], "reordered", t_sent,
                         f"frame {_frame_text(frame)} received at t={t:.6g}, after a frame {s} sent later")
        rows.delivered(matching.links[s], t_sent, (t - t_sent) * acc.unit)
    return foreign


def _foreign_frames(acc: Accounts, rows: Rows, bus: str, receiver: str, matching: _Matching,
                    foreign: list[tuple[float, tuple]]) -> None:
    """Frames `receiver` got that no station sent: altered, if one of the same id is missing."""
    sent = matching.sent
    by_head: dict[str, dict[tuple, deque]] = {s: {} for s in matching.links}
    for s, k, _, frame in matching.unmatched():
        by_head[s].setdefault(frame[:3], deque()).append(k)
    for t, frame in foreign:
        pick = None
        for s in matching.links:
            queue = by_head[s].get(frame[:3])
            if queue and sent[s][queue[0]][0] <= t + acc.tolerance and \
                    (pick is None or sent[s][queue[0]][0] < sent[pick][by_head[pick][frame[:3]][0]][0]):
                pick = s
        if pick is not None:
            matching.alter(rows, pick, by_head[pick][frame[:3]].popleft(),
                           f"{receiver} received {_frame_text(frame)} at t={t:.6g}")
        elif acc.virtual and Port(receiver, CAN_RX, None) in acc.system.external:
            # an input script's frame into a can_rx the system file declares external
            rows.note("external", f"can {bus}: (outside) -> {receiver}", t, f"{receiver} received frame "
                      f"{_frame_text(frame)} from outside (its {CAN_RX} is external)", (receiver,))
        elif acc.virtual:  # every station of the modelled bus is a node: the frame is no one's
            link = rows.link(f"can {bus}: (no station) -> {receiver}", "can", (receiver,))
            link.unexplained += 1
            rows.finding(link, "unexplained", t, f"{receiver} received frame {_frame_text(frame)}, "
                         "which no station's can_tx sent")
        else:
            rows.note("foreign", f"can {bus}: -> {receiver}", t, f"{receiver} received frame "
                      f"{_frame_text(frame)}, which no station's can_tx sent (a device that is not a node, "
                      "or a station's final frames)", (receiver,))


def _unreceived(acc: Accounts, rows: Rows, receiver: str, matching: _Matching) -> None:
    """Every frame sent that `receiver` never got: lost, or not judged (it was not running)."""
    window = acc.can_window()
    life = acc.life.get(receiver)
    for s, k, t_sent, frame in matching.unmatched():
        if life is not None and life.before_start(t_sent):
            # a real bus delivers only to sockets open at the time: a station that had
            # not started could not hear it, whatever it heard later
            verdict, reason = life.judge(t_sent, window, receiver)
        elif k < matching.last_taken.get(s, -1):
            verdict = "lost"
            reason = (life is not None and life.down(t_sent, window, receiver)) or \
                f"{receiver} received frames {s} sent after it"
        elif life is not None:
            verdict, reason = life.judge(t_sent, window, receiver)
        else:
            verdict, reason = "unjudged", f"{receiver} is not in this recording"
        _unmatched_frame(rows, matching.links[s], verdict, reason, t_sent, frame, f"never reached {receiver}")


def _unmatched_frame(rows: Rows, link: Link, verdict: str, reason: str, t_sent: float, frame: tuple,
                     missed: str) -> None:
    """A sent frame nobody matched: counted and reported lost, or not judged, by `verdict`."""
    if verdict == "lost":
        link.lost += 1
        rows.finding(link, "lost", t_sent, f"frame {_frame_text(frame)} sent at t={t_sent:.6g} {missed}; {reason}")
    else:
        link.unjudged += 1
        rows.finding(link, "not judged", t_sent, f"frame {_frame_text(frame)}: {reason}", False)


# ------------------------------------------------------------------------------ station to bus log
def check_bus_log(acc: Accounts, bus: str, stations: list[str], sent: Frames) -> Rows:
    """Each station's can_tx frames against the bus's own log of the frames it carried (the
    modelled bus's `frames` output, `iotad.can.frame_log`: sender station and frame), in the
    station's order: a frame sent and never on the bus is lost, a frame on the bus its station
    never sent is unexplained (or altered, when one of the same id is missing)."""
    rows = Rows()
    log = acc.on_wire(wire.channel_key(acc.system.name, bus, BUS_LOG, None))
    if not log:
        return rows
    params = (acc.specs.get(bus) or {}).get("params") or {}
    fifo = params.get("station_queue", "fifo") == "fifo"  # else a station's frames may overtake
    links = {s: rows.link(f"can {bus}: {s} -> (bus)", "can", (s,), sent=len(sent[s])) for s in stations}
    matching = _Matching(sent, links)
    strays, nameless = _logged(acc, rows, stations, matching, log, fifo)
    _strays(acc, rows, bus, stations, matching, strays)
    _nameless(acc, rows, bus, matching, nameless)
    _unlogged(acc, rows, bus, matching, log, fifo)
    return rows


def _logged(acc: Accounts, rows: Rows, stations: list[str], matching: _Matching, log: list, fifo: bool) -> tuple:
    """Match each logged frame to its station's earliest send of it. Returns the strays, (t,
    station, frame, the station number logged) of frames no send of their station explains,
    and the nameless: (t, frame, the send time of the frame logged before it) of frames of a
    real bus's log (no station) that no station sent (the log is in bus order, so a changed
    frame was sent after that one)."""
    sent, window = matching.sent, acc.can_window()
    waiting = _frame_queues(sent, stations)
    strays: list[tuple[float | None, str | None, tuple, Any]] = []
    nameless: list[tuple[float | None, tuple, float | None]] = []
    previous_sent: float | None = None
    for message in log:
        value = message.value
        value = value if isinstance(value, dict) else {}
        station = value.get("station")
        frame, t = _frame(value), message.t
        if station is None:  # a listener that cannot tell the sender: the station that sent it first
            heads = [(sent[x][waiting[x][frame][-1]][0], x) for x in stations if waiting[x].get(frame)]
            if not heads:
                nameless.append((t, frame, previous_sent))
                continue
            s = min(heads)[1]
        else:
            s = stations[station] if isinstance(station, int) and 0 <= station < len(stations) else None
        queue = waiting[s].get(frame) if s is not None else None
        if queue and t is not None:
            while len(queue) > 1 and sent[s][queue[-1]][0] < t - window \
                    and sent[s][queue[-2]][0] <= t + acc.tolerance:
                queue.pop()  # an older twin that waited past the window never made it
        if not queue or (t is not None and sent[s][queue[-1]][0] > t + acc.tolerance):
            strays.append((t, s, frame, station))
            continue
        k = queue.pop()
        t_sent = previous_sent = sent[s][k][0]
        if matching.take(s, k) and fifo:
            rows.finding(matching.links[s], "reordered", t_sent, f"frame {_frame_text(frame)} went on the bus at "
                         f"t={t:.6g}, after a frame {s} sent later")
        matching.links[s].delivered += 1
        if t is not None:
            matching.links[s].latencies.append((t - t_sent) * acc.unit)
    return strays, nameless


def _strays(acc: Accounts, rows: Rows, bus: str, stations: list[str], matching: _Matching, strays: list) -> None:
    """Logged frames their station never sent: altered (one of the same id is missing), after
    the station's trace ends (a killed node), or unexplained."""
    sent = matching.sent
    for t, s, frame, station in strays:
        if s is None:
            link = rows.link(f"can {bus}: station {station!r} -> (bus)", "can", ())
            link.unexplained += 1
            rows.finding(link, "unexplained", t, f"the bus carried frame {_frame_text(frame)} from station "
                         f"{station!r}, which is none of {stations}")
            continue
        twin = next((k for k in range(len(sent[s])) if k not in matching.taken[s] and k not in matching.altered[s]
                     and sent[s][k][1][:3] == frame[:3] and (t is None or sent[s][k][0] <= t + acc.tolerance)),
                    None)
        if twin is not None:
            matching.alter(rows, s, twin, f"the bus carried {_frame_text(frame)}" + ("" if t is None else f" at t={t:.6g}"))
            continue
        life = acc.life.get(s)
        lost_trace = life.untraced_at(t) if life is not None and t is not None else None
        if lost_trace is not None:
            rows.finding(matching.links[s], "untraced", t, f"the bus carried frame {_frame_text(frame)} from {s} "
                         f"after {s}'s recorded trace of that run ends (t={lost_trace:.6g}; a killed node loses its "
                         "last trace period)", False)
            continue
        matching.links[s].unexplained += 1
        rows.finding(matching.links[s], "unexplained", t, f"the bus carried frame {_frame_text(frame)} from {s}, "
                     f"and {s}'s trace holds no such can_tx")


def _nameless(acc: Accounts, rows: Rows, bus: str, matching: _Matching, nameless: list) -> None:
    """Frames heard on a real bus that no station's can_tx sent: altered, or not a node's."""
    sent, window = matching.sent, acc.can_window()
    for t, frame, floor in nameless:
        twins = [(t_sent, s, k) for s, k, t_sent, sent_frame in matching.unmatched()
                 if sent_frame[:3] == frame[:3] and (t is None or t_sent <= t + acc.tolerance)]
        if twins:
            # the first one sent after the frame logged before it; else the latest sent by then
            # (earlier ones may predate the logger). Not simply the latest: a real-time log's
            # time is when the logger published, and frames sent after the logger stopped are
            # missing from it too.
            later = [twin for twin in twins if floor is not None and twin[0] >= floor - window]
            _, s, k = min(later) if later else max(twins)
            matching.alter(rows, s, k, f"the bus carried {_frame_text(frame)}" + ("" if t is None else f" at t={t:.6g}"))
            continue
        rows.note("foreign", f"can {bus}: (bus)", t, f"the bus carried frame {_frame_text(frame)}, which no "
                  "station's can_tx sent (a device that is not a node, or a station's final frames)")


def _unlogged(acc: Accounts, rows: Rows, bus: str, matching: _Matching, log: list, fifo: bool) -> None:
    """Every frame sent that the log does not hold: lost, or not judged (the logger was down)."""
    window = acc.can_window()
    end = max((m.t for m in log if m.t is not None), default=None)
    # a real-time log is a node (iotad.can.frame_log.BusLogger): it logs only while it runs
    logger = acc.life.get(bus) if not acc.virtual and bus not in acc.system.bus_nodes else None
    cut = _cut_at_end(acc, bus, list(matching.links))
    for s, k, t_sent, frame in matching.unmatched():
        down = _logger_down(logger, bus, t_sent, window) if logger is not None else None
        under_way = cut[s].get(frame) if cut is not None else None
        if under_way:  # the run's end says where it was: judged by that, not left in flight
            state, start, ended = under_way.pop(0)
            if state == "ended":  # carried: it ended before the run did, its burst still to come
                matching.links[s].delivered += 1
                matching.links[s].latencies.append((ended - t_sent) * acc.unit)
                continue
            verdict = "unjudged"
            reason = (f"cut at the end: {state} when the run ended at t={acc.recording.can_at_end_t:.6g} (it would "
                      f"have gone on the bus at t={start:.6g}, ended at t={ended:.6g}; the recording's end lists it)")
        elif down is not None:
            verdict, reason = "unjudged", down
        elif fifo and k < matching.last_taken.get(s, -1):
            verdict, reason = "lost", f"the bus carried frames {s} sent after it"
        elif logger is not None and logger.seen:
            verdict, reason = "lost", f"the bus logger {bus} was running"
        elif end is not None and t_sent + window <= end:
            verdict, reason = "lost", f"the bus logged frames until t={end:.6g}"
        elif cut is not None:
            verdict, reason = "lost", "the bus neither carried it nor held it when the run ended (its end lists what it held)"
        else:
            verdict, reason = "unjudged", "in flight (queued or on the bus) when the run ended"
        _unmatched_frame(rows, matching.links[s], verdict, reason, t_sent, frame, "never went on the bus")


def _cut_at_end(acc: Accounts, bus: str, stations: list[str]) -> dict[str, dict[tuple, list]] | None:
    """Per station: each frame the modelled bus still held when a virtual run ended -> [(state,
    wire start, wire end)], its sends in order (`iotad.can_at_end`); None where the recording does
    not say (format 1, a real bus, a run that broke off): its frames under way are not judged."""
    if not acc.virtual or acc.recording.run_end is None or acc.recording.can_at_end_t is None:
        return None
    held = acc.recording.can_at_end
    frames = held.get(bus)
    if frames is None:
        frames = next((v for k, v in held.items() if k.rsplit("/", 1)[-1] == bus), None)
    if frames is None:
        return None
    cut: dict[str, dict[tuple, list]] = {s: {} for s in stations}
    for f in frames:
        station = f.get("station")
        if isinstance(station, int) and 0 <= station < len(stations):
            cut[stations[station]].setdefault(_frame(f), []).append((f.get("state"), f.get("start"), f.get("end")))
    return cut


def _logger_down(life: Life, bus: str, t: float, window: float) -> str | None:
    """Why the real-time bus logger `bus` could not have logged a frame sent at `t` (it had not
    started, was down, or the run ended within `window`), or None: it was listening."""
    if not life.seen:
        return f"the bus logger {bus} has no trace in this recording"
    starts = [run[0] for run in life.runs]
    k = last_at_or_before(starts, t)
    if k < 0:
        return f"sent before the bus logger {bus} started (t={starts[0]:.6g}): it could not hear it"
    last = life.runs[k][1]
    if t + window <= last:
        return None
    if k + 1 < len(life.runs):
        return (f"sent while the bus logger {bus} was down: its last sign of life at t={last:.6g}, "
                f"restarted at t={life.runs[k + 1][0]:.6g}")
    return f"in flight when the run ended: the bus logger {bus}'s last sign of life is at t={last:.6g}"


def _frame_queues(sent: dict[str, list], stations) -> dict[str, dict[tuple, list[int]]]:
    """Per station: each frame it sent -> the indices of its sends of that frame, the earliest
    last (a receiver's or the log's copy is matched to the earliest one not yet taken: `queue[-1]`,
    taken with `queue.pop()`). A list, not a deque: most frames are sent once (their data differ),
    and a deque of one costs 800 bytes, a list of one about 100."""
    waiting: dict[str, dict[tuple, list[int]]] = {s: {} for s in stations}
    for s in stations:
        for k, (_, frame) in enumerate(sent[s]):
            waiting[s].setdefault(frame, []).append(k)
        for queue in waiting[s].values():
            queue.reverse()
    return waiting


def _unheard_before_start(waiting: dict[str, dict[tuple, list[int]]], sent: dict[str, list],
                          got: list[tuple[float, tuple]], life: Any) -> None:
    """Take out of the candidates the frames a receiver cannot have heard: sent before its
    engine started, before its socket was open. A socket opened a little before the engine
    starts hears the last of them, so of the twins (the same frame, sent again and again, as an
    ODrive's heartbeat is) sent before the start it keeps as many as it received beyond those
    sent after; the earlier ones, if left, would be paired with its first receptions, and every
    reception after with a frame sent periods before it (false 'reordered', then 'lost').
    The sends after the start that it received are counted up to its last reception of the
    frame: the twins sent after that (while it stopped, or after it had stopped, as a sender
    that outlives it sends them) reached nothing, and counted they would push a twin it did
    hear out of the candidates (its first reception then 'altered')."""
    received: dict[tuple, int] = {}
    last_got: dict[tuple, float] = {}
    for t, frame in got:
        received[frame] = received.get(frame, 0) + 1
        last_got[frame] = max(t, last_got.get(frame, -math.inf))
    for sender, queues in waiting.items():
        for frame, queue in queues.items():
            before = sum(1 for k in queue if life.before_start(sent[sender][k][0]))  # the earliest sends
            if not before:
                continue
            heard_until = last_got.get(frame, -math.inf)
            after = sum(1 for k in queue if not life.before_start(sent[sender][k][0])
                        and sent[sender][k][0] <= heard_until)
            keep = max(0, received.get(frame, 0) - after)
            for _ in range(before - keep):
                queue.pop()


def _frame(value: Any) -> tuple:
    """A canFrame value as CAN compares it: id, extended, rtr, then the dlc valid data bytes."""
    if not isinstance(value, dict):
        return ("?", repr(value))
    data = value.get("data") or []
    dlc = value.get("dlc")
    dlc = dlc if isinstance(dlc, int) else len(data)
    return (value.get("id"), bool(value.get("extended")), bool(value.get("rtr")), dlc, tuple(data[:dlc]))


def _frame_text(frame: tuple) -> str:
    if len(frame) != 5 or not isinstance(frame[0], int):
        return str(frame[-1])
    ident, extended, rtr, dlc, data = frame
    head = f"0x{ident:0{8 if extended else 3}X}"
    return head + (f" RTR dlc {dlc}" if rtr else " [" + " ".join(f"{b:02X}" for b in data if isinstance(b, int)) + "]")


