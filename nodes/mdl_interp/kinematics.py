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
        movable, by_name, links, urdf_limits = [], {}, {}, []
        for j in range(pybullet.getNumJoints(body, physicsClientId=client)):
            info = pybullet.getJointInfo(body, j, physicsClientId=client)
            name, kind, link = info[1].decode(), info[2], info[12].decode()
            links[link] = j
            if kind != pybullet.JOINT_FIXED:
                by_name[name] = (j, len(movable))
                movable.append(j)
                low, high = info[8], info[9]
                urdf_limits.append((low, high) if low < high else (-2 * math.pi, 2 * math.pi))  # continuous
        missing = [j for j in self.joints if j not in by_name]
        if missing or self.ee_link not in links:
            pybullet.disconnect(client)
            what = f"joints {missing}" if missing else f"link {self.ee_link!r}"
            raise KinematicsError(f"urdf {self.urdf} has no {what}")
        self._pb, self._client, self._body = pybullet, client, body
        self._ee = links[self.ee_link]
        self._joint_ids = [by_name[j][0] for j in self.joints]
        self._solution_slots = [by_name[j][1] for j in self.joints]  # IK returns movable joints in order
        self._movable, self._urdf_limits = movable, urdf_limits

    def solve(self, pose: Pose, start: list[float], lower: list[float] | None = None,
              upper: list[float] | None = None) -> list[float]:
        """Joint positions (in the order of `joints`) that put the end-effector link at `pose`.
        With `lower` and `upper` (the joints' limits), a solution found outside them is sought
        again within them (PyBullet's null-space solver, from `start`, then from the middle of
        every range): the first solver knows no limits, and refused poses the arm can reach
        within them."""
        self.load()
        result, error = self._solve(pose, start, None)
        if lower is not None and upper is not None and (
                not error <= self.tolerance or not all(lo <= v <= hi for v, lo, hi in zip(result, lower, upper))):
            limits = list(self._urdf_limits)
            for slot, lo, hi in zip(self._solution_slots, lower, upper):
                limits[slot] = (lo, hi)
            # from where the arm is, then from the middle of every range: the solver follows
            # the gradient from its start, and a start far from any solution within the limits
            # finds one outside them
            middle = [(lo + hi) / 2 for lo, hi in zip(lower, upper)]
            for begin, rest in ((start, None), (middle, middle)):
                again, error_again = self._solve(pose, begin, limits, rest)
                if error_again <= self.tolerance and all(lo <= v <= hi for v, lo, hi in zip(again, lower, upper)):
                    result, error = again, error_again
                    break
        if not error <= self.tolerance:
            raise KinematicsError(f"pose {list(pose.position)} is out of reach: the closest solution is "
                                  f"{error:.3g} m away (tolerance {self.tolerance:g} m)")
        if not all(math.isfinite(v) for v in result):
            raise KinematicsError(f"pose {list(pose.position)}: the solver returned {result}")
        return result

    def _solve(self, pose: Pose, start: list[float], limits: list[tuple] | None,
               rest_at: list[float] | None = None) -> tuple[list[float], float]:
        """(a solution from `start`, its distance from the pose); `limits`: per movable joint,
        solved in the null space of those limits, resting at `rest_at` (our joints; default:
        where they start)."""
        pb, client, body = self._pb, self._client, self._body
        for joint, value in zip(self._joint_ids, start):
            pb.resetJointState(body, joint, value, physicsClientId=client)
        kwargs = {"maxNumIterations": 200, "residualThreshold": 1e-6, "physicsClientId": client}
        if pose.orientation is not None:
            x, y, z, w = pose.orientation
            norm = math.sqrt(x * x + y * y + z * z + w * w)
            kwargs["targetOrientation"] = [x / norm, y / norm, z / norm, w / norm]
        if limits is not None:
            rest = [pb.getJointState(body, j, physicsClientId=client)[0] for j in self._movable]
            for slot, value in zip(self._solution_slots, rest_at or ()):
                rest[slot] = value
            kwargs.update(lowerLimits=[lo for lo, _ in limits], upperLimits=[hi for _, hi in limits],
                          jointRanges=[hi - lo for lo, hi in limits],
                          restPoses=[min(max(r, lo), hi) for r, (lo, hi) in zip(rest, limits)])
        solution = pb.calculateInverseKinematics(body, self._ee, list(pose.position), **kwargs)
        result = [float(solution[slot]) for slot in self._solution_slots]
        for joint, value in zip(self._joint_ids, result):
            pb.resetJointState(body, joint, value, physicsClientId=client)
        reached = pb.getLinkState(body, self._ee, computeForwardKinematics=True, physicsClientId=client)[4]
        return result, math.dist(reached, pose.position)

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
