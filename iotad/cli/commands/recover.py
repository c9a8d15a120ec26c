"""`iotad recover`: make a recording whole again after its recorder was killed (no footer)."""
from __future__ import annotations

import argparse
from pathlib import Path

from iotad.cli import new_recording, not_its_own_file, output_file

ORDER = 36

EPILOG = """\
example:
  iotad recover recordings/fig2.mcap                 writes recordings/fig2.recovered.mcap

'iotad info FILE' says INCOMPLETE for a recording whose recorder was killed; 'iotad check'
and 'iotad replay' read such a file as it is, but other MCAP tools want the summary.
A damaged recording (a chunk or attachment that fails its CRC: the bytes changed after they were
written) is refused by every other command; recover keeps the records before the damage."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "recover", help="rewrite a killed recording as a complete MCAP (summary, indexes)",
        description="Read what a killed recorder left (sequentially, up to where it stopped) and write a "
                    "complete MCAP file with summary, statistics and indexes. Everything flushed before "
                    "the kill comes back: at most the recorder's last --flush-period is lost.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", metavar="FILE", help="the cut-short (or damaged) recording")
    parser.add_argument("-o", "--output", metavar="OUT",
                        help="where to write (default: FILE with .recovered.mcap)")
    parser.add_argument("--force", action="store_true",
                        help="replace a recording already at OUT (default: refuse, so that none is lost)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from iotad.cli import CliError
    from iotad.cli.recordings import load
    from iotad.recording.mcap_sink import copy_recording

    source = Path(args.file)
    output = Path(args.output) if args.output else source.with_suffix(".recovered.mcap")
    if output.resolve() == source.resolve():
        raise CliError("-o must name another file than the recording")
    output_file(str(output))
    new_recording(str(output), args.force)
    recording = load(args.file, salvage=True)
    not_its_own_file(str(output), recording)
    count = copy_recording(recording, output, extra_metadata={"iotad.recovered": {
        "from": str(source), "was_complete": recording.complete, "messages": len(recording.messages),
        "stopped_at": recording.truncated_reason or "footer", "damaged": recording.damaged}})
    state = ("was already complete" if recording.complete else
             f"is damaged ({recording.damaged}): what comes before the damage is kept" if recording.damaged else
             "was cut short")
    print(f"{source} {state}; wrote {count} messages, {len(recording.attachments)} attachments to {output}")
    return 0
