"""Manipulation control (Figure 1): picks planning's target off the belt and places it in the bin.

On a pick goal it asks the scheduler for the arm (`req`, priority `priority`, above vision's)
with one MDL program, every move an end-effector pose solved by the interpreter's inverse
kinematics: approach above the meeting point, go down to it, wait there for the object the belt
brings, close the gripper (drive_joint), lift, carry over the bin, open. The meeting point is
downstream of where the object will be when the hand is down, even if the program starts late
(the scheduler's mdl_command has a switching time of 1 s), so the hand waits still and the belt
does the last centimetres; the wait ends on an interrupt, `near.dy < close_at`: vision sees the
object under the camera, which looks along the gripper's axis, that close upstream of the
fingers, or once the hand has waited `hold_margin` past the wait the goal predicts (`max_wait` at
most), so that the program ends within its epoch. Arm lag and a late start do not matter. The request's epoch is the program's length:
the scheduler commits it when the motion is over and gives the arm back (vision resumes).
`done` tells planning how the request ended (COMMIT: the motion ran).

A restarted scheduler knows nothing of the request it had: it would never answer, and
manipulation, planning (which waits for `done`) and so the whole cell would wait for ever. The
node host tells manipulation through `peer_restart` (an enum of the channels it cares about:
`ack`, bound to the scheduler), and a restart while it waits is the ABORT it is: `done`, not
committed, and planning goes on (docs/failures.md, "A restart strands no request").
"""
from __future__ import annotations

from channels.mdl import MDL_PROGRAM_REQ, program_from_plain
from channels.messages import ACK
from iotad import Enum, Input, Iota, Output, Param
from iotad.esprit.runtime import esprit_now

from conveyor_geometry import BIN, OBJECT_Z, hand_pose
from conveyor_types import PICK_DONE, PICK_GOAL, REQ_SWITCHING

GRIPPER = "drive_joint"
CLOSED, OPEN = 0.85, 0.0
DROP_SPACING = 0.08  # m between drop spots over the bin (examples/conveyor.toml makes it 0.3 m wide)
MARGIN = 0.01  # m the object is still upstream of where the wait must end, at the latest hand-down
# the channels through which a peer's restart matters: `ack`'s sender, the scheduler (not planning's)
SCHEDULER_RESTART = Enum("manipulation_peer", "ack")


class ManipulationControl(Iota):
    react = Param(0.01)          # s: every output goes out this soon after it is due (a deadline, so
                                 # that no legal schedule, the random policy's, lets it fall behind)
    priority = Param(5)
    timeout = Param(2.0)          # s it may wait for the arm
    approach_time = Param(0.8)    # s to above the meeting point
    down_time = Param(0.4)        # s down to it
    slack = Param(1.2)            # s the program may start late: the windows from goal to motion (req and
                                  # the scheduler's R, its mdl_command's switching time 1 + R, the
                                  # interpreter's tick) add up to 1.09 s at their latest (docs/stress.md)
    max_wait = Param(4.0)         # s the hand waits down for the object at most
    close_at = Param(0.015)       # m: close when the object is this far upstream of the fingers
    close_time = Param(0.45)      # s to close the gripper (0.85 rad at its 2 rad/s: 0.43 s at least)
    lift_time = Param(0.4)
    carry_time = Param(1.0)
    open_time = Param(0.45)       # s to open it (a ramp cut short leaves it half closed: no release)
    epoch_margin = Param(0.4)     # s more than the program should take (camera frames, sensor ages)
    # s the hand waits down past the expected wait at most, less than epoch_margin: the program
    # ends within its epoch. A wait to max_wait outlived it (the object came later than a stale
    # goal said, or vision's `near` was cut off with the camera), the scheduler committed the
    # pick in the middle of its carry, the gripper stayed closed on the object, and the camera
    # took the held object for new ones on the belt: picks of nothing for 16 s of a bad day.
    # Closing on time instead misses at worst, and a missed object is picked again (planning).
    hold_margin = Param(0.3)
    above = Param(0.10)           # m above the object's centre on the way in and out
    carry_height = Param(0.30)    # m: grasp point height over the bin
    grasp_offset = Param(0.01)    # m: grasp point above the object's centre when closing
    meet_y_max = Param(0.20)      # m: meet no further upstream than this

    goal = Input(PICK_GOAL)
    ack = Input(ACK, switching=1)
    peer_restart = Input(SCHEDULER_RESTART)  # fed by the node host: the scheduler restarted
    req = Output(MDL_PROGRAM_REQ, switching=REQ_SWITCHING)
    done = Output(PICK_DONE)

    def init(self):
        if not 0 <= self.hold_margin < self.epoch_margin:
            raise ValueError(f"hold_margin ({self.hold_margin!r} s) must be at least 0 and less than epoch_margin "
                             f"({self.epoch_margin!r} s): the pick must end within its epoch")
        self.current = None     # the target being picked
        self.out_req = None
        self.out_done = []
        self.picks = 0

    @goal.input
    def on_goal(self, goal):
        if self.current is None:  # one pick at a time; planning waits for `done`
            self.current = goal.target
            self.out_req = self._request(goal, esprit_now())

    @ack.input
    def on_ack(self, value):
        if self.current is not None:
            self.out_done.append(PICK_DONE(target=self.current, committed=value == ACK.COMMIT))
            self.current = None

    @peer_restart.input
    def scheduler_restarted(self, channel):
        if self.current is not None:  # the request died with the old scheduler: an ABORT
            self.out_done.append(PICK_DONE(target=self.current, committed=False))
            self.current = None

    # within `react` of the goal: its request is what starts the pick, and the pick tolerates a
    # start `slack` late in all (docs/stress.md). (A request follows the last one by a REJECT's
    # timeout or a COMMIT's epoch at least, so req's switching time never holds it back.)
    @req.action(value=lambda self: self.out_req, when=lambda self: self.out_req is not None,
                within=(0, "react"))
    def sent_req(self):
        self.out_req = None

    @done.action(value=lambda self: self.out_done[0], when=lambda self: len(self.out_done) > 0,
                 within=(0, "react"))
    def sent_done(self):
        del self.out_done[0]

    def _request(self, goal, now):
        self.picks += 1
        # where the object will be when the hand is down, even if the program starts `slack` late
        down = now + self.slack + self.approach_time + self.down_time
        meet_y = min(goal.y + goal.vy * (down - goal.t) - self.close_at - MARGIN, self.meet_y_max)
        x = goal.x
        z_in, z_grasp = OBJECT_Z + self.above, OBJECT_Z + self.grasp_offset
        expected = self._expected_wait(goal, now, meet_y)
        wait = min(self.max_wait, expected + self.hold_margin)
        atoms = [
            {"u": {"kind": "minimum_jerk", "pose": hand_pose(x, meet_y, z_in)}, "T": self.approach_time},
            {"u": {"kind": "minimum_jerk", "pose": hand_pose(x, meet_y, z_grasp)}, "T": self.down_time},
            {"u": {"kind": "hold"}, "T": wait, "xi": f"near.dy < {self.close_at!r}"},
            {"u": {"kind": "ramp", "target": {GRIPPER: CLOSED}}, "T": self.close_time},
            {"u": {"kind": "minimum_jerk", "pose": hand_pose(x, meet_y, z_in + 0.08)}, "T": self.lift_time},
            {"u": {"kind": "minimum_jerk", "pose": hand_pose(*self._drop_point(), self.carry_height)},
             "T": self.carry_time},
            {"u": {"kind": "ramp", "target": {GRIPPER: OPEN}}, "T": self.open_time},
        ]
        epoch = sum(a["T"] for a in atoms) - wait + expected + self.epoch_margin
        program = program_from_plain({"id": f"pick-{goal.target}", "behaviours": [
            {"name": "approach", "atoms": atoms[:3]}, {"name": "grasp", "atoms": atoms[3:5]},
            {"name": "place", "atoms": atoms[5:]}]})
        return MDL_PROGRAM_REQ(control=program, epoch=epoch, timeout=self.timeout, priority=self.priority)

    def _drop_point(self) -> tuple[float, float]:
        """Over the bin, one of a 3 x 3 grid of spots in turn, so that objects do not pile up."""
        k = self.picks % 9
        return BIN[0] + DROP_SPACING * (k % 3 - 1), BIN[1] + DROP_SPACING * (k // 3 - 1)

    def _expected_wait(self, goal, now, meet_y) -> float:
        """How long the hand waits down if the program starts now (the longest: a late start
        waits less, and the epoch counts from the program's start): until the object is
        `close_at` upstream of the meeting point."""
        speed = -goal.vy if goal.vy < 0 else 0.0
        down = now + self.approach_time + self.down_time
        y_down = goal.y + goal.vy * (down - goal.t)
        travel = (y_down - meet_y - self.close_at) / speed if speed > 0 else 0.0
        return min(self.max_wait, max(0.0, travel))
