"""`iotad merge`: join the recordings of one run's hosts into one file, ordered by the hub's clock,
each message once and each gap in a host's events marked."""
from __future__ import annotations

import argparse

from iotad.cli import new_recording, output_file

ORDER = 37

EPILOG = """\
example:
  iotad merge recordings/split.mcap recordings/split.arm.mcap -o recordings/split.merged.mcap

'iotad run SYSTEM.toml -o REC.mcap' of a system spread over hosts records on every host: the hub's
machine writes REC.mcap, each other host REC.<host>.mcap on its own machine (docs/hosts.md, "The
recording"). Copy them to one place and merge them. Host files' times are moved onto the hub's
clock by the offset each host measured; a message two files hold is kept once; each stretch where
a host's events are missing from a recording (cut off from the hub, a recording begun late or cut
short, a host whose file was not given) is an event on @merge/gaps naming the host and the
interval. 'iotad info', 'iotad check' and 'iotad replay' read the merged file as any other."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("merge", help="join the recordings of a run's hosts into one, on the hub's clock",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("files", nargs="+", metavar="FILE",
                        help="every host's recording of one run (the hub's and REC.<host>.mcap of each other host)")
    parser.add_argument("-o", "--output", required=True, metavar="OUT", help="the merged recording to write")
    parser.add_argument("--force", action="store_true",
                        help="replace a recording already at OUT (default: refuse, so that none is lost)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from iotad.cli import CliError
    from iotad.cli.recordings import load
    from iotad.recording.merge import MergeError, merge, write_merged

    output = Path(args.output)
    for name in args.files:
        if Path(name).resolve() == output.resolve():
            raise CliError(f"-o {args.output}: is one of the recordings being merged; name another file")
    output_file(args.output)
    new_recording(args.output, args.force)
    try:
        merged = merge(args.files, read=load)
    except MergeError as exc:
        raise CliError(str(exc)) from None
    count = write_merged(merged, output)
    print(f"merged {len(args.files)} recordings of {merged.recording.system}: {count} messages to {output}")
    for line in merged.lines():
        print(line)
    return 0
