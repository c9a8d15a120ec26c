"""Access control derived from the specs (docs/access-control.md), against a running Figure 2:
a process without credentials cannot even join the hub, a node's valid credentials do not let it
publish outside its outputs (the scheduler's `mdl_command`, a motor setpoint key, another node's
input), nothing of theirs reaches a subscriber or the recording, and the system runs on with its
legitimate traffic intact (the recording passes `iotad check`). With --insecure the same rogue
command does get through, which is what the policy prevents."""
import json
import re
import time
from pathlib import Path

import pytest
import zenoh

from launcher_helpers import free_port, launcher, wait_until
from recorded_systems import check_of_a_real_run

from iotad.cli import main
from iotad.node_host import credentials as creds
from iotad.node_host import wire
from iotad.node_host.transport import open_session
from iotad.recording.mcap_reader import read_recording

ROOT = Path(__file__).resolve().parents[2]
ROGUE = "ROGUE"
TARGETS = ["iota/figure2/scheduler/mdl_command",   # the scheduler's motor command
           "iota/figure2/motor/setpoints",         # a motor node's setpoint key
           "iota/figure2/scheduler/req/1"]         # an input of another node


def figure2_copy(tmp_path: Path, port: int) -> Path:
    text = (ROOT / "examples/figure2.toml").read_text()
    text = text.replace("../nodes/", f"{ROOT}/nodes/").replace('"requesters.py:', f'"{ROOT}/examples/requesters.py:')
    text = text.replace("tcp/127.0.0.1:7447", f"tcp/127.0.0.1:{port}")
    path = tmp_path / "figure2.toml"
    path.write_text(text)
    return path


class Probe:
    """A subscriber (with the tools' read-only credentials) on every key a rogue aims at."""

    def __init__(self, hub: str):
        self.session = open_session((), [hub], mode="client", connect_timeout=5.0, credentials=creds.for_endpoints([hub]))
        self.seen: list[tuple[str, object]] = []
        self.subs = [self.session.declare_subscriber(key, self._on) for key in
                     [*TARGETS, "iota/figure2/vision/@heartbeat"]]

    def _on(self, sample) -> None:
        try:
            value = wire.decode(sample.payload.to_bytes())
        except wire.WireError:
            value = None
        self.seen.append((str(sample.key_expr), value))

    def rogue_values(self) -> list:
        return [(k, v) for k, v in self.seen if v == ROGUE]

    def close(self) -> None:
        for sub in self.subs:
            sub.undeclare()
        self.session.close()


def rogue_puts(session) -> None:
    for key in TARGETS:
        session.put(key, wire.encode(ROGUE), attachment=wire.encode_attachment(0, time.time_ns()))


@pytest.fixture(scope="module")
def guarded_run(tmp_path_factory):
    tmp_path = tmp_path_factory.mktemp("acl")
    port = free_port()
    hub = f"tcp/127.0.0.1:{port}"
    system = figure2_copy(tmp_path, port)
    recording = tmp_path / "fig2.mcap"
    found = {}
    with launcher(system, "--until", "14", "--after-live", "-o", str(recording), secure=True) as proc:
        out = lambda: proc.output.read_text()  # noqa: E731
        assert wait_until(lambda: "vision: live" in out() and "manipulation: live" in out(), 30), out()
        folder = re.search(r"credentials in (\S+),", out()).group(1)
        probe = Probe(hub)
        try:
            # 1. no credentials: the hub does not let it in at all
            with pytest.raises(zenoh.ZError):
                open_session((), [hub], mode="client", connect_timeout=2.0, credentials=False)
            # 2. vision's own credentials, publishing outside vision's outputs
            vision = creds.load(Path(folder) / "node-vision.json")
            session = open_session((), [hub], mode="client", connect_timeout=5.0, credentials=vision)
            try:
                rogue_puts(session)
                # a canary on a key vision may write, after the rogue puts on the same session:
                # once the probe has it, whatever of the rogue puts the hub let through has arrived
                session.put("iota/figure2/vision/@heartbeat", wire.encode({"t": 0.0, "queue": 0, "canary": 1}))
                found["canary"] = wait_until(
                    lambda: any(isinstance(v, dict) and v.get("canary") for _, v in probe.seen), 10)
            finally:
                session.close()
            found["mdl_before"] = sum(1 for k, v in probe.seen if k.endswith("mdl_command"))
            found["rogue"] = probe.rogue_values()
            # the system runs on: the scheduler keeps commanding after the attempts
            found["mdl_after"] = wait_until(lambda: sum(1 for k, v in probe.seen if k.endswith("mdl_command"))
                                            > found["mdl_before"], 10)
        finally:
            probe.close()
        assert proc.wait(40) == 0, out()[-3000:]
        found["out"] = out()
        found["folder"] = folder
    return recording, found


def test_nothing_of_the_rogues_reaches_a_subscriber_and_the_system_runs_on(guarded_run):
    recording, found = guarded_run
    assert found["canary"], "the probe never saw the canary: it cannot vouch for the rogue puts"
    assert found["rogue"] == []
    assert found["mdl_after"], "the scheduler stopped commanding after the rogue attempts"
    assert not Path(found["folder"]).exists(), "the credentials outlived the run"


def test_the_recording_holds_no_rogue_message_and_passes_check(guarded_run):
    recording, _ = guarded_run
    data = read_recording(recording)
    assert [m.topic for m in data.messages if m.topic in TARGETS[1:]] == []
    commands = [m for m in data.messages if m.topic == TARGETS[0]]
    assert commands and all(m.value != ROGUE for m in commands)
    inputs = [e for e in data.trace("scheduler") if e["kind"] == "input"]
    assert inputs and all(e.get("value") != ROGUE for e in inputs)
    check_of_a_real_run(recording)  # every message delivered as sent; a node late only under load


def test_without_access_control_the_same_rogue_command_gets_through(tmp_path):
    port = free_port()
    hub = f"tcp/127.0.0.1:{port}"
    system = figure2_copy(tmp_path, port)
    with launcher(system, "--until", "20", "--after-live", "--no-record") as proc:  # the helper adds --insecure
        assert wait_until(lambda: "vision: live" in proc.output.read_text(), 30), proc.output.read_text()
        assert "access control is OFF" in proc.output.read_text()
        probe = Probe(hub)
        rogue = open_session((), [hub], mode="client", connect_timeout=5.0, credentials=False)
        try:
            assert wait_until(lambda: rogue_puts(rogue) or probe.rogue_values(), 10)
        finally:
            rogue.close()
            probe.close()


def test_credentials_are_private_files_and_the_tools_find_theirs_by_port(tmp_path, monkeypatch):
    monkeypatch.delenv(creds.ENV, raising=False)
    store = creds.CredentialStore(["node-a", "iotad-tools"])
    try:
        assert store.folder.stat().st_mode & 0o777 == 0o700
        assert {p.stat().st_mode & 0o777 for p in store.folder.iterdir()} == {0o600}
        assert json.loads(store.file_of("node-a").read_text())["user"] == "node-a"
        lines = store.dictionary.read_text().splitlines()
        assert sorted(line.split(":")[0] for line in lines) == ["iotad-hub", "iotad-tools", "node-a"]
        assert creds.for_endpoints(["tcp/127.0.0.1:1"]) is None
        store.advertise(["tcp/127.0.0.1:1"], "iotad-tools")
        assert creds.for_endpoints(["tcp/127.0.0.1:1"]).user == "iotad-tools"
    finally:
        store.remove()
    assert not store.folder.exists() and creds.for_endpoints(["tcp/127.0.0.1:1"]) is None


def test_pub_refuses_a_key_the_hub_would_drop_and_says_where_to_allow_it(tmp_path, monkeypatch, capsys):
    # the run writes into the tools' file where they may publish (allow_pub); `iotad pub` reads it
    monkeypatch.delenv(creds.ENV, raising=False)
    store = creds.CredentialStore(["iotad-tools"], may_publish={"iotad-tools": ["iota/s/arm/estop"]})
    try:
        assert creds.load(store.file_of("iotad-tools")).may_publish == ("iota/s/arm/estop",)
        store.advertise(["tcp/127.0.0.1:9"], "iotad-tools")
        assert main(["pub", "iota/s/motor/setpoints", "{}", "--connect", "tcp/127.0.0.1:9"]) == 2
        err = capsys.readouterr().err
        assert "iota/s/motor/setpoints: the hub there is under access control and would drop this" in err
        assert "allow_pub (iota/s/arm/estop)" in err and "--insecure" in err
        # an allowed key passes that check and goes on to the hub (none listens on port 9 here)
        assert main(["pub", "iota/s/arm/estop", "true", "--connect", "tcp/127.0.0.1:9",
                     "--connect-timeout", "0.5"]) == 2
        assert "no zenoh peer at tcp/127.0.0.1:9" in capsys.readouterr().err
    finally:
        store.remove()
