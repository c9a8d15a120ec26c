"""`iotad check` widens the windows and switching times of a node on a host whose clock was
measured against the hub's by that host's bound at that time, and no more, and says so; the
hub's own nodes, and a recording of one host, are judged exactly as before. The Figure 2
recording, its scheduler put on host "arm" by launcher events, with the arm's clock measurements."""
import pytest

from iotad.cli import main
from iotad.recording.clock_offsets import ClockOffsetAt, Widening, clock_offsets, widenings
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_reader import read_recording
from recorded_systems import figure2, find, mutate

LAUNCHER = "iota/figure2/@launcher"


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "fig2.mcap"
    record_run(figure2(vision_pause=1.0), path, until=30)
    return path


def on_hosts(*measurements):
    """Launcher events: the scheduler on host arm, vision on the hub's host brain, and the arm's
    clock measured as (t, bound) says; one measurement that failed (no offset) besides."""
    events = [(LAUNCHER, 0.0, {"event": "start", "node": "scheduler", "host": "arm", "pid": 1}),
              (LAUNCHER, 0.0, {"event": "start", "node": "vision", "host": "brain", "pid": 2}),
              (LAUNCHER, 0.5, {"event": "clock_violation", "node": None, "host": "arm",
                               "message": "the hub answered no clock query"})]
    for t, bound in measurements:
        events.append((LAUNCHER, t, {"event": "clock", "node": None, "host": "arm", "t": t, "offset": -0.05,
                                     "bound": bound, "samples": 16, "best_delay": 2 * bound, "moved": 0.0}))
    return events


def late_commit(by):
    """The scheduler's ack[1]=COMMIT moved to `by` seconds after its window [3, 3.5] closed."""
    def change(events):
        k = find(events, action="ack", value="COMMIT", index=1)
        events[k] = dict(events[k], t=3.5 + by)
        return events
    return change


def check(path, capsys, *args):
    code = main(["check", str(path), *args])
    return code, capsys.readouterr().out


def test_a_late_firing_inside_the_bound_passes_and_the_report_says_why(recorded, tmp_path, capsys):
    path = mutate(recorded, tmp_path / "m.mcap", "scheduler", late_commit(0.0003), on_hosts((0.0, 0.0004)))
    code, out = check(path, capsys, "--no-delivery")  # the wire still holds the firing at its old time
    assert code == 0, out
    assert "scheduler: " in out and "0 problem(s)" in out.split("scheduler: ", 1)[1].splitlines()[0]
    assert "  windows of host arm widened by 0.4 ms (clock bound; 1 measurement(s) of its offset to the hub's clock)" in out
    # vision ran on the hub's host: judged exactly, nothing said
    assert out.count("widened") == 1


def test_a_late_firing_beyond_the_bound_is_reported(recorded, tmp_path, capsys):
    path = mutate(recorded, tmp_path / "m.mcap", "scheduler", late_commit(0.0005), on_hosts((0.0, 0.0004)))
    code, out = check(path, capsys)
    assert code == 1
    assert "[late] output ack[1]=COMMIT at t=3.5005 fired 0.0005 after its window [3, 3.5] closed" in out
    assert "windows of host arm widened by 0.4 ms" in out


def test_the_bound_in_force_at_the_time_of_the_event_is_the_one_used(recorded, tmp_path, capsys):
    # 0.1 ms until t=5, 0.6 ms after: a firing 0.3 ms late at t=3.5 is beyond the bound then
    path = mutate(recorded, tmp_path / "m.mcap", "scheduler", late_commit(0.0003), on_hosts((0.0, 0.0001), (5.0, 0.0006)))
    code, out = check(path, capsys)
    assert code == 1 and "[late] output ack[1]=COMMIT at t=3.5003" in out
    assert "windows of host arm widened by 0.1 to 0.6 ms, the bound at each time (clock bound; 2 measurement(s)" in out


def test_a_switching_time_is_widened_by_the_bound_too(recorded, tmp_path, capsys):
    def early_input(events):
        first = events[find(events, action="req", kind="input", index=0)]
        return events + [dict(first, t=first["t"] + 1.0 - 0.0002)]  # switching time 1, 0.2 ms too soon
    inside = mutate(recorded, tmp_path / "in.mcap", "scheduler", early_input, on_hosts((0.0, 0.0004)))
    code, out = check(inside, capsys, "--node", "scheduler", "--no-delivery")
    assert "[switching_time]" not in out and "widened by 0.4 ms" in out
    beyond = mutate(recorded, tmp_path / "out.mcap", "scheduler", early_input, on_hosts((0.0, 0.0001)))
    code, out = check(beyond, capsys, "--node", "scheduler", "--no-delivery")
    assert code == 1 and "[switching_time] input req[0]=" in out and "came 0.9998 after the previous one" in out


def test_a_recording_of_one_host_is_judged_exactly(recorded, tmp_path, capsys):
    path = mutate(recorded, tmp_path / "m.mcap", "scheduler", late_commit(0.0003))
    code, out = check(path, capsys)
    assert code == 1 and "[late] output ack[1]=COMMIT at t=3.5003" in out and "widened" not in out
    assert read_recording(path).clock_offsets() == {} and widenings(read_recording(path)) == {}


def test_the_offsets_over_time_are_read_per_host_in_time_order(recorded, tmp_path):
    path = mutate(recorded, tmp_path / "m.mcap", "scheduler", lambda events: events, on_hosts((5.0, 0.0006), (0.0, 0.0001)))
    recording = read_recording(path)
    assert recording.clock_offsets() == clock_offsets(recording) == {
        "arm": [ClockOffsetAt(0.0, -0.05, 0.0001), ClockOffsetAt(5.0, -0.05, 0.0006)]}
    widening = widenings(recording)["scheduler"]
    assert [widening.bound_at(t) for t in (-1.0, 0.0, 4.99, 5.0, 100.0)] == [0.0001, 0.0001, 0.0001, 0.0006, 0.0006]
    assert set(widenings(recording)) == {"scheduler"}
    # in spec units: a system whose time unit is a millisecond widens by 0.6 units
    assert Widening("arm", [ClockOffsetAt(0.0, 0.0, 0.0006)], time_unit=0.001)(3.0) == pytest.approx(0.6)
    with pytest.raises(ValueError, match="no clock measurement"):
        Widening("arm", [])


def test_implements_is_widened_by_the_bound_too(recorded, tmp_path, capsys):
    spec = f"{__import__('scheduler').__file__}:Scheduler"
    args = ["--node", "scheduler", "--spec", spec, "--param", "N=2", "--param", "T=0.5"]
    inside = mutate(recorded, tmp_path / "in.mcap", "scheduler", late_commit(0.0003), on_hosts((0.0, 0.0004)))
    code, out = check(inside, capsys, *args)
    assert code == 0 and "scheduler implements" in out, out
    assert "  windows of host arm widened by 0.4 ms (clock bound" in out
    beyond = mutate(recorded, tmp_path / "out.mcap", "scheduler", late_commit(0.0003), on_hosts((0.0, 0.0002)))
    code, out = check(beyond, capsys, *args)
    assert code == 1 and "does not implement" in out and "widened by 0.2 ms" in out, out
