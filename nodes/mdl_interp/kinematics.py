"""End-effector poses to joint targets: PyBullet inverse kinematics on the robot's URDF.

The interpreter's own PyBullet client (DIRECT, no GUI, separate from any simulation) holds one
copy of the arm, loaded the first time a pose is solved (~0.15 s; `preload` does it earlier).
A solution starts from the joints' current command (so the arm takes the nearest branch) and is
checked by forward kinematics: a pose further than `tolerance` from what the arm reaches is
refused, not approximated.
"""
from __future__ import annotations

import math
from pathlib import Path

from channels.mdl import Pose


class KinematicsError(Exception):
    """A pose cannot be solved: no PyBullet, a bad URDF or link, or an unreachable pose."""


class Kinematics:
    def __init__(self, urdf: str, joints: tuple[str, ...], ee_link: str, tolerance: float):
        self.urdf, self.joints, self.ee_link, self.tolerance = urdf, tuple(joints), ee_link, tolerance
        self._pb = None

    def load(self) -> None:
        if self._pb is not None:
            return
        try:
            import pybullet
            import pybullet_data
        except ImportError as exc:
            raise KinematicsError(f"pose targets need pybullet (pip install pybullet numpy): {exc}") from None
        path = Path(self.urdf)
        if not path.is_absolute():
            path = Path(pybullet_data.getDataPath()) / path
        if not path.is_file():
            raise KinematicsError(f"urdf {self.urdf}: no such file ({path})")
        client = pybullet.connect(pybullet.DIRECT)
        try:
            body = pybullet.loadURDF(str(path), useFixedBase=True, physicsClientId=client)
        except pybullet.error as exc:
            pybullet.disconnect(client)
            raise KinematicsError(f"urdf {self.urdf}: cannot load it: {exc}") from None
        movable, by_name, links = [], {}, {}
        for j in range(pybullet.getNumJoints(body, physicsClientId=client)):
            info = pybullet.getJointInfo(body, j, physicsClientId=client)
            name, kind, link = info[1].decode(), info[2], info[12].decode()
            links[link] = j
            if kind != pybullet.JOINT_FIXED:
                by_name[name] = (j, len(movable))
                movable.append(j)
        missing = [j for j in self.joints if j not in by_name]
        if missing or self.ee_link not in links:
            pybullet.disconnect(client)
            what = f"joints {missing}" if missing else f"link {self.ee_link!r}"
            raise KinematicsError(f"urdf {self.urdf} has no {what}")
        self._pb, self._client, self._body = pybullet, client, body
        self._ee = links[self.ee_link]
        self._joint_ids = [by_name[j][0] for j in self.joints]
        self._solution_slots = [by_name[j][1] for j in self.joints]  # IK returns movable joints in order

    def solve(self, pose: Pose, start: list[float]) -> list[float]:
        """Joint positions (in the order of `joints`) that put the end-effector link at `pose`."""
        self.load()
        pb, client, body = self._pb, self._client, self._body
        for joint, value in zip(self._joint_ids, start):
            pb.resetJointState(body, joint, value, physicsClientId=client)
        kwargs = {"maxNumIterations": 200, "residualThreshold": 1e-6, "physicsClientId": client}
        if pose.orientation is not None:
            x, y, z, w = pose.orientation
            norm = math.sqrt(x * x + y * y + z * z + w * w)
            kwargs["targetOrientation"] = [x / norm, y / norm, z / norm, w / norm]
        solution = pb.calculateInverseKinematics(body, self._ee, list(pose.position), **kwargs)
        result = [float(solution[slot]) for slot in self._solution_slots]
        for joint, value in zip(self._joint_ids, result):
            pb.resetJointState(body, joint, value, physicsClientId=client)
        reached = pb.getLinkState(body, self._ee, computeForwardKinematics=True, physicsClientId=client)[4]
        error = math.dist(reached, pose.position)
        if not error <= self.tolerance:
            raise KinematicsError(f"pose {list(pose.position)} is out of reach: the closest solution is "
                                  f"{error:.3g} m away (tolerance {self.tolerance:g} m)")
        if not all(math.isfinite(v) for v in result):
            raise KinematicsError(f"pose {list(pose.position)}: the solver returned {result}")
        return result

    def close(self) -> None:
        if self._pb is not None:
            try:
                self._pb.disconnect(self._client)
            except Exception:  # noqa: BLE001 - already disconnected
                pass
            self._pb = None


_shared: dict[tuple, Kinematics] = {}


def kinematics_for(urdf: str, joints: tuple[str, ...], ee_link: str, tolerance: float) -> Kinematics:
    """One solver per robot description in a process: loading the URDF is the slow part."""
    key = (urdf, tuple(joints), ee_link, tolerance)
    if key not in _shared:
        _shared[key] = Kinematics(urdf, joints, ee_link, tolerance)
    return _shared[key]
