"""A bad day's schedule of faults drawn from a seed: partitions of one host (1 to 20 s, some past
zenoh's 10 s lease), a link slowed by a token bucket, SIGSTOP of a process for 0.2 to 2 s, and kill
-9 of a node, a host's agent, a host's launcher or a recorder, one after another with time to
recover between them. The same seed and arguments draw the same schedule. Shared by
bench/bad_day.py and its short campaign in tests/hosts/."""
from __future__ import annotations

import math
import random
import re
from dataclasses import dataclass

LEASE = 10.0  # s: zenoh's default lease; a cut longer than it closes the links (docs/hosts.md, section 8)
KINDS = ("partition", "slow", "stop", "kill")
KILL_TARGETS = ("node", "agent", "launcher", "recorder")
_RATE = re.compile(r"^(\d+(?:\.\d+)?)(bit|kbit|mbit|gbit)$", re.IGNORECASE)  # tc reads the units in any case
_RATE_UNIT = {"bit": 1, "kbit": 1_000, "mbit": 1_000_000, "gbit": 1_000_000_000}


def rate_bits(rate: str) -> float:
    """Bits a second of a `tc tbf` rate as a schedule writes it ("64kbit", "1mbit"); ValueError
    for anything else (tc would refuse it only when the fault is made)."""
    found = _RATE.match(rate.strip())
    if not found or not float(found.group(1)) > 0:
        raise ValueError(f"not a tc rate: {rate!r} (a number above 0 with bit, kbit, mbit or gbit: 256kbit)")
    return float(found.group(1)) * _RATE_UNIT[found.group(2).lower()]


@dataclass(frozen=True)
class Fault:
    """One fault: `kind` at `at` s into the campaign, lasting `duration` s (0: a kill, which is at
    once), on `host`'s link or on the process `target` (`node:NAME`, `agent`, `launcher`,
    `recorder`) of `host`; `rate` for a slowed link."""

    at: float
    kind: str
    host: str
    duration: float = 0.0
    target: str = ""
    rate: str = ""

    @property
    def end(self) -> float:
        return self.at + self.duration

    def describe(self) -> str:
        if self.kind == "partition":
            past = " (past the lease)" if self.duration > LEASE else ""
            return f"partition of {self.host} for {self.duration:.1f} s{past}"
        if self.kind == "slow":
            return f"link brain-{self.host} slowed to {self.rate} (tc tbf) for {self.duration:.1f} s"
        what = self.target.replace("node:", "node ")
        if self.kind == "stop":
            return f"SIGSTOP of {what} on {self.host} for {self.duration:.2f} s"
        return f"kill -9 of {what} on {self.host}"


# s left after a fault ends before the next may begin: long enough for the system to have
# recovered, so that each gap, safe time and recovery belongs to one fault
SETTLE = {"partition": 6.0, "partition_past_lease": 14.0, "slow": 4.0, "stop": 5.0,
          "kill:node": 7.0, "kill:recorder": 6.0, "kill:agent": 22.0, "kill:launcher": 22.0}


def settle(fault: Fault) -> float:
    if fault.kind == "partition":
        return SETTLE["partition_past_lease" if fault.duration > LEASE else "partition"]
    if fault.kind == "kill":
        return SETTLE["kill:" + fault.target.split(":")[0]]
    return SETTLE[fault.kind]


def draw_schedule(seed: int, length: float, nodes: dict[str, str], cut_hosts: tuple[str, ...],
                  kinds: tuple[str, ...] = KINDS, kill_targets: tuple[str, ...] = KILL_TARGETS,
                  first: float = 3.0, longest_cut: float = 20.0, recorder_hosts: tuple[str, ...] | None = None) -> list[Fault]:
    """Faults from `first` s to `length` s into the campaign, each begun once the one before has
    ended and settled (`SETTLE`). `nodes`: node name -> its host (a node to kill or stop);
    `cut_hosts`: the hosts besides the hub's, whose link can be cut or slowed and whose agent or
    launcher can be killed. A third of the partitions last longer than the lease when
    `longest_cut` allows it. Every fault ends, and settles, by `length`."""
    draw = random.Random(seed)
    recorder_hosts = recorder_hosts or cut_hosts
    faults: list[Fault] = []
    t = first
    for _ in range(1000):  # bounded: a draw that fits nowhere ends the schedule
        kind = draw.choice(kinds)
        host = draw.choice(cut_hosts)
        if kind == "partition":
            past = longest_cut > LEASE + 1 and draw.random() < 1 / 3
            duration = draw.uniform(LEASE + 1, longest_cut) if past else draw.uniform(1.0, min(longest_cut, LEASE - 1))
            fault = Fault(t, kind, host, round(duration, 1))
        elif kind == "slow":
            fault = Fault(t, kind, host, round(draw.uniform(3.0, 10.0), 1),
                          rate=draw.choice(("64kbit", "256kbit", "1mbit")))
        elif kind == "stop":
            node = draw.choice(sorted(nodes))
            fault = Fault(t, kind, nodes[node], round(draw.uniform(0.2, 2.0), 2), target=f"node:{node}")
        else:
            target = draw.choice(kill_targets)
            if target == "node":
                node = draw.choice(sorted(nodes))
                fault = Fault(t, kind, nodes[node], target=f"node:{node}")
            else:
                fault = Fault(t, kind, draw.choice(recorder_hosts) if target == "recorder" else host, target=target)
        if fault.end + settle(fault) > length:
            if all(fault.end + settle(fault) > length for fault in _shortest(t, nodes, cut_hosts, kinds)):
                break
            continue
        faults.append(fault)
        # up to the next tenth of a second: never sooner than the settling allows
        t = math.ceil((fault.end + settle(fault) + draw.uniform(0.0, 2.0)) * 10 - 1e-9) / 10
    return faults


def _shortest(t: float, nodes: dict[str, str], cut_hosts: tuple[str, ...], kinds: tuple[str, ...]) -> list[Fault]:
    """The least each kind can take from `t`: whether anything still fits."""
    node = sorted(nodes)[0]
    least = {"partition": Fault(t, "partition", cut_hosts[0], 1.0), "slow": Fault(t, "slow", cut_hosts[0], 3.0),
             "stop": Fault(t, "stop", nodes[node], 0.2, target=f"node:{node}"),
             "kill": Fault(t, "kill", nodes[node], target=f"node:{node}")}
    return [least[kind] for kind in kinds]


def parse_schedule(text: str) -> list[Fault]:
    """A schedule written out rather than drawn: faults separated by `;`, each `AT KIND HOST`
    and then what the kind needs, as `describe` names it:

        25 slow arm 20 1mbit; 70 partition camera 12; 90 stop arm node:sim 0.5; 100 kill brain recorder

    (a slowed link: seconds and rate; a partition: seconds; SIGSTOP: the process and seconds; a
    kill -9: the process, `node:NAME`, `agent`, `launcher` or `recorder`). ValueError says what
    is wrong with which fault. Faults are taken in the order of their times."""
    faults = []
    for part in (p.strip() for p in text.split(";")):
        if not part:
            continue
        words = part.split()
        shape = {"slow": "AT slow HOST SECONDS RATE", "partition": "AT partition HOST SECONDS",
                 "stop": "AT stop HOST node:NAME SECONDS", "kill": "AT kill HOST node:NAME|agent|launcher|recorder"}
        kind = words[1] if len(words) > 1 else ""
        if kind not in shape:
            raise ValueError(f"{part!r}: the second word is the kind of fault, one of {', '.join(KINDS)}")
        if len(words) != len(shape[kind].split()):
            raise ValueError(f"{part!r}: a {kind} is written {shape[kind]!r}")
        try:
            at = float(words[0])
            if kind == "slow":
                fault = Fault(at, kind, words[2], float(words[3]), rate=words[4])
            elif kind == "partition":
                fault = Fault(at, kind, words[2], float(words[3]))
            elif kind == "stop":
                fault = Fault(at, kind, words[2], float(words[4]), target=words[3])
            else:
                fault = Fault(at, kind, words[2], target=words[3])
        except ValueError:
            raise ValueError(f"{part!r}: times and seconds are numbers ({shape[kind]})") from None
        target = fault.target.split(":")[0]
        if kind in ("stop", "kill") and target not in ("node",) + (KILL_TARGETS[1:] if kind == "kill" else ()):
            raise ValueError(f"{part!r}: the process is node:NAME" + (", agent, launcher or recorder" if kind == "kill" else ""))
        if fault.at < 0 or fault.duration < 0:
            raise ValueError(f"{part!r}: times and seconds are >= 0")
        if kind == "slow":
            try:
                rate_bits(fault.rate)
            except ValueError as exc:
                raise ValueError(f"{part!r}: {exc}") from None
        faults.append(fault)
    return sorted(faults, key=lambda f: f.at)
