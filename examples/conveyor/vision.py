"""Vision control (Figure 1): keeps planning's target in view of the end-effector camera.

Every camera frame: colour segmentation (conveyor_geometry.segment), each blob's centre on the
belt plane (the pixel's ray from the camera pose), reported to planning on `seen`; the blob that
is planning's target (nearest its predicted position) gives the visual error on `visual_error`:
x the bearing of the target about the arm's base (joint1's axis) minus the bearing of the image
centre's point, in radians; y the radial distance between them, in metres (valid false: the
target is not in the image).

When planning's perceptual goal names a new target, vision asks the scheduler for the arm
(`req`, priority `priority`) with an MDL program of two atoms: a minimum-jerk move to the end-
effector pose above where the target will be, then a hold whose feedback term turns joint1 by
`gain` x visual_error.x, which keeps the target in the middle of the image as the belt carries it.
With no target known it looks upstream, where new objects come in. A request waits at most
`timeout`: the program is computed for the moment it is asked for, so one that waited longer
(PENDING behind manipulation, or SUSPENDED by it) would look where the object was. The scheduler
rejects or aborts it instead, and vision asks again with planning's next goal. A request that
died with a restarted scheduler is never answered: the node host tells vision (`peer_restart`,
the scheduler's restart only) and vision asks again for the goal it holds. Without it the arm
went on tracking an object long gone, planning saw no other, and a 10-minute bad day placed no
cube in the 290 s after the scheduler's kill -9 (docs/failures.md).

`near` is the offset (dx, dy) on the belt plane of the blob nearest the image centre's point
from that point, whatever the target: the image centre is on the gripper's axis, so while
manipulation waits with the hand down it says how far the object still has to come.
"""
from __future__ import annotations

import math

from channels.mdl import MDL_PROGRAM_REQ, SENSOR_READING, SENSOR_WIDTH, program_from_plain
from channels.messages import ACK
from iotad import Enum, Input, Iota, Output, Param
from iotad.esprit.runtime import esprit_now

from conveyor_geometry import BELT_X, MIN_PIXELS, hand_pose, on_plane, pixel_ray, segment
from conveyor_types import CAMERA_FRAME, LOOK_GOAL, MAX_BLOBS, REQ_SWITCHING, SIGHTING

UPSTREAM_Y = 0.35   # m: where vision looks with no target


class VisionControl(Iota):
    react = Param(0.01)          # s: every output goes out this soon after it is due (a deadline, so
                                 # that no legal schedule, the random policy's, lets it fall behind)
    priority = Param(1)
    epoch = Param(1000.0)        # s: tracking has no end of its own
    timeout = Param(1.5)         # s it may wait (pending or suspended) before the scheduler drops it: more
                                 # than the scheduler may take to start it (R + mdl_command's 1 + R: 1.02 s)
    look_height = Param(0.30)    # m: height of the grasp point while looking (the camera ~0.28 m above objects)
    move_time = Param(0.8)       # s: the move to the looking pose
    gain = Param(3.0)            # joint1 rad/s per rad of bearing error
    match_radius = Param(0.08)   # m: a blob this near the target's prediction is the target
    switching_margin = Param(0.1)  # s more than req's switching time between two requests: the
                                 # scheduler measures the switching time between arrivals, and a
                                 # request delivered sooner than the one before (across hosts, under
                                 # load: 4 ms then 1 ms) arrived inside it and was dropped, no ack
                                 # ever came, and vision believed it live (docs/conveyor.md)

    camera = Input(CAMERA_FRAME)
    goal = Input(LOOK_GOAL)
    ack = Input(ACK, switching=1)
    peer_restart = Input(Enum("vision_peer", "ack"))  # fed by the node host: the scheduler (ack's sender) restarted
    seen = Output(SIGHTING)
    visual_error = Output(SENSOR_READING)
    near = Output(SENSOR_READING)
    req = Output(MDL_PROGRAM_REQ, switching=REQ_SWITCHING)

    def init(self):
        self.target_goal = None     # the latest LOOK_GOAL
        self.requested_for = None   # the target of the last request (None: none yet)
        self.live = False           # that request is still with the scheduler (no ack yet)
        self.requests = 0
        self.out_seen = None
        self.out_error = None
        self.out_near = None
        self.out_req = None
        self.req_free = 0.0         # when req's switching time allows the next request
        self.acks = []

    # ------------------------------------------------------------------ inputs
    @goal.input
    def on_goal(self, goal):
        self.target_goal = goal
        if goal.target != self.requested_for or not self.live:
            self.requested_for, self.live = goal.target, True
            self.out_req = self._request(goal, esprit_now())

    @camera.input
    def on_frame(self, frame):
        self._look(frame)

    @ack.input
    def on_ack(self, value):
        self.acks.append(value)
        self.live = False

    @peer_restart.input
    def scheduler_restarted(self, channel):
        if self.live and self.target_goal is not None:  # the request died with it: ask the new one
            self.requested_for = self.target_goal.target
            self.out_req = self._request(self.target_goal, esprit_now())

    # ------------------------------------------------------------------ outputs
    @seen.action(value=lambda self: self.out_seen, when=lambda self: self.out_seen is not None,
                 within=(0, "react"))
    def sent_seen(self):
        self.out_seen = None

    @visual_error.action(value=lambda self: self.out_error, when=lambda self: self.out_error is not None,
                         within=(0, "react"))
    def sent_error(self):
        self.out_error = None

    @near.action(value=lambda self: self.out_near, when=lambda self: self.out_near is not None,
                 within=(0, "react"))
    def sent_near(self):
        self.out_near = None

    # within `react` of when req's switching time allows it (docs/stress.md): a request waits out
    # the switching time after the last one and `switching_margin` more (the window's lower bound:
    # the channel's own switching time would let it go at 1 s), and no longer
    @req.action(value=lambda self: self.out_req, when=lambda self: self.out_req is not None,
                within=(lambda self: max(0.0, self.req_free - esprit_now()),
                        lambda self: max(0.0, self.req_free - esprit_now()) + self.react))
    def sent_req(self):
        self.out_req = None
        self.req_free = esprit_now() + REQ_SWITCHING + self.switching_margin

    # ------------------------------------------------------------------ the work
    def _look(self, frame) -> None:
        size = int(math.isqrt(len(frame.rgb) // 3))
        blobs = []
        for colour, col, row, pixels in segment(frame.rgb, size, size):
            point = on_plane(frame.eye, pixel_ray(col, row, size, size, frame.fov, frame.forward, frame.up))
            if point is not None and pixels >= MIN_PIXELS:
                blobs.append((point[0], point[1], colour, pixels))
        blobs = sorted(blobs, key=lambda b: b[1])[:MAX_BLOBS]  # downstream first
        pad = MAX_BLOBS - len(blobs)
        self.out_seen = SIGHTING(t=frame.t, count=len(blobs), x=[b[0] for b in blobs] + [0.0] * pad,
                                 y=[b[1] for b in blobs] + [0.0] * pad, colour=[b[2] for b in blobs] + [0] * pad,
                                 pixels=[b[3] for b in blobs] + [0] * pad)
        centre = on_plane(frame.eye, pixel_ray((size - 1) / 2, (size - 1) / 2, size, size, frame.fov,
                                               frame.forward, frame.up))
        nearest = None if centre is None else min(
            blobs, key=lambda b: math.hypot(b[0] - centre[0], b[1] - centre[1]), default=None)
        if nearest is None:
            self.out_near = SENSOR_READING(valid=False, value=[0.0] * SENSOR_WIDTH)
        else:
            self.out_near = SENSOR_READING(valid=True, value=[nearest[0] - centre[0], nearest[1] - centre[1]]
                                           + [0.0] * (SENSOR_WIDTH - 2))
        target = self._target(blobs, frame.t)
        if target is None or centre is None:
            self.out_error = SENSOR_READING(valid=False, value=[0.0] * SENSOR_WIDTH)
            return
        bearing = math.atan2(target[1], target[0]) - math.atan2(centre[1], centre[0])
        radial = math.hypot(*target) - math.hypot(*centre)
        self.out_error = SENSOR_READING(valid=True, value=[bearing, radial] + [0.0] * (SENSOR_WIDTH - 2))

    def _target(self, blobs, t):
        goal = self.target_goal
        if goal is None or goal.target < 0:
            return None
        y = goal.y + goal.vy * (t - goal.t)
        best = min(blobs, key=lambda b: math.hypot(b[0] - goal.x, b[1] - y), default=None)
        if best is None or math.hypot(best[0] - goal.x, best[1] - y) > self.match_radius:
            return None
        return best[0], best[1]

    def _request(self, goal, now):
        self.requests += 1
        if goal.target < 0:
            x, y = BELT_X, UPSTREAM_Y
            atoms = [{"u": {"kind": "minimum_jerk", "pose": hand_pose(x, y, self.look_height)}, "T": self.move_time},
                     {"u": {"kind": "hold"}}]
        else:
            x, y = goal.x, goal.y + goal.vy * (now + self.move_time - goal.t)
            atoms = [{"u": {"kind": "minimum_jerk", "pose": hand_pose(x, y, self.look_height)}, "T": self.move_time},
                     {"u": {"kind": "hold"}, "k": [{"joint": "joint1", "sensor": "visual_error.x", "gain": self.gain}]}]
        program = program_from_plain({"id": f"look-{goal.target}-{self.requests}",
                                      "behaviours": [{"name": "track", "atoms": atoms}]})
        return MDL_PROGRAM_REQ(control=program, epoch=self.epoch, timeout=self.timeout, priority=self.priority)
