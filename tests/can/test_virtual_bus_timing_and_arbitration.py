"""The in-process CAN bus of virtual time: frame times with bit stuffing, arbitration by id when
the bus goes idle, delivery to every station but the sender, bus load; exact virtual times."""
import pytest

from iotad import Composite, Engine, Input, Iota, Output
from iotad.can.bit_timing import crc15, frame_bits, stuff_bit_count, stuffed_region
from iotad.can.frame import CAN_FRAME, Frame
from iotad.can.virtual_bus import CanBus, arbitration_key, bus_summary

BIT = 1e-6  # at 1 Mbit/s


class Station(Iota):
    """Sends what it is told (external input `send`) on its CAN output at once; keeps what it hears."""
    send = Input(CAN_FRAME, switching=0)
    can_tx = Output(CAN_FRAME, switching=0)
    can_rx = Input(CAN_FRAME, switching=0)

    def init(self):
        self.outbox = []
        self.heard = []

    @send.input
    def told(self, frame):
        self.outbox.append(frame)

    @can_tx.action(value=lambda self: self.outbox[0], when=lambda self: bool(self.outbox), after=0)
    def sent(self):
        self.outbox.pop(0)

    @can_rx.input
    def received(self, frame):
        self.heard.append(Frame.from_value(frame))


def system(stations=3, bus_first=False, **bus_params):
    bus = CanBus("bus", stations=stations, **bus_params)
    members = [Station(f"s{k}") for k in range(stations)]
    parts = [bus, *members] if bus_first else [*members, bus]
    binds = [(f"s{k}.can_tx", f"bus.tx[{k}]") for k in range(stations)]
    binds += [(f"bus.rx[{k}]", f"s{k}.can_rx") for k in range(stations)]
    return Composite("net", *parts, bind=binds), bus, members


def deliveries(trace):
    """(t, receiving station, frame) of every rx event of the bus."""
    return [(e["t"], e["index"], Frame.from_value(e["value"])) for e in trace
            if e["iota"].endswith("bus") and e["action"] == "rx"]


def bits(frame, stuffing="exact"):
    return frame_bits(frame.id, frame.extended, frame.rtr, frame.data, stuffing)


def close(a, b):
    return abs(a - b) < 1e-12


# ------------------------------------------------------------------ bit times

def test_crc15_is_the_can_crc():
    data = b"123456789"  # the CRC catalogue's check string: CRC-15/CAN gives 0x059E
    assert crc15([(byte >> s) & 1 for byte in data for s in range(7, -1, -1)]) == 0x059E


def test_an_eight_byte_standard_frame_takes_111_to_135_bits():
    for data in (bytes(8), b"\xff" * 8, b"\x55" * 8, bytes(range(8)), b"\x0f\xf0" * 4):
        frame = Frame(0x06C, data)
        assert bits(frame, "none") == 111
        assert bits(frame, "worst") == 135
        assert 111 <= bits(frame) <= 135
    # 0x55 alternates: no run of five in the data, so only the header and CRC may need stuffing
    assert bits(Frame(0x06C, b"\x55" * 8)) < bits(Frame(0x06C, bytes(8)))


def test_stuffing_counts_runs_of_five_and_the_stuff_bit_starts_a_new_run():
    assert stuff_bit_count([0] * 5) == 1
    assert stuff_bit_count([0] * 4) == 0
    assert stuff_bit_count([0] * 9) == 1   # 00000 s 0000: the stuff bit broke the run
    assert stuff_bit_count([0] * 10) == 2  # 00000 s 00000
    assert stuff_bit_count([0, 0, 0, 0, 0, 1, 1, 1, 1]) == 2  # stuff 1 + four 1s = five 1s


def test_remote_extended_and_empty_frames_have_their_own_lengths():
    assert bits(Frame(0x123), "none") == 47             # 34 + 10 + 3
    assert bits(Frame.remote(0x123, dlc=8), "none") == 47  # RTR: DLC sent, no data field
    assert bits(Frame(0x12345, bytes(8), extended=True), "none") == 131  # 54 + 64 + 10 + 3
    assert len(stuffed_region(0x123, False, False, b"\x01")) == 34 + 8


# ------------------------------------------------------------------ arbitration and delivery

@pytest.mark.parametrize("bus_first", [False, True])
def test_frames_posted_at_one_instant_go_lowest_id_first_one_frame_time_apart(bus_first):
    net, bus, members = system(bus_first=bus_first, load_period=0)
    high, low = Frame(0x0C9, b"\x01\x02\x03"), Frame(0x069, bytes(8))
    engine = Engine(net)
    engine.post("net/s0", "send", high.to_value(), t=0.5)
    engine.post("net/s2", "send", low.to_value(), t=0.5)
    trace = engine.run(until=1.0)
    got = deliveries(trace)
    assert [(i, f) for _, i, f in got] == [(0, low), (1, low), (1, high), (2, high)]
    assert close(got[0][0], 0.5 + bits(low) * BIT) and got[0][0] == got[1][0]
    assert close(got[2][0] - got[0][0], bits(high) * BIT)  # back to back: exactly its frame time
    assert members[0].heard == [low] and members[1].heard == [low, high] and members[2].heard == [high]


def test_a_frame_is_never_echoed_to_its_sender():
    net, bus, members = system(stations=4, load_period=0)
    engine = Engine(net)
    for k in range(4):
        engine.post(f"net/s{k}", "send", Frame(0x100 + k, bytes([k])).to_value(), t=0.001 * k)
    engine.run(until=1.0)
    for k, member in enumerate(members):
        assert sorted(f.id for f in member.heard) == [0x100 + j for j in range(4) if j != k]


def test_a_frame_posted_while_the_bus_is_busy_waits_and_then_wins_by_id():
    net, bus, members = system(load_period=0)
    engine = Engine(net)
    first, late_high, late_low = Frame(0x300, bytes(8)), Frame(0x200, bytes(2)), Frame(0x010, bytes(2))
    engine.post("net/s0", "send", first.to_value(), t=0.0)
    engine.post("net/s1", "send", late_high.to_value(), t=20e-6)  # during `first`: waits
    engine.post("net/s2", "send", late_low.to_value(), t=40e-6)   # also waits, and wins
    got = deliveries(engine.run(until=1.0))
    order = [f for _, i, f in got if i == 0]
    assert order == [late_low, late_high]
    assert close(got[0][0], bits(first) * BIT)                 # `first` ended, not preempted
    assert close(got[2][0], (bits(first) + bits(late_low)) * BIT)


@pytest.mark.parametrize("late, wins", [(0.4e-6, True), (0.999e-6, True), (1e-6, False), (30e-6, False)])
def test_a_frame_posted_during_the_start_of_frame_bit_takes_part_in_arbitration(late, wins):
    """Arbitration ends with the SOF bit: a lower id posted before then takes the bus, and ends
    one frame time after the SOF; posted after it, it waits for the frame on the bus."""
    net, bus, members = system(load_period=0)
    high, low = Frame(0x0C9, b"\x01\x02\x03"), Frame(0x069, bytes(8))
    engine = Engine(net)
    engine.post("net/s0", "send", high.to_value(), t=0.5)
    engine.post("net/s2", "send", low.to_value(), t=0.5 + late)
    trace = engine.run(until=1.0)
    got = [(t, f) for t, i, f in deliveries(trace) if i == 1]
    first, second = (low, high) if wins else (high, low)
    assert [f for _, f in got] == [first, second]
    assert close(got[0][0], 0.5 + bits(first) * BIT)
    assert close(got[1][0], got[0][0] + bits(second) * BIT) if wins else \
        close(got[1][0], max(got[0][0], 0.5 + late) + bits(second) * BIT)
    assert [e["t"] for e in trace if e["action"] == "rearbitrated"] == ([0.5 + late] if wins else [])
    assert members[0].heard == [low] and members[2].heard == [high]


def test_arbitration_field_order_data_before_remote_standard_before_extended():
    data, remote = Frame(0x123, b"\x00"), Frame.remote(0x123)
    assert arbitration_key(data) < arbitration_key(remote)
    standard, extended = Frame(0x123, b""), Frame(0x123 << 18, b"", extended=True)
    assert arbitration_key(standard) < arbitration_key(extended)
    assert arbitration_key(Frame(0x122 << 18 | 0x3FFFF, extended=True)) < arbitration_key(Frame(0x123))


@pytest.mark.parametrize("queue, expected", [("fifo", [0x300, 0x100]), ("priority", [0x100, 0x300])])
def test_one_stations_frames_go_in_its_queue_order(queue, expected):
    net, bus, members = system(load_period=0, station_queue=queue)
    engine = Engine(net)
    engine.post("net/s0", "send", Frame(0x300, b"\x01").to_value(), t=0.0)
    engine.post("net/s0", "send", Frame(0x100, b"\x02").to_value(), t=0.0)
    engine.run(until=1.0)
    assert [f.id for f in members[1].heard] == expected


def test_the_bus_carries_one_frame_at_a_time():
    net, bus, members = system(load_period=0)
    engine = Engine(net)
    for n in range(30):  # a burst from all three stations
        engine.post(f"net/s{n % 3}", "send", Frame(0x700 - n * 7, bytes([n] * (n % 9))).to_value(), t=0.01)
    trace = engine.run(until=1.0)
    # the bus's log: each frame as it ended, with its bit time
    starts = [(e["t"] - e["value"]["duration"], Frame.from_value(e["value"])) for e in trace if e["action"] == "frames"]
    assert len(starts) == 30 and bus.frames == 30 and not any(bus.waiting)
    for (t0, frame), (t1, _) in zip(starts, starts[1:]):
        assert close(t1 - t0, bits(frame) * BIT)  # back to back, never overlapping
    # every arbitration picked the lowest id among the stations' queue heads (each queue FIFO)
    queues = [[0x700 - n * 7 for n in range(k, 30, 3)] for k in range(3)]
    expected = []
    while any(queues):
        winner = min((q for q in queues if q), key=lambda q: q[0])
        expected.append(winner.pop(0))
    assert [f.id for _, f in starts] == expected


def test_dependency_tracking_gives_the_reference_trace():
    traces = []
    for track in (True, False):
        net, bus, members = system(load_period=0.001)
        engine = Engine(net, track_dependencies=track)
        for n in range(12):
            engine.post(f"net/s{n % 3}", "send", Frame(0x50 + (n * 5) % 11, bytes(n % 9)).to_value(),
                        t=0.0002 * (n // 4))
        traces.append(engine.run(until=0.005))
    assert traces[0] == traces[1]


# ------------------------------------------------------------------ bus load

def test_load_of_one_eight_byte_frame_per_millisecond():
    net, bus, members = system(load_period=0.01, stuffing="worst")
    engine = Engine(net)
    for k in range(40):
        engine.post("net/s0", "send", Frame(0x06C, bytes([k] * 8)).to_value(), t=k * 0.001)
    trace = engine.run(until=0.04)
    loads = [e["value"] for e in trace if e["action"] == "load"]
    assert loads == pytest.approx([0.135] * 4, abs=1e-9)  # 135 bits per ms at 1 Mbit/s
    assert bus.frames == 40 and bus.busy_time == pytest.approx(40 * 135e-6, abs=1e-12)
    assert bus.average_load == pytest.approx(0.135, abs=1e-9)
    summary = bus_summary(trace, "net/bus", stuffing="worst", until=0.04)
    assert summary["frames"] == 40 and summary["load"] == pytest.approx(0.135, abs=1e-9)
    # over a span that cuts a frame in two, the summary counts the part inside
    part = bus_summary(trace, "net/bus", stuffing="worst", start=0.0, until=0.0001)
    assert part["busy_time"] == pytest.approx(0.0001, abs=1e-12) and part["load"] == pytest.approx(1.0)


def test_a_saturated_bus_reports_full_load_and_a_lone_station_still_occupies_it():
    bus = CanBus("bus", stations=1, load_period=0.001, stuffing="worst")
    engine = Engine(bus)
    for k in range(20):
        engine.post(None, "tx", Frame(0x10, bytes(8)).to_value(), index=0, t=0.0)
    trace = engine.run(until=0.00271)  # 20 frames of 135 us: 2.7 ms back to back
    assert not [e for e in trace if e["action"] == "rx"]  # nobody else on the bus
    ends = [e["t"] for e in trace if e["action"] == "finish"]
    assert len(ends) == 20 and close(ends[-1], 20 * 135e-6)
    loads = [e["value"] for e in trace if e["action"] == "load"]
    assert loads[0] == pytest.approx(7 * 135e-6 / 0.001)  # 7 frames ended by 1 ms (completion-counted)
    assert bus_summary(trace, "bus", stuffing="worst", until=0.0027)["load"] == pytest.approx(1.0)


def test_bad_parameters_are_clear_errors():
    with pytest.raises(ValueError, match="stuffing"):
        CanBus("bus", stuffing="some")
    with pytest.raises(ValueError, match="station_queue"):
        CanBus("bus", station_queue="lifo")


def test_a_frame_no_controller_could_send_is_refused_once_and_the_bus_goes_on():
    """canFrame's ranges let a standard id of 0x800 through; the bus refuses it as it is posted
    (one violation naming it), and the frames before and after it are carried as usual."""
    net, bus, members = system(stations=2, load_period=0)
    engine = Engine(net)
    bad = Frame(0x100, b"\x01").to_value()
    bad.id = 0x800  # as a station's own code could build it: extended False, id past 11 bits
    for t, value in ((0.001, Frame(0x101, b"\x01").to_value()), (0.002, bad), (0.003, Frame(0x102, b"\x02").to_value())):
        engine.post("net/s0", "send", value, t=t)
    engine.run(until=1.0)
    violations = [e for e in engine.trace if e["kind"] == "violation"]
    assert len(violations) == 1 and violations[0]["action"] == "tx"
    assert "CAN id 0x800 does not fit a 11-bit standard id" in violations[0]["value"]["message"]
    assert [f.id for f in members[1].heard] == [0x101, 0x102]
    assert bus.frames == 2 and not any(bus.waiting)


def test_a_full_station_queue_refuses_frames_and_reports_how_many_once_per_period():
    """A station's queue holds `queue_limit` frames: what is posted beyond is refused (never on the
    bus), and `refused[k]` says how many, once per load period, not once per frame."""
    net, bus, members = system(stations=2, queue_limit=5, load_period=0.01)
    engine = Engine(net)
    for k in range(12):  # all at once: the first goes on the bus, five wait, six are refused
        engine.post("net/s0", "send", Frame(0x100 + k, bytes([k])).to_value(), t=0.0)
    for k in range(3):   # later, with room again: carried
        engine.post("net/s0", "send", Frame(0x200 + k, bytes([k])).to_value(), t=0.02)
    trace = engine.run(until=0.05)
    assert [f.id for f in members[1].heard] == [0x100 + k for k in range(6)] + [0x200, 0x201, 0x202]
    refused = [(e["t"], e["index"], e["value"]) for e in trace if e["action"] == "refused"]
    assert refused == [(0.01, 0, 6)]
    assert not [e for e in trace if e["kind"] == "violation"] and bus.refusals == [0, 0]


def test_without_a_queue_limit_nothing_is_refused():
    net, bus, members = system(stations=2, queue_limit=0, load_period=0.01)
    engine = Engine(net)
    for k in range(1500):
        engine.post("net/s0", "send", Frame(0x100, bytes([k % 256])).to_value(), t=0.0)
    trace = engine.run(until=0.5)
    assert len(members[1].heard) == 1500 and not [e for e in trace if e["action"] == "refused"]


@pytest.mark.parametrize("bitrate", [250_000, 500_000, 1_000_000])
def test_the_start_of_frame_bit_ends_on_the_engines_time_grid_whatever_the_start(bitrate):
    """A frame posted exactly one bit after the SOF waits; one nanosecond earlier it takes part.
    (start + 1 bit in floats lands on either side of that instant, depending on the start.)"""
    bit = 1 / bitrate
    for start in (0.001, 0.001664, 0.5, 0.123456789):
        for late, takes_part in ((bit, False), (bit - 1e-9, True)):
            net, bus, members = system(load_period=0, bitrate=bitrate)
            engine = Engine(net)
            engine.post("net/s0", "send", Frame(0x11, b"\x01").to_value(), t=start)
            engine.post("net/s1", "send", Frame(0x10, b"\x02").to_value(), t=round(start + late, 9))  # on the grid
            engine.run(until=start + 0.01)
            assert [f.id for f in members[2].heard] == ([0x10, 0x11] if takes_part else [0x11, 0x10]), (start, late)
