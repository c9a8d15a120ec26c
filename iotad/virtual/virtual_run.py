"""A system's IOTAs in one process in virtual time (`iotad run SYSTEM.toml --virtual`, sweeps,
scripts): `run_virtual(system, VirtualOptions(until=...))`, recorded in the same MCAP format as a
real-time run, with a progress line on long runs. Raises `VirtualRunError`, one line for the user."""
from __future__ import annotations

import contextlib
import gc
import json
import os
import signal
import sys
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from iotad.launcher.run.recording_paths import RecordingClaimError, claim_recording, drop_empty_claim, unwritable
from iotad.launcher.system.system_file import System
from iotad.launcher.run.violation_examples import ViolationExamples

PROGRESS_EVERY = 1.0  # wall-clock seconds between progress lines


class VirtualRunError(Exception):
    """A virtual run that cannot be made as asked, said in one line."""


@dataclass(frozen=True)
class VirtualOptions:
    """How a system runs in virtual time (`iotad run --virtual`'s options, docs there)."""

    until: float                      # virtual seconds
    seed: int | None = None           # None: the eager policy; else random(seed)
    record_to: str | None = None      # None: a new name under recordings/
    force: bool = False               # replace a recording that is there
    no_record: bool = False
    inputs: str | None = None         # an input script (JSONL, times in spec units)
    plain: bool = False               # no progress line rewritten in place on a terminal
    strict: bool = False              # any violation ends the run non-zero (as [system] strict = true)
    recording_format: int = 2         # 1: each CAN frame as before bursts (docs/design.md, section 5)
    policy: str | None = None         # eager, latest or random:SEED (None: eager, or random(seed) with seed)
    goals: bool | None = None         # None: goals not judged; False: judged and printed; True: a miss exits 1


def run_virtual(system: System, args: VirtualOptions, second_process: bool = True) -> int:
    """Run `system` (checked) as `args` say; its exit status (0: the run went to its end).
    `second_process=False`: the recording is written in this process even with cores to spare
    (a sweep's runs already use every core)."""
    from iotad.recording.mcap_format import MAX_RECORDED_SECONDS
    from iotad.recording.writer_process import RecordingProcess

    if not args.no_record and args.until > MAX_RECORDED_SECONDS:
        raise VirtualRunError(f"--until {args.until:g}: a recording holds at most {MAX_RECORDED_SECONDS:.3g} s "
                       "(its times are 64-bit nanoseconds: 584 years); --no-record runs without one")
    # With a core to spare, the recording is written by a second process (a quarter of the work
    # of a run): started now, its start-up overlaps building the system.
    writer = None
    if not args.no_record and second_process and cores() > 1:
        try:
            writer = RecordingProcess()
        except OSError:  # no interpreter to start (an embedded Python): this process writes it
            writer = None
    try:
        return _run(system, args, writer)
    finally:
        if writer is not None:
            writer.close()


def cores() -> int:
    """CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def _run(system: System, args: VirtualOptions, writer) -> int:
    from iotad.launcher.system.in_process import compose
    from iotad.kernel.compose import flatten

    inputs = _read_inputs(args.inputs) if args.inputs else []
    try:
        root = compose(system, args.recording_format)
    except Exception as exc:  # noqa: BLE001 - a node that fails to build: the user's message
        raise VirtualRunError(f"{system.file}: cannot compose the system: {type(exc).__name__}: {exc}") from None
    # Every input's node is found before a recording is opened (or, with --force, replaced).
    leaves = {leaf.path: leaf for leaf in flatten(root).leaves}
    try:
        return _run_composed(system, args, writer, root, leaves, inputs)
    finally:
        close_nodes(leaves.values())


def close_nodes(leaves) -> None:
    """Close what the nodes hold (a PyBullet world), as their processes would at their end."""
    from iotad.kernel.api import close_iotas

    close_iotas(leaf.iota for leaf in leaves)


def _run_composed(system: System, args: VirtualOptions, writer, root, leaves: dict, inputs: list) -> int:
    from iotad.kernel.clock import VirtualClock
    from iotad.kernel.engine import Engine
    from iotad.kernel.policy import PolicyError
    from iotad.launcher.run_policy import run_policy
    from iotad.recording.engine_sink import EngineRecorder, recording_header
    from iotad.recording.mcap_format import CAN_AT_END, RUN_END, RUN_ERROR
    from iotad.recording.writer_process import WriterFailed

    try:
        policy = run_policy(system, args.policy, args.seed)
    except PolicyError as exc:
        raise VirtualRunError(str(exc)) from None
    inputs = [_external_entry(entry, system, args.inputs) for entry in inputs]
    posts = [(_input_path(entry.get("iota"), root.instance_name, leaves, args.inputs), entry)
             for entry in inputs]
    output = None
    sinks = []
    counts: Counter = Counter()
    examples = ViolationExamples()

    def count(event: dict) -> None:
        counts[event["kind"]] += 1
        if event["kind"] == "violation":
            value = event.get("value") or {}
            examples.add(f"t={event['t']:.4f} {event['iota']}.{event['action']}: "
                         f"{value.get('message', value) if isinstance(value, dict) else value}", event.get("index"))

    sinks.append(count)
    if not args.no_record:
        output, sink = _open_recording(system, args, writer)
    if output is not None:
        header = recording_header(root, system.name, time_unit=system.time_unit, policy=policy,
                                  external=sorted(str(port) for port in system.external))
        if writer is not None:
            writer.begin(header)
            sinks.insert(0, writer)
        else:
            sinks.insert(0, EngineRecorder.from_header(sink, header))
    engine = Engine(root, VirtualClock(), policy, record=False, sinks=sinks)
    until = args.until / system.time_unit  # --until is seconds; the engine counts spec units
    for path, entry in posts:
        if entry["t"] <= until:
            engine.post(path, entry["action"], entry.get("value"), entry.get("index"), t=entry["t"])
    # The system's objects (specs, worlds, grammars) live as long as the run: full garbage
    # collections need not walk them (~30 ms each, a few % of a minute of Buggy recorded).
    gc.freeze()
    started = time.perf_counter()
    step = longest = max(until / 1000, 1e-3)
    progress = sys.stderr.isatty() and not args.plain
    next_report = started + PROGRESS_EVERY
    interrupted = raised = False
    stop = None
    try:
        with _ctrl_c() as stop:
            t = 0.0
            while t < until and not engine.halted and not stop:
                t = min(until, t + step)
                before = time.perf_counter()
                engine.run(t)
                now = time.perf_counter()
                # steps of about a tenth of a second of wall time, so that a Ctrl-C (seen between
                # steps) is answered at once; where the steps fall does not change the run
                if now - before > 0.2:
                    step /= 2
                elif now - before < 0.05 and step < longest:
                    step = min(longest, step * 2)
                if now >= next_report:
                    next_report = now + PROGRESS_EVERY
                    line = (f"t = {_seconds(t * system.time_unit, 2):>8} s of {args.until:g} s virtual, "
                            f"{t * system.time_unit / (now - started):6.1f}x real time, {counts['output']} outputs")
                    print("\r" + line if progress else line, end="" if progress else "\n", file=sys.stderr, flush=True)
            if stop:
                print(file=sys.stderr)
                print(f"stopped by Ctrl-C at t = {engine.now() * system.time_unit:.3f} s", file=sys.stderr)
    except KeyboardInterrupt:  # a second Ctrl-C: at once, wherever the run was
        stopped = engine.now() * system.time_unit
        # with no first Ctrl-C seen, a node's own code raised it (the first one only sets a flag)
        raised = stop is not None and not stop.asked
        interrupted = not raised
        how = ("a node's code raised KeyboardInterrupt (no Ctrl-C was pressed)" if raised
               else "stopped hard by a second Ctrl-C")
        print(file=sys.stderr)
        print(f"{how} at t = {stopped:.3f} s" + ("; the run broke off there" if raised else ""), file=sys.stderr)
        # it may have landed in the middle of a firing (an output recorded, not yet delivered):
        # the recording says the run broke off there, so that `iotad check` does not pass it
        if output is not None and not getattr(sink, "torn", False):  # torn: the writer says so
            try:
                sink.add_metadata(RUN_ERROR, {"error": f"{how}, possibly in the middle of a firing", "t": stopped})
            except WriterFailed:
                pass
    except BaseException as exc:
        # an error of iotad itself: the recording keeps what happened, and says the run broke off
        # there, so that `iotad check` does not pass it as a whole run
        if output is not None:
            try:
                sink.add_metadata(RUN_ERROR, {"error": f"{type(exc).__name__}: {exc}",
                                              "t": engine.now() * system.time_unit})
            except WriterFailed:
                pass  # the writer is what failed: it has said so
        raise
    else:
        # how far every node ran (a Ctrl-C stops between steps, so this holds then too):
        # windows that closed before it are judged
        if output is not None:
            sink.add_metadata(RUN_END, {"t": engine.now()})
            # each modelled bus's frames still under way (none too), so that the check tells them from lost ones
            cut = {leaf.iota.instance_name: leaf.iota.frames_at_end(engine.now()) for leaf in engine.flat.leaves
                   if callable(getattr(leaf.iota, "frames_at_end", None))}
            if cut:
                sink.add_metadata(CAN_AT_END, {"t": engine.now(), "buses": cut})
    finally:
        if output is not None:
            try:
                sink.finish()
            except WriterFailed:
                if not interrupted:
                    raise
    wall = time.perf_counter() - started
    if progress:
        print(file=sys.stderr)
    virtual = engine.now() * system.time_unit
    print(f"summary of {system.name} (virtual time, one process):")
    speed = virtual / wall if wall > 0 else float("inf")
    print(f"  {_seconds(virtual, 3)} s virtual in {wall:.2f} s wall ({_seconds(speed, 1)}x real time)")
    # an input is an event, not a firing: the firings are the outputs and internal actions
    print(f"  {engine.firings} firings ({counts['output']} outputs, {counts['internal']} internal), "
          f"{counts['input']} inputs, {counts['violation']} violations")
    for line in examples.lines():
        print(f"  violation {line}")
    more = examples.more(str(output) if output is not None else None)
    if more:
        print(f"  {more}")
    if engine.halted:
        print("  engine halted: a loop of actions enabled itself without time passing (see the zeno violation)")
    if output is not None:
        where = " (written by a second process)" if writer is not None else ""
        print(f"  recording: {output}{where}  (iotad info|check|plot {output})")
    if interrupted:
        return 130
    if args.strict or system.strict:
        from iotad.launcher.strict_verdict import strict_failures

        failures = strict_failures(counts["violation"], [])
        for line in failures:
            print(f"  strict: {line}")
        if failures:
            return 1
    code = 1 if engine.halted or raised else 0
    # a whole run of `iotad run` (a sweep's and a stress run's are measured by their worker):
    # its goals (a part of a run would miss them)
    if not stop and not engine.halted and args.goals is not None:
        from iotad.virtual.goal_report import report_goals
        met = report_goals(system, output, counts["violation"])
        if met is False and args.goals:
            return code or 1
    return code


def _open_recording(system: System, args: VirtualOptions, writer):
    """The recording's path, claimed (no other run writes it too; created here, so that the run may
    remove it if it writes nothing), and what writes it: the second process `writer`, or a sink in
    this process."""
    from iotad.launcher.run.recording_paths import unused_recording_path
    from iotad.recording.mcap_sink import McapSink
    from iotad.recording.writer_process import WriterFailed

    claimed = False
    if args.record_to:
        output = Path(args.record_to)
        _output_file(str(output))  # a folder, or a path under a file: one line
        # no other run writes it too; created here: the run may remove it if it writes nothing
        try:
            claimed = claim_recording(str(output), args.force)
        except RecordingClaimError as exc:
            raise VirtualRunError(str(exc)) from None
    else:
        output = Path(f"recordings/{system.name}-virtual-{time.strftime('%Y%m%d-%H%M%S')}.mcap")
        _output_file(str(output))
        try:
            output = unused_recording_path(output, claim=True)
            claimed = True
        except OSError as exc:
            raise VirtualRunError(f"cannot create {output.parent}: {exc.strerror or exc}") from None
    try:
        output.parent.mkdir(parents=True, exist_ok=True)
        if writer is not None:
            writer.open(output)
            sink = writer
        else:
            sink = McapSink(output)
    except OSError as exc:
        drop_empty_claim(output if claimed else None)
        raise VirtualRunError(f"-o {output}: cannot write: {exc.strerror or exc}") from None
    except WriterFailed as exc:  # "cannot write: ..." in the writer's words, or how it died
        drop_empty_claim(output if claimed else None)
        raise VirtualRunError(f"-o {output}: {exc}") from None
    return output, sink


def _output_file(path: str) -> None:
    """Refuse, with one line, an output path that cannot be written: a folder, or one under a file."""
    problem = unwritable(path)
    if problem:
        raise VirtualRunError(f"-o {path}: {problem}")


class _Stop:
    """Whether a Ctrl-C asked the run to stop (true once one came)."""

    def __init__(self):
        self.asked = False

    def __bool__(self) -> bool:
        return self.asked


@contextlib.contextmanager
def _ctrl_c():
    """The first Ctrl-C asks the run to stop after the step in progress (at most ~0.2 s), so it never
    lands inside a node's code or half-way through handing events to the recording; a second one
    stops it at once (KeyboardInterrupt). Outside the main thread, Ctrl-C is left as it is."""
    stop = _Stop()

    def asked(signum, frame):
        stop.asked = True
        signal.signal(signal.SIGINT, signal.default_int_handler)

    try:
        previous = signal.signal(signal.SIGINT, asked)
    except ValueError:  # not the main thread
        yield stop
        return
    try:
        yield stop
    finally:
        signal.signal(signal.SIGINT, previous)


def _seconds(value: float, decimals: int) -> str:
    """A time (or speed) with `decimals` places, or in 6 significant digits once it is too big
    for that to be readable (`--until 1e300` would print 300 digits)."""
    return f"{value:.{decimals}f}" if abs(value) < 1e9 else f"{value:.6g}"


def _input_path(name: str | None, root: str, leaves, script: str) -> str | None:
    """The engine path of an input script's "iota": a node's name as the system file gives it
    ("scheduler"), or its full path ("figure2/scheduler"); none: the system's external input."""
    if name is None or name in leaves:
        return name
    full = f"{root}/{name}"
    if full in leaves:
        return full
    nodes = sorted({path[len(root) + 1:].split("/")[0] for path in leaves if path.startswith(root + "/")})
    raise VirtualRunError(f"--inputs {script}: no node {name!r} in this system (nodes: {', '.join(nodes)}; "
                   f"an external input is {{\"action\": \"NODE.CHANNEL\"}}, as `external` names it)")


def _external_entry(entry: dict, system, script: str) -> dict:
    """An input-script line without "iota" names one of the system file's external inputs as
    its action, as `external` writes it ("motor.estop", "scheduler.req[1]"): it becomes that
    node's input. Lines that name their node are left as they are."""
    if entry.get("iota") is not None:
        return entry
    action, index = entry["action"], entry.get("index")
    for port in system.external:
        if action == str(port) or (action == f"{port.node}.{port.channel}" and index in (None, port.index)):
            return dict(entry, iota=port.node, action=port.channel, index=port.index)
    known = ", ".join(sorted(str(port) for port in system.external)) or "none"
    raise VirtualRunError(f"--inputs {script}: {{\"action\": {json.dumps(action)}}} without \"iota\" must be one of "
                   f"the system's external inputs ({known}); or name the node: "
                   f"{{\"iota\": \"NODE\", \"action\": \"CHANNEL\"}}")


def _read_inputs(path: str) -> list[dict]:
    from iotad.kernel.input_script import ScriptError, parse_script
    from iotad.kernel.text_file import read_text_file

    try:
        return parse_script(read_text_file(path).splitlines(), path)
    except OSError as exc:
        raise VirtualRunError(f"--inputs {path}: cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:
        raise VirtualRunError(f"--inputs {path}: not UTF-8 text") from None
    except ScriptError as exc:
        raise VirtualRunError(f"--inputs {exc}") from None
