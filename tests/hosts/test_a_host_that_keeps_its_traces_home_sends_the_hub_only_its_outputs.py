"""`[hosts.arm] traces = "home"`: a host on a link too thin for its nodes' traces (a robot's arm
on a radio link: the conveyor's arm traces about 3.5 Mbit/s, its outputs to the other hosts about
0.3) keeps them on its own recording. The hub still hears the arm's outputs that its own nodes
read, but neither its recorder nor its launcher subscribes to the arm's traces, so none cross the
link; the arm's recording holds them, and `iotad merge` joins the two into a run that checks and
replays as one recorded at the hub. A strict run, whose verdict counts violations at the hub, is
refused with such a host, and a hub host that keeps its own traces home is an error of the file.
Each host's file checks alone, leaving what it was not made to hold to the merge."""
from namespaces import agent, hosts
from recorded_systems import check_of_a_real_run
from iotad.launcher.system.system_file import SystemFileError, load_system
from iotad.recording.mcap_reader import read_recording
from iotad.recording.merge import merged_gaps

import pytest

from test_each_host_records_and_the_recordings_merge import figure2_over, iotad, traced


def keeps_traces_home(text: str) -> str:
    return text.replace("[hosts.arm]\n", '[hosts.arm]\ntraces = "home"\n')


def test_the_hub_records_none_of_the_arms_traces_and_the_merge_holds_them(tmp_path):
    with hosts("brain", "arm", net=207) as net:
        hub = net.addresses[("brain", "arm")]
        system = tmp_path / "split2.toml"
        system.write_text(keeps_traces_home(figure2_over(hub, net.addresses["arm"], port=7627)))
        with agent(net, "arm", f"tcp/{hub}:7627"):
            done = iotad("run", system, "--insecure", "--until", "9", "--after-live", "--plain", "-o", tmp_path / "split.mcap",
                         place=lambda *c: net.exec("brain", *c))
    out = done.stdout
    assert done.returncode == 0, out[-3000:] + done.stderr[-2000:]
    hub_file, arm_file = read_recording(tmp_path / "split.mcap"), read_recording(tmp_path / "split.arm.mcap")
    # nothing of vision's trace at the hub, all of it at home
    assert not traced(hub_file, "vision") and traced(arm_file, "vision")
    assert traced(hub_file, "scheduler") and traced(hub_file, "manipulation")
    # vision's requests still reached the scheduler on the hub: it accounts for them on its trace
    heard = [m.value for m in hub_file.messages if m.topic == "iota/split2/scheduler/@trace"
             and isinstance(m.value, dict) and m.value.get("kind") == "input" and m.value.get("action") == "req"
             and m.value.get("index") == 0]
    assert heard, "the scheduler heard no request from vision"
    # the hub's summary says whose outputs it did not count
    assert "not counted here: the nodes of arm, which keep their traces home" in out, out[-3000:]
    # its recorder subscribed to the hub's nodes' traces by name, not to every trace; it still
    # hears every node's heartbeats, vision's among them: the hub sees the arm's nodes alive
    assert [k for k in hub_file.info["keys"] if k.endswith("/@trace")] == [
        "iota/split2/scheduler/@trace", "iota/split2/manipulation/@trace"], hub_file.info["keys"]
    assert [m for m in hub_file.messages if m.topic == "iota/split2/vision/@heartbeat"]

    # each file checks alone: what a node sent whose trace the file was not made to hold is left
    # to the merge ("not in this recording"), not called unexplained
    for alone in ("split.mcap", "split.arm.mcap"):
        said = check_of_a_real_run(tmp_path / alone)
        assert "trace is not in this recording, which was made to hold other nodes'" in said, said[-3000:]

    merged_path = tmp_path / "split.merged.mcap"
    joined = iotad("merge", tmp_path / "split.mcap", tmp_path / "split.arm.mcap", "-o", merged_path)
    assert joined.returncode == 0, joined.stderr
    merged = read_recording(merged_path)
    assert traced(merged, "vision") == traced(arm_file, "vision")
    # and the hub's file lacking them is no gap: it was not made to hold them
    assert merged_gaps(merged) == [], merged_gaps(merged)
    checked = check_of_a_real_run(merged_path)
    # every node judged in the merge, vision too: it holds what the arm's file was made to hold
    for node in ("scheduler", "vision", "manipulation"):
        assert f"\n{node}: " in "\n" + checked and f"{node}: in another host's recording" not in checked, checked[-3000:]
    assert "NOT CHECKED" not in checked and "vision.req -> scheduler.req[0]   " in checked, checked[-3000:]
    replayed = iotad("replay", merged_path, "--node", "vision")
    assert replayed.returncode == 0 and "vision: replay agrees" in replayed.stdout, replayed.stdout + replayed.stderr


def test_a_strict_run_with_a_host_that_keeps_its_traces_home_is_refused_in_a_line(tmp_path):
    system = tmp_path / "split2.toml"
    system.write_text(keeps_traces_home(figure2_over("127.0.0.1", "127.0.0.1", port=7628)))
    done = iotad("run", system, "--strict", "--insecure", "--until", "1", "--plain", "--no-record", timeout=60)
    assert done.returncode != 0
    assert "a strict run judges every node's violations at the hub, but arm keeps its traces home" in done.stderr, \
        done.stdout[-2000:] + done.stderr[-2000:]
    assert "Traceback" not in done.stderr


@pytest.mark.parametrize("edit, error", [
    (lambda t: t.replace("[hosts.arm]\n", '[hosts.arm]\ntraces = "nowhere"\n'),
     "[hosts.arm]: traces must be \"hub\""),
    (lambda t: t.replace("[hosts.brain]\n", '[hosts.brain]\ntraces = "home"\n'),
     "[hosts.brain]: traces = \"home\" on the hub's own host"),
])
def test_a_bad_traces_setting_is_an_error_of_the_file(tmp_path, edit, error):
    system = tmp_path / "split2.toml"
    system.write_text(edit(figure2_over("127.0.0.1", "127.0.0.1")))
    with pytest.raises(SystemFileError) as raised:
        load_system(system)
    assert error in str(raised.value)


def test_the_setting_is_read(tmp_path):
    system = tmp_path / "split2.toml"
    system.write_text(keeps_traces_home(figure2_over("127.0.0.1", "127.0.0.1")))
    loaded = load_system(system)
    assert loaded.hosts_keeping_traces() == ["arm"]
    assert [n.name for n in loaded.nodes_traced_at("brain")] == ["scheduler", "manipulation"]
    assert [n.name for n in loaded.nodes_traced_at("arm")] == ["vision"]
