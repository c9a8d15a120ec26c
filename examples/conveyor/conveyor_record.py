"""What a conveyor recording says: picks, the world's tally, who held the arm, scheduler answers.

    python examples/conveyor/conveyor_record.py recordings/conveyor.mcap

reads the recording's channels (not the traces), one pass: the world's `tally` over time, every
`mdl_command` (which requester's program the scheduler gave the arm, and when), every ack, every
pick goal and the interpreter's faults and program ends.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field

from iotad.recording.mcap_reader import iter_messages


@dataclass
class ConveyorRecord:
    system: str = ""
    end: float = 0.0
    tally: list = field(default_factory=list)          # (t, {spawned, held, placed, missed, dropped})
    commands: list = field(default_factory=list)       # (t, program id)
    acks: list = field(default_factory=list)           # (t, requester index, ack)
    picks: list = field(default_factory=list)          # (t, target)
    program_ends: list = field(default_factory=list)   # (t, program, end)
    faults: list = field(default_factory=list)         # (t, message)

    def final(self) -> dict:
        return self.tally[-1][1] if self.tally else {"spawned": 0, "held": 0, "placed": 0, "missed": 0, "dropped": 0}

    def holders(self) -> list[tuple[float, float, str]]:
        """(start, end, owner) spans: who the arm's program came from ('vision' or 'manipulation')."""
        spans = []
        for k, (t, program) in enumerate(self.commands):
            end = self.commands[k + 1][0] if k + 1 < len(self.commands) else self.end
            spans.append((t, end, "manipulation" if program.startswith("pick") else "vision"))
        return spans

    def preemptions(self) -> int:
        """How often manipulation took the arm while vision held it."""
        spans = self.holders()
        return sum(1 for a, b in zip(spans, spans[1:]) if a[2] == "vision" and b[2] == "manipulation")


def read(path: str) -> ConveyorRecord:
    record = ConveyorRecord()
    origin = None
    for message in iter_messages(path):
        topic = message.topic
        if not topic.startswith("iota/") or "/@" in topic:
            continue
        parts = topic.split("/")
        record.system = parts[1]
        t_ns = message.log_time
        if origin is None:
            origin = t_ns
        rest = "/".join(parts[2:])
        if rest not in _WANTED and not rest.startswith("scheduler/ack/"):
            continue
        value = message.value
        t = _time(value, t_ns, origin)
        record.end = max(record.end, t)
        if rest == "sim/tally":
            record.tally.append((value["t"], {k: value[k] for k in ("spawned", "held", "placed", "missed", "dropped")}))
        elif rest == "scheduler/mdl_command":
            record.commands.append((t, value["id"]))
        elif rest.startswith("scheduler/ack/"):
            record.acks.append((t, int(rest.rsplit("/", 1)[1]), value))
        elif rest == "planning/pick":
            record.picks.append((t, value["target"]))
        elif rest == "interpreter/program_end":
            record.program_ends.append((value["t"], value["program"], value["end"]))
        elif rest == "interpreter/fault":
            record.faults.append((value["t"], value["message"]))
    return record


_WANTED = {"sim/tally", "scheduler/mdl_command", "planning/pick", "interpreter/program_end", "interpreter/fault"}


def _time(value, t_ns: int, origin: int) -> float:
    # in-process recordings stamp messages with virtual time from 0; real-time ones with wall time
    return (t_ns - origin) / 1e9 if origin > 10**17 else t_ns / 1e9


def main(argv: list[str]) -> int:
    record = read(argv[0])
    final = record.final()
    print(f"{record.system}: {record.end:.1f} s; objects {final}; {len(record.picks)} pick goals; "
          f"{len(record.commands)} mdl_commands; {record.preemptions()} preemptions of vision by manipulation; "
          f"acks {[(round(t, 2), i, a) for t, i, a in record.acks][:6]}...; {len(record.faults)} interpreter faults")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
