"""INPUT_MODE TRAP_TRAJ, as the firmware's `TrapezoidalTrajectory` plans it: accelerate at
Traj_Accel_Limit to Traj_Vel_Limit, cruise, brake at Traj_Decel_Limit to rest at the goal; a
short move is a triangle, a start moving the wrong way brakes first. The axis follows the plan
with the acceleration times Traj_Inertia as torque feed-forward, and Heartbeat's
Trajectory_Done_Flag is 0 while it moves. (The motor node could arm a TRAP_TRAJ joint on real
hardware but never in simulation, which refused the mode as BAD_CONFIG.)"""
import pytest

from iotad.can import odrive
from iotad.can.odrive import CONTROL_MODE, INPUT_MODE
from sim.trap_traj import plan

from sim_helpers import DT, command, run


def test_a_long_move_is_a_trapezoid():
    move = plan(xf=10.0, xi=0.0, vi=0.0, vmax=2.0, amax=1.0, dmax=0.5)
    assert (move.ta, move.td) == (2.0, 4.0)                 # 2 / 1 and 2 / 0.5
    assert move.tv == pytest.approx((10.0 - 2.0 - 4.0) / 2.0)  # what the ramps leave, at 2 turn/s
    assert move.eval(move.ta) == pytest.approx((2.0, 2.0, 0.0))
    assert move.eval(move.tf) == (10.0, 0.0, 0.0)
    samples = [move.eval(k * 0.01) for k in range(round(move.tf * 100) + 1)]
    assert all(b[0] >= a[0] - 1e-12 for a, b in zip(samples, samples[1:]))  # never back
    assert max(v for _, v, _ in samples) <= 2.0 + 1e-12


def test_a_short_move_is_a_triangle_and_a_wrong_way_start_brakes_first():
    short = plan(xf=1.0, xi=0.0, vi=0.0, vmax=2.0, amax=1.0, dmax=1.0)
    assert short.tv == 0.0 and short.vr == pytest.approx(1.0) and short.tf == pytest.approx(2.0)
    back = plan(xf=1.0, xi=0.0, vi=-1.0, vmax=2.0, amax=1.0, dmax=1.0)
    assert back.ar == 1.0 and back.eval(1.0)[1] == pytest.approx(0.0)  # braked to rest at 1 s, then on
    assert back.eval(back.tf) == (1.0, 0.0, 0.0)


def test_unset_limits_plan_a_step():
    assert plan(xf=3.0, xi=0.0, vi=0.0, vmax=0.0, amax=1.0, dmax=1.0).eval(0.0) == (3.0, 0.0, 0.0)


def test_a_trap_traj_axis_follows_the_plan_and_says_when_it_is_done(armed_axis):
    axis, plant = armed_axis
    axis.handle(command(3, "Set_Controller_Mode", Control_Mode=CONTROL_MODE["POSITION"],
                        Input_Mode=INPUT_MODE["TRAP_TRAJ"]), 0.0)
    axis.handle(command(3, "Set_Traj_Vel_Limit", Traj_Vel_Limit=1.0), 0.0)
    axis.handle(command(3, "Set_Traj_Accel_Limits", Traj_Accel_Limit=2.0, Traj_Decel_Limit=2.0), 0.0)
    axis.handle(command(3, "Set_Traj_Inertia", Traj_Inertia=0.01), 0.0)
    axis.handle(command(3, "Set_Input_Pos", Input_Pos=2.0), 0.0)
    done = []
    run(axis, plant, 0.0, 3.0, feed=lambda t: done.append((round(t, 6), odrive.decode(axis.heartbeat())
                                                            .signals["Trajectory_Done_Flag"])))
    # 0.5 s to 1 turn/s, 1.5 s cruising, 0.5 s braking: done once 2.5 s have passed
    moving = [t for t, flag in done if not flag]
    assert moving[0] == pytest.approx(DT, abs=1e-6) and moving[-1] == pytest.approx(2.5, abs=2 * DT)
    assert done[-1][1] == 1 and axis.pos_setpoint == 2.0
    assert plant.position == pytest.approx(2.0, abs=2e-3)
