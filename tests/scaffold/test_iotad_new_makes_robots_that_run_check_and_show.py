"""`iotad new NAME` makes a working robot: every template it offers (ODrive or CiA 402 drives;
the shipped pan-tilt URDF, a URDF of the user's, a shipped URDF with meshes, or a chain made for
the joints; one behaviour or several with priorities) runs clean under --strict in virtual time,
passes `iotad check`, and shows in 3D (what `iotad view` and `iotad export` send) with its own
joint names. The default asks nothing when input is not a terminal, and its own test file passes."""
import json
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

import iotad
from iotad.cli import main
from iotad.scaffold.questions import ask_choices
from iotad.scaffold.robot_plan import make_plan

ROOT = Path(__file__).resolve().parents[2]

TEMPLATES = {  # name: (options, joints, behaviours)
    "odrive-shipped": ([], ["pan", "tilt"], ["sweep"]),
    "cia402-shipped": (["--drives", "cia402", "--behaviour", "sweep:1", "--behaviour", "startle:5"],
                       ["pan", "tilt"], ["sweep", "startle"]),
    "odrive-own-urdf": (["--urdf", "{own}", "--node-ids", "7,9", "--behaviour", "scan:2", "--behaviour", "glance:3"],
                        ["pan", "tilt"], ["scan", "glance"]),
    "cia402-own-urdf": (["--urdf", "{own}", "--drives", "cia402", "--node-ids", "21,22"], ["pan", "tilt"], ["sweep"]),
    "odrive-chain": (["--joint", "shoulder:-1.5:1.5", "--joint", "elbow:-2:2", "--joint", "wrist"],
                     ["shoulder", "elbow", "wrist"], ["sweep"]),
    "cia402-chain": (["--joint", "a:-1:1", "--joint", "b", "--drives", "cia402", "--behaviour", "sweep:1",
                      "--behaviour", "look:4", "--behaviour", "dodge:9"], ["a", "b"], ["sweep", "look", "dodge"]),
    "odrive-meshes": (["--urdf", "kuka", "--behaviour", "sweep:1", "--behaviour", "look:3"],
                      [f"lbr_iiwa_joint_{k}" for k in range(1, 8)], ["sweep", "look"]),
    "cia402-meshes": (["--urdf", "kuka", "--drives", "cia402"], [f"lbr_iiwa_joint_{k}" for k in range(1, 8)],
                      ["sweep"]),
}


@pytest.mark.parametrize("template", list(TEMPLATES))
def test_every_template_runs_strict_checks_clean_and_shows_its_joints(template, tmp_path, capsys):
    options, joints, behaviours = TEMPLATES[template]
    own = tmp_path / "mine" / "head.urdf"  # a URDF of the user's, somewhere else
    own.parent.mkdir()
    own.write_text((ROOT / "sim/robots/pan_tilt.urdf").read_text())
    options = [o.replace("{own}", str(own)) for o in options]
    assert main(["new", "bot", "--in", str(tmp_path), *options]) == 0
    folder = tmp_path / "bot"
    assert {p.name for p in folder.iterdir()} >= {"README.md", "behaviours.py", "robot.toml", "test_robot.py"}
    # a URDF without meshes is copied in (the user's to change); one with meshes is named where it is
    assert (folder / "robot.urdf").is_file() == ("meshes" not in template)
    assert main(["run", "--check", str(folder / "robot.toml")]) == 0
    recording = tmp_path / "run.mcap"
    until = "3" if "meshes" in template else "5"  # seven joints cost; every behaviour has asked by then
    assert main(["run", str(folder / "robot.toml"), "--virtual", "--until", until, "--strict", "-o", str(recording),
                 "--plain"]) == 0
    assert ", 0 violations" in capsys.readouterr().out
    assert main(["check", str(recording)]) == 0
    opened = iotad.open_recording(recording)
    assert opened.raw.specs["motor"]["params"]["joints"][0]["name"] == joints[0]
    asked = {e["index"] for e in opened.events("scheduler", kind="input") if e["action"] == "req"}
    assert asked == set(range(len(behaviours)))  # every behaviour asked for the motors
    shown = tmp_path / "shown.mcap"
    assert main(["export", "--json", str(recording), "-o", str(shown)]) == 0
    with open(shown, "rb") as stream:
        described = [json.loads(m.data)["data"] for _, _, m in make_reader(stream).iter_messages(
            topics=["/robot_description"])]
    assert len(described) == 1 and all(f'name="{joint}"' in described[0] for joint in joints)


def test_the_default_asks_nothing_without_a_terminal_and_its_own_tests_pass(tmp_path):
    made = subprocess.run([sys.executable, "-m", "iotad", "new", "head"], cwd=tmp_path, stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=60)
    assert made.returncode == 0, made.stderr
    assert "joints pan (id 1), tilt (id 2) on simulated ODrives; behaviours sweep (priority 1)" in made.stdout
    tests = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "test_robot.py"],
                           cwd=tmp_path / "head", capture_output=True, text=True, timeout=300)
    assert tests.returncode == 0, tests.stdout + tests.stderr
    assert "2 passed" in tests.stdout
    again = subprocess.run([sys.executable, "-m", "iotad", "new", "head"], cwd=tmp_path, stdin=subprocess.DEVNULL,
                           capture_output=True, text=True, timeout=60)
    assert again.returncode == 2 and "exists and is not empty" in again.stderr


def test_at_a_terminal_it_asks_each_choice_with_defaults():
    answers = iter(["none", "yaw:-1:1 pitch", "cia402", "5,6", "wander:1 flee:8"])
    plan = make_plan("asked", **ask_choices(lambda prompt: next(answers)))
    assert [(j.name, j.lower, j.upper, j.node_id) for j in plan.joints] == [("yaw", -1.0, 1.0, 5), ("pitch", -1.5, 1.5, 6)]
    assert plan.family == "cia402" and plan.urdf is None
    assert [(b.name, b.priority) for b in plan.behaviours] == [("wander", 1), ("flee", 8)]
    defaults = make_plan("dflt", **ask_choices(lambda prompt: ""))
    assert [j.name for j in defaults.joints] == ["pan", "tilt"] and defaults.urdf == "pan_tilt"


@pytest.mark.parametrize("options, said", [
    (["--joint", "a", "--node-ids", "1,1"], "--node-ids gives 2 ids for 1 joints"),
    (["--joint", "a", "--joint", "b", "--node-ids", "3,3"], "one id per joint, all different"),
    (["--urdf", "pan_tilt", "--joint", "neck"], "joint(s) neck not in the URDF (its joints: pan, tilt)"),
    (["--urdf", "/no/such.urdf"], "no such file"),
    (["--joint", "a:2:1"], "LOWER must be below UPPER"),
    (["--behaviour", "motor:3"], "taken by one of the robot's own nodes"),
    (["--drives", "odrive", "--joint", "a", "--node-ids", "64"], "1..63"),
])
def test_choices_that_cannot_work_are_one_line(options, said, tmp_path, capsys):
    assert main(["new", "bot", "--in", str(tmp_path), *options]) == 2
    assert said in capsys.readouterr().err
    assert not (tmp_path / "bot").exists()


def test_urdf_joint_names_that_are_no_bare_key_are_quoted_and_unusable_ones_refused(tmp_path, capsys):
    text = (ROOT / "sim/robots/pan_tilt.urdf").read_text()
    dotted = tmp_path / "dotted.urdf"
    dotted.write_text(text.replace('name="pan"', 'name="head.pan"'))
    assert main(["new", "dots", "--in", str(tmp_path), "--urdf", str(dotted)]) == 0
    assert main(["run", str(tmp_path / "dots" / "robot.toml"), "--virtual", "--until", "2", "--no-record",
                 "--strict", "--plain"]) == 0
    spaced = tmp_path / "spaced.urdf"
    spaced.write_text(text.replace('name="pan"', 'name="the pan"'))
    assert main(["new", "spaces", "--in", str(tmp_path), "--urdf", str(spaced)]) == 2
    assert "joint name 'the pan' is not usable as a joint's name" in capsys.readouterr().err


def test_the_default_robot_is_viewed_live_in_real_time_on_a_can_tier(tmp_path):
    """`iotad run robot.toml --view` on the tier's bus, and a Foxglove client in the same network
    namespace: the 3D scene's joint states carry the robot's joint names."""
    from iotad.can.tiers import TierBus, TierUnavailable
    from iotad.node_host.transport import free_port

    try:
        bus = TierBus("udp_multicast")
    except TierUnavailable as exc:
        pytest.skip(f"no udp_multicast CAN tier: {exc}")
    assert main(["new", "head", "--in", str(tmp_path)]) == 0
    done = bus.run([sys.executable, str(Path(__file__).with_name("view_in_a_tier.py")), str(tmp_path / "head"),
                    str(free_port()), str(free_port())], timeout=200, cwd=str(ROOT))
    line = next((l for l in done.output.splitlines() if l.startswith("VIEWED ")), None)
    assert line is not None, done.output[-3000:]
    viewed = json.loads(line[len("VIEWED "):])
    assert viewed.get("names") == ["pan", "tilt"], done.output[-3000:]
    assert all(-2.6 <= p <= 2.6 for p in viewed["positions"])
