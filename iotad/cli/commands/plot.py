"""`iotad plot`: a PNG timeline of which requester held the motors, the acks and the violations."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from iotad.cli import nonnegative_float, output_file

ORDER = 34
FORMATS = (".png", ".pdf", ".svg", ".jpg", ".jpeg")

EPILOG = """\
examples:
  iotad plot recordings/fig2.mcap -o fig2.png
  iotad plot recordings/fig2.mcap -o fig2.svg --title "Figure 2, run 3"
  iotad plot recordings/fig2.mcap -o fig2.png --late 2       mark deliveries slower than 2 ms

The image format follows the extension of -o: .png, .pdf, .svg or .jpg. The time axis is the
nodes' clock, the t of their events: spec time units (seconds unless the system file's time_unit
says otherwise) from the system's start. A recording of a robot with a picture of its own is
drawn as that picture: pictures are plug-ins in the entry-point group 'iotad.pictures' (Buggy's
and the conveyor arm's come with iotad). See also: 'iotad info FILE', 'iotad export FILE
-o OUT.mcap --json' (every channel in Foxglove)."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("plot", help="draw who held the motors, the acks and the violations (PNG)",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", metavar="FILE", help="an MCAP recording (from 'iotad run' or 'iotad record')")
    parser.add_argument("-o", "--output", required=True, metavar="OUT.png",
                        help="image to write (.png, .pdf, .svg, .jpg)")
    parser.add_argument("--node", metavar="PATH",
                        help="the scheduler whose timeline to draw (default: the one that schedules most; a Buggy "
                             "or conveyor recording is drawn as its robot's picture unless --node is given)")
    parser.add_argument("--title", help="title of the plot")
    parser.add_argument("--late", type=nonnegative_float, metavar="MS",
                        help="also mark every delivery slower than MS milliseconds (lost, altered, duplicated "
                             "and unexplained messages are always marked)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from iotad.cli import CliError
    from iotad.cli.recordings import load
    from iotad.recording.mcap_format import RecordingError

    if Path(args.output).suffix.lower() not in FORMATS:
        raise CliError(f"-o {args.output}: the image format follows the extension; use one of "
                       f"{', '.join(FORMATS)}")
    output_file(args.output)
    recording = load(args.file)
    # A robot's own picture when the recording is of one (Buggy: Figures 4 and 5; the conveyor
    # arm: its picks and who held it: registered pictures, iotad.recording.pictures); else the
    # scheduler's timeline.
    from iotad.recording.pictures import pictures

    found, problems = pictures()
    for problem in problems:
        print(f"warning: {problem}", file=sys.stderr)
    for _, picture in found:
        if picture.matches(recording) and not args.node:  # --node: that scheduler's timeline instead
            try:
                print(f"wrote {picture.plot(recording, args.output, args.title)}")
            except ImportError:
                raise CliError("plotting needs matplotlib: pip install 'iotad[plot]'") from None
            except RecordingError as exc:
                raise CliError(str(exc)) from None
            return 0
    try:
        from iotad.recording.timeline_plot import plot
    except ImportError:
        raise CliError("plotting needs matplotlib: pip install 'iotad[plot]'") from None
    if args.node and args.node not in recording.nodes():
        raise CliError(f"no node {args.node!r} in {args.file} (nodes: {', '.join(recording.nodes())})")
    try:
        path = plot(recording, args.output, args.node, args.title,
                    late=None if args.late is None else args.late / 1e3)
    except RecordingError as exc:
        why = str(exc)
        if args.node is None:
            why += ("; nor is it a Buggy recording (outputs pose, mood and landmark) or a conveyor one (tally and "
                    "mdl_command), or not yet: a run this short may have sent none")
        raise CliError(why) from None
    print(f"wrote {path}")
    return 0
