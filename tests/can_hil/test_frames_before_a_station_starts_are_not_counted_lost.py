"""On a real CAN bus a frame reaches only the stations whose sockets are open: frames a station
sent before another had started are 'not judged' by the delivery check, never 'lost', and every
frame after the start is delivered (ping-pong over `system_can_tier`, the echo started last). The
pinger sends the same frame every time, as an ODrive's heartbeat is: the frames before the
start must not be taken for the first ones received (each reception then paired with a frame
sent periods before it: false 'reordered', then 'lost', findings)."""
from pingpong import run_pingpong
from iotad.recording.delivery import check_delivery
from iotad.recording.mcap_reader import read_recording


def test_frames_sent_before_the_echo_started_are_not_judged_and_the_rest_delivered(system_can_tier, tmp_path):
    # no bus logger: one process less to start (on the one vCPU of user-mode Linux, where it runs there)
    # a frame every 10 ms: the twins sent in the last 0.1 s before the echo started (the check's
    # window for a frame waiting on a busy bus) are candidates for its first receptions
    # no start gate: the echo's engine starts once its process is live, after the pinger's
    recording = run_pingpong(system_can_tier, tmp_path, echo='after = ["pinger"]', bus="log = false",
                             pinger="CanTwinPinger", period=0.01, system_lines="start_gate = false")
    report = check_delivery(read_recording(recording))
    link = next(link for link in report.links if link.label == "can can0: pinger -> echo")
    early = [f for f in report.notes if f.code == "not judged" and "before echo's engine started" in f.message]
    problems = [f for f in report.findings if f.link == link.label]
    assert link.lost == 0 and link.altered == 0, [f.message for f in problems][:3]
    assert not [f.message for f in problems if f.code == "reordered"][:3]
    assert link.delivered >= 10
    assert len(early) >= 1  # the echo started after the pinger's first frames
    assert link.latency()[0] < 0.005  # p50 under half a period: each reception paired with its own frame
