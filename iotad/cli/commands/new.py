"""`iotad new NAME`: make a working robot in the new folder NAME: joints on simulated drives on a
CAN bus, driving a URDF in PyBullet, behaviours asking the program scheduler for the motors, the
MDL interpreter and the CAN motor node; with its tests and a README. It runs at once."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

ORDER = 11

EPILOG = """\
examples:
  iotad new head                     the default: the shipped pan-tilt head (joints pan, tilt) on two
                                     simulated ODrives (node ids 1, 2), one sweeping behaviour
  iotad new head --behaviour sweep:1 --behaviour startle:5      a startle that preempts the sweep
  iotad new arm --joint shoulder:-1.5:1.5 --joint elbow:-2:2 --joint wrist --drives cia402 --node-ids 11,12,13
  iotad new kuka --urdf ~/robots/my_arm.urdf                    your URDF: its movable joints, by name
  cd head && iotad run robot.toml --virtual --until 12 -o run.mcap && iotad check run.mcap

At a terminal with no option given it asks for each choice (Enter takes the default); with input
that is not a terminal, or with any option, it asks nothing. NAME's folder must not exist or be
empty. docs/first-robot.md walks from here to a robot recorded, checked and viewed on CAN."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("new", help="make a working robot in a new folder: joints, drives, behaviours, URDF",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("name", metavar="NAME", help="the robot's folder (made here) and its system's name")
    parser.add_argument("--joint", action="append", metavar="NAME[:LOWER:UPPER]",
                        help="a joint and its limits in radians, repeatable, in order (default: the URDF's joints, "
                             "or pan and tilt)")
    parser.add_argument("--drives", choices=("odrive", "cia402"), help="drive family (default odrive)")
    parser.add_argument("--node-ids", metavar="ID,ID,...", help="the joints' CAN node ids (default 1, 2, ...)")
    parser.add_argument("--behaviour", action="append", metavar="NAME[:PRIORITY]",
                        help="a behaviour and its priority, repeatable (default: sweep:1; the first one sweeps "
                             "every joint, each other one glances with a joint)")
    parser.add_argument("--urdf", metavar="FILE|pan_tilt",
                        help="the robot's URDF, copied in (default: the shipped pan_tilt, or with --joint a chain "
                             "made for the joints)")
    parser.add_argument("--in", dest="where", default=".", metavar="DIR", help="where to make NAME (default: here)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from iotad.cli import CliError
    from iotad.scaffold.questions import ask_choices
    from iotad.scaffold.robot_files import FolderTaken, write_robot
    from iotad.scaffold.robot_plan import PlanError, make_plan

    given = any(v is not None for v in (args.joint, args.drives, args.node_ids, args.behaviour, args.urdf))
    try:
        if not given and sys.stdin is not None and sys.stdin.isatty():
            choices = ask_choices(input)
        else:
            choices = {"joints": args.joint, "family": args.drives or "odrive",
                       "node_ids": _ids(args.node_ids), "behaviours": args.behaviour, "urdf": args.urdf}
        plan = make_plan(args.name, **choices)
        folder = write_robot(plan, Path(args.where))
    except (PlanError, FolderTaken) as exc:
        raise CliError(str(exc)) from None
    except (EOFError, KeyboardInterrupt):
        raise CliError("no robot made: the questions were not answered") from None
    except OSError as exc:
        raise CliError(f"{args.where}/{args.name}: cannot write it: {exc.strerror or exc}") from None
    joints = ", ".join(f"{j.name} (id {j.node_id})" for j in plan.joints)
    behaviours = ", ".join(f"{b.name} (priority {b.priority})" for b in plan.behaviours)
    print(f"made {folder}: joints {joints} on simulated {'ODrives' if plan.family == 'odrive' else 'CiA 402 drives'}; "
          f"behaviours {behaviours}")
    print(f"  cd {folder} && iotad run robot.toml --virtual --until 12 -o run.mcap && iotad check run.mcap")
    print("  README.md says what is there; test_robot.py holds its tests (pytest test_robot.py)")
    return 0


def _ids(text: str | None) -> list[int] | None:
    from iotad.cli import CliError

    if text is None:
        return None
    try:
        return [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise CliError(f"--node-ids {text!r}: whole numbers separated by commas, e.g. 1,2") from None
