"""The node as a system file states it: joint map as nested TOML tables, a [[can]] bus, the
simulated ODrives as the other station; the whole file composed in one process in virtual time
(what `iotad run --virtual` runs) moves the arm to its target."""
import textwrap
from pathlib import Path

import pytest

pytest.importorskip("pybullet")

from iotad.kernel.engine import Engine  # noqa: E402
from iotad.launcher.in_process import compose  # noqa: E402
from iotad.launcher.system_file import load_system  # noqa: E402

HERE = Path(__file__).resolve().parent
TARGET = [0.2, 0.1, -0.9, -0.3, 1.2, 0.4]


def system_text() -> str:
    joints = "".join(textwrap.dedent(f'''
        [[node.params.joints]]
        name = "joint{k}"
        node_id = {k}
        velocity_limit = 3.14
        current_limit = {effort}
        out_of_range = "clamp"
        ''') for k, effort in zip(range(1, 7), (50.0, 50.0, 32.0, 32.0, 32.0, 20.0)))
    return textwrap.dedent(f'''
        [system]
        name = "arm_can"
        external = ["motor.estop"]

        [[node]]
        name = "trajectory"
        python = "{HERE / 'arm_system.py'}:Trajectory"
        params = {{ target = {TARGET}, start = 0.3, duration = 1.0 }}

        [[node]]
        name = "motor"
        python = "nodes.can_motor:CanMotor"

        [node.params]
        polls = {{ Get_Error = 0.1, Get_Torques = 0.05 }}
        ''') + joints + textwrap.dedent('''
        [[node]]
        name = "odrives"
        python = "sim.odrive_sim:SimulatedOdrives"
        params = { world = "arm", node_ids = { joint1 = 1, joint2 = 2, joint3 = 3, joint4 = 4, joint5 = 5, joint6 = 6 } }

        [[can]]
        name = "can0"
        interface = "socketcan"
        channel = "vcan0"
        stations = ["motor", "odrives"]

        [[bind]]
        from = "trajectory.setpoints"
        to = "motor.setpoints"

        [[bind]]
        from = "motor.joint_states"
        to = "trajectory.joint_states"
        ''')


def test_the_system_file_runs_the_arm_to_its_target_in_virtual_time(tmp_path):
    path = tmp_path / "arm_can.toml"
    path.write_text(system_text())
    engine = Engine(compose(load_system(path)))
    try:
        engine.run(until=1.6)
    finally:
        engine.iota("arm_can/odrives").close()
    states = [e for e in engine.trace if e["iota"] == "arm_can/motor" and e["action"] == "joint_states"]
    assert states[-1]["value"]["position"] == pytest.approx(TARGET, abs=0.01)
    efforts = states[-1]["value"]["effort"]
    assert any(abs(effort) > 0.5 for effort in efforts)  # Get_Torques polled: gravity holds joint2 up
    assert not [e for e in engine.trace if e["kind"] == "violation"]
