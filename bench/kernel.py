"""Kernel benchmark: firings per second of CPU time in virtual time, and peak memory.

(a) two IOTAs ping-ponging a counter through a binding;
(b) the Figure 2 scheduler with N=64 requesters asking at random (Random policy);
(c) the same ping-pong in SimPy (two processes, a timeout and a store each hit), run interleaved
    with (a) in one process so that both see the same machine: hits per second each.
Goals (issue 2): (a) >= 100,000 firings/s; cost per firing in (b) within 3x of (a), because a
firing must not re-evaluate preconditions it cannot affect. (b) is also run with dependency
tracking off, to show what the tracking saves. Issue 35: (a) >= 2x (c), and the N=64 system's
cost per firing at most 3x that of N=2.

    .venv/bin/python bench/kernel.py [--seconds S]
"""
from __future__ import annotations

import argparse
import gc
import resource
import sys
import time
import tracemalloc
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))

from iotad import Composite, Engine, Input, Int, Iota, Output, Random  # noqa: E402

from requesters import Requester  # noqa: E402
from scheduler import Scheduler  # noqa: E402


class Player(Iota):
    inp = Input(Int)
    out = Output(Int)

    def init(self):
        self.ball = None

    @inp.input
    def got(self, x):
        self.ball = x

    @out.action(value=lambda self: self.ball + 1, when=lambda self: self.ball is not None, after=0.001)
    def hit(self):
        self.ball = None


def ping_pong() -> Composite:
    first = Player("ping")
    first.ball = 0
    return Composite("pingpong", first, Player("pong"), bind=[("ping.out", "pong.inp"), ("pong.out", "ping.inp")])


def figure2(n: int = 64) -> Composite:
    requesters = [Requester(f"r{i}", priority=1 + i % 7, epoch=0.5 + (i % 5) * 0.3, timeout=2.0 + i % 3,
                            start=0.01 * i, pause=1.0 + (i % 4) * 0.5, count=10**9) for i in range(n)]
    return Composite("figure2", Scheduler("scheduler", N=n, T=0.5), *requesters,
                     bind=[(f"r{i}.req", f"scheduler.req[{i}]") for i in range(n)]
                     + [(f"scheduler.ack[{i}]", f"r{i}.ack") for i in range(n)])


def simpy_ping_pong(hits: int) -> float:
    """CPU seconds SimPy takes for `hits` hits of the ping-pong: each player waits for the ball (a
    store's get), holds it 0.001 (a timeout) and puts it, plus one, in the other's store."""
    import simpy

    env = simpy.Environment()
    boxes = (simpy.Store(env), simpy.Store(env))
    count = [0]

    def player(inbox, outbox, ball):
        while True:
            if ball is None:
                ball = yield inbox.get()
            yield env.timeout(0.001)
            outbox.put(ball + 1)
            count[0] += 1
            ball = None

    env.process(player(boxes[0], boxes[1], 0))
    env.process(player(boxes[1], boxes[0], None))
    started = time.process_time()
    env.run(until=hits * 0.001 + 0.0005)
    elapsed = time.process_time() - started
    assert count[0] == hits, count[0]
    return elapsed


def iotad_ping_pong(hits: int) -> float:
    """CPU seconds the engine takes for `hits` firings of the ping-pong (a), not recorded."""
    engine = Engine(ping_pong(), record=False)
    started = time.process_time()
    engine.run(hits * 0.001 + 0.0005)
    elapsed = time.process_time() - started
    assert engine.firings == hits, engine.firings
    return elapsed


def versus_simpy(seconds: float, rounds: int = 15) -> tuple[float, float, float]:
    """(iotad, SimPy) hits per second, the best of `rounds` rounds each, and the median of the
    rounds' ratios: the two alternate in short runs, so that a busy spell of the shared machine
    falls on both alike, and each round's ratio compares runs seconds apart. Both are timed in
    the process's CPU time, not the wall clock's: on a machine that other work keeps busy the
    wall clock counts the others' turns too (on a machine at load 12, one round's ratio swung
    0.6-2.2x by the wall clock, 1.0-1.9x in CPU time; the median moves far less)."""
    hits = 10_000
    best_iotad = best_simpy = 0.0
    ratios = []
    started = time.perf_counter()
    for _ in range(rounds):
        gc.collect()
        ours = hits / iotad_ping_pong(hits)
        gc.collect()
        theirs = hits / simpy_ping_pong(hits)
        best_iotad, best_simpy = max(best_iotad, ours), max(best_simpy, theirs)
        ratios.append(ours / theirs)
        if time.perf_counter() - started > 4 * seconds:
            break
    ratios.sort()
    return best_iotad, best_simpy, ratios[len(ratios) // 2]


def figure2_of(n: int):
    return lambda: figure2(n)


def measure(build, policy_seed: int | None, seconds: float, record: bool, track: bool = True) -> tuple[float, int]:
    """Firings per second of CPU time over about `seconds` of wall time (virtual time grows in
    chunks). CPU time, as `versus_simpy` says why: on a busy machine the wall clock counts the
    other work's turns too, and moved one figure 3x against another measured a second later."""
    policy = Random(policy_seed) if policy_seed is not None else None
    engine = Engine(build(), policy=policy, record=record, track_dependencies=track)
    until, start = 0.0, time.perf_counter()
    gc.collect()
    cpu = time.process_time()
    while time.perf_counter() - start < seconds:
        until += 10.0
        engine.run(until)
        if record:
            engine.trace.clear()  # keep memory flat: this measures the engine, not list growth
    elapsed = time.process_time() - cpu
    return engine.firings / elapsed, engine.firings


def peak_memory(build, until: float) -> float:
    """Peak traced Python memory (MiB) of building and running a system with its trace kept."""
    tracemalloc.start()
    engine = Engine(build(), policy=Random(1))
    engine.run(until)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak / 2**20, len(engine.trace)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="wall time per measurement (default 3)")
    args = parser.parse_args()

    print(f"iotad kernel benchmark (virtual time, {args.seconds:g} s per figure)")
    a, a_n = measure(ping_pong, None, args.seconds, record=False)
    a_rec, _ = measure(ping_pong, None, args.seconds, record=True)
    b, b_n = measure(figure2, 1, args.seconds, record=False)
    b_rec, _ = measure(figure2, 1, args.seconds, record=True)
    b_full, _ = measure(figure2, 1, args.seconds, record=False, track=False)
    print(f"(a) ping-pong:                 {a:>10,.0f} firings/s  ({a_n:,} firings); with trace kept {a_rec:,.0f}/s")
    print(f"(b) Figure 2, N=64, random:    {b:>10,.0f} firings/s  ({b_n:,} firings); with trace kept {b_rec:,.0f}/s")
    print(f"    without dependency tracking {b_full:>9,.0f} firings/s  (tracking is {b / b_full:.1f}x faster)")
    ratio = a / b
    print(f"cost per firing (b)/(a): {ratio:.2f}x")
    b2, _ = measure(figure2_of(2), 1, args.seconds, record=False)
    print(f"(b) Figure 2, N=2, random:     {b2:>10,.0f} firings/s; N=64 costs {b2 / b:.2f}x N=2 per firing")
    ours, simpys, versus = versus_simpy(args.seconds)
    print(f"(c) ping-pong, iotad vs SimPy interleaved: best iotad {ours:,.0f} hits/s, best SimPy {simpys:,.0f} "
          f"hits/s; iotad is {versus:.2f}x SimPy (the median of the rounds' ratios)")
    mem_a, events_a = peak_memory(ping_pong, 100)
    mem_b, events_b = peak_memory(figure2, 500)
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak traced memory: (a) {mem_a:.1f} MiB for {events_a:,} trace events; "
          f"(b) {mem_b:.1f} MiB for {events_b:,} trace events; process max RSS {rss:.0f} MiB")
    goal_a = a >= 100_000
    goal_b = ratio <= 3.0
    print(f"goal (a) >= 100,000 firings/s: {'met' if goal_a else 'MISSED'}")
    print(f"goal (b) cost within 3x of (a): {'met' if goal_b else 'MISSED'}")
    print(f"goal N=64 within 3x of N=2: {'met' if b2 / b <= 3.0 else 'MISSED'}")
    print(f"goal (c) iotad >= 2x SimPy: {'met' if versus >= 2 else 'MISSED'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
