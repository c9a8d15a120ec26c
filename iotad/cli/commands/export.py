"""`iotad export`: a JSON-encoded copy of a recording that Foxglove displays, or a rosbag2 bag (`--ros2`)."""
from __future__ import annotations

import argparse
from pathlib import Path

from iotad.cli import new_recording, not_its_own_file, output_file

ORDER = 35

EPILOG = """\
example:
  iotad export recordings/fig2.mcap -o fig2-json.mcap --json     then open it in Foxglove Studio
  iotad export --ros2 recordings/arm.mcap -o arm_bag              then: ros2 bag info arm_bag (docs/ros2.md)

See also: 'iotad plot FILE -o OUT.png' (the motor arbitration timeline), 'iotad info FILE'."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("export", help="write a JSON-encoded MCAP copy of a recording (for Foxglove), "
                                           "or a rosbag2 bag (--ros2)",
                            usage="iotad export FILE -o OUT.mcap --json [--force]\n       iotad export --ros2 FILE -o BAG",
                            description="Re-encode every message of a recording as JSON (message encoding "
                                        "'json', JSON Schema kept), so that Foxglove Studio shows and plots "
                                        "it; attachments (specs, system file) and metadata are copied.",
                            epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("file", metavar="FILE", help="an MCAP recording (from 'iotad run' or 'iotad record')")
    parser.add_argument("-o", "--output", required=True, metavar="OUT.mcap", help="file to write")
    parser.add_argument("--force", action="store_true",
                        help="replace a recording already at OUT (default: refuse, so that none is lost)")
    how = parser.add_mutually_exclusive_group(required=True)
    how.add_argument("--json", action="store_true", help="encode messages as JSON (an MCAP file for Foxglove)")
    how.add_argument("--ros2", action="store_true",
                     help="a rosbag2 bag (a new folder; MCAP storage, CDR): the [[ros2]]-mapped channels on their "
                          "topics, joint states and poses on /iotad/<node>/<channel> (docs/ros2.md)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from iotad.cli import CliError
    from iotad.cli.recordings import load
    from iotad.recording.foxglove_export import export_json

    if Path(args.output).resolve() == Path(args.file).resolve():
        raise CliError("-o must name another file than the recording")
    if args.ros2:
        return _ros2(args)
    output_file(args.output)
    new_recording(args.output, args.force)
    recording = load(args.file)
    not_its_own_file(args.output, recording)
    extra = None
    if not recording.complete or recording.damaged:
        # the copy is a whole file, but not of a whole run: its metadata says so as `iotad
        # recover`'s does, for whoever opens it (Foxglove shows a file's metadata)
        extra = {"iotad.recovered": {"from": str(args.file), "was_complete": False, "messages": len(recording.messages),
                                     "stopped_at": recording.truncated_reason or "footer",
                                     "damaged": recording.damaged}}
    count = export_json(recording, args.output, extra)
    print(f"wrote {count} messages for Foxglove to {args.output}")
    if extra is not None:
        print(f"{args.file} is cut short ({recording.damaged or recording.truncated_reason or 'no footer'}): the copy "
              f"holds what it holds, and its metadata says so (iotad.recovered)")
    return 0


def _ros2(args: argparse.Namespace) -> int:
    import shutil

    from iotad.cli import CliError
    from iotad.cli.recordings import load
    from iotad.recording.rosbag_export import RosbagExportError, export_rosbag

    output = Path(args.output)
    if output.exists():
        if Path(args.file).resolve().is_relative_to(output.resolve()):
            # --force would remove the bag, and the recording being exported with it
            raise CliError(f"-o {output}: holds the recording being exported ({args.file}); name another folder")
        if not args.force or not (output / "metadata.yaml").is_file():
            raise CliError(f"{output} exists" + ("" if args.force else "; --force replaces a bag")
                           + (" (and is not a rosbag2 bag: not removed)" if args.force else ""))
        shutil.rmtree(output)
    recording = load(args.file)
    try:
        counts = export_rosbag(recording, output)
    except RosbagExportError as exc:
        raise CliError(str(exc)) from None
    total = sum(counts.values())
    print(f"wrote a rosbag2 bag of {total} messages to {output}/ (MCAP storage, cdr):")
    for topic, count in sorted(counts.items()):
        print(f"  {topic}: {count}")
    if not counts:
        print("  (nothing to export: no [[ros2]] mappings, joint states or poses in the recording)")
    return 0
