"""What became of the cubes on a bad day (tests/bad_day_reading.py, `cube_fates`): a kill of the
simulated world's node, or of its host's part, starts a new world whose belt is empty, and the
cubes on the old belt or in its hand go with it. Counted from the world's own counts, carried
across its restarts as `iotad plot` carries them (sim/worlds/conveyor_plot.py), beside the cubes
placed, fallen off the belt's end and dropped."""
from bad_day_reading import cube_fates
from sim.worlds.conveyor_plot import _across_restarts


def counts(t: float, spawned: int, placed: int, missed: int = 0, dropped: int = 0, held: int = 0) -> tuple:
    return t, {"t": t, "spawned": spawned, "held": held, "placed": placed, "missed": missed, "dropped": dropped}


def test_the_cubes_a_restarted_world_held_are_gone_and_the_rest_keep_their_fates():
    raw = [counts(1, 2, 0), counts(9, 5, 2, missed=1, held=1),   # the first world: 1 on its belt, 1 in its hand
           counts(11, 1, 0), counts(19, 4, 3, dropped=1),        # the second: nothing left on it
           counts(21, 0, 0), counts(29, 3, 1, missed=1)]         # the third, to the end: 1 still on its belt
    tally = _across_restarts(raw, restarts=[10.0, 20.0])
    assert tally[-1][1]["spawned"] == 12  # carried: what every belt brought
    assert cube_fates(tally, [10.0, 20.0]) == {"brought": 12, "placed": 6, "missed": 2, "dropped": 1,
                                               "gone with a world": 2, "worlds restarted": 2}


def test_a_world_never_restarted_loses_nothing_and_no_counts_are_no_cubes():
    tally = _across_restarts([counts(1, 3, 1), counts(5, 6, 4, missed=1)], restarts=[])
    assert cube_fates(tally, []) == {"brought": 6, "placed": 4, "missed": 1, "dropped": 0,
                                     "gone with a world": 0, "worlds restarted": 0}
    assert cube_fates([], [3.0])["brought"] == 0
