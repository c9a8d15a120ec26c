"""Buggy's body: the simulated ODrives that drive its arena, and its sensors, as one IOTA.

`BuggyBody` is `SimulatedOdrives` (sim/odrive_sim.py) on world "buggy" (sim/worlds/buggy.py)
with Buggy's sensors added. One IOTA, not a composite of a simulator and a sensor IOTA, because
the sensors read the arena the axes move: as one IOTA's own state the arena evolves from the
IOTA's inputs alone, so a recording of it replays exactly (`iotad check`), in one process or as a
node of its own. Its channels: `can_rx`, `can_tx` (the axes' CAN station), and the readings.

Every `sense_period` s, in Buggy's body frame (x ahead, y to the left, m; angles rad, + to the left):
- `proximity`: distance and direction of the nearest wall, by a fan of ray casts (one PyBullet
  rayTestBatch). Nothing within the rays' reach reads as `distance` = that reach.
- `crack`: the vector to the nearest point of a crack within range (perpendicular to the crack
  unless that point is an end); `found` false when none is in range.
- `food`: true while uneaten food lies within reach of Buggy's centre. A piece Buggy stays over
  for `eat_time` s is eaten: gone, until it grows back `regrow` s later (0: never).
- `pose`: x, y (m, arena frame), yaw (rad), speed (m/s), and the bumps and eaten counts.

`landmark` tells a recording what the arena holds, for `iotad plot`: at the first firing the walls
(WALL: the inner square, x1 y1 - x2 y2), each crack (CRACK: its end points) and each piece of food
(FOOD: x1 y1); later EATEN and GROWN when a piece goes and comes back.
"""
from __future__ import annotations

from collections import deque

from iotad.kernel.api import Internal, Output, Param
from iotad.kernel.types import Bool, Enum, Float, Int, Struct
from sim.odrive_sim import SimulatedOdrives

PROXIMITY = Struct("proximity", distance=Float(0, None), direction=Float)
CRACK = Struct("crack", found=Bool, x=Float, y=Float)
POSE = Struct("buggyPose", x=Float, y=Float, yaw=Float, speed=Float, bumps=Int(0, None), eaten=Int(0, None))
LANDMARK_KIND = Enum("landmarkKind", "WALL", "CRACK", "FOOD", "EATEN", "GROWN")
LANDMARK = Struct("landmark", kind=LANDMARK_KIND, id=Int(0, None), x1=Float, y1=Float, x2=Float, y2=Float)


class BuggyBody(SimulatedOdrives):
    world = Param("buggy")
    sense_period = Param(0.1)      # s between readings
    eat_time = Param(1.0)          # s over a piece of food before it is eaten
    regrow = Param(30.0)           # s until an eaten piece is back; 0: never

    proximity = Output(PROXIMITY, switching=0)
    crack = Output(CRACK, switching=0)
    food = Output(Bool, switching=0)
    pose = Output(POSE, switching=0)
    landmark = Output(LANDMARK, switching=0)
    sense = Internal(switching=0)

    def init(self):
        if self.world != "buggy":
            raise ValueError(f"BuggyBody drives world 'buggy', not {self.world!r}")
        super().init()
        for name in ("sense_period", "eat_time"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0:
                raise ValueError(f"{name} must be a number > 0 s, got {value!r}")
        if isinstance(self.regrow, bool) or not isinstance(self.regrow, (int, float)) or self.regrow < 0:
            raise ValueError(f"regrow must be a number >= 0 s (0: never), got {self.regrow!r}")
        self.now = 0.0
        self.readings: deque = deque()     # (channel, value) waiting to go out, in order
        self.landmarks: deque = deque()
        self.gone: dict[int, float] = {}   # food index -> when it was eaten
        self.over: int | None = None       # the piece Buggy is over ...
        self.over_since = 0.0              # ... since when
        self.eaten = 0

    # ------------------------------------------------------------------ actions
    # Each reading goes out within timing_slack of the one before: a spec that allowed any delay
    # would let a legal schedule (the random policy's, `--seed`) steer on readings seconds old.
    @sense.action(after="sense_period")
    def sensed(self):
        if self.now == 0.0:
            self._announce()
        self.now += self.sense_period
        self._read()

    @proximity.action(value=lambda self: self.readings[0][1],
                      when=lambda self: len(self.readings) > 0 and self.readings[0][0] == "proximity",
                      within=(0, "timing_slack"))
    def sent_proximity(self):
        self.readings.popleft()

    @crack.action(value=lambda self: self.readings[0][1],
                  when=lambda self: len(self.readings) > 0 and self.readings[0][0] == "crack",
                  within=(0, "timing_slack"))
    def sent_crack(self):
        self.readings.popleft()

    @food.action(value=lambda self: self.readings[0][1],
                 when=lambda self: len(self.readings) > 0 and self.readings[0][0] == "food",
                 within=(0, "timing_slack"))
    def sent_food(self):
        self.readings.popleft()

    @pose.action(value=lambda self: self.readings[0][1],
                 when=lambda self: len(self.readings) > 0 and self.readings[0][0] == "pose",
                 within=(0, "timing_slack"))
    def sent_pose(self):
        self.readings.popleft()

    @landmark.action(value=lambda self: self.landmarks[0], when=lambda self: len(self.landmarks) > 0,
                     within=(0, "timing_slack"))
    def sent_landmark(self):
        self.landmarks.popleft()

    # ------------------------------------------------------------------ the work
    def _announce(self) -> None:
        w = self.plant
        self.landmarks.append(LANDMARK(kind="WALL", id=0, x1=-w.inner, y1=-w.inner, x2=w.inner, y2=w.inner))
        for k, ((ax, ay), (bx, by)) in enumerate(w.cracks):
            self.landmarks.append(LANDMARK(kind="CRACK", id=k, x1=ax, y1=ay, x2=bx, y2=by))
        for k, (fx, fy) in enumerate(w.food):
            self.landmarks.append(LANDMARK(kind="FOOD", id=k, x1=fx, y1=fy, x2=fx, y2=fy))

    def _read(self) -> None:
        w = self.plant
        seen = w.proximity()
        if seen is None:
            near = PROXIMITY(distance=float(w.proximity_range), direction=0.0)
        else:
            near = PROXIMITY(distance=seen.distance, direction=seen.bearing)
        vector = w.crack_vector()
        crack = CRACK(found=vector is not None, x=vector.x if vector else 0.0, y=vector.y if vector else 0.0)
        x, y, yaw = w.pose()
        food = self._food(x, y)
        pose = POSE(x=x, y=y, yaw=yaw, speed=w.speed(), bumps=w.bumps, eaten=self.eaten)
        self.readings.extend((("proximity", near), ("crack", crack), ("food", food), ("pose", pose)))

    def _food(self, x: float, y: float) -> bool:
        w, now = self.plant, self.now
        for k, eaten_at in list(self.gone.items()):
            if self.regrow > 0 and now - eaten_at >= self.regrow:
                del self.gone[k]
                fx, fy = w.food[k]
                self.landmarks.append(LANDMARK(kind="GROWN", id=k, x1=fx, y1=fy, x2=fx, y2=fy))
        best = None
        for k, (fx, fy) in enumerate(w.food):
            if k in self.gone:
                continue
            d = ((fx - x) ** 2 + (fy - y) ** 2) ** 0.5
            if d <= w.food_range and (best is None or d < best[0]):
                best = (d, k)
        piece = None if best is None else best[1]
        if piece != self.over:
            self.over, self.over_since = piece, now
        elif piece is not None and now - self.over_since >= self.eat_time:
            self.gone[piece] = now
            self.eaten += 1
            fx, fy = w.food[piece]
            self.landmarks.append(LANDMARK(kind="EATEN", id=piece, x1=fx, y1=fy, x2=fx, y2=fy))
            self.over = None
        return piece is not None
