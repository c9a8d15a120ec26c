"""A host cut off from the hub goes on recording its own nodes: a source on host arm feeds a sink on
host brain (the hub), one `iotad run --host` per namespace, each with `-o`. The link between them
is cut for 3 s mid-run. The arm's own recording holds every event its source fired, those of
the cut included, each recorded as it happened (not when the link came back); whatever the hub's
recording lacks of them is inside a gap the merge marks, naming the arm (over TCP a 3 s cut
loses nothing at the hub: its events arrive late; tests/recording/ has merges of a hub that
lacks them); the merged recording holds them all once."""
import time

from cut_recording import check_kept_recording, cut_a_while, source_to_sink
from launcher_helpers import launcher
from namespaces import hosts

CUT = 3.0  # s the link is down


def wait_for(path, text: str, deadline: float = 60.0) -> None:
    end = time.monotonic() + deadline
    while time.monotonic() < end:
        if text in path.read_text(errors="replace"):
            return
        time.sleep(0.05)
    raise AssertionError(f"no {text!r} in {path} within {deadline:g} s:\n{path.read_text(errors='replace')[-3000:]}")


def test_a_host_cut_off_from_the_hub_keeps_recording_and_the_merge_marks_what_the_hub_missed(tmp_path):
    with hosts("brain", "arm", net=207) as net:
        path = tmp_path / "cut.toml"
        path.write_text(source_to_sink(net.addresses[("brain", "arm")], net.addresses["arm"], 7619))
        hub_file, arm_file = tmp_path / "cut.mcap", tmp_path / "cut.arm.mcap"
        with launcher(path, "--host", "brain", "--until", "30", "-o", str(hub_file),
                      prefix=tuple(net.exec("brain"))) as brain:
            wait_for(brain.output, "hub: ")
            with launcher(path, "--host", "arm", "--until", "30", "-o", str(arm_file),
                          prefix=tuple(net.exec("arm"))) as arm:
                wait_for(arm.output, "start gate open")
                wait_for(arm.output, "recording to")
                cut_at, healed_at = cut_a_while(net, CUT)
                arm.send_signal(2)
                assert arm.wait(30) in (0, 130), arm.output.read_text()[-3000:]
            brain.send_signal(2)
            brain.wait(30)
    check_kept_recording(hub_file, arm_file, cut_at, healed_at)
