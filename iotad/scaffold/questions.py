"""The questions `iotad new` asks at a terminal (joints, drives, behaviours, URDF), each with its
default in brackets: Enter takes it. Never asked when input is not a terminal."""
from __future__ import annotations

from typing import Callable

from .robot_plan import DEFAULT_JOINTS, FAMILIES, SHIPPED


def ask_choices(ask: Callable[[str], str]) -> dict:
    """The options of `make_plan`, from answers to `ask(prompt)` (input() at a terminal)."""
    shipped = ", ".join(SHIPPED)
    urdf = ask(f"URDF of the robot: a file, a shipped one ({shipped}), or 'none' to make one for the joints "
               "[pan_tilt]: ").strip() or "pan_tilt"
    default_joints = "from the URDF" if urdf != "none" else " ".join(
        f"{j.name}:{j.lower:g}:{j.upper:g}" for j in DEFAULT_JOINTS)
    joints = ask(f"joints, NAME or NAME:LOWER:UPPER (radians), separated by spaces [{default_joints}]: ").split()
    if urdf == "none" and not joints:
        joints = default_joints.split()
    family = ask(f"drive family ({' or '.join(FAMILIES)}) [odrive]: ").strip() or "odrive"
    ids = ask("CAN node ids, one per joint, separated by commas [1, 2, ...]: ").replace(" ", "")
    behaviours = ask("behaviours, NAME or NAME:PRIORITY, separated by spaces [sweep:1]: ").split()
    return {"joints": joints or None, "family": family,
            "node_ids": [int(i) for i in ids.split(",") if i] if ids else None,
            "behaviours": behaviours or None, "urdf": None if urdf == "none" else urdf}
