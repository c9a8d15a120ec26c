"""`iotad cat REC.mcap [KEYEXPR]`: print a recording's values as `iotad echo` prints live ones:
key, #sequence number, value as JSON, one message a line, in recorded order."""
from __future__ import annotations

import argparse
import json

from iotad.cli import finite_float, key_expression

ORDER = 42

EPILOG = """\
examples:
  iotad cat recordings/fig2.mcap                                   every value of the run
  iotad cat recordings/fig2.mcap 'iota/figure2/scheduler/ack/*'    the scheduler's answers
  iotad cat recordings/fig2.mcap iota/figure2/scheduler/@trace --json    the node's events
  iotad cat arm.mcap 'iota/arm/motor/joint_states' --since 2 --until 3

Each line is what 'iotad echo KEYEXPR' printed when the message went out: key, #sequence number,
value as JSON (a @trace burst: one line per event). KEYEXPR defaults to '**' (every value; as in
zenoh, '*' and '**' match no '@' chunk: name @trace keys). --since/--until are seconds of the
run (from its t = 0). --json: one object a line, echo's (key, seq, send_ns, value) and t.
From Python: iotad.open_recording(path) (docs/recordings.md)."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("cat", help="print a recording's values as 'iotad echo' prints live ones",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("recording", metavar="REC.mcap", help="a recording (iotad run -o, iotad record -o)")
    parser.add_argument("keyexpr", metavar="KEYEXPR", nargs="?", default="**", type=key_expression,
                        help="which keys, e.g. 'iota/figure2/scheduler/ack/*' (default: every value key)")
    parser.add_argument("--since", type=finite_float, metavar="S", help="only messages at t >= S seconds")
    parser.add_argument("--until", type=finite_float, metavar="S", help="only messages at t <= S seconds")
    parser.add_argument("--json", action="store_true", help="one JSON object a line: key, seq, send_ns, value, t")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import sys

    from iotad.cli import CliError
    from iotad.recording.mcap_format import RecordingError
    from iotad.recording.open_recording import open_recording

    if args.since is not None and args.until is not None and args.since > args.until:
        raise CliError(f"--since {args.since:g} is after --until {args.until:g}")
    try:
        recording = open_recording(args.recording)
    except RecordingError as exc:
        raise CliError(str(exc)) from None
    except OSError as exc:
        raise CliError(f"{args.recording}: {exc.strerror or exc}") from None
    shown = 0
    for sample in recording.iter_values(args.keyexpr, args.since, args.until):
        shown += 1
        if args.json:
            print(json.dumps({"key": sample.key, "seq": sample.seq, "send_ns": sample.send_ns,
                              "value": sample.value, "t": sample.t}, default=repr))
        else:
            seq = "" if sample.seq is None else f"#{sample.seq} "
            print(f"{sample.key} {seq}{json.dumps(sample.value, default=repr)}")
    if not shown:
        print(f"iotad cat: no message on {args.keyexpr} in {args.recording}"
              + (" in that time" if args.since is not None or args.until is not None else ""), file=sys.stderr)
        return 1
    return 0
