"""Closed loop in one process in virtual time: CanMotor + CanBus + SimulatedOdrives (xArm6 in
PyBullet) follow a trajectory to within 0.01 rad at the end, every frame through the bus."""
import pytest

pytest.importorskip("pybullet")

from arm_system import HOME, arm_system  # noqa: E402
from iotad.kernel.engine import Engine  # noqa: E402

TARGET = (0.5, 0.1, -0.6, 0.4, 1.0, -0.5)


@pytest.fixture
def run_arm():
    engines = []

    def run(until, **kw):
        engine = Engine(arm_system(TARGET, **kw))
        engines.append(engine)
        engine.run(until=until)
        return engine

    yield run
    for engine in engines:  # the PyBullet client of each world is closed, also on failure
        engine.iota("arm/odrives").close()


def test_arm_follows_a_trajectory_through_can_to_within_a_hundredth_of_a_radian(run_arm):
    engine = run_arm(3.0, start=0.3, duration=2.0)
    trace = engine.trace
    states = [e for e in trace if e["iota"] == "arm/motor" and e["action"] == "joint_states"]
    assert states[0]["value"]["position"] == pytest.approx(HOME, abs=0.01)
    final = states[-1]["value"]["position"]
    assert final == pytest.approx(TARGET, abs=0.01)
    odrives = engine.iota("arm/odrives")
    measured, _ = odrives.plant.read_joints()
    assert measured[:6] == pytest.approx(TARGET, abs=0.01)  # the world agrees with the node
    status = [e["value"] for e in trace if e["iota"] == "arm/motor" and e["action"] == "joint_status"]
    assert {s["joint"] for s in status if s["event"] == "ARM_DONE"} == set(range(6))
    assert not [s for s in status if s["event"] in ("LOST", "DISARMED", "ARM_TIMEOUT", "AXIS_ERROR")]
    assert not [e for e in trace if e["kind"] == "violation"]
    assert not [e for e in trace if e["action"] == "bad_frame"]
