"""A host cut off from the hub goes on recording under access control: a source on host arm feeds
a sink on host brain (the hub), linked by TLS and started by one `iotad run --certs -o cut.mcap`
through arm's agent. The link is cut for 3 s mid-run. Arm's nodes and recorder are clients of
arm's own router (its launcher), not of the hub, so arm's recording holds every event its source
fired, those of the cut included, each recorded as it happened; whatever the hub's recording
lacks of them is inside a gap the merge marks, naming arm; the merged recording holds them all."""
import sys
import time

from agent_helpers import Lines, authority_for, start
from cut_recording import check_kept_recording, cut_a_while, source_to_sink
from namespaces import hosts

from iotad.launcher.processes import interrupt_then_kill

PORT = 7632
CUT = 3.0  # s the link is down


def test_under_access_control_a_host_cut_off_keeps_recording_and_the_merge_marks_what_the_hub_missed(tmp_path):
    hub_file, arm_file = tmp_path / "cut.mcap", tmp_path / "cut.arm.mcap"
    with hosts("brain", "arm", net=209) as net:
        hub, arm = net.addresses[("brain", "arm")], net.addresses["arm"]
        certs = authority_for(tmp_path / "certs", {"brain": [hub], "arm": [arm]})
        path = tmp_path / "cut.toml"
        path.write_text(source_to_sink(hub, arm, PORT, "tls"))
        agent = start(net.exec("arm", sys.executable, "-m", "iotad", "agent", "--name", "arm",
                               "--connect", f"tls/{hub}:{PORT}", "--certs", str(certs)))
        run = start(net.exec("brain", sys.executable, "-m", "iotad", "run", str(path), "--plain",
                             "--certs", str(certs), "--until", "60", "-o", str(hub_file)))
        lines = Lines(run)
        try:
            assert lines.wait_for(f"recording to {arm_file}", 90), lines.text()[-4000:]
            assert lines.wait_for("source: live (on another host)", 60), lines.text()[-4000:]
            deadline = time.monotonic() + 60  # both hosts' start gates open: the source fires
            while lines.text().count("start gate open") < 2 and time.monotonic() < deadline and run.poll() is None:
                time.sleep(0.1)
            assert lines.text().count("start gate open") == 2, lines.text()[-4000:]
            cut_at, healed_at = cut_a_while(net, CUT)
            time.sleep(1.0)  # a second of the healed link, for what waited in it
        finally:
            code = interrupt_then_kill(run)
            interrupt_then_kill(agent)
    output = lines.text()
    assert code == 130, output[-4000:]
    assert "access control: on (" in output, output[-4000:]
    check_kept_recording(hub_file, arm_file, cut_at, healed_at)
