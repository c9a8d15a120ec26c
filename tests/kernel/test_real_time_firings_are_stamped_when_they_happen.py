"""In real time, firings due at one instant happen one after another: each is stamped, and judged
against its deadline, at the time it happens. A slow do-block must not hide the deadline miss of
what waited behind it. The zeno guard still stops a loop of actions that enable each other with
no delay, and does not mistake a node that runs late for one.

`ProcessClock` is a real-time clock (not virtual) whose time moves only when the IOTAs' code
says it took time: the tests are exact, with no sleeping."""
from iotad import Engine, Internal, Iota, Output, Param, VirtualClock


class ProcessClock(VirtualClock):
    virtual = False

    def spend(self, seconds):
        self._now += seconds


class SlowThenDue(Iota):
    """`slow` takes 0.3 s of the process; `due` must fire within 0.1 s of the start."""
    slow = Internal()
    due = Output()

    def init(self):
        self.done = set()

    @slow.action(when=lambda self: "slow" not in self.done)
    def ran_slow(self):
        self.done.add("slow")
        self.clock.spend(0.3)

    @due.action(when=lambda self: "due" not in self.done, within=(0, 0.1))
    def sent_due(self):
        self.done.add("due")


def events(engine, kind=None):
    return [(e["t"], e["action"], e["kind"]) for e in engine.trace if kind in (None, e["kind"])]


def test_a_firing_behind_a_slow_one_is_stamped_late_and_misses_its_deadline():
    clock = ProcessClock()
    iota = SlowThenDue("s")
    iota.clock = clock
    engine = Engine(iota, clock)
    engine.run(1.0)
    assert [(t, a) for t, a, _ in events(engine, "internal") + events(engine, "output")] == [(0.0, "slow"), (0.3, "due")]
    [miss] = [e for e in engine.trace if e["kind"] == "violation"]
    assert miss["value"]["violation"] == "deadline_miss" and miss["t"] == 0.3
    assert "after its deadline 0.1" in miss["value"]["message"]


def test_the_same_in_virtual_time_fires_both_at_once():
    iota = SlowThenDue("s")
    iota.clock = ProcessClock()  # spent time does not move the engine's virtual clock
    engine = Engine(iota, VirtualClock())
    engine.run(1.0)
    assert [t for t, _, _ in events(engine, "internal") + events(engine, "output")] == [0.0, 0.0]
    assert not [e for e in engine.trace if e["kind"] == "violation"]


class Spin(Iota):
    """A loop with no delay; every firing takes `cost` s of the process."""
    cost = Param(1e-6)
    spin = Internal()

    @spin.action()
    def spun(self):
        self.clock.spend(self.cost)


def test_a_loop_with_no_delay_is_zeno_in_real_time_too():
    clock = ProcessClock()
    iota = Spin("z")
    iota.clock = clock
    engine = Engine(iota, clock, max_firings_per_instant=100)
    engine.run(10.0)
    assert engine.halted
    [zeno] = [e for e in engine.trace if e["kind"] == "violation"]
    assert zeno["value"]["violation"] == "zeno" and len(events(engine, "internal")) == 100


class TwoLoopsAndATimer(Iota):
    """Two loops with no delay, side by side, and a 5 ms timer: none of them ends the others'
    chains (a guard that counted one chain for the whole engine never halted this one)."""
    a = Internal()
    b = Internal()
    tick = Internal()

    @a.action()
    def spun_a(self):
        self.clock.spend(1e-6)

    @b.action()
    def spun_b(self):
        self.clock.spend(1e-6)

    @tick.action(after=0.005)
    def ticked(self):
        pass


def test_loops_with_no_delay_are_zeno_whatever_fires_in_between():
    clock = ProcessClock()
    iota = TwoLoopsAndATimer("z")
    iota.clock = clock
    engine = Engine(iota, clock, max_firings_per_instant=100)
    engine.run(10.0)
    assert engine.halted
    [zeno] = [e for e in engine.trace if e["kind"] == "violation"]
    assert zeno["value"]["violation"] == "zeno"
    assert len([e for e in engine.trace if e["action"] in ("a", "b")]) <= 2 * 100


class LateTicker(Iota):
    """A 1 kHz tick whose every firing takes 2 ms: always late, never a loop without delay."""
    tick = Internal()

    def init(self):
        self.ticks = 0

    @tick.action(after=0.001)
    def ticked(self):
        self.ticks += 1
        self.clock.spend(0.002)


def test_a_node_that_runs_late_is_not_zeno():
    clock = ProcessClock()
    iota = LateTicker("t")
    iota.clock = clock
    engine = Engine(iota, clock, max_firings_per_instant=100, deadline_tolerance=1.0)
    engine.run(1.0)
    assert not engine.halted and iota.ticks > 300
    assert not [e for e in engine.trace if e["kind"] == "violation"]
