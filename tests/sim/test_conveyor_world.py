"""The conveyor world: cubes carried at the belt's speed, a pick by simulated axes closing the
gripper on a cube, placing it in the bin (counted), drops and misses, and the hand camera."""
import math

import numpy
import pytest

from sim.odrive_axis import AxisConfig, OdriveAxis
from sim.worlds.conveyor import ConveyorWorld

from sim_helpers import DT, TWO_PI, command

DOWN = (1.0, 0.0, 0.0, 0.0)  # the tool pointing at the floor


class Hand:
    """Seven simulated axes in position mode driving the xArm of a conveyor world: a test's arm."""

    def __init__(self, world):
        self.world = world
        inertias, efforts, speeds = world.joint_inertias(), world.effort_limits(), world.velocity_limits()
        self.axes = []
        positions, _ = world.read_joints()
        for k, (j, effort, speed) in enumerate(zip(inertias, efforts, speeds)):
            j *= TWO_PI
            axis = OdriveAxis(k, AxisConfig(pos_gain=15, vel_gain=j * 60, vel_integrator_gain=j * 900,
                                            vel_limit=speed / TWO_PI, current_limit=effort))
            axis.update(positions[k] / TWO_PI, 0.0, 0.0, DT)
            axis.handle(command(k, "Set_Axis_State", Axis_Requested_State=8), 0.0)
            self.axes.append(axis)

    def aim(self, tool_point):
        """Put the tool point at `tool_point` (the arm's joints by inverse kinematics)."""
        x, y, z = tool_point
        for axis, q in zip(self.axes, self.world.inverse_kinematics((x, y, z + self.world.model.tool_offset), DOWN)):
            axis.input_pos = q / TWO_PI

    def grip(self, closure):
        self.axes[6].input_pos = closure * 0.85 / TWO_PI

    def run(self, seconds, each_step=None):
        for _ in range(round(seconds / DT)):
            if each_step is not None:
                each_step()
            self.world.step()
            positions, velocities = self.world.read_joints()
            self.world.apply_torques([axis.update(q / TWO_PI, v / TWO_PI, self.world.time, DT)
                                      for axis, q, v in zip(self.axes, positions, velocities)])


@pytest.fixture
def world():
    world = ConveyorWorld(seed=2, first_cube=0.2, belt_speed=0.1, cube_count=3, cube_interval=4.0)
    yield world
    world.close()


def test_cubes_appear_at_intervals_and_ride_at_the_belt_speed(world):
    for _ in range(round(1.2 / DT)):
        world.step()
    (index, (x, y, z)), = world.cube_positions().items()
    assert index == 0 and y == pytest.approx(0.6 - 0.1 * (world.time - 0.2), abs=1e-3)
    assert z == pytest.approx(world.belt_height + world.cube_size / 2, abs=1e-3)
    assert x == pytest.approx(world.belt_x + world.cubes[0].offset)
    for _ in range(round(20.0 / DT)):  # nobody picks: every cube falls off the end
        world.step()
    assert world.missed == 3 and world.placed == 0 and not world.cube_positions()
    assert [state for _, state in world.cubes[0].history] == ["riding", "missed"]
    assert world.cubes[1].history[0][0] == pytest.approx(4.2, abs=DT)


def test_colours_and_offsets_are_deterministic_for_a_seed():
    def layout(seed):
        world = ConveyorWorld(seed=seed)
        try:
            return [(c.colour, c.offset) for c in world.cubes]
        finally:
            world.close()
    assert layout(5) == layout(5) and layout(5) != layout(6)
    assert len(layout(5)) == 20 and {colour for colour, _ in layout(5)} <= {"red", "green", "blue", "yellow"}


def test_a_cube_picked_off_the_belt_and_dropped_in_the_bin_is_counted(world):
    hand = Hand(world)
    bx, by = world.bin_position

    def follow():
        cube = world.cube_positions().get(0)
        if cube is not None:
            hand.aim(cube)

    hand.aim((world.belt_x, 0.3, 0.25))
    hand.run(3.0)                    # wait above the belt; the cube comes
    hand.run(1.0, follow)            # down onto it, moving with it
    hand.grip(1.0)
    hand.run(0.5, follow)
    assert world.held is world.cubes[0]
    hand.aim((bx, by, 0.3))
    hand.run(2.0)
    assert world.cube_positions()[0][2] > 0.2  # carried up and over
    hand.grip(0.0)
    hand.run(1.0)
    assert world.placed == 1 and world.held is None
    assert [state for _, state in world.cubes[0].history] == ["riding", "held", "free", "placed"]


def test_closing_away_from_a_cube_grasps_nothing_and_a_closed_hand_does_not_pick(world):
    hand = Hand(world)
    hand.grip(1.0)
    hand.run(1.0)
    assert world.held is None          # closed over the empty belt
    follow = lambda: hand.aim(world.cube_positions()[0]) if 0 in world.cube_positions() else None
    hand.run(3.0, follow)              # the closed hand meets the cube
    assert world.held is None and world.cubes[0].state == "riding"


def test_a_cube_released_over_the_floor_is_dropped(world):
    hand = Hand(world)
    hand.aim((world.belt_x, 0.3, 0.25))
    hand.run(3.0)
    hand.run(1.0, lambda: hand.aim(world.cube_positions()[0]))
    hand.grip(1.0)
    hand.run(0.5, lambda: hand.aim(world.cube_positions()[0]))
    hand.aim((0.2, 0.35, 0.3))        # beside the belt, away from the bin
    hand.run(1.5)
    hand.grip(0.0)
    hand.run(1.5)
    assert world.dropped == 1 and world.placed == 0


def test_the_hand_camera_sees_a_red_cube_below_it():
    # a still belt, short enough that the cube sits within the arm's reach
    world = ConveyorWorld(seed=0, colours=("red",), first_cube=0.0, belt_speed=0.0, belt_length=0.6)
    try:
        world.step()
        (x, y, z), = world.cube_positions().values()
        world.reset(world.inverse_kinematics((x, y, z + 0.25), DOWN))
        image = world.camera_image(64, 64)
        assert image.shape == (64, 64, 3) and image.dtype == numpy.uint8
        red = (image[:, :, 0] > 150) & (image[:, :, 1] < 80) & (image[:, :, 2] < 80)
        rows, cols = numpy.nonzero(red)
        assert red.sum() > 20
        assert abs(rows.mean() - 32) < 8 and abs(cols.mean() - 32) < 8  # straight below: mid-image
        assert world.camera_image(96, 96).shape == (96, 96, 3)
    finally:
        world.close()


def test_bad_options_are_clear_errors():
    with pytest.raises(ValueError, match="colours must be some of"):
        ConveyorWorld(colours=("purple",))
    with pytest.raises(ValueError, match="cube_interval > 0"):
        ConveyorWorld(cube_interval=0)


def drop_into_bin(world, cube, height):
    """Put `cube` free above the bin's centre at `height` (m above the floor): as if released there."""
    import pybullet
    world._spawn(cube)
    bx, by = world.bin_position
    pybullet.resetBasePositionAndOrientation(cube.body, (bx, by, height), (0, 0, 0, 1), physicsClientId=world.client)
    pybullet.resetBaseVelocity(cube.body, (0, 0, 0), (0, 0, 0), physicsClientId=world.client)
    world._set_state(cube, "free")


def test_cubes_at_rest_in_the_bin_sleep_and_a_newcomer_lands_on_them(world):
    import pybullet

    def where(cube):
        return pybullet.getBasePositionAndOrientation(cube.body, physicsClientId=world.client)[0]

    first, second = world.cubes[0], world.cubes[1]
    for cube in world.cubes:
        cube.spawn_time = math.inf  # none rides in: the test places them
    drop_into_bin(world, first, 0.2)
    while first.state != "placed":
        world.step()
    still = set()
    for _ in range(240):
        world.step()
        still.add(where(first))
    # asleep: not a nanometre of the contact solver's jitter, step after step
    assert len(still) == 1
    drop_into_bin(world, second, 0.25)
    for _ in range(round(2.0 / DT)):
        world.step()
    assert world.placed == 2 and second.state == "placed"
    (_, _, z0), (_, _, z1) = where(first), where(second)
    # it did not fall through the sleeping cube: it rests on top of it, both in the bin
    assert z1 == pytest.approx(z0 + world.cube_size, abs=0.01)
    assert z0 == pytest.approx(0.01 + world.cube_size / 2, abs=0.01)  # on the bin's floor (0.01 thick)


def test_a_cube_at_rest_on_a_pile_higher_than_the_rim_is_in_the_bin(world):
    import pybullet

    for cube in world.cubes:
        cube.spawn_time = math.inf  # none rides in: the test places them
    pile = world.cubes[:3]
    for k, cube in enumerate(pile):  # one on the other, at the bin's centre
        drop_into_bin(world, cube, 0.03 + k * (world.cube_size + 0.005))
        for _ in range(round(1.0 / DT)):
            world.step()
    top = pybullet.getBasePositionAndOrientation(pile[-1].body, physicsClientId=world.client)[0]
    assert top[2] > world.bin_height  # its centre over the rim
    assert [cube.state for cube in pile] == ["placed"] * 3 and world.placed == 3
