"""A flood into a node whose input queue is small (`input_queue` in the system file): the node
host drops what does not fit, records each drop as an `input_overflow` violation that says how
many inputs it dropped, keeps serving, and loses nothing else: served + dropped = sent, and an
input sent after the flood is served. Real `iotad run`; assertions from the recording."""
import signal
import time

import zenoh

from iotad.node_host import wire
from iotad.recording.mcap_reader import read_recording
from launcher_helpers import Observer, free_port, launcher, wait_until

FLOOD, QUEUE, LAST = 400, 5, 1_000_000

SLOW_SINK = """
import time
from iotad import Input, Int, Iota, Output


class SlowSink(Iota):
    \"\"\"Takes 5 ms per input (a busy node), and says what it served.\"\"\"
    inp = Input(Int, switching=0)
    served = Output(Int, switching=0)

    def init(self):
        self.last = None

    @inp.input
    def got(self, x):
        time.sleep(0.005)
        self.last = x

    @served.action(value=lambda self: self.last, when=lambda self: self.last is not None)
    def said(self):
        self.last = None
"""


def test_flood_into_a_small_queue_is_recorded_with_counts_and_later_inputs_are_served(tmp_path):
    (tmp_path / "slow_sink.py").write_text(SLOW_SINK)
    port = free_port()
    path = tmp_path / "flood.toml"
    path.write_text(f"""
[system]
name = "flood"
external = ["slow.inp"]
[system.endpoints]
listen = ["tcp/127.0.0.1:{port}"]
[[node]]
name = "slow"
python = "{tmp_path / 'slow_sink.py'}:SlowSink"
input_queue = {QUEUE}
""")
    output = tmp_path / "flood.mcap"
    observer = Observer("flood", f"tcp/127.0.0.1:{port}")
    served: list[int] = []
    key = wire.channel_key("flood", "slow", "inp")
    try:
        with launcher(path, "-o", str(output), "--until", "60") as proc:
            assert observer.wait_all_alive(("slow",), 30), proc.output.read_text()
            served_sub = observer.session.declare_subscriber(
                wire.channel_key("flood", "slow", "served"), lambda s: served.append(wire.decode(s.payload.to_bytes())))
            beats: list[tuple[int, int]] = []  # (queue, how many served so far) at each heartbeat
            beat_sub = observer.session.declare_subscriber(
                f"{wire.PREFIX}/flood/slow/@heartbeat",
                lambda s: beats.append((wire.decode(s.payload.to_bytes())["queue"], len(served))))
            publisher = observer.session.declare_publisher(key, congestion_control=zenoh.CongestionControl.BLOCK)
            assert wait_until(lambda: publisher.matching_status.matching, 20)
            for n in range(FLOOD):  # as fast as zenoh takes them: far faster than 5 ms each
                publisher.put(wire.encode(n), attachment=wire.encode_attachment(n, time.time_ns()))
            # the flood has drained when two heartbeats in a row, after it, say the queue is empty
            # and nothing was served between them
            beats.clear()
            assert wait_until(lambda: len(beats) >= 2 and beats[-1] == beats[-2] and beats[-1][0] == 0
                              and beats[-1][1] > 0, 30), (beats, proc.output.read_text())
            publisher.put(wire.encode(LAST), attachment=wire.encode_attachment(FLOOD, time.time_ns()))
            assert wait_until(lambda: LAST in served, 20), (served[-5:], proc.output.read_text())
            publisher.undeclare()
            served_sub.undeclare()
            beat_sub.undeclare()
            proc.send_signal(signal.SIGINT)
            assert proc.wait(30) in (0, 130), proc.output.read_text()
    finally:
        observer.close()
    recording = read_recording(output)
    trace = recording.trace("slow")
    inputs = [e["value"] for e in trace if e["kind"] == "input" and e["action"] == "inp"]
    overflows = [e["value"] for e in trace if e["kind"] == "violation"
                 and e["value"]["violation"] == "input_overflow"]
    assert overflows, trace[:20]
    dropped = sum(v["dropped"] for v in overflows)
    assert all(f"{v['dropped']} input(s) on inp dropped" in v["message"] for v in overflows)
    assert dropped > 0 and len(inputs) - 1 + dropped == FLOOD  # each flood input served or counted
    assert inputs[-1] == LAST and inputs[:-1] == sorted(inputs[:-1])  # served in order, the late one too
    assert [v for v in (e["value"] for e in trace if e["kind"] == "violation")
            if v["violation"] != "input_overflow"] == []  # no other loss, no other complaint
    # the recorder, which rebuilds the input messages from the trace, sees exactly the dropped
    # ones missing on the input's key, and nothing missing anywhere else
    gaps = recording.gaps()
    assert {g["key"] for g in gaps} == {wire.channel_key("flood", "slow", "inp")}
    assert sum(g["missing"] for g in gaps) == dropped
