"""Planning, vision control and manipulation control, each alone: planning turns sightings into a
perceptual goal and, once the object will be in reach, a manipulative goal; manipulation asks for
the arm with one MDL program of end-effector poses whose wait ends on vision's `near` interrupt;
vision's look program turns joint1 by the visual error. The conveyor's scheduler is the resume
scheduler's text with programs for modes."""
import re

import pytest

from channels.mdl import Program
from channels.messages import ACK
from conveyor_variant import FOLDER, ROOT
from conveyor_types import PICK_DONE, PICK_GOAL, SIGHTING
from manipulation import ManipulationControl
from planning import Planning
from vision import VisionControl


def sighting(t, y, x=0.45, colour=2):
    return SIGHTING(t=t, count=1, x=[x, 0, 0, 0], y=[y, 0, 0, 0], colour=[colour, 0, 0, 0], pixels=[30, 0, 0, 0])


def feed(planning, monkeypatch, t, y):
    monkeypatch.setattr("planning.esprit_now", lambda: t)
    planning.on_seen(sighting(t, y))


def test_planning_looks_then_picks_once_the_object_will_be_in_reach(monkeypatch):
    planning = Planning("planning")
    planning.init()
    feed(planning, monkeypatch, 2.0, 0.50)
    assert planning.out_look.target == 0 and planning.out_pick is None
    t, y = 2.0, 0.50
    while planning.out_pick is None and t < 10:
        t, y = t + 0.1, y - 0.005   # 0.05 m/s toward -y
        feed(planning, monkeypatch, t, y)
    goal = planning.out_pick
    assert goal is not None and goal.target == 0
    assert goal.vy == pytest.approx(-0.05, abs=0.002)
    assert goal.y + goal.vy * planning.pick_lead <= planning.pick_y + 0.006  # in reach by the time the hand is down
    # while manipulation works, sightings are not the belt's: nothing is tracked, no look goal
    planning.out_look = None
    feed(planning, monkeypatch, t + 0.1, 0.30)
    assert planning.out_look is None and len(planning.tracks) == 1


def picking_the_first_object(monkeypatch):
    """Planning fed an object on the belt until it asks for its pick: (planning, t, y) then."""
    planning = Planning("planning")
    planning.init()
    t, y = 2.0, 0.50
    while planning.out_pick is None and t < 10:
        feed(planning, monkeypatch, t, y)
        t, y = t + 0.1, y - 0.005
    assert planning.out_pick is not None and planning.out_pick.target == 0
    planning.out_pick = None
    return planning, t, y


def test_a_target_not_seen_for_a_while_is_looked_at_again_before_it_is_picked(monkeypatch):
    """A track the camera lost (cut off) would be picked where its fit puts it by now: a bad day's
    picks from 4-6 s old tracks met nothing. It is looked at first, and picked once seen again."""
    planning = Planning("planning")
    planning.init()
    t, y = 2.0, 0.50
    while t < 3.5:  # tracked until it is nearly in reach
        feed(planning, monkeypatch, t, y)
        t, y = t + 0.1, y - 0.005
    assert planning.out_pick is None
    # unseen for 3 s (the camera's host cut off); a sighting of something else off the belt
    # line wakes planning: by its fit the object is in reach, but its last sighting is old
    later = t + 3.0
    monkeypatch.setattr("planning.esprit_now", lambda: later)
    planning.on_seen(sighting(later, 0.45, x=0.2))
    assert planning.out_pick is None
    assert planning.out_look is not None and planning.out_look.target == 0
    feed(planning, monkeypatch, later + 0.1, y - 0.05 * 3.1)  # seen again where the belt brought it
    assert planning.out_pick is not None and planning.out_pick.target == 0


def test_an_object_seen_on_the_belt_after_its_pick_committed_is_picked_again(monkeypatch):
    """COMMIT says the pick's motion ran for its epoch, not that the hand holds the object: after
    a cut or a stall the hand may close on nothing (a 10-minute bad day had 20 picks that ran to
    their end and held nothing, each object then let go by). Seen again on the belt where its
    track predicts, it is picked again; the next object upstream is a new track."""
    planning, t, y = picking_the_first_object(monkeypatch)
    # the pick's 5 s go by (sightings then are the hand's work, ignored); it commits
    t, y = t + 5.0, y - 0.25
    monkeypatch.setattr("planning.esprit_now", lambda: t)
    planning.on_done(PICK_DONE(target=0, committed=True))
    assert planning.out_pick is None and planning.regrasps == 0
    # the object is still on the belt, where the belt carried it: picked again
    while planning.out_pick is None and y > planning.lost_y:
        feed(planning, monkeypatch, t, y)
        t, y = t + 0.1, y - 0.005
    again = planning.out_pick
    assert again is not None and again.target == 0 and planning.regrasps == 1
    assert again.y == pytest.approx(y + 0.005, abs=1e-9)  # from the new sightings, not the old track


def test_a_placed_object_is_not_picked_again_and_the_next_one_is_a_new_track(monkeypatch):
    planning, t, _ = picking_the_first_object(monkeypatch)
    t += 5.0
    monkeypatch.setattr("planning.esprit_now", lambda: t)
    planning.on_done(PICK_DONE(target=0, committed=True))
    # nothing where object 0 would be (it is in the bin); the next object comes 0.35 m upstream
    y_next = 0.50
    while planning.out_pick is None and t < 30:
        feed(planning, monkeypatch, t, y_next)
        t, y_next = t + 0.1, y_next - 0.005
    assert planning.out_pick is not None and planning.out_pick.target == 1 and planning.regrasps == 0


def test_an_object_off_the_belt_is_no_target_and_an_unseen_track_is_given_up(monkeypatch):
    """A track that stands still (an object knocked off the belt, within its width) was never
    predicted past lost_y: it stayed planning's look target, the look at it was out of reach, the
    camera never saw the belt again, and a 10-minute bad day placed nothing in its last 425 s."""
    planning = Planning("planning")
    planning.init()
    t = 2.0
    while t < 4.0:                              # 2 s of sightings, standing still
        feed(planning, monkeypatch, t, 0.02)
        t = round(t + 0.1, 6)
    assert [track.state for track in planning.tracks] == ["off"]
    assert planning.out_pick is None and planning.out_look.target == -1   # looks upstream again
    feed(planning, monkeypatch, t, 0.02)        # its own sightings go to it, not to a new track
    assert len(planning.tracks) == 1
    # an object on the belt meanwhile is a track, a target, and picked
    y = 0.50
    while planning.out_pick is None and t < 20:
        feed(planning, monkeypatch, t, y)
        t, y = round(t + 0.1, 6), y - 0.005
    assert planning.out_pick is not None and planning.out_pick.target == 1
    # unseen for forget_after (a camera cut off), every track is given up
    planning.out_pick, planning.busy = None, False
    monkeypatch.setattr("planning.esprit_now", lambda: t + planning.forget_after + 0.1)
    planning.on_done(PICK_DONE(target=1, committed=False))
    assert [track.id for track in planning.tracks if track.state != "done"] == []


def test_manipulation_asks_for_the_arm_with_one_pick_program(monkeypatch):
    monkeypatch.setattr("manipulation.esprit_now", lambda: 6.0)
    manipulation = ManipulationControl("manipulation")
    manipulation.init()
    manipulation.on_goal(PICK_GOAL(target=3, x=0.46, y=0.33, vy=-0.05, t=6.0))
    request = manipulation.out_req
    program = request.control
    assert isinstance(program, Program) and program.id == "pick-3"
    assert request.priority > VisionControl.priority.default
    atoms = [atom for _, _, atom in program.atoms()]
    kinds = [atom.u.kind for atom in atoms]
    assert kinds == ["minimum_jerk", "minimum_jerk", "hold", "ramp", "minimum_jerk", "minimum_jerk", "ramp"]
    approach, down = atoms[0].u.pose, atoms[1].u.pose
    # the meeting point is downstream of where the object is when the hand is down, even 1 s late
    latest_down = 6.0 + manipulation.slack + manipulation.approach_time + manipulation.down_time
    assert down.position[1] < 0.33 - 0.05 * (latest_down - 6.0) - manipulation.close_at
    assert down.position[2] < approach.position[2]
    assert atoms[2].xi == f"near.dy < {manipulation.close_at!r}"
    assert dict(atoms[3].u.target) == {"drive_joint": 0.85} and dict(atoms[6].u.target) == {"drive_joint": 0.0}
    # the epoch covers the program when it starts at once (the longest wait), and the hand waits
    # hold_margin past the expected wait at most: the whole program, waiting its longest, ends
    # within the epoch (a pick committed mid-carry kept the object in its closed gripper)
    fixed = sum(a.T for a in atoms) - atoms[2].T
    expected = request.epoch - fixed - manipulation.epoch_margin
    assert 0 < expected < manipulation.max_wait - manipulation.hold_margin
    assert atoms[2].T == pytest.approx(expected + manipulation.hold_margin)
    assert sum(a.T for a in atoms) < request.epoch
    # one pick at a time; the ack reports it to planning
    manipulation.on_goal(PICK_GOAL(target=4, x=0.46, y=0.5, vy=-0.05, t=6.0))
    assert manipulation.current == 3
    manipulation.on_ack(ACK.COMMIT)
    assert manipulation.out_done[0].target == 3 and manipulation.out_done[0].committed


def test_vision_tracks_with_feedback_on_joint1_and_asks_again_after_an_abort(monkeypatch):
    from conveyor_types import LOOK_GOAL
    monkeypatch.setattr("vision.esprit_now", lambda: 3.0)
    vision = VisionControl("vision")
    vision.init()
    vision.on_goal(LOOK_GOAL(target=0, x=0.45, y=0.4, vy=-0.05, t=3.0))
    program = vision.out_req.control
    look, track = [atom for _, _, atom in program.atoms()]
    assert look.u.pose.position[1] == pytest.approx(0.4 - 0.05 * vision.move_time)
    assert [(g.joint, g.sensor) for g in track.k] == [("joint1", "visual_error.x")]
    vision.out_req = None
    vision.on_goal(LOOK_GOAL(target=0, x=0.45, y=0.35, vy=-0.05, t=4.0))
    assert vision.out_req is None            # same target, request still live: no new request
    vision.on_ack(ACK.ABORT)
    vision.on_goal(LOOK_GOAL(target=0, x=0.45, y=0.30, vy=-0.05, t=5.0))
    assert vision.out_req is not None        # dropped by the scheduler: ask again


def test_the_conveyor_scheduler_is_the_resume_scheduler_carrying_programs():
    ours = (FOLDER / "resume_program.iota").read_text()
    resume = (ROOT / "nodes" / "scheduler" / "resume.iota").read_text()
    tail = lambda text: text[text.index("\nenum ack"):]  # noqa: E731
    expected = tail(resume).replace("struct mdlReq command;", "struct mdlProgramReq command;") \
        .replace("req[N](struct mdlReq)/1", "req[N](struct mdlProgramReq)/1") \
        .replace("mdl_command(struct mode)/1", "mdl_command(struct mdlProgram)/1")
    assert tail(ours) == expected
    assert re.search(r'extern struct mdlProgram = "channels.mdl:MDL_PROGRAM"', ours)


@pytest.mark.parametrize("params, message", [
    ({"world": "arm"}, "ConveyorSim drives the conveyor world, not 'arm'"),
    ({"camera_period": 0}, "camera_period must be seconds > 0, got 0"),
    # text for a number: refused as the IOTA is made (iotad.kernel.model.param_kind_problem)
    ({"camera_period": "fast"}, "parameter camera_period: expected a number (its default is 0.1), got 'fast'"),
])
def test_the_conveyor_sim_refuses_bad_parameters_with_a_clear_message(params, message):
    from conveyor_sim import ConveyorSim
    from iotad.kernel.model import SpecError
    with pytest.raises((ValueError, SpecError), match=re.escape(message)):
        ConveyorSim("sim", **params)
    from sim.worlds import find_world
    assert find_world("sim") is None  # nothing left open


def test_a_malformed_camera_frame_is_refused_at_the_channel():
    from conveyor_types import CAMERA_FRAME
    from iotad.kernel.types import BadValue
    plain = {"t": 0.0, "rgb": "AAAA", "fov": 60.0, "eye": [0, 0, 0], "forward": [0, 0, -1], "up": [1, 0, 0]}
    with pytest.raises(BadValue, match="expected 4800 bytes"):
        CAMERA_FRAME.from_plain(plain)


def test_a_camera_frame_travels_compressed_and_an_older_recordings_plain_frame_still_reads():
    """Raw, the camera's frames queued 1.4 s in zenoh over a link slowed to 1 Mbit/s (vision saw
    the belt that late); compressed they are a few dozen times smaller. Bad compressed data is a
    clear error, and a payload that would inflate past one frame is refused, not inflated."""
    import base64
    import zlib

    from conveyor_types import CAMERA_FRAME, RGB_IMAGE
    from iotad.kernel.types import BadValue

    rgb = bytes([200, 30, 30]) * 400 + bytes([90, 90, 90]) * 1200   # a red blob on the grey belt
    frame = CAMERA_FRAME(t=1.0, rgb=rgb, fov=60.0, eye=[0, 0, 1], forward=[0, 0, -1], up=[1, 0, 0])
    plain = CAMERA_FRAME.to_plain(frame)
    assert plain["rgb"].startswith("zlib:") and len(plain["rgb"]) < len(rgb) // 20
    assert CAMERA_FRAME.from_plain(plain).rgb == rgb
    older = dict(plain, rgb=base64.b64encode(rgb).decode("ascii"))
    assert CAMERA_FRAME.from_plain(older).rgb == rgb
    for packed, message in [(zlib.compress(bytes(10 ** 6)), "expected 4800 bytes"),
                            (zlib.compress(rgb)[:-4], "cut short"),
                            (b"not zlib", "not zlib data")]:
        with pytest.raises(BadValue, match=message):
            RGB_IMAGE.from_plain("zlib:" + base64.b64encode(packed).decode("ascii"))


def test_a_scheduler_restart_while_manipulation_waits_is_an_abort_and_the_next_goal_is_picked():
    """A restarted scheduler never answers the request it lost: without the notice, manipulation
    kept its target and ignored every later goal, and planning waited for its `done` (a 10-minute
    bad day placed no cube in the 390 s after the scheduler's kill -9)."""
    from iotad.kernel.engine import Engine

    manipulation = ManipulationControl("manipulation")
    engine = Engine(manipulation)
    engine.post(None, "goal", PICK_GOAL(target=3, x=0.46, y=0.33, vy=-0.05, t=1.0), t=1.0)
    engine.post(None, "peer_restart", "ack", t=2.0)         # the scheduler restarted: no ack will come
    engine.post(None, "goal", PICK_GOAL(target=4, x=0.46, y=0.35, vy=-0.05, t=3.0), t=3.0)
    engine.post(None, "ack", ACK.COMMIT, t=8.0)
    engine.run(until=9.0)
    outputs = [(round(e["t"], 6), e["action"], e["value"]) for e in engine.trace if e["kind"] == "output"]
    assert [(t, action) for t, action, _ in outputs] == [(1.0, "req"), (2.0, "done"), (3.0, "req"), (8.0, "done")]
    assert [v["control"]["id"] if a == "req" else (v["target"], v["committed"]) for _, a, v in outputs] == [
        "pick-3", (3, False), "pick-4", (4, True)]
    # a restart with no request in flight changes nothing
    engine.post(None, "peer_restart", "ack", t=9.5)
    engine.run(until=10.0)
    assert [e for e in engine.trace if e["kind"] == "output" and e["t"] > 9.0] == []


def test_a_scheduler_restart_while_vision_waits_makes_it_ask_the_new_one_for_its_goal():
    """The request vision waits on died with the old scheduler: without the notice it never asked
    again for the same target, the arm tracked an object long gone and the cell placed nothing for
    290 s of a bad day. It asks again, once req's switching time allows; with no request in flight
    a restart changes nothing."""
    from iotad.kernel.engine import Engine
    from conveyor_types import LOOK_GOAL, REQ_SWITCHING

    vision = VisionControl("vision")
    engine = Engine(vision)
    engine.post(None, "goal", LOOK_GOAL(target=20, x=0.45, y=0.2, vy=-0.05, t=1.0), t=1.0)
    engine.post(None, "peer_restart", "ack", t=1.5)   # inside req's switching time: waits it out
    engine.run(until=4.0)
    asked = [(round(e["t"], 6), e["value"]["control"]["id"]) for e in engine.trace
             if e["kind"] == "output" and e["action"] == "req"]
    assert asked == [(1.0, "look-20-1"), (round(1.0 + REQ_SWITCHING + vision.switching_margin, 6), "look-20-2")]
    engine.post(None, "ack", ACK.ABORT, t=4.5)         # the new scheduler answered: nothing in flight
    engine.post(None, "peer_restart", "ack", t=5.0)
    engine.run(until=7.0)
    assert [e for e in engine.trace if e["kind"] == "output" and e["action"] == "req" and e["t"] > 4.0] == []
