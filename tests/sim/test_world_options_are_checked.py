"""A world's options (a system file's `world_options`) are checked before the world is built: an
unknown one lists those there are, one of the wrong kind or out of range is named, and none
ends in a bare Python error (a wheel_radius of 0 divided by zero; an unknown option said
"__init__() got an unexpected keyword argument"). `time_step` is the simulated controllers'
`step_period`: given in world_options it made the world run faster than the clock."""
import pytest

from sim.odrive_sim import SimulatedOdrives
from sim.worlds import make_world, world_options


@pytest.mark.parametrize("world, options, message", [
    ("buggy", {"bogus": 1}, "world 'buggy' has no option 'bogus'; its options: arena_size, body_radius"),
    ("conveyor", {"bogus": 1}, "world 'conveyor' has no option 'bogus'; its options: belt_height, belt_length"),
    ("buggy", {"wheel_radius": 0.0}, "world 'buggy': option wheel_radius must be > 0, got 0.0"),
    ("buggy", {"start": "x"}, "world 'buggy': option start must be a list, got 'x'"),
    ("buggy", {"proximity_rays": 2.5}, "world 'buggy': option proximity_rays must be a whole number, got 2.5"),
    ("buggy", {"food_per_crack": -2}, "food_per_crack, friction and brake_torque must be >= 0, got -2, 0.001 and 0.1"),
    ("conveyor", {"belt_speed": "fast"}, "world 'conveyor': option belt_speed must be a finite number, got 'fast'"),
    ("conveyor", {"cube_count": 2.5}, "world 'conveyor': option cube_count must be a whole number, got 2.5"),
    ("conveyor", {"bin_size": 0}, "world 'conveyor': option bin_size must be > 0, got 0"),
    ("conveyor", {"seed": "a"}, "world 'conveyor': option seed must be a whole number, got 'a'"),
    ("arm", {"floor": 1}, "world 'arm': option floor must be true or false, got 1"),
])
def test_a_bad_option_is_named(world, options, message):
    with pytest.raises(ValueError) as caught:
        make_world(world, **options)
    assert message in str(caught.value)


def test_a_world_lists_its_base_classes_options_too():
    assert {"belt_speed", "solver_iterations", "time_step"} <= set(world_options("conveyor"))
    assert "robot" not in world_options("arm")  # fixed by the world's name


def test_time_step_is_the_nodes_step_period_not_a_world_option():
    with pytest.raises(ValueError, match="world_options: time_step is this node's step_period"):
        SimulatedOdrives("sim", world="buggy", world_options={"time_step": 0.5})
