"""Vision control's eyes: the end-effector camera of the conveyor world renders the cubes, colour
segmentation finds them, and each blob's pixel ray meets the belt plane where the cube is; the
visual error says which way joint1 must turn; the image type checks and records its bytes."""
import math

import pytest

pytest.importorskip("pybullet")
pytest.importorskip("numpy")

import pybullet  # noqa: E402

from conveyor_variant import FOLDER  # noqa: E402,F401  (puts the example's folder on sys.path)
from conveyor_geometry import DOWN, TOOL, on_plane, pixel_ray, segment  # noqa: E402
from conveyor_types import CAMERA_FRAME, IMAGE_SIZE, LOOK_GOAL, RGB_IMAGE  # noqa: E402
from iotad.kernel.types import BadValue  # noqa: E402
from sim.worlds.conveyor import COLOURS, ConveyorWorld  # noqa: E402
from vision import VisionControl  # noqa: E402


@pytest.fixture
def world():
    world = ConveyorWorld(first_cube=0.0, cube_count=2, cube_interval=2.0, seed=3)
    # the hand above the belt at y = 0.45, pointing down; the belt carries the cubes for 4 s
    for joint, q in zip(world.arm_joints, world.inverse_kinematics([0.45, 0.45, 0.45], DOWN)):
        pybullet.resetJointState(world.body, joint, q, physicsClientId=world.client)
    for _ in range(int(4.0 / world.time_step)):
        world._spawn_and_carry()
        world.time += world.time_step
    try:
        yield world
    finally:
        world.close()


def camera_frame(world):
    position, orientation = world.end_effector_pose()
    m = pybullet.getMatrixFromQuaternion(orientation)
    forward, up = [m[2], m[5], m[8]], [m[0], m[3], m[6]]
    eye = [p + 0.05 * f for p, f in zip(position, forward)]
    rgb = world.camera_image(IMAGE_SIZE, IMAGE_SIZE, fov=60.0).tobytes()
    return CAMERA_FRAME(t=world.time, rgb=rgb, fov=60.0, eye=eye, forward=forward, up=up)


def test_each_cube_is_one_blob_of_its_colour_found_within_a_centimetre(world):
    frame = camera_frame(world)
    blobs = segment(frame.rgb, IMAGE_SIZE, IMAGE_SIZE)
    truth = world.cube_positions()
    assert len(blobs) == len(truth) == 2
    names = list(COLOURS)
    for colour, col, row, pixels in blobs:
        x, y = on_plane(frame.eye, pixel_ray(col, row, IMAGE_SIZE, IMAGE_SIZE, 60.0, frame.forward, frame.up))
        index, (tx, ty, _) = min(truth.items(), key=lambda item: math.dist(item[1][:2], (x, y)))
        assert math.dist((x, y), (tx, ty)) < 0.01
        assert names[colour] == world.cubes[index].colour
        assert pixels >= 10


def test_vision_reports_sightings_and_a_visual_error_toward_its_target(world):
    frame = camera_frame(world)
    vision = VisionControl("vision")
    vision.init()
    target = min(world.cube_positions().values(), key=lambda p: p[1])
    vision.target_goal = LOOK_GOAL(target=0, x=target[0], y=target[1], vy=0.0, t=frame.t)
    vision._look(frame)
    seen = vision.out_seen
    assert seen.count == 2 and seen.y[0] < seen.y[1]  # downstream first
    error = vision.out_error
    assert error.valid
    # turning joint1 by the bearing error brings the image centre's bearing to the target's
    centre_bearing = math.atan2(frame.eye[1], frame.eye[0])
    assert centre_bearing + error.value[0] == pytest.approx(math.atan2(target[1], target[0]), abs=0.03)
    near = vision.out_near
    assert near.valid and abs(near.value[1]) < 0.2


def test_no_target_in_view_is_an_invalid_reading_not_a_guess(world):
    frame = camera_frame(world)
    vision = VisionControl("vision")
    vision.init()
    vision.target_goal = LOOK_GOAL(target=5, x=0.45, y=-0.5, vy=0.0, t=frame.t)
    vision._look(frame)
    assert not vision.out_error.valid


def test_the_image_type_checks_sizes_and_records_base64():
    image = bytes(range(256)) * (IMAGE_SIZE * IMAGE_SIZE * 3 // 256) + bytes(IMAGE_SIZE * IMAGE_SIZE * 3 % 256)
    plain = RGB_IMAGE.to_plain(image)
    assert isinstance(plain, str) and RGB_IMAGE.from_plain(plain) == image
    with pytest.raises(BadValue, match="expected 4800 bytes"):
        RGB_IMAGE.check(b"\x00" * 10)
    with pytest.raises(BadValue, match="not base64"):
        RGB_IMAGE.from_plain("not base64 at all!")
    with pytest.raises(BadValue, match="expected base64 text"):
        RGB_IMAGE.from_plain(12)


def _image(width, height, pixels):
    """Grey (unsaturated) everywhere but at `pixels`: {(col, row): (r, g, b)}."""
    rgb = bytearray([128] * (3 * width * height))
    for (col, row), colour in pixels.items():
        rgb[3 * (row * width + col):3 * (row * width + col) + 3] = bytes(colour)
    return bytes(rgb)


def test_segmentation_rules_on_a_drawn_image():
    # a 6x4 image: a red L of 3 pixels (4-connected), a red pixel touching it only diagonally (its
    # own blob, too small), a dark green pair on the right edge (its channels 0.51 apart: saturated;
    # scaled to its peak, nearest green), a pale pixel below the saturation threshold (not a blob)
    red, green = (230, 25, 25), (10, 140, 10)
    pixels = {(0, 0): red, (0, 1): red, (1, 1): red, (2, 2): red,
              (5, 2): green, (5, 3): green, (3, 0): (200, 150, 150)}
    blobs = segment(_image(6, 4, pixels), 6, 4)
    assert blobs == [(0, 1 / 3, 2 / 3, 3), (1, 5.0, 2.5, 2)]


def test_each_reference_colour_is_its_own_class_and_brightness_does_not_matter():
    from conveyor_geometry import MIN_SATURATION, REFERENCE
    for k, colour in enumerate(REFERENCE):
        for scale in (1.0, 0.7, 0.3):  # 0.3: too dark to be saturated
            rgb = tuple(round(255 * c * scale) for c in colour)
            saturated = (max(rgb) - min(rgb)) / 255 >= MIN_SATURATION
            assert saturated == (scale > 0.5), (colour, scale)
            blobs = segment(_image(3, 3, {(1, 1): rgb, (1, 2): rgb}), 3, 3)
            assert blobs == ([(k, 1.0, 1.5, 2)] if saturated else []), (colour, scale)
