"""What the hub lets a ROS 2 peer do is derived from the [[ros2]] tables alone: subscribe to the
out topics (asking a latched one's cache), publish on the in topics, the graph's liveliness keys of
the tables' domains, nothing else; `iotad certs ros2` writes rmw_zenoh's session configuration and
refuses, in one line, what cannot work."""
import json
import re
import subprocess
import sys
from pathlib import Path

from iotad.launcher.access.access_policy import derive
from iotad.launcher.access.ros2_peers import grants_for, password
from iotad.launcher.system.system_file import load_system

ROOT = Path(__file__).resolve().parents[2]
BUGGY = (ROOT / "examples" / "buggy" / "buggy.iota").as_posix()


def certs(cwd, *args):
    return subprocess.run([sys.executable, "-m", "iotad", "certs", *args], capture_output=True, text=True,
                          timeout=60, cwd=cwd)


def test_a_peer_may_read_the_out_topics_write_the_in_topics_and_nothing_else(tmp_path):
    assert certs(tmp_path, "init", "certs", "--name", "buggy").returncode == 0
    made = certs(tmp_path, "ros2", "op", "--dir", "certs", "--connect", "tls/10.0.0.1:7448", "--files-at", "/etc/iotad")
    assert made.returncode == 0, made.stderr
    system = load_system(ROOT / "examples" / "buggy_ros2.toml")
    (grant,) = grants_for(system, tmp_path / "certs")
    keys = {m["topic"]: m for m in system.nodes["ros2"].params["mappings"]}
    from iotad.ros2.mapping import Mapping
    key = {topic: Mapping.from_plain(m).key for topic, m in keys.items()}
    assert grant.user == "ros2-op"
    assert grant.publish == [key["/cmd_vel"]]
    # an out topic's data, and what a transient-local subscription of either rmw_zenoh generation
    # asks: the publication caches (`*/<key>`), the advanced publishers' (`<key>/@adv/...`)
    advanced = [f"{key['/buggy/pose']}/@adv/**", f"{key['/buggy/wheels']}/@adv/**"]
    assert grant.subscribe == [key["/buggy/pose"], key["/buggy/wheels"], *advanced]
    assert set(grant.ask) == {key["/buggy/pose"], key["/buggy/wheels"], f"*/{key['/buggy/pose']}",
                              f"*/{key['/buggy/wheels']}", *advanced}
    assert grant.tokens == grant.watch == ["@ros2_lv/0/**", *advanced]
    assert not grant.serve
    every = grant.publish + grant.subscribe + grant.ask + grant.tokens
    assert not [k for k in every if k.startswith("iota") or k in ("**", "*")]
    # the hub's dictionary gets the same password the peer's file holds
    text = (tmp_path / "certs" / "ros2-op.json5").read_text()
    config = json.loads(text[text.index("{"):])
    assert config["transport"]["auth"]["usrpwd"] == {"user": "ros2-op", "password": password(tmp_path / "certs", "op")}
    assert config["mode"] == "client" and config["connect"]["endpoints"] == ["tls/10.0.0.1:7448"]
    # it replaces rmw_zenoh's default configuration: a transient-local publisher there needs timestamps
    assert config["timestamping"]["enabled"] is True
    tls = config["transport"]["link"]["tls"]
    assert tls["root_ca_certificate"] == "/etc/iotad/ca.pem" and tls["connect_certificate"] == "/etc/iotad/ros2-op.pem"
    assert tls["enable_mtls"] is True
    assert (tmp_path / "certs" / "ros2-op.json5").stat().st_mode & 0o077 == 0  # it holds a password
    # a system without the peer's folder admits no such user
    assert "ros2-op" not in derive(system).users() and grants_for(system, None) == []


def test_what_cannot_work_is_refused_in_one_line(tmp_path):
    assert certs(tmp_path, "init", "certs", "--name", "t").returncode == 0
    for args, said in ((["ros2", "op", "--dir", "certs", "--connect", "tcp/10.0.0.1:7447"], "over TLS only"),
                       (["ros2", "bad/name", "--dir", "certs", "--connect", "tls/10.0.0.1:7447"], "ROS 2 peer name"),
                       (["ros2", "op", "--dir", "nowhere", "--connect", "tls/10.0.0.1:7447"], "no authority's key")):
        done = certs(tmp_path, *args)
        assert done.returncode == 2 and said in done.stderr and len(done.stderr.strip().splitlines()) == 1, done.stderr
        assert re.match(r"^iotad: error: ", done.stderr)
    assert not list((tmp_path / "certs").glob("ros2-*"))
