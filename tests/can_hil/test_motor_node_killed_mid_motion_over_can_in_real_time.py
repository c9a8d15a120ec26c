"""examples/arm_can.toml as processes in real time on a CAN bus (conftest's `system_can_tier`:
udp_multicast in a private network namespace where the host has it, else the best tier), its
motor node killed with SIGKILL while the arm moves:

- every simulated axis is IDLE with a watchdog error within 100 ms of the last command it got
  (in the axis's own time: its recorded steps), and stays put, braked, until the restart;
- the launcher restarts the node (restart = "on-failure"), which clears the errors, re-arms every
  axis, and the arm moves again and ends within 0.01 rad of the trajectory's last waypoint.

One run (about 25 s on udp_multicast, a minute and more in user-mode Linux, where the nodes take
10-30 s to start; it stops 14 s after the restarted node is live, time for the rest of the trajectory and to settle) serves every
test; every assertion reads the recording's timestamps, none the wall clock. The legs are longer
than the example's, so that the kill lands mid-motion, and the axes beat every 10 ms, so that a
heartbeat says IDLE soon after the watchdog trips.
"""
import json
import sys

import pytest

pytest.importorskip("pybullet")
pytestmark = pytest.mark.timeout(300)  # the run's start-up alone can take a minute in user-mode Linux

from arm_hil import (CLOSED_LOOP, FINAL, ROOT, after_the_kill, motor_starts, settled_positions,  # noqa: E402
                     system_variant)
from iotad.recording.mcap_reader import read_recording  # noqa: E402

STEP = 0.005            # the example's simulated step_period
KILL_AFTER = 3.0        # s after the motor node is live (the first leg runs 0.5-4.5 s after its first state)
TWO_PI = 6.283185307179586
BRAKE_SETTLE = 0.4      # s of the axis's time after its first IDLE heartbeat
# s the launcher waits before it restarts the node: the axes stay braked at least this long, time
# for BRAKE_SETTLE and a few encoder estimates after it, however fast the tier starts a process
# (in user-mode Linux a start takes seconds; on udp_multicast on the host, a fraction of one)
RESTART_AFTER = 1.5


@pytest.fixture(scope="module")
def run(system_can_tier, tmp_path_factory):
    folder = tmp_path_factory.mktemp("arm_rt")
    system = system_variant(folder, segment=4.0, bus=(system_can_tier.interface, system_can_tier.channel),
                            odrives={"heartbeat_period": "0.01", "encoder_period": "0.05"},
                            motor={"heartbeat_period": "0.01", "lost_after": "20", "encoder_period": "0.05"},
                            backoff=RESTART_AFTER)
    recording = folder / "arm.mcap"
    result = system_can_tier.run([sys.executable, str(ROOT / "tests" / "can_hil" / "arm_driver.py"),
                           str(system), str(recording), "--kill-after", str(KILL_AFTER), "--run-for", "14"],
                          timeout=400, cwd=str(ROOT)).check()
    driver = json.loads(next(line for line in result.output.splitlines() if line.startswith("DRIVER {"))[7:])
    assert driver["killed_pid"] and driver["lives"] == 2, result.output[-3000:]
    print(f"\nCAN tier {system_can_tier.describe()}: run took {result.seconds:.1f} s")
    loaded = read_recording(recording)
    return {"recording": loaded, "after": after_the_kill(loaded, STEP), "output": result.output}


def test_the_launcher_restarted_the_killed_motor_node(run):
    assert "motor: killed by SIGKILL" in run["output"] and "motor: restarted (#1)" in run["output"]
    assert len(motor_starts(run["recording"])) == 2


def test_every_axis_is_idle_with_a_watchdog_error_within_100_ms_of_its_last_command(run):
    # Measured in each axis's own time (its recorded steps, in the order its engine ran them):
    # the firmware's watchdog counts that time, and a busy one-vCPU user-mode kernel makes it lag
    # the wall clock. The trip lies between the last heartbeat not saying it and the first saying it.
    # An axis may trip before the kill, when the node stalls for 80 ms: then both are 0. The
    # heartbeats come every 10 ms of that time, one may come late under load: the first saying
    # IDLE is allowed 10 ms past 100 ms; the exact figure is the virtual-time test's
    # (test_watchdog_after_the_motor_node_falls_silent_in_virtual_time: 80-95 ms).
    axes = run["after"]["axes"]
    print("axis: (not yet, idle) s of the axis's time after its last command:",
          {node: (axis["sim_not_yet"], axis["sim_delay"]) for node, axis in axes.items()})
    for node, axis in axes.items():
        assert axis["idle"] is not None, f"axis {node} never said IDLE with a watchdog error before the restart"
        assert axis["sim_not_yet"] is None or axis["sim_not_yet"] <= 0.085, f"axis {node}: {axis['sim_not_yet']}"
        assert axis["sim_delay"] <= 0.1 + 0.01, f"axis {node}: {axis['sim_delay']}"


def test_nothing_moves_between_the_watchdog_and_the_restart(run):
    # The brake is a stiff spring, not a wall (PyBullet's position motor, sim/worlds/arm.py): it
    # takes the joint where it engaged and gives a little under gravity, 0.5-6 mrad by the pose
    # the kill caught, and a joint braked while moving stops within its braking distance (3 mrad
    # at 0.9 rad/s for the heaviest), settled within 0.4 s of the axis's time. It may give at
    # most 10 mrad; after BRAKE_SETTLE nothing may move (the virtual-time watchdog test has the
    # same bound).
    for node, axis in run["after"]["axes"].items():
        held = [turns for _, turns in axis["held"]]
        still = [turns for since, turns in axis["held"] if since >= BRAKE_SETTLE]
        assert len(still) >= 3, f"axis {node}: too few encoder estimates while it was idle"
        assert (max(held) - min(held)) * TWO_PI < 0.01, f"axis {node} gave way under the brake"
        assert (max(still) - min(still)) * TWO_PI < 0.002, f"axis {node} moved while idle"


def test_the_restarted_node_clears_errors_re_arms_and_the_arm_moves_on(run):
    axes = run["after"]["axes"]
    for node, axis in axes.items():
        assert axis["first_again"][0] == "Clear_Errors", f"axis {node}: {axis['first_again']}"
        assert {"Set_Controller_Mode", "Set_Limits", "Set_Axis_State"} <= set(axis["first_again"])
        assert any(b["Axis_State"] == CLOSED_LOOP and b["Axis_Error"] == 0 for b in axis["beats_after"]), node
    moved = [(max(a["positions_after"]) - min(a["positions_after"])) * TWO_PI for a in axes.values()]
    assert max(moved) > 0.1  # the arm was stopped mid-leg: it goes on to the waypoints


def test_the_arm_ends_within_0_01_rad_of_the_last_waypoint_in_real_time(run):
    # Judged at the last joint state at which every joint had been armed for 2 s: on a busy
    # machine the motor node can stall past the 80 ms watchdog again after its restart, and a
    # run may end while it re-arms (it then holds the arm braked where it stood).
    trace = run["recording"].trace()
    settled = settled_positions(trace, since=run["after"]["restart"])
    assert settled is not None, "no moment after the restart with every joint armed for 2 s"
    t, positions = settled
    assert t - run["after"]["restart"] >= 4.0, "judged before the arm could reach the last waypoint"
    assert positions == pytest.approx(FINAL, abs=0.01), f"at {t:.2f} s"
