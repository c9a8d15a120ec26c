"""Recording format 2's bus (`BurstCanBus`: the frames of an instant arbitrated in one firing,
each handed to its receivers at its own wire end, the frames carried recorded in bursts) is the
same bus model as format 1's (`CanBus`: a firing per frame and receiver): for the same posts,
every station receives the same frames at the same times, the bursts hold the frames of format
1's log with the same stations and wire times, and the load reports, refusals and violations
are the same. Scenarios: frames at one instant, during a frame, in the SOF bit, FIFO and
priority queues, the bus declared first or last, three bitrates, and random traffic."""
import random

import pytest

from iotad import Composite, Engine, Input, Iota, Output
from iotad.can.burst_bus import BurstCanBus
from iotad.can.frame import CAN_FRAME, Frame
from iotad.can.virtual_bus import CanBus

from test_virtual_bus_timing_and_arbitration import Station


def system(bus_class, stations=3, bus_first=False, **bus_params):
    bus = bus_class("bus", stations=stations, **bus_params)
    members = [Station(f"s{k}") for k in range(stations)]
    parts = [bus, *members] if bus_first else [*members, bus]
    binds = [(f"s{k}.can_tx", f"bus.tx[{k}]") for k in range(stations)]
    binds += [(f"bus.rx[{k}]", f"s{k}.can_rx") for k in range(stations)]
    return Composite("net", *parts, bind=binds), bus


def run(bus_class, posts, until, **params):
    net, bus = system(bus_class, **params)
    engine = Engine(net)
    for t, station, frame in posts:
        engine.post(f"net/s{station}", "send", frame.to_value(), t=t)
    return engine.run(until=until), bus


def received(trace):
    return [(e["t"], e["iota"], e["value"]) for e in trace if e["action"] == "can_rx" and e["kind"] == "input"]


def logged(trace):
    """(station, frame, start, end) in whole ns of every frame the bus logged."""
    out = []
    for e in trace:
        if e["iota"] != "net/bus" or e["kind"] != "output":
            continue
        if e["action"] == "frames":
            v = e["value"]
            out.append((v["station"], Frame.from_value(v), round((e["t"] - v["duration"]) * 1e9), round(e["t"] * 1e9)))
        elif e["action"] == "burst":
            for v in e["value"]:
                frame = Frame.from_value({k: v[k] for k in ("id", "extended", "rtr", "dlc", "data")})
                out.append((v["station"], frame, round(v["start"] * 1e9), round(v["end"] * 1e9)))
    return out


def others(trace, actions):
    return [(e["t"], e["action"], e["index"], e["value"] if e["kind"] != "violation" else e["value"]["code"])
            for e in trace if e["action"] in actions]


def assert_same(posts, until, **params):
    one, bus1 = run(CanBus, posts, until, **params)
    two, bus2 = run(BurstCanBus, posts, until, **params)
    assert received(two) == received(one)
    assert logged(two) == logged(one)
    assert others(two, ("load", "refused", "tx")) == others(one, ("load", "refused", "tx"))
    assert (bus2.frames, bus2.busy_time) == (bus1.frames, pytest.approx(bus1.busy_time, abs=1e-12))
    bursts = [e for e in two if e["action"] == "burst"]
    orders = [f["order"] for e in bursts for f in e["value"]]
    assert orders == list(range(len(orders)))  # arbitration order on the bus, no gap, no repeat
    for e in bursts:
        assert all(f["end"] <= e["t"] + 1e-12 for f in e["value"])  # recorded once its times are final
    return one, two


@pytest.mark.parametrize("bus_first", [False, True])
def test_frames_posted_at_one_instant(bus_first):
    posts = [(0.5, 0, Frame(0x0C9, b"\x01\x02\x03")), (0.5, 2, Frame(0x069, bytes(8))), (0.5, 1, Frame(0x7FF))]
    one, two = assert_same(posts, 1.0, bus_first=bus_first, load_period=0)
    assert len(received(two)) == 6
    # one firing computes the instant's frames: one burst then, one as the bus goes idle
    assert len([e for e in two if e["action"] == "burst"]) < len([e for e in one if e["action"] in ("rx", "frames")])


def test_frames_posted_while_the_bus_is_busy_wait_and_win_by_id():
    posts = [(0.0, 0, Frame(0x300, bytes(8))), (20e-6, 1, Frame(0x200, bytes(2))), (40e-6, 2, Frame(0x010, bytes(2)))]
    assert_same(posts, 1.0, load_period=0)


@pytest.mark.parametrize("late", [0.4e-6, 0.999e-6, 1e-6, 30e-6])
def test_a_frame_posted_in_the_start_of_frame_bit(late):
    posts = [(0.5, 0, Frame(0x0C9, b"\x01\x02\x03")), (0.5 + late, 2, Frame(0x069, bytes(8)))]
    assert_same(posts, 1.0, load_period=0)


@pytest.mark.parametrize("queue", ["fifo", "priority"])
def test_one_stations_queue_order(queue):
    posts = [(0.0, 0, Frame(0x300, b"\x01")), (0.0, 0, Frame(0x100, b"\x02")), (0.0, 1, Frame(0x200, b"\x03"))]
    assert_same(posts, 1.0, load_period=0, station_queue=queue)


@pytest.mark.parametrize("bitrate", [250_000, 500_000, 1_000_000])
def test_load_reports_and_bitrates(bitrate):
    posts = [(k * 0.001, k % 3, Frame(0x06C + k % 5, bytes([k] * (k % 9)))) for k in range(40)]
    assert_same(posts, 0.04, load_period=0.01, bitrate=bitrate, stuffing="exact")


def test_a_full_queue_refuses_the_same_frames():
    posts = [(0.0, 0, Frame(0x100 + k, bytes([k]))) for k in range(12)]
    posts += [(0.02, 0, Frame(0x200 + k, bytes([k]))) for k in range(3)]
    assert_same(posts, 0.05, stations=2, queue_limit=5, load_period=0.01)


@pytest.mark.parametrize("seed", range(6))
def test_random_traffic_from_three_stations(seed):
    rng = random.Random(seed)
    posts = []
    for _ in range(120):
        # posting times on a coarse grid, so that many land at one instant, in a frame or its SOF bit
        t = rng.randrange(0, 4000) * 0.5e-6
        data = bytes(rng.randrange(256) for _ in range(rng.randrange(9)))
        posts.append((t, rng.randrange(3), Frame(rng.randrange(0x7FF), data)))
    assert_same(posts, 0.01, load_period=0.001, station_queue=rng.choice(["fifo", "priority"]))


class Echo(Iota):
    """Answers every frame it hears with a frame of its own at once (a drive answering a remote
    request): its answers take part in arbitration against the frames still queued."""
    can_tx = Output(CAN_FRAME, switching=0)
    can_rx = Input(CAN_FRAME, switching=0)

    def init(self):
        self.outbox = []

    @can_rx.input
    def received(self, frame):
        heard = Frame.from_value(frame)
        if heard.id < 0x600:
            self.outbox.append(Frame(heard.id + 0x100, heard.data).to_value())

    @can_tx.action(value=lambda self: self.outbox[0], when=lambda self: bool(self.outbox), after=0)
    def sent(self):
        self.outbox.pop(0)


def test_answers_at_each_wire_end_interleave_as_they_do_frame_by_frame():
    def run_echo(bus_class):
        bus = bus_class("bus", stations=2, load_period=0)
        a, b = Station("a"), Echo("b")
        net = Composite("net", a, b, bus, bind=[("a.can_tx", "bus.tx[0]"), ("b.can_tx", "bus.tx[1]"),
                                                 ("bus.rx[0]", "a.can_rx"), ("bus.rx[1]", "b.can_rx")])
        engine = Engine(net)
        for k in range(12):  # a tick's worth at once, then again
            for tick in (0.0, 0.002):
                engine.post("net/a", "send", Frame(0x020 * (k + 1) % 0x500, bytes([k])).to_value(), t=tick)
        return engine.run(until=0.01)
    one, two = run_echo(CanBus), run_echo(BurstCanBus)
    assert received(two) == received(one)
    assert len([r for r in received(two) if r[1] == "net/a"]) == 24  # every frame answered
    assert logged(two) == logged(one)
