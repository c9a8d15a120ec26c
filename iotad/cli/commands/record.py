"""`iotad record`: record every event of a running system to MCAP until SIGINT or SIGTERM."""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from iotad.cli import byte_size, endpoint, key_expression, positive_float

ORDER = 30

EPILOG = """\
examples:
  iotad record 'iota/figure2/**' -o recordings/fig2.mcap --connect tcp/127.0.0.1:7447
                                    (quote '**' for the shell; the hub 'iotad run' opens)
  iotad record --system-file examples/figure2.toml -o fig2.mcap --duration 30
                                    (connects to the hub the system file names)
  iotad record --system-file examples/figure2.toml -o fig2.mcap --max-size 100M --max-duration 600

'iotad run' starts a recorder by itself (-o FILE, or --no-record); use this command to record
a system started elsewhere, or only some keys. Started before the system, it waits for the hub
(--duration counts the wait; stopped before a hub answered, it writes no file). Missing folders of -o are created. On a terminal
a status line shows what has been written so far. Ctrl-C (SIGINT) or SIGTERM stops it cleanly
(exit 0). Then: 'iotad info FILE', 'iotad check FILE', 'iotad replay FILE --node PATH';
a killed recorder's file: 'iotad recover FILE'.

direct or trace-sourced: by default every sample on the keys is recorded as it arrives, so every
message also wakes the recorder, which costs the nodes latency on a machine with few cores.
--from-traces (what 'iotad run' uses) subscribes only to the nodes' @trace, @launcher and
@heartbeat keys and writes each output (and each input no node sent, e.g. from 'iotad pub') on
its own key from the trace event that describes it, with the sender's sequence number and send
time: one wake-up per trace burst. It records what the nodes sent and saw: a message that no
node received is only recorded in direct mode; a node killed with SIGKILL loses its last trace
period (20 ms) of messages as well.

split recordings: with --max-size and/or --max-duration the recording goes to numbered files
fig2_0.mcap, fig2_1.mcap... next to -o fig2.mcap: a file is closed and the next one begun at the
first flush after it reached either bound (so a file may pass --max-size by one flush period of
data). Each file is a whole recording on its own (system file, specs, summary): any MCAP tool
opens it. -o fig2.mcap is the set file: it lists the files, and 'iotad info/check/replay/export/
plot fig2.mcap' read the whole set as one recording. A killed recorder cuts only the last file;
the earlier ones are complete."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "record", help="record a running system (every event, specs, gaps) to an MCAP file",
        description="Record every external event and every node's @trace (internal events and "
                    "violations) of a running system to MCAP, with the system file and each node's spec, "
                    "so that 'iotad replay' and 'iotad check' need nothing else. Stops cleanly on "
                    "SIGINT/SIGTERM; a killed recording loses at most the last --flush-period seconds "
                    "and is made whole by 'iotad recover'.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("keys", nargs="*", metavar="KEYEXPR", type=key_expression,
                        help="zenoh key expressions; 'iota/SYS/**' also covers SYS's @trace, @launcher "
                             "and @heartbeat keys (default: every key of the system file's system)")
    parser.add_argument("-o", "--output", required=True, metavar="FILE",
                        help="MCAP file to write (an existing recording is kept: see --force)")
    parser.add_argument("--force", action="store_true",
                        help="replace a recording already at FILE (default: refuse, so that none is lost)")
    parser.add_argument("--system-file", metavar="SYSTEM.toml",
                        help="system file to store in the recording (refused, before anything starts, "
                             "where 'iotad run --check' would refuse it: its nodes' specs and code are "
                             "loaded to check their channels and bindings)")
    # the recorder `iotad run` starts: the launcher checked the system file (this recorder checks
    # only its form, loads no node code and is subscribed at once, beside nodes that are
    # starting) and claimed the output's name
    parser.add_argument("--from-launcher", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--connect", action="append", default=[], metavar="EP", type=endpoint,
                        help="zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable; default: "
                             "the hub of --system-file's [system.endpoints] listen; without --system-file none: "
                             "peers find the recorder through --listen). Connected and not told --listen, the "
                             "recorder is a client of that hub, which relays every node's first sample to it")
    parser.add_argument("--listen", action="append", default=None, metavar="EP", type=endpoint,
                        help="zenoh endpoint to listen on, as a peer (default without --connect: "
                             "tcp/127.0.0.1:0, any free loopback port)")
    parser.add_argument("--from-traces", action="store_true",
                        help="record a whole system from its nodes' @trace bursts, not every sample "
                             "(see below; needs 'iota/SYS/**' or --system-file)")
    parser.add_argument("--flush-period", type=positive_float, default=0.05, metavar="S",
                        help="close the MCAP chunk in progress every S seconds (default 0.05)")
    parser.add_argument("--duration", type=positive_float, default=None, metavar="S",
                        help="stop by itself after S seconds (default: until Ctrl-C or SIGTERM)")
    parser.add_argument("--max-size", type=byte_size, default=None, metavar="SIZE",
                        help="split: begin a new file once the current one holds SIZE bytes (100M, 1G...)")
    parser.add_argument("--max-duration", type=positive_float, default=None, metavar="S",
                        help="split: begin a new file once the current one spans S seconds")
    parser.add_argument("--ready-file", metavar="PATH",
                        help="create PATH once subscribed (for launchers and tests to wait on)")
    parser.add_argument("--quiet", action="store_true", help="print nothing but errors")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from iotad.cli import CliError, claim_recording, drop_empty_claim, new_recording, output_file

    if args.flush_period <= 0 or args.flush_period > 10:
        raise CliError("--flush-period must be in (0, 10] seconds")
    output = Path(args.output)
    if output.is_dir():
        raise CliError(f"-o {args.output}: is a directory; name the .mcap file to write")
    output_file(args.output)  # a folder, or a path under a file: one line
    new_recording(args.output, args.force)
    try:
        output.parent.mkdir(parents=True, exist_ok=True)  # as the help says, and as `run -o` does
    except OSError as exc:
        raise CliError(f"-o {args.output}: cannot create its folder: {exc.strerror or exc}") from None
    # the name claimed (created empty, atomically), as `iotad run -o` does: of two recorders
    # started together on one -o, one is refused here instead of both writing the file. The
    # launcher's recorder records to a name its launcher has claimed already.
    claimed = None
    if not args.from_launcher and claim_recording(args.output, args.force):
        claimed = args.output
    try:
        return _record(args)
    finally:
        drop_empty_claim(claimed)  # nothing was written: no empty file left to refuse the next run


def _record(args: argparse.Namespace) -> int:
    from iotad.cli import CliError
    from iotad.recording.recorder import Recorder
    from iotad.recording.recorder_process import record_until_stopped, stop_on_signals

    if args.system_file is not None:
        if Path(args.system_file).is_dir():
            raise CliError(f"--system-file {args.system_file}: is a directory")
        if not Path(args.system_file).is_file():
            what = "not a regular file" if Path(args.system_file).exists() else "no such file"
            raise CliError(f"--system-file {args.system_file}: {what}")
        _check_system_file(args.system_file, whole=not args.from_launcher)
    connect = args.connect or _hub_of(args.system_file)
    try:
        recorder = Recorder(args.keys, args.output, system_file=args.system_file, connect=connect,
                            listen=args.listen, flush_period=args.flush_period,
                            background=True,  # a process of its own: yield the CPU to the nodes
                            from_traces=args.from_traces, max_size=args.max_size,
                            max_duration=args.max_duration, replace=args.force)
    except UnicodeDecodeError:
        raise CliError(f"--system-file {args.system_file}: not UTF-8 text") from None
    except OSError as exc:
        raise CliError(f"{exc.filename or args.output}: {exc.strerror or exc}") from None
    except ValueError as exc:
        raise CliError(str(exc)) from None
    stop = stop_on_signals()
    try:
        # --duration counts from the start, waiting for a hub included
        deadline = None if args.duration is None else time.monotonic() + args.duration

        def keep_waiting() -> bool:
            # a recorder may be started before the system it records: wait for its hub, say so once
            if not args.quiet and not waited:
                print(f"waiting for a hub at {', '.join(connect)} (Ctrl-C to stop)", file=sys.stderr)
            waited.append(True)
            return not stop.is_set() and (deadline is None or time.monotonic() < deadline)

        waited: list[bool] = []
        try:
            recorder.start(keep_waiting)
        except OSError as exc:
            raise CliError(f"cannot start recording: {exc.filename or args.output}: {exc.strerror or exc}") from None
        except Exception as exc:  # noqa: BLE001 - zenoh said no
            if waited:  # stopped, or --duration over, before any hub answered: the file holds nothing
                _remove_empty(recorder)
                why = "stopped" if stop.is_set() else f"--duration {args.duration:g} s over"
                raise CliError(f"{why} while waiting for a hub at {', '.join(connect)}: nothing recorded, "
                               f"no file written") from None
            reason = str(exc).split(" at /", 1)[0]  # zenoh appends its Rust source location
            raise CliError(f"cannot start recording: {reason}") from None
        stats = record_until_stopped(recorder, stop, ready_file=args.ready_file, deadline=deadline,
                                     said=None if args.quiet else lambda line: print(line, file=sys.stderr))
    finally:
        stop.close()
    if not args.quiet:
        where = str(recorder.output)
        if recorder.split:
            where += f" (a set of {len(recorder.files)} files: {recorder.files[0].name} .. {recorder.files[-1].name})"
        print(f"recorded {stats['written']} messages to {where}; "
              f"{stats['gaps']} sequence gaps ({stats['missing']} missing)", file=sys.stderr)
    return 0



def _remove_empty(recorder) -> None:
    """Remove the files of a recording that never began (no hub came): an empty recording left
    at -o would only make the next run with the same -o ask for --force. Only regular files: a
    device named as the output (-o /dev/null) is no recording, and stays."""
    from iotad.cli import is_regular_file

    for path in {recorder.output, *recorder.files}:
        if is_regular_file(path):
            try:
                path.unlink()
            except OSError:
                pass


def _check_system_file(path: str, whole: bool = True) -> None:
    """Refuse a system file `iotad run --check` would refuse, before recording: a recording stores
    it for check and replay, which would fail on it later. `whole`: its specs are parsed and its
    nodes instantiated, so that a TOML file that is no valid system (a binding to a channel no
    node has, a spec with a syntax error) is refused in the parser's words. Not `whole` (the
    recorder `iotad run` starts, on a file it checked): only its form (nodes, keys, bindings'
    shape), so that the recorder starts at once, beside a system already starting, and imports
    no robot code."""
    from iotad.cli import CliError
    from iotad.launcher.system.system_file import SystemFileError, load_system

    try:
        load_system(path, check=whole)
    except SystemFileError as exc:
        more = "" if len(exc.errors) == 1 else \
            f" (and {len(exc.errors) - 1} more: 'iotad run --check {path}' lists them)"
        raise CliError(f"--system-file {path}: {exc.errors[0]}{more}") from None


def _hub_of(system_file: str | None) -> list[str]:
    """Where to connect a recorder given a system file and no --connect: the hub its `iotad run`
    opens, to record that system. None given: [] (listen only)."""
    from iotad.recording.recorder import read_system_file

    if system_file is None:
        return []
    try:
        return read_system_file(system_file).hub()
    except ValueError:
        return []  # the Recorder says what is wrong with the file
