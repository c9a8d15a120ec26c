"""The node as a system file states it: joint map as nested TOML tables, a [[can]] bus, the
simulated ODrives as the other station; the whole file composed in one process in virtual time
(what `iotad run --virtual` runs) moves the arm to its target."""
import pytest

pytest.importorskip("pybullet")

from arm_system import system_toml  # noqa: E402
from iotad.kernel.engine import Engine  # noqa: E402
from iotad.launcher.system.in_process import compose  # noqa: E402
from iotad.launcher.system.system_file import load_system  # noqa: E402

TARGET = [0.2, 0.1, -0.9, -0.3, 1.2, 0.4]


def test_the_system_file_runs_the_arm_to_its_target_in_virtual_time(tmp_path):
    path = tmp_path / "arm_can.toml"
    path.write_text(system_toml(TARGET))
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
