"""A bad day's schedule written out (`bench/bad_day.py --schedule`, tests/fault_schedule.py
`parse_schedule`): each fault as `describe` names it, in the order of its time, and a fault
written wrong is a clear ValueError that quotes it."""
import pytest

from fault_schedule import Fault, parse_schedule


def test_each_kind_reads_as_the_fault_it_names_in_time_order():
    faults = parse_schedule("70 slow arm 20 256kbit; 25 slow arm 20 1mbit;  40 partition camera 12.5; "
                            "90 stop arm node:sim 0.5; 100 kill brain recorder; 110 kill arm node:motor;")
    assert faults == [Fault(25.0, "slow", "arm", 20.0, rate="1mbit"), Fault(40.0, "partition", "camera", 12.5),
                      Fault(70.0, "slow", "arm", 20.0, rate="256kbit"),
                      Fault(90.0, "stop", "arm", 0.5, target="node:sim"), Fault(100.0, "kill", "brain", target="recorder"),
                      Fault(110.0, "kill", "arm", target="node:motor")]
    assert faults[1].describe() == "partition of camera for 12.5 s (past the lease)"


@pytest.mark.parametrize("text, said", [
    ("25 slow arm 20", "'25 slow arm 20': a slow is written 'AT slow HOST SECONDS RATE'"),
    ("soon slow arm 2 1mbit", "times and seconds are numbers"),
    ("3 kill arm nobody", "the process is node:NAME, agent, launcher or recorder"),
    ("3 stop arm agent 1", "the process is node:NAME"),
    ("3 zap arm", "the second word is the kind of fault, one of partition, slow, stop, kill"),
    ("-3 partition arm 2", "times and seconds are >= 0"),
    ("3 slow arm 2 fast", "'3 slow arm 2 fast': not a tc rate: 'fast'"),
    ("3 slow arm 2 0kbit", "not a tc rate: '0kbit'"),
])
def test_a_fault_written_wrong_is_said_with_its_text(text, said):
    with pytest.raises(ValueError) as raised:
        parse_schedule(f"10 partition arm 2; {text}")
    assert said in str(raised.value)
