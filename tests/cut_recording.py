"""A source on host arm feeding a sink on host brain (the hub), for tests that cut the link between
them, and what they check afterwards: the arm's own recording kept every event of the source, each
recorded as it happened, and the merge marks whatever the hub's recording lacks of them."""
from __future__ import annotations

import signal
import time
from collections import Counter

from launcher_helpers import ROOT, wait_until
from namespaces import hosts_header

from iotad.recording.mcap_reader import read_recording
from iotad.recording.merge import merge


def source_to_sink(hub: str, arm: str, port: int, scheme: str = "tcp") -> str:
    """The system file: `source` (one output a second) on arm, `sink` on brain, the hub at `hub`:`port`."""
    iotas = ROOT / "tests" / "system_iotas.py"
    return hosts_header("cut", hub, port, "brain", "arm", arm, scheme) + f"""

[[node]]
name = "source"
host = "arm"
python = "{iotas}:Source"
params = {{ period = 1.0 }}
[[node]]
name = "sink"
host = "brain"
python = "{iotas}:FreeSink"

[[bind]]
from = "source.out"
to = "sink.inp"
"""


def outputs(recording) -> dict:
    """The source's output events by their value n: (t, the message's log time)."""
    return {m.value["value"]: (m.value["t"], m.log_time) for m in recording.messages
            if m.topic == "iota/cut/source/@trace" and m.value.get("kind") == "output"}


def check_kept_recording(hub_file, arm_file, cut_at: float, healed_at: float) -> None:
    """The arm's recording holds every event of its source, those of the cut (wall-clock times
    `cut_at` to `healed_at`) included, each within a second of its `t`; the merge of both files
    holds them all, and each one the hub's file lacks is inside a gap naming the arm."""
    own, hubs = read_recording(arm_file), read_recording(hub_file)
    origin = own.info["run"]["origin"]
    fired = outputs(own)
    # every event of the source, one per second from n=0, none missing from its own recording
    assert sorted(fired) == list(range(len(fired))), fired
    during = [n for n, (t, _) in fired.items() if cut_at - origin + 0.1 < t < healed_at - origin - 0.1]
    assert len(during) >= 2, (fired, cut_at - origin, healed_at - origin)
    # each recorded as it happened (the arm's clock is the hub's here): within a second of its t,
    # not when the link came back
    for n in during:
        t, log_time = fired[n]
        assert 0 <= log_time / 1e9 - origin - t < 1.0, (n, t, log_time / 1e9 - origin)
    merged = merge([hub_file, arm_file])
    joined = outputs(merged.recording)  # log times on the hub's clock
    assert sorted(joined) == sorted(fired)
    missed = sorted(n for n in fired if n not in outputs(hubs))
    gaps = [g for g in merged.gaps if g["host"] == "arm" and "did not reach the hub" in g["reason"]]
    for n in missed:  # whatever the hub lacks is inside a gap that names the arm
        t_ns = joined[n][1]
        assert any(g["from_ns"] <= t_ns <= g["to_ns"] for g in gaps), (n, missed, gaps)
    assert sum(g["events"] for g in gaps) >= len(missed)


def cut_a_while(net, seconds: float) -> tuple[float, float]:
    """Cut the link between brain and arm for `seconds` (the partition itself: how long the arm is
    on its own), then heal it; the wall-clock times of the cut and of the heal."""
    import time

    # stamped before the cut is made: `ip` takes a while, and what is sent while it runs may already
    # be cut off (a message sent 1.3 ms before a stamp taken after it was lost)
    cut_at = time.time()
    net.cut("brain", "arm")
    try:
        time.sleep(seconds)
    finally:
        net.heal("brain", "arm")
    return cut_at, time.time()


def cut_arm_while_running(net, log, run, hosts: int, recordings: list, cut: float, after_heal: float) -> tuple:
    """The middle of a partition test, the hub's `iotad run` started as `run` writing `log`: once
    `hosts` hosts' engines run (each its start gate) and every file of `recordings` is being
    written, 2 s of outputs to compare the cut with, arm's link cut for `cut` s, the hub's word
    that arm is back, `after_heal` s more of traffic across the healed link, then Ctrl-C.
    (cut_at, healed_at, the run's exit status)."""
    # a run that ended (a host's part failed as it started: the hub stops at once and says why)
    # is not waited for
    assert wait_until(lambda: run.poll() is not None or (log.read_text().count("start gate open") == hosts
                      and all(f"recording to {path}" in log.read_text() for path in recordings)), 90) \
        and run.poll() is None, log.read_text()[-3000:]
    time.sleep(2.0)  # outputs before the cut, to compare the cut with
    cut_at, healed_at = cut_a_while(net, cut)
    back = "host arm: back; its nodes ran on while it was cut off"
    assert wait_until(lambda: back in log.read_text(), 60), log.read_text()[-3000:]
    time.sleep(after_heal)
    run.send_signal(signal.SIGINT)
    return cut_at, healed_at, run.wait(60)


def per_second(recording, system: str, node: str, kind: str, since: float, until: float) -> dict[int, int]:
    """How many `kind` events of `node` (of the system named `system`) the recording received in
    each whole second from `since` to `until` (wall-clock times; receipt times, not the events' own)."""
    counts = Counter({second: 0 for second in range(int(until - since))})
    for m in recording.messages:
        if m.topic == f"iota/{system}/{node}/@trace" and m.value.get("kind") == kind:
            second = int(m.log_time / 1e9 - since)
            if 0 <= m.log_time / 1e9 - since and second in counts:
                counts[second] += 1
    return dict(sorted(counts.items()))


def received_after(recording, system: str, node: str, kind: str, when: float) -> int:
    """How many `kind` events of `node` the recording received after the wall-clock time `when`."""
    return sum(1 for m in recording.messages if m.topic == f"iota/{system}/{node}/@trace"
               and m.value.get("kind") == kind and m.log_time / 1e9 > when)
