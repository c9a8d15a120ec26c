"""The policy `iotad run` enforces comes from the checked system: each node publishes only its
outputs and its own @ keys, subscribes to what is bound to its inputs; `iotad pub` writes only
where `[system.debug] allow_pub` says; `iotad run --check` prints it; bad allow_pub entries are
one-line errors naming the entry."""
import subprocess
import sys
from pathlib import Path

import pytest

from iotad.launcher.access.access_policy import RECORDER_USER, TOOLS_USER, derive
from iotad.launcher.system.system_file import SystemFileError, load_system

ROOT = Path(__file__).resolve().parents[2]


def figure2(tmp_path: Path, extra: str = "") -> Path:
    text = (ROOT / "examples/figure2.toml").read_text()
    text = text.replace("../nodes/", f"{ROOT}/nodes/").replace('"requesters.py:', f'"{ROOT}/examples/requesters.py:')
    text = text.replace('time_unit = 1.0 ', f'time_unit = 1.0\n{extra}\n', 1) if extra else text
    path = tmp_path / "figure2.toml"
    path.write_text(text)
    return path


def test_each_node_publishes_its_outputs_and_subscribes_to_its_bound_inputs(tmp_path):
    policy = derive(load_system(figure2(tmp_path)))
    scheduler = policy.grant("node-scheduler")
    assert scheduler.publish == ["iota/figure2/scheduler/ack/0", "iota/figure2/scheduler/ack/1",
                                 "iota/figure2/scheduler/mdl_command", "iota/figure2/scheduler/@trace",
                                 "iota/figure2/scheduler/@heartbeat"]
    assert "iota/figure2/vision/req" in scheduler.subscribe
    vision = policy.grant("node-vision")
    assert vision.publish == ["iota/figure2/vision/req", "iota/figure2/vision/@trace", "iota/figure2/vision/@heartbeat"]
    assert vision.tokens == ["iota/figure2/vision/@alive"] and vision.serve == ["iota/figure2/vision/@spec"]
    assert not any("mdl_command" in key for g in policy.grants if g.user != "node-scheduler" for key in g.publish)
    assert policy.grant(RECORDER_USER).publish == [] and policy.grant(TOOLS_USER).publish == []


def test_the_zenoh_config_denies_by_default_and_names_one_subject_per_user(tmp_path):
    acl = derive(load_system(figure2(tmp_path))).acl()
    assert acl["enabled"] and acl["default_permission"] == "deny"
    assert sorted(u for s in acl["subjects"] for u in s["usernames"]) == sorted(
        ["node-scheduler", "node-vision", "node-manipulation", RECORDER_USER, TOOLS_USER])
    puts = {key for rule in acl["rules"] if rule["flows"] == ["ingress"] and rule["messages"] == ["put"]
            for key in rule["key_exprs"]}
    assert "iota/figure2/scheduler/mdl_command" in puts and "iota/figure2/scheduler/req/1" not in puts
    rule_ids = {rule["id"] for rule in acl["rules"]}
    assert all(set(p["rules"]) <= rule_ids for p in acl["policies"])


def test_allow_pub_gives_iotad_pub_exactly_the_named_inputs(tmp_path):
    system = load_system(figure2(tmp_path, '[system.debug]\nallow_pub = ["scheduler.req[1]", "vision.ack"]'))
    assert derive(system).grant(TOOLS_USER).publish == ["iota/figure2/scheduler/req/1", "iota/figure2/vision/ack"]


@pytest.mark.parametrize("entry, message", [
    ('allow_pub = ["scheduler.ack[0]"]', "is an output channel; expected an input"),
    ('allow_pub = ["nobody.x"]', "no node named 'nobody'"),
    ('allow_pub = "vision.ack"', "must be a list"),
    ('allow = ["vision.ack"]', "unknown key 'allow'"),
])
def test_a_bad_allow_pub_is_one_line_naming_the_entry(tmp_path, entry, message):
    with pytest.raises(SystemFileError) as error:
        load_system(figure2(tmp_path, f"[system.debug]\n{entry}"))
    assert any("[system.debug]" in line and message in line for line in error.value.errors), error.value.errors


def test_run_check_prints_the_policy(tmp_path):
    done = subprocess.run([sys.executable, "-m", "iotad", "run", "--check", str(figure2(tmp_path))],
                          capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert done.returncode == 0, done.stderr
    assert "access control of figure2 (default: deny" in done.stdout
    assert "node-scheduler (node)" in done.stdout and "iota/figure2/scheduler/mdl_command" in done.stdout


def test_run_check_prints_the_policy_of_a_system_spread_over_hosts_with_its_launchers_and_agents(tmp_path, capsys):
    # the nodes keep their one-machine rights; each other host adds a launcher and an agent that
    # may only serve and publish on its own agent keys, and the hub's side of the agents
    from iotad.cli import main

    path = figure2(tmp_path)
    text = path.read_text()
    for node, host in (("scheduler", "brain"), ("vision", "arm"), ("manipulation", "arm")):
        assert text.count(f'name = "{node}"') == 1
        text = text.replace(f'name = "{node}"', f'name = "{node}"\nhost = "{host}"')
    text = text.replace("[system]", '[system]\nhub_host = "brain"')
    path.write_text(text)
    assert main(["run", "--check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "on when its hub starts the other hosts through their agents over tls/" in out
    # the hub admits brain's node; arm's log in to arm's router, which enforces their rights
    hub, router = out.split("access control of figure2 (default: deny; the router of host arm enforces it):")
    assert "node-scheduler (node)" in hub and "iota/figure2/scheduler/mdl_command" in hub
    assert "node-vision" not in hub and "node-manipulation" not in hub
    assert "node-vision (node)" in router and "node-manipulation (node)" in router and "node-scheduler" not in router
    assert "iotad-launcher-arm (launcher of host arm)" in out and "iotad-launcher-brain" not in out
    agent = out[out.index("iotad-agent-arm (agent of host arm)"):].split("\n  iotad-", 1)[0]
    assert "publish:            iota/@agent/arm/log, iota/@agent/arm/exit" in agent
    assert "answer queries on:  iota/@agent/arm/run, iota/@agent/arm/stop" in agent
    assert "iota/figure2" not in agent.replace("iota/*/@clock", "")  # no key of the system itself
