"""`iotad replay --live`: every recorded message is republished on its key, in order."""
import threading
import time

from iotad.node_host import wire
from iotad.recording.engine_sink import record_run
from iotad.recording.mcap_reader import read_recording
from iotad.recording.replay import republish
from iotad.node_host.transport import free_port, open_session
from recorded_systems import figure2


def test_republish_everything_in_order(tmp_path):
    path = tmp_path / "fig2.mcap"
    record_run(figure2(), path, until=30)
    recording = read_recording(path)
    port = free_port()
    listener = open_session([f"tcp/127.0.0.1:{port}"])
    talker = open_session(connect=[f"tcp/127.0.0.1:{port}"])
    try:
        got, lock = [], threading.Lock()

        def on_sample(sample):
            with lock:
                got.append((str(sample.key_expr), wire.decode(sample.payload.to_bytes()),
                            wire.decode_attachment(sample.attachment.to_bytes())))

        subscribers = [listener.declare_subscriber(key, on_sample) for key in wire.subscription_keys("figure2")]
        probe = talker.declare_publisher("iota/figure2/x/@trace")
        deadline = time.monotonic() + 10
        while not probe.matching_status.matching and time.monotonic() < deadline:
            time.sleep(0.01)
        assert probe.matching_status.matching
        progress = []
        sent = republish(recording, talker, rate=100.0, progress=lambda done, total: progress.append((done, total)))
        assert sent == len(recording.messages) and progress[-1] == (sent, sent)
        deadline = time.monotonic() + 10
        while len(got) < sent and time.monotonic() < deadline:
            time.sleep(0.01)
        expected = [(m.topic, m.value) for m in sorted(recording.messages, key=lambda m: m.log_time)]
        assert sorted(map(repr, [(k, v) for k, v, _ in got])) == sorted(map(repr, expected))
        ack = [a for k, _, a in got if k == "iota/figure2/scheduler/ack/0"]
        assert [seq for seq, _ in ack] == list(range(len(ack)))  # fresh sequence numbers per key
        for subscriber in subscribers:
            subscriber.undeclare()
    finally:
        talker.close()
        listener.close()


class _Recorded:
    def __init__(self, topic, log_time, publish_time, data):
        self.topic, self.log_time, self.publish_time, self.data = topic, log_time, publish_time, data


class _FakeSession:
    """Collects what republish puts, in order, without a network."""

    def __init__(self):
        self.put_order = []

    def declare_publisher(self, topic):
        session = self

        class Publisher:
            def put(self, data, attachment=None):
                session.put_order.append((topic, data))

            def undeclare(self):
                pass

        return Publisher()


def test_republish_paces_by_send_time_not_burst_arrival():
    # A trace-sourced recording logs a whole 20 ms burst at one arrival time; the senders' send
    # times (publish_time) keep the real order and spacing.
    burst = 5_000_000_000
    messages = [_Recorded("iota/s/a/out", burst, 4_980_000_000, b"late-logged-first-sent"),
                _Recorded("iota/s/b/out", burst - 1, 4_990_000_000, b"second"),
                _Recorded("iota/s/c/out", burst + 1, 0, b"no-send-time")]

    class Recording:
        pass

    recording = Recording()
    recording.messages = messages
    session = _FakeSession()
    assert republish(recording, session, rate=1000.0) == 3
    assert [data for _, data in session.put_order] == [b"late-logged-first-sent", b"second", b"no-send-time"]
