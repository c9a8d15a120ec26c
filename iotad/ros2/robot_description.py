"""The system's robot model on ROS 2: a `[[ros2]]` table with `robot_description = "FILE.urdf"`
publishes the URDF's text as `std_msgs/msg/String` on `/robot_description`, transient local, as
robot_state_publisher does, so RViz or a ROS 2 node started at any time gets it.

    [[ros2]]
    robot_description = "xarm/xarm6_with_gripper.urdf"   # the arm's model; a path of its own works too

The file is found beside the system file first, then in pybullet_data (where the simulated robots'
models are). Its text goes into the mapping as a constant, so the bridge's @spec, and so the
recording, hold the model that was published.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any

from iotad.ros2.mapping import Mapping, MappingError, parse_durability
from iotad.ros2.rmw_zenoh import check_topic

KEYS = {"robot_description", "topic", "domain", "durability"}
TOPIC = "/robot_description"
TYPE = "std_msgs/msg/String"


def is_robot_description(raw: Any) -> bool:
    return isinstance(raw, dict) and "robot_description" in raw


def find_urdf(name: str, base: Path | None) -> Path | None:
    """The URDF file `name` names: absolute, beside the system file, or in pybullet_data."""
    path = Path(name).expanduser()
    candidates = [path] if path.is_absolute() else [(base or Path.cwd()) / path]
    if not path.is_absolute():
        try:
            import pybullet_data
            candidates.append(Path(pybullet_data.getDataPath()) / path)
        except ImportError:  # pybullet is a dependency; without it only the system's own files count
            pass
    return next((c for c in candidates if c.is_file()), None)


def parse(raw: dict, entry: str, base: Path | None) -> Mapping:
    """The constant mapping of a `robot_description` table; MappingError says what is wrong."""
    unknown = sorted(set(raw) - KEYS)
    if unknown:
        raise MappingError(f"{entry}: unknown key(s) {', '.join(unknown)} for a robot_description table "
                           f"(expected {', '.join(sorted(KEYS))})")
    name = raw["robot_description"]
    if not isinstance(name, str) or not name:
        raise MappingError(f"{entry}: robot_description = \"FILE.urdf\" (a path), not {name!r}")
    topic = raw.get("topic", TOPIC)
    domain = raw.get("domain", 0)
    if isinstance(domain, bool) or not isinstance(domain, int) or not 0 <= domain <= 232:
        raise MappingError(f"{entry}: domain must be a ROS_DOMAIN_ID from 0 to 232, not {domain!r}")
    try:
        check_topic(topic)
    except ValueError as exc:
        raise MappingError(f"{entry}: {exc}") from None
    path = find_urdf(name, base)
    if path is None:
        raise MappingError(f"{entry}: robot_description {name!r}: no such file beside the system file "
                           f"or in pybullet_data")
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise MappingError(f"{entry}: robot_description {name!r}: cannot read it: {exc}") from None
    if "<robot" not in text:
        raise MappingError(f"{entry}: robot_description {name!r} is not a URDF (no <robot> element)")
    return Mapping(None, topic, TYPE, "out", domain, {"data": {"value": text}}, None,
                   parse_durability({**raw, "topic": topic}, entry))
