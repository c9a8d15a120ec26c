"""Buggy's arena: deterministic for a seed, its sensors (proximity, crack vector, food), eating,
its kinematic motion from the two actuators, and that it never leaves the arena."""
import math

import pytest

from iotad.can.odrive import CONTROL_MODE
from sim.odrive_axis import AxisConfig, OdriveAxis
from sim.worlds.buggy import BuggyWorld, closest_point

from sim_helpers import DT, TWO_PI, command


@pytest.fixture
def make_world():
    worlds = []

    def make(**options):
        world = BuggyWorld(**options)
        worlds.append(world)
        return world

    yield make
    for world in worlds:
        world.close()


def test_the_arena_is_deterministic_for_a_seed(make_world):
    a, b, c = make_world(seed=7), make_world(seed=7), make_world(seed=8)
    assert a.food == b.food and a.pose() == b.pose() and a.cracks == b.cracks
    assert a.food != c.food and a.pose() != c.pose()
    assert len(a.food) == 6 and len(a.cracks) == 2 and a.inside()
    for fx, fy in a.food:  # the food lies on the cracks
        assert min(math.dist((fx, fy), closest_point(p, q, (fx, fy))) for p, q in a.cracks) < 1e-9


def test_proximity_gives_distance_and_bearing_of_the_nearest_wall(make_world):
    world = make_world(start=(1.5, 0.0, 0.0))  # facing the east wall, 0.475 m from it
    near = world.proximity()
    assert near.distance == pytest.approx(world.inner - 1.5, abs=1e-3) and near.bearing == pytest.approx(0.0)
    world = make_world(start=(1.5, 0.0, math.pi / 2))  # facing north: the wall is on the right
    assert world.proximity().bearing == pytest.approx(-math.pi / 2)
    assert make_world(start=(0.0, 0.0, 0.3)).proximity() is None  # 1.975 m away: out of range
    fan = make_world(start=(1.5, 0.0, math.pi), proximity_fov=math.pi / 2, proximity_rays=5)
    assert fan.proximity() is None  # the wall is behind a forward fan


def test_crack_vector_is_perpendicular_to_the_crack_within_range(make_world):
    crack = ((-1.0, 0.0), (1.0, 0.0))
    world = make_world(cracks=[crack], start=(0.2, 0.3, 0.0), crack_range=0.5)
    vector = world.crack_vector()
    assert (vector.x, vector.y) == pytest.approx((0.0, -0.3))  # straight to the right of Buggy
    world.turn.position = math.pi / 2  # facing along +y: the crack is behind
    assert (world.crack_vector().x, world.crack_vector().y) == pytest.approx((-0.3, 0.0))
    world.y = 0.6
    assert world.crack_vector() is None
    world.x, world.y = 1.2, 0.0  # beyond the end: the vector points at the end
    assert world.crack_vector().distance == pytest.approx(0.2)


def test_food_is_detected_nearby_and_eating_removes_it(make_world):
    world = make_world(seed=1)
    fx, fy = world.food[0]
    world.x, world.y = fx + 0.3, fy
    assert not world.food_detected() and not world.eat()
    world.x = fx + 0.1
    assert world.food_detected() and world.eat()
    assert world.eaten == 1 and len(world.food) == 5 and (fx, fy) not in world.food
    assert not world.food_detected()


class Driver:
    """Buggy's two actuators as simulated ODrive axes in velocity mode, as SimulatedOdrives runs them."""

    def __init__(self, world):
        self.world = world
        self.axes = []
        for k, (j, effort, speed) in enumerate(zip(world.joint_inertias(), world.effort_limits(),
                                                   world.velocity_limits())):
            j *= TWO_PI
            axis = OdriveAxis(k, AxisConfig(vel_gain=j * 60, vel_integrator_gain=j * 900, vel_limit=speed / TWO_PI,
                                            current_limit=effort, control_mode=CONTROL_MODE["VELOCITY"]))
            axis.handle(command(k, "Set_Axis_State", Axis_Requested_State=8), 0.0)
            self.axes.append(axis)

    def command(self, speed, turn_rate):
        self.axes[0].input_vel = speed / self.world.wheel_radius / TWO_PI
        self.axes[1].input_vel = turn_rate / TWO_PI

    def step(self):
        world = self.world
        world.step()
        positions, velocities = world.read_joints()
        world.apply_torques([axis.update(q / TWO_PI, v / TWO_PI, world.time, DT)
                             for axis, q, v in zip(self.axes, positions, velocities)])


def test_the_actuators_move_buggy_forward_and_turn_it(make_world):
    world = make_world(start=(0.0, 0.0, 0.0))
    driver = Driver(world)
    driver.command(0.2, 0.0)
    for _ in range(round(2.0 / DT)):
        driver.step()
    assert world.speed() == pytest.approx(0.2, rel=1e-3)
    assert world.x == pytest.approx(0.2 * 2.0, abs=0.03) and world.y == pytest.approx(0.0, abs=1e-9)
    driver.command(0.0, 1.0)
    for _ in range(round(1.5 / DT)):
        driver.step()
    assert world.turn.velocity == pytest.approx(1.0, rel=1e-3) and world.speed() == pytest.approx(0, abs=1e-3)
    assert world.pose()[2] == pytest.approx(1.5, abs=0.05)


def naive_run(world, seconds, avoid=True):
    """Forward at 0.25 m/s; when a wall within 0.4 m is ahead, turn away from it on the spot."""
    driver = Driver(world)
    outside = 0
    for k in range(round(seconds / DT)):
        if k % 12 == 0:  # the sensor at 20 Hz
            near = world.proximity() if avoid else None
            if near is not None and near.distance < 0.4 and abs(near.bearing) < math.radians(100):
                driver.command(0.0, -2.0 if near.bearing >= 0 else 2.0)
            else:
                driver.command(0.25, 0.0)
        driver.step()
        outside += not world.inside()
    return outside


@pytest.mark.parametrize("seed", range(4))
def test_a_naive_controller_that_reacts_to_proximity_keeps_buggy_inside(make_world, seed):
    world = make_world(seed=seed)
    assert naive_run(world, 40.0) == 0
    assert world.distance > 4.0 and world.bumps == 0


def test_even_driving_blind_into_a_wall_buggy_stays_inside(make_world):
    world = make_world(start=(1.0, 0.3, 0.2))
    assert naive_run(world, 10.0, avoid=False) == 0
    assert world.bumps > 0 and world.x == pytest.approx(world.limit)


def test_bad_options_are_clear_errors():
    with pytest.raises(ValueError, match="leaves the arena"):
        BuggyWorld(cracks=[((0, 0), (5, 0))])
    with pytest.raises(ValueError, match="not inside the arena"):
        BuggyWorld(start=(3.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="proximity_rays must be >= 1"):
        BuggyWorld(proximity_rays=0)
