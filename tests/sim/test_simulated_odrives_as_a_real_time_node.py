"""SimulatedOdrives, unchanged, as a node process in real time: frames in and out over zenoh,
heartbeats at their period by the wall clock, an axis armed over CAN, and its watchdog."""
import time

from iotad.can import odrive
from iotad.can.frame import CAN_FRAME, Frame
from iotad.node_host import wire
from node_harness import Node, node_config, wait_for, wait_ready


def frames(hub, node, name, node_id):
    out = []
    for value in hub.values(f"{node.base}/can_tx"):
        message = odrive.decode(Frame.from_value(value))
        if message.name == name and message.node_id == node_id:
            out.append(message)
    return out


def test_a_buggy_axis_arms_runs_and_trips_its_watchdog_in_real_time(hub):
    params = {"world": "buggy", "control_mode": "VELOCITY", "watchdog_timeout": 0.2}
    node = Node(node_config(hub, "sim", "sim.odrive_sim:SimulatedOdrives", params=params))
    try:
        hub.subscribe(f"{node.base}/can_tx", f"{node.base}/@heartbeat")
        wait_ready(hub, node, timeout=30)
        wait_for(lambda: len(frames(hub, node, "Heartbeat", 0)) >= 3, what="three heartbeats of axis 0")
        started = time.monotonic()
        seq = 0

        def send(name, **signals):
            nonlocal seq
            hub.session.put(f"{node.base}/can_rx", wire.encode(CAN_FRAME.to_plain(odrive.encode(0, name, **signals).to_value())),
                            attachment=wire.encode_attachment(seq))
            seq += 1

        send("Set_Axis_State", Axis_Requested_State=8)
        for _ in range(10):  # commands every 50 ms for half a second feed the watchdog
            send("Set_Input_Vel", Input_Vel=0.5)
            time.sleep(0.05)
        beats = frames(hub, node, "Heartbeat", 0)
        assert beats[-1].signals["Axis_State"] == 8 and beats[-1].signals["Axis_Error"] == 0
        tripped = wait_for(lambda: [m for m in frames(hub, node, "Heartbeat", 0)
                                    if m.signals["Axis_Error"] == odrive.AXIS_ERROR["WATCHDOG_TIMER_EXPIRED"]],
                           timeout=5, what="a heartbeat with the watchdog error")
        assert tripped[0].signals["Axis_State"] == 1
        estimates = frames(hub, node, "Get_Encoder_Estimates", 1)
        elapsed = time.monotonic() - started
        # about 100 estimates a second per axis, by the wall clock (loose: a shared machine)
        assert len(estimates) > 50 * elapsed
        assert max(m.signals["Vel_Estimate"] for m in frames(hub, node, "Get_Encoder_Estimates", 0)) > 0.4
    finally:
        assert node.stop() == 0
