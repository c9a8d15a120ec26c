"""A partition mid-motion: the arm (simulated ODrives, the CAN motor node and their bus) on host
arm, its setpoints' source (the trajectory) and the hub on host brain, network namespaces joined
by a veth pair. While the arm moves, the link is cut for 1.5 s, then healed.

Measured on the frames the arm host itself recorded (its own recorder, as `iotad run -o` gives
each host, which the cut does not separate from the arm's nodes): the motor node, its setpoints gone for the link_timeout the
launcher gave it (it is fed from another host), tells every axis IDLE, 60-80 ms after the cut
on a machine not overloaded (printed; on its own clock, link_timeout and a tick after the last
setpoint it took, asserted);
nothing commands them while the link is down, and their heartbeats say IDLE. After the heal the
axes re-arm and follow the trajectory again, in the same run: no restart of the whole."""
import time

from namespaces import hosts
from partition_run import NODE_IDS, SplitArm, read_partition

HOLD = 1.5  # s the link stays down


def test_a_partition_mid_motion_puts_the_motors_safe_and_the_system_resumes(tmp_path):
    with hosts("brain", "arm", net=206) as net:
        arm = SplitArm(net, tmp_path, port=7616)
        try:
            arm.start()
            arm.wait_moving(timeout=120)
            arm.wait_recorded(timeout=30)  # the arm's own recording, which the cut is judged from, has begun
            cut = arm.cut()
            time.sleep(HOLD)  # the partition's length, the stimulus (nothing to wait on: brain hears nothing)
            heal = arm.heal()
            # the arm comes back: every joint reports LINK_FOUND, re-arms, and moves again
            arm.wait_all("LINK_FOUND", 60)
            arm.wait_all("ARM_DONE", 30)
            arm.wait_moving(timeout=30, by=0.05)
        finally:
            arm.stop()
        output = arm.output()
        assert "Traceback" not in output, output[-3000:]
        partition = read_partition(arm.recording, arm.name, cut, heal)
    # Every axis told IDLE while cut. The motor node's contract, on its own clock: within its
    # link_timeout (0.06 s, given by the launcher) and one tick (0.02 s) of the last setpoint it
    # took, plus its deadline tolerance. From the cut on the wall clock it is about 60-80 ms
    # (printed below; bench/hosts.py gives p50 and max over cuts), which a loaded machine may
    # stretch: that figure is measured, not asserted.
    assert all(partition.safe[node] is not None for node in NODE_IDS), (partition.safe, partition.story, output[-2000:])
    assert partition.silence is not None and 0.06 <= partition.silence <= 0.06 + 0.02 + 0.005, partition
    assert partition.commands_while_cut == 0, partition
    assert partition.idle_heartbeats >= 6 and partition.armed_heartbeats == 0, partition
    # a trip per joint for the cut and a recovery after the heal (on a loaded machine a late
    # setpoint after the heal may trip it again: the watch's price, docs/hosts.md)
    assert partition.link_events["LINK_LOST"] >= 6 and partition.link_events["LINK_FOUND"] >= 6, partition
    assert partition.rearmed == set(NODE_IDS) and partition.commanded_after == set(NODE_IDS), partition
    print("from the cut to IDLE, per axis (s):", {n: round(s, 3) for n, s in partition.safe.items()},
          f"(on the motor node's clock, from its last setpoint: {partition.silence:.3f} s)")
