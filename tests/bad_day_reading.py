"""What a bad day's recordings say of each fault (tests/bad_day_run.py): from the CAN frames the
arm's host recorded, how long after the fault every axis was safe and whether a command reached
an axis while its host was cut off; from the hub's recording, when the nodes the fault touched
were heard again (recovered) and what the launchers restarted; each gap of the merged recording
named with the fault that caused it. Shared by bench/bad_day.py and its short campaign test."""
from __future__ import annotations

import re
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

from bad_day_run import Campaign, Done
from fault_schedule import rate_bits
from partition_run import CLOSED_LOOP, HEARTBEAT, IDLE, SET_AXIS_STATE, SET_INPUT_POS, read_partition

from iotad.recording.mcap_format import GAP_TOPIC
from iotad.recording.mcap_reader import RecordingError, read_recording
from iotad.recording.merge import MergeError, merge, write_merged

SLACK_NS = 2_000_000_000  # a gap this close to a fault's window is the fault's (the recorders' flush, a heartbeat)


@dataclass
class FaultReading:
    """One fault as the recordings tell it. `safe`: s from the fault to every axis safe (told IDLE,
    or saying by its heartbeat that it is not in closed loop), None where the fault does not take
    the motors' setpoints away; `unsafe`: axes never safe before the fault ended; `silence`: on
    the motor node's own clock, from its last setpoint to its first IDLE (a partition of arm);
    `commands_while_cut`: Set_Input_Pos or closed-loop requests sent to an axis after it was made
    safe and before the heal; `recovered`: s from the fault's end until every node it touched was
    heard at the hub again (None: never, within the run)."""

    done: Done
    safe: float | None = None
    unsafe: list[int] = field(default_factory=list)
    silence: float | None = None
    commands_while_cut: int | None = None
    recovered: float | None = None
    touched: tuple[str, ...] = ()
    note: str = ""


@dataclass
class Reading:
    faults: list[FaultReading]
    events: list[dict]             # launcher events: exit, live, stale, lost, down, host_back, giveup...
    gaps: list[dict]               # the merged recording's gaps, each with "cause"
    merged: Path | None
    merge_error: str = ""
    check: str = ""                # `iotad check` of the merged recording (or of the hub's, if the merge failed)
    check_code: int | None = None
    placements: list[float] = field(default_factory=list)  # s into the campaign of each cube placed
    placed: int | None = None
    fates: dict = field(default_factory=dict)  # what became of the cubes the belts brought (cube_fates)
    problems: list[dict] = field(default_factory=list)  # those `iotad check` listed, each with its "cause"
    # the motor node's link watch: the wall-clock ns of each LINK_LOST it reported (every axis
    # made safe for want of setpoints), each with the fault whose window holds it ('' if none)
    trips: list[tuple[int, str]] = field(default_factory=list)


def takes_setpoints_away(fault, machine) -> bool:
    """Whether `fault` stops the motor node's setpoints or the motor node itself, so that the
    axes must be made safe: a partition of arm, a kill or stop of the setpoints' source or of the
    motor node, a kill of arm's agent or launcher (its nodes die with it), a stop of arm's launcher
    (the router its nodes reach the hub through)."""
    if fault.kind == "partition":
        return fault.host == machine.nodes[machine.motor]
    if fault.kind in ("kill", "stop"):
        if fault.target in (f"node:{machine.setpoints_from}", f"node:{machine.motor}"):
            return True
        return fault.host == machine.nodes[machine.motor] and fault.target in ("agent", "launcher") \
            and not (fault.kind == "stop" and fault.target == "agent")
    return False


def touched_nodes(fault, machine) -> tuple[str, ...]:
    """The nodes a fault cuts off, stops or kills: those whose recovery is waited for."""
    if fault.target.startswith("node:"):
        return (fault.target[5:],)
    if fault.kind in ("partition", "slow") or fault.target in ("agent", "launcher"):
        return tuple(sorted(node for node, host in machine.nodes.items() if host == fault.host))
    return ()


def frames(recording, system: str, motor: str, drives: str) -> list[tuple[int, int, int, bytes]]:
    """(sender's wall-clock ns, CAN node id, command id, data) of every frame the motor node and the
    drives sent, in time order."""
    senders = (f"iota/{system}/{motor}/can_tx", f"iota/{system}/{drives}/can_tx")
    out = []
    for message in recording.messages:
        if message.topic in senders:
            value = message.value
            out.append((message.publish_time, value["id"] >> 5, value["id"] & 0x1F, bytes(value["data"])))
    return sorted(out)


def node_hosts(recording, machine) -> dict[str, str | None]:
    """node -> its host: the campaign's nodes, and those the recorded system file adds (a CAN
    bus's logger, on its stations' host)."""
    from iotad.launcher.system.declaration import SystemFileError
    from iotad.recording.recorded_system import recorded_declaration

    try:
        declared = recorded_declaration(recording)
    except SystemFileError:
        declared = None
    hosts = {name: node.host for name, node in declared.nodes.items()} if declared is not None else {}
    return {**hosts, **machine.nodes}


def link_watch_trips(recording, system: str, motor: str) -> list[int]:
    """The receipt times (ns) of the motor node's LINK_LOST reports on `joint_status`: each is its
    link watch making every axis safe because setpoints stopped coming (one report per axis)."""
    prefix = f"iota/{system}/{motor}/joint_status/"
    out = []
    for message in recording.messages:
        if message.topic.startswith(prefix):
            value = message.value
            if isinstance(value, dict) and value.get("event") == "LINK_LOST":
                out.append(message.log_time)
    return sorted(out)


def time_to_safe(all_frames, node_ids, start_ns: int, until_ns: int) -> tuple[float | None, list[int]]:
    """From `start_ns`, seconds until every axis of `node_ids` was safe (told IDLE by the motor
    node, or saying by its heartbeat it is not in closed loop: its own watchdog); an axis already
    safe at `start_ns` counts 0. The axes never safe before `until_ns` are the second value."""
    worst, unsafe = 0.0, []
    for node in node_ids:
        mine = [(t, cmd, data) for t, n, cmd, data in all_frames if n == node]
        told = [data[0] for t, cmd, data in mine if cmd == SET_AXIS_STATE and t < start_ns]
        said = [data[4] for t, cmd, data in mine if cmd == HEARTBEAT and t < start_ns and len(data) > 4]
        if (told and told[-1] == IDLE) or (said and said[-1] != CLOSED_LOOP):
            continue  # safe already
        after = [t for t, cmd, data in mine if start_ns <= t <= until_ns and (
            (cmd == SET_AXIS_STATE and data[0] == IDLE) or (cmd == HEARTBEAT and len(data) > 4 and data[4] != CLOSED_LOOP))]
        if after:
            worst = max(worst, (after[0] - start_ns) / 1e9)
        else:
            unsafe.append(node)
    return worst, unsafe


def heard_again(recording, system: str, nodes: tuple[str, ...], after_ns: int) -> int | None:
    """The hub's receipt time (ns) by which every node of `nodes` had sent a heartbeat that reached
    the hub after `after_ns`; None if one never did."""
    firsts = {}
    for message in recording.messages:
        for node in nodes:
            if node not in firsts and message.topic == f"iota/{system}/{node}/@heartbeat" \
                    and message.log_time > after_ns:
                firsts[node] = message.log_time
    return max(firsts.values()) if len(firsts) == len(nodes) and nodes else None


def launcher_events(recording, system: str, kinds=("exit", "live", "stale", "lost", "down", "host_back", "giveup")) -> list[dict]:
    out, seen = [], set()
    for message in recording.messages:
        if message.topic == f"iota/{system}/@launcher":
            try:
                value = message.value
            except RecordingError:
                continue
            if isinstance(value, dict) and value.get("event") in kinds:
                key = (value.get("event"), value.get("node"), value.get("host"), value.get("t_ns"))
                if key not in seen:  # a hub's later file read beside the merge holds copies
                    seen.add(key)
                    out.append({**value, "log_time": message.log_time})
    return out


def cause_of(gap: dict, done: list[Done], machine, end_ns: int | None = None) -> str:
    """The fault of `done` that explains `gap` (a gap of the merge, or a recorder's sequence gap):
    the latest begun of those on the gap's host whose window (from its start to its end and the
    time it settles) holds the gap's start and whose kind can make such a gap (a recording cut
    short, begun late or ended early: a kill of that host's recorder, agent or launcher; events
    that did not reach the hub: a partition, a slowed link, a stop or a kill on that host, or a
    kill of the hub's recorder, whatever the host); past the campaign's end (`end_ns`), the run's
    stop; '' if none."""
    from fault_schedule import settle

    start, host, reason = gap.get("from_ns", 0), gap.get("host"), gap.get("reason", "")
    own_file = any(words in reason for words in ("cut short", "began after", "ended before", "between its recordings"))
    hub_lacks = "did not reach the hub" in reason
    found = ""
    for made in sorted(done, key=lambda d: d.start_ns):
        fault = made.fault
        if made.missed:
            continue
        if fault.kind == "kill" and fault.target == "recorder" and fault.host == "brain" and hub_lacks \
                and start >= made.start_ns - SLACK_NS:
            # what the hub's recorder did not write after its kill: every host's events, until
            # its successor wrote the hub's next file
            found = f"{fault.describe()} at {fault.at:.1f} s"
            continue
        window = (made.start_ns - SLACK_NS, made.end_ns + int(settle(fault) * 1e9) + SLACK_NS)
        if not window[0] <= start <= window[1]:
            continue
        if own_file and not (fault.kind == "kill" and fault.target in ("recorder", "agent", "launcher")):
            continue
        hosts = {fault.host} | ({machine.nodes[fault.target[5:]]} if fault.target.startswith("node:") else set())
        if host is None or host in hosts:
            found = f"{fault.describe()} at {fault.at:.1f} s"
        elif hub_lacks and fault.kind in ("partition", "slow") and not found:
            # another host's events that the hub lacks (its own file holds them) while this host's
            # link was cut or slowed, or its backlog drained: seen in every 10-minute campaign at
            # a heal or a slowdown's end (1 to 22 events), as if the hub's router, taking this
            # host's backlog, fell behind the others' links, which drop across hosts. Named so,
            # as the likeliest cause; not measured inside the router
            found = f"{fault.describe()} at {fault.at:.1f} s (its backlog at the hub, it seems)"
    if not found and end_ns is not None and start >= end_ns:
        found = "the run's stop (Ctrl-C) after the campaign"
    return found


def read_campaign(campaign: Campaign, check: bool = True) -> Reading:
    """Everything the campaign's recordings say: merged first (`iotad merge` of every file the
    hosts wrote), then read per fault."""
    machine, folder = campaign.machine, campaign.folder
    files = campaign.files()
    merged_path, merge_error, merged = folder / f"{machine.name}.merged.mcap", "", None
    try:
        merged = merge(files)
        write_merged(merged, merged_path)
    except (MergeError, RecordingError, OSError) as error:
        merge_error, merged_path = f"{type(error).__name__}: {error}", None
    if merged_path is not None:
        recording = merged.recording  # as written (reading it again would take as long as the merge)
        gaps = [dict(g) for g in merged.gaps]
    else:  # what each file holds, read alone
        recording = read_recording(campaign.recording, salvage=True)
        gaps = []
    host_of = node_hosts(recording, machine)
    for message in recording.messages:  # recorders' own sequence gaps the merge kept
        if message.topic == GAP_TOPIC:
            value = message.value
            key = str(value.get("key", ""))
            node = key.split("/")[2] if key.count("/") >= 2 else ""
            gaps.append({"host": host_of.get(node), "from_ns": message.log_time, "to_ns": message.log_time,
                         "events": value.get("missing", 0),
                         "reason": f"recorder sequence gap on {value.get('key', '?')}"})
    for gap in gaps:
        gap["cause"] = cause_of(gap, campaign.done, machine, campaign.began_ns + int(campaign.length * 1e9))
    arm_frames = frames(recording, machine.name, machine.motor, machine.drives)
    readings = []
    for made in campaign.done:
        fault, reading = made.fault, FaultReading(made, touched=touched_nodes(made.fault, machine))
        if not made.missed and takes_setpoints_away(fault, machine):
            until = max(made.end_ns, made.start_ns + 1_000_000_000)
            reading.safe, reading.unsafe = time_to_safe(arm_frames, machine.node_ids, made.start_ns, until)
            drives_after = any(n in machine.node_ids and cmd == HEARTBEAT and made.start_ns + 200_000_000 < t <= until
                               for t, n, cmd, data in arm_frames)
            if reading.unsafe and not drives_after:
                # the simulated drives are a node of the arm's host and died with it: nothing is
                # left to be safe or unsafe (real drives stay powered, and their watchdogs disarm)
                reading.note = f"the simulated drives ({machine.drives}) stopped with their host: axes " \
                               f"{reading.unsafe} not told IDLE before"
                reading.safe, reading.unsafe = None, []
            if fault.kind == "partition":
                partition = read_partition(recording, machine.name, made.start_ns, made.end_ns, machine.node_ids,
                                           machine.motor, machine.drives)
                reading.silence, reading.commands_while_cut = partition.silence, partition.commands_while_cut
        if reading.touched:
            back = heard_again(recording, machine.name, reading.touched, made.end_ns)
            reading.recovered = None if back is None else (back - made.end_ns) / 1e9
        elif fault.target == "recorder" and not made.missed:
            begun = [first for path, first in file_starts(campaign).items() if host_of_file(path, machine.name)
                     == (fault.host if fault.host != "brain" else None) and first > made.end_ns]
            reading.recovered = (min(begun) - made.end_ns) / 1e9 if begun else None
        readings.append(reading)
    out = Reading(readings, launcher_events(recording, machine.name), gaps, merged_path, merge_error)
    if check:
        target = merged_path or campaign.recording
        done = subprocess.run([sys.executable, "-m", "iotad", "check", "--all", str(target)], capture_output=True, text=True,
                              timeout=600, cwd=Path(__file__).resolve().parents[1])
        out.check, out.check_code = (done.stdout + done.stderr).strip(), done.returncode
        (folder / "check.txt").write_text(out.check + "\n")
        origin = float(recording.info["run"]["origin"])
        out.problems = check_problems(out.check)
        for problem in out.problems:
            problem["cause"] = problem_cause(problem["t"] + origin - campaign.began_ns / 1e9, campaign.done,
                                             campaign.began_ns)
    reports = link_watch_trips(recording, machine.name, machine.motor)
    # a trip reports once per axis, at one instant: one trip per run of reports within 50 ms
    starts = [t for k, t in enumerate(reports) if k == 0 or t - reports[k - 1] > 50_000_000]
    out.trips = [(t, problem_cause((t - campaign.began_ns) / 1e9, campaign.done, campaign.began_ns)) for t in starts]
    try:
        out.placements, out.placed, out.fates = placements(recording, campaign)
    except RecordingError:
        pass  # not the conveyor
    return out


PROBLEM = re.compile(r"^\s+t=(?P<t>[-\d.e]+) \[(?P<kind>[a-z_ ]+)\] (?P<text>.*)$")
NODE_HEADER = re.compile(r"^(?P<node>[\w/]+): \d+ events, \d+ firings checked, (?P<count>\d+) problem")


def check_problems(text: str) -> list[dict]:
    """The problems `iotad check` listed (its report's `t=... [kind] ...` lines): t (s of the run),
    kind (late, expired, lost...), where (the node whose section it is in, or the link a delivery
    line names) and the line."""
    out, node = [], None
    for line in text.splitlines():
        header = NODE_HEADER.match(line)
        if header:
            node = header["node"]
            continue
        if line.startswith("delivery"):
            node = None
        found = PROBLEM.match(line)
        if found:
            where = node or found["text"].split(":", 1)[0]
            out.append({"t": float(found["t"]), "kind": found["kind"], "where": where, "line": line.strip()})
    return out


def problem_cause(second: float, done: list[Done], began_ns: int) -> str:
    """The fault in whose window (from a second before it to its end and the time it settles) the
    campaign's `second` falls (the campaign began at wall-clock `began_ns`); '' if none."""
    from fault_schedule import settle

    found = ""
    for made in done:
        start, end = (made.start_ns - began_ns) / 1e9, (made.end_ns - began_ns) / 1e9
        after = settle(made.fault)
        if made.fault.kind == "slow":
            # a slowed link's backlog drains after it: seed 7's 7.8 s at 256 kbit to camera had
            # images 10 s late delivered 5 s after its end, and fresh ones dropped behind them
            after = max(after, made.fault.duration)
        if start - 1.0 <= second <= end + after:
            found = f"{made.fault.describe()} at {made.fault.at:.1f} s"
    return found


def host_of_file(path: Path, system: str) -> str | None:
    """The host whose recording `path` is, by its name: NAME.mcap and NAME_N.mcap the hub's (None),
    NAME.HOST.mcap, NAME.HOST_N.mcap and NAME.HOST-N.mcap HOST's."""
    rest = path.name.removeprefix(system).removesuffix(".mcap")
    if not rest.startswith("."):
        return None
    return rest[1:].split("_")[0].split("-")[0]


def file_starts(campaign: Campaign) -> dict[Path, int]:
    """Each recording's first receipt time (ns): from its summary, or, for a file cut short (a
    recorder killed in its turn has written no summary), from its first message read in order."""
    from mcap.reader import make_reader
    from mcap.records import Message
    from mcap.stream_reader import StreamReader

    starts = {}
    for path in campaign.files():
        try:
            with open(path, "rb") as stream:
                summary = make_reader(stream).get_summary()
            if summary is not None and summary.statistics is not None:
                starts[path] = summary.statistics.message_start_time
                continue
        except Exception:  # noqa: BLE001 - no footer: read it from its start below
            pass
        try:
            with open(path, "rb") as stream:
                first = next((r.log_time for r in StreamReader(stream).records if isinstance(r, Message)), None)
        except Exception:  # noqa: BLE001 - cut inside its first chunk: no start to tell
            first = None
        if first is not None:
            starts[path] = first
    return starts


def placements(recording, campaign: Campaign) -> tuple[list[float], int, dict]:
    """s into the campaign of each cube the conveyor's world counted placed, how many in all
    (a world started again counts on from the one before it: conveyor_data), and what became of
    every cube the belts brought (`cube_fates`)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
    from sim.worlds.conveyor_plot import conveyor_data

    data = conveyor_data(recording)
    origin = recording.info["run"]["origin"]
    times, last = [], 0
    for t, counts in data["tally"]:
        if counts["placed"] > last:
            times.extend([t + origin - campaign.began_ns / 1e9] * (counts["placed"] - last))
            last = counts["placed"]
    return times, last, cube_fates(data["tally"], data["restarts"])


def cube_fates(tally: list[tuple[float, dict]], restarts: list[float]) -> dict:
    """What became of the cubes the belts brought, from the world's counts carried across its
    restarts (conveyor_data): placed, fell off the belt's end ("missed"), dropped, and gone with a
    world that was started again (on its belt or in its hand when its node was killed: the new
    world's belt starts empty), with how many worlds were. The rest were on the belt or in the hand
    at the end."""
    fates = {"brought": 0, "placed": 0, "missed": 0, "dropped": 0, "gone with a world": 0, "worlds restarted": 0}
    if not tally:
        return fates
    cuts, last, start = sorted(restarts), None, {"spawned": 0, "placed": 0, "missed": 0, "dropped": 0}
    for t, counts in tally:
        while cuts and t >= cuts[0]:
            cuts.pop(0)
            if last is not None:  # the world before ended with `last`: what it held besides its fates is gone
                fates["gone with a world"] += sum(sign * (last[key] - start[key]) for key, sign in
                                                  (("spawned", 1), ("placed", -1), ("missed", -1), ("dropped", -1)))
                fates["worlds restarted"] += 1
                start = {key: last[key] for key in start}
        last = counts
    fates.update(brought=last["spawned"], placed=last["placed"], missed=last["missed"], dropped=last["dropped"])
    return fates


# What the cell's traffic across hosts needs, measured: arm's link slowed to 256 kbit/s for 50 s
# (`bench/bad_day.py --minutes 1.5 --no-baseline --schedule '20 slow arm 50 256kbit'`) placed 11
# cubes in 90 s, one every 7-8 s as with no fault, and the motor node's link watch never tripped;
# at 64 kbit/s nothing it needs fits (docs/hosts.md, "A slowed link").
CELL_NEEDS_BITS = 256_000


def impaired_share(campaign: Campaign) -> float:
    """The share of the campaign during which the link of arm or camera was cut, or slowed below
    what the cell's traffic across hosts needs (CELL_NEEDS_BITS), counted once where such faults
    overlap. The cell cannot pick through those (the motors go safe, vision sees nothing, the
    setpoints do not fit), so the cubes a campaign can place are bounded by the time left,
    whatever recovers how fast. A link slowed to what still carries that traffic takes nothing."""
    spans = sorted((d.start_ns, d.end_ns) for d in campaign.done
                   if (d.fault.kind == "partition"
                       or d.fault.kind == "slow" and rate_bits(d.fault.rate) < CELL_NEEDS_BITS)
                   and not d.missed and d.end_ns > d.start_ns)
    total, current = 0, None
    for start, end in spans:
        if current is not None and start <= current[1]:
            current[1] = max(current[1], end)
            continue
        if current is not None:
            total += current[1] - current[0]
        current = [start, end]
    if current is not None:
        total += current[1] - current[0]
    return total / 1e9 / campaign.length if campaign.length else 0.0
