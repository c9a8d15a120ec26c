"""Planning (Figure 1): perceptual and manipulative goals from what vision sees.

It keeps a track per object vision reports (`seen`): a sighting near a track's prediction (same
colour) refines it, else it starts a new one; the belt velocity of a track is its own fit once
it has been seen for `fit_after` seconds, `belt_speed` before. Goals:

- perceptual (`look`, to vision): the furthest-downstream object still to pick, or none (-1:
  look upstream); sent when it changes and every `refresh` seconds with the newest estimate;
- manipulative (`pick`, to manipulation): that object, once it has been seen `min_sightings`
  times over `fit_after` seconds and will be in reach (predicted y below `pick_y` by the time
  the hand is down), if manipulation is free. `done` frees it; an object whose pick did not
  commit is tried again while it is still in reach, and so is one seen on the belt again after
  its pick committed (COMMIT says the motion ran for its epoch, not that the hand holds the
  object: a grasp that closed on nothing, after a cut or a stall, leaves it on the belt where
  its track predicts).

An object predicted past `lost_y` (downstream, out of reach) is given up, and so is a track unseen
for `forget_after` seconds; one whose fitted velocity does not go with the belt is no object to
pick (`off`: it takes its own sightings until it is unseen that long). While manipulation
has the arm, sightings are ignored: the camera then looks at the hand's work (a held object
seen from above lands anywhere on the belt plane), not at the belt.
"""
from __future__ import annotations

from iotad import Input, Iota, Output, Param
from iotad.esprit.runtime import esprit_now

from conveyor_geometry import BELT_X
from conveyor_types import LOOK_GOAL, PICK_DONE, PICK_GOAL, SIGHTING


class Track:
    __slots__ = ("id", "colour", "x", "t0", "y0", "t1", "y1", "hits", "state")

    def __init__(self, id, colour, x, y, t):
        self.id, self.colour, self.x = id, colour, x
        self.t0, self.y0, self.t1, self.y1 = t, y, t, y
        self.hits, self.state = 1, "seen"

    def velocity(self, prior: float, fit_after: float) -> float:
        span = self.t1 - self.t0
        return (self.y1 - self.y0) / span if span >= fit_after else prior

    def y_at(self, t: float, vy: float) -> float:
        return self.y1 + vy * (t - self.t1)


class Planning(Iota):
    react = Param(0.01)          # s: every output goes out this soon after it is due (a deadline, so
                                 # that no legal schedule, the random policy's, lets it fall behind)
    belt_speed = Param(0.05)     # m/s, the prior for a new track (toward -y)
    fit_after = Param(1.0)       # s of sightings before a track's own velocity is used
    match_x = Param(0.04)        # m
    match_y = Param(0.06)        # m
    min_sightings = Param(5)
    pick_lead = Param(1.8)       # s from a pick goal to the hand being down
    pick_y = Param(0.25)         # m: pick once the object is predicted below this by then
    lost_y = Param(-0.30)        # m: past this an object is out of reach
    refresh = Param(1.0)         # s between look goals for the same target
    forget_after = Param(15.0)   # s unseen after which a track is given up (longer than a pick, while
                                 # sightings are ignored; a cut camera's tracks go, new ones come after)
    belt_half_width = Param(0.08)  # m: sightings further from the belt's centre line are not objects on it
    # s: a pick goal only from a target seen this recently (picks are decided on sightings 5-26 ms
    # old). A track unseen for seconds (the camera cut off) predicts the object wrongly: a bad day's
    # picks from 4-6 s old tracks met nothing, or waited past their epoch. Such a target is looked
    # at again first.
    pick_fresh = Param(0.25)

    seen = Input(SIGHTING)
    done = Input(PICK_DONE)
    look = Output(LOOK_GOAL)
    pick = Output(PICK_GOAL)

    def init(self):
        self.tracks: list[Track] = []
        self.next_id = 0
        self.busy = False
        self.look_target = None
        self.look_sent = -1e9
        self.out_look = None
        self.out_pick = None
        self.picked = 0
        self.regrasps = 0  # objects seen on the belt again after their pick committed

    @seen.input
    def on_seen(self, sighting):
        now = esprit_now()
        if not self.busy:  # while manipulation has the arm the camera sees its hand's work, not the belt
            for k in range(sighting.count):
                if abs(sighting.x[k] - BELT_X) <= self.belt_half_width:
                    self._observe(sighting.colour[k], sighting.x[k], sighting.y[k], sighting.t)
        self._plan(now)

    @done.input
    def on_done(self, report):
        self.busy = False
        self.look_target = None  # a fresh look goal now: vision's request was dropped meanwhile
        for track in self.tracks:
            if track.id == report.target:
                track.state = "done" if report.committed else "seen"
        self._plan(esprit_now())

    @look.action(value=lambda self: self.out_look, when=lambda self: self.out_look is not None,
                 within=(0, "react"))
    def sent_look(self):
        self.out_look = None

    @pick.action(value=lambda self: self.out_pick, when=lambda self: self.out_pick is not None,
                 within=(0, "react"))
    def sent_pick(self):
        self.out_pick = None

    # ------------------------------------------------------------------ the work
    def _observe(self, colour, x, y, t) -> None:
        vy0 = -self.belt_speed
        for track in self.tracks:
            if track.colour != colour or track.state == "lost":
                continue
            predicted = track.y_at(t, track.velocity(vy0, self.fit_after))
            if abs(track.x - x) < self.match_x and abs(predicted - y) < self.match_y:
                if track.state == "done":
                    # still on the belt where it would be had nobody touched it: the pick ran
                    # (committed) but the hand closed on nothing. A new track of it, to pick
                    # again while it is in reach (its old fit spans the failed grasp)
                    track.x, track.t0, track.y0, track.t1, track.y1 = x, t, y, t, y
                    track.hits, track.state = 1, "seen"
                    self.regrasps += 1
                elif track.state == "seen":  # a held object is not on the belt
                    track.x = (track.x * track.hits + x) / (track.hits + 1)
                    track.t1, track.y1 = t, y
                    track.hits += 1
                elif track.state == "off":  # still where it lies: it keeps its sightings, not a new track's
                    track.t1, track.y1 = t, y
                return
        if y > self.lost_y:
            self.tracks.append(Track(self.next_id, colour, x, y, t))
            self.next_id += 1

    def _plan(self, now: float) -> None:
        vy0 = -self.belt_speed
        for track in self.tracks:
            vy = track.velocity(vy0, self.fit_after)
            if track.state in ("seen", "picking") and track.y_at(now, vy) < self.lost_y:
                track.state = "lost"
            elif track.state == "seen" and vy > -self.belt_speed / 4:
                # its fit stands still or goes upstream: not carried by the belt (knocked off it,
                # the hand's work seen from above). Kept as a candidate, such a track was never
                # predicted past lost_y, stayed the look target, and the look at it, out of reach,
                # pointed the camera away from the belt for good (a 10-minute bad day placed
                # nothing in its last 425 s). Kept as "off", it takes its own sightings
                track.state = "off"
            elif track.state in ("seen", "off") and now - track.t1 > self.forget_after:
                track.state = "lost"
        self.tracks = [t for t in self.tracks if t.state != "lost" and not (t.state == "done" and now - t.t1 > 30)]
        candidates = [t for t in self.tracks if t.state == "seen"]
        target = min(candidates, key=lambda t: t.y_at(now, t.velocity(vy0, self.fit_after)), default=None)
        target_id = -1 if target is None else target.id
        if self.busy:
            return  # the arm is manipulation's: a look goal now would be stale when vision got it
        if target_id != self.look_target or now - self.look_sent >= self.refresh:
            self.look_target, self.look_sent = target_id, now
            if target is None:
                self.out_look = LOOK_GOAL(target=-1, x=0.0, y=0.0, vy=0.0, t=now)
            else:
                self.out_look = LOOK_GOAL(target=target.id, x=target.x, y=target.y1,
                                          vy=target.velocity(vy0, self.fit_after), t=target.t1)
        # its own fit first: an object that only the prior says is moving may lie off the belt
        if target is None or target.hits < self.min_sightings or target.t1 - target.t0 < self.fit_after \
                or now - target.t1 > self.pick_fresh:
            return
        vy = target.velocity(vy0, self.fit_after)
        if target.y_at(now + self.pick_lead, vy) <= self.pick_y:
            self.busy = True
            target.state = "picking"
            self.picked += 1
            self.out_pick = PICK_GOAL(target=target.id, x=target.x, y=target.y1, vy=vy, t=target.t1)
