"""The Figure 2 scheduler under a partition: the scheduler (and the hub) on brain, two requesters
on arm. hi holds the motors (epoch 2 s); lo waits behind it with a timeout of 1 s; the moment
lo's request reaches brain the link is cut for 3 s. The scheduler judges both on its own clock
during the cut: lo's timeout passes (REJECT) and hi's motion ends (COMMIT). Its answers wait in
the link and reach the requesters after the heal, which then go on with their next requests; in
the end every request of both is answered at its requester, or, where an answer came too soon
after a late one and its switching time refused it (recorded as a `switching_time` violation),
given up as aborted after the request's own bounds (the requester's `no_answer`): no request is
left waiting."""
import time

from namespaces import hosts
from partition_run import SplitRun, split_header
from iotad.recording.mcap_reader import read_recording

HOLD = 3.0  # s the link stays down: past lo's timeout and hi's epoch
PARAMS = {"hi": "priority = 5, epoch = 2.0, timeout = 3.0, start = 1.0, pause = 0.5, count = 2",
          "lo": "priority = 1, epoch = 0.5, timeout = 1.0, start = 1.5, pause = 0.5, count = 2"}


def system(hub: str, arm: str, port: int) -> str:
    from launcher_helpers import ROOT
    requesters = "".join(f"""
[[node]]
name = "{name}"
host = "arm"
python = "{ROOT}/examples/requesters.py:Requester"
params = {{ {params} }}
after = ["scheduler"]
[[bind]]
from = "{name}.req"
to = "scheduler.req[{k}]"
[[bind]]
from = "scheduler.ack[{k}]"
to = "{name}.ack"
""" for k, (name, params) in enumerate(PARAMS.items()))
    return split_header("cutsched", hub, port, arm) + f"""
[[node]]
name = "scheduler"
host = "brain"
python = "{ROOT}/examples/scheduler.py:Scheduler"
params = {{ N = 2, T = 0.5 }}
{requesters}"""


def test_requests_whose_bounds_pass_during_a_partition_are_answered_after_it(tmp_path):
    with hosts("brain", "arm", net=208) as net:
        hub, port = net.addresses[("brain", "arm")], 7618
        run = SplitRun(net, tmp_path, port, "cutsched", system(hub, net.addresses["arm"], port),
                       watch=("lo/req", "hi/@trace", "lo/@trace"), run_args=("-o", str(tmp_path / "hub.mcap")))
        try:
            run.start()
            # every trace burst the watcher prints counts, from the first on
            progress = {name: Progress() for name in PARAMS}

            def track(key, burst) -> bool:
                if key.endswith("/@trace"):
                    progress[key.split("/")[0]].take(burst)
                return all(p.done(2) for p in progress.values())
            run.wait_for(lambda key, value: track(key, value) or key == "lo/req", 90, "lo's first request at brain")
            cut = run.cut()
            time.sleep(HOLD)  # the partition's length, the stimulus
            heal = run.heal()
            # until each requester has made both its requests and has an answer to the last (its
            # trace says so: an ack taken, or the request given up)
            run.wait_for(track, 60, "both requesters' second answers")
        finally:
            run.stop()
        output = run.output()
    assert "Traceback" not in output, output[-3000:]
    recording = read_recording(tmp_path / "hub.mcap")
    acks = {k: [(m.publish_time, m.value) for m in recording.messages if m.topic == f"iota/cutsched/scheduler/ack/{k}"]
            for k in (0, 1)}
    # the scheduler answered both first requests on its own clock while the link was down
    assert cut < acks[1][0][0] < heal and acks[1][0][1] == "REJECT", (acks, cut, heal)
    assert cut < acks[0][0][0] < heal and acks[0][0][1] == "COMMIT", (acks, cut, heal)
    for name in PARAMS:  # every request followed by its answer at the requester, or given up
        trace = [m.value for m in recording.messages if m.topic == f"iota/cutsched/{name}/@trace"]
        progress = Progress()
        progress.take(trace)
        assert progress.done(2) and progress.unanswered == 0, (name, trace)
        refused = [e for e in trace if e["kind"] == "violation" and e["value"]["violation"] != "deadline_miss"]
        assert all(e["action"] == "ack" and e["value"]["violation"] == "switching_time" for e in refused), refused
    heard = [m.value for m in recording.messages if m.topic == "iota/cutsched/hi/@trace"
             and m.value["action"] == "ack" and m.value["kind"] == "input"]
    assert [e["value"] for e in heard][:1] == ["COMMIT"], heard


class Progress:
    """A requester's requests and their answers, from its trace events (an answer: an ack taken,
    or its own giving up, `no_answer`): `unanswered` requests were followed by no answer before the next."""

    def __init__(self):
        self.requests, self.unanswered, self.answered = 0, 0, True

    def take(self, events) -> None:
        for event in [events] if isinstance(events, dict) else events:  # a burst of one may be one dict
            if event["action"] == "req" and event["kind"] == "output":
                self.unanswered += 0 if self.answered else 1
                self.requests, self.answered = self.requests + 1, False
            elif (event["action"] == "ack" and event["kind"] == "input") or event["action"] == "no_answer":
                self.answered = True

    def done(self, requests: int) -> bool:
        return self.requests == requests and self.answered
