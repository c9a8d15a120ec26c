"""`iotad demo`: the paper's Figure 2 scheduler arbitrating two requesters (virtual time)."""
from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

ORDER = 90
EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("demo", help="run the Figure 2 scheduler with two requesters and summarise",
                            description=__doc__)
    parser.add_argument("--until", type=float, default=30.0, help="virtual time to run to (default 30)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from iotad.compose import Composite
    from iotad.engine import Engine
    from iotad.loader import load_object

    Scheduler = load_object(str(EXAMPLES / "scheduler.py") + ":Scheduler")
    Requester = load_object(str(EXAMPLES / "requesters.py") + ":Requester")
    system = Composite(
        "figure2",
        Scheduler("scheduler", N=2, T=0.5),
        Requester("vision", priority=1, epoch=3.0, timeout=4.0, start=0.0, pause=0.5, setpoint=0.2),
        Requester("manipulation", priority=5, epoch=2.0, timeout=3.0, start=1.0, pause=4.0, setpoint=1.5),
        bind=[("vision.req", "scheduler.req[0]"), ("manipulation.req", "scheduler.req[1]"),
              ("scheduler.ack[0]", "vision.ack"), ("scheduler.ack[1]", "manipulation.ack")])
    engine = Engine(system)
    engine.run(args.until)
    acks = Counter()
    for event in engine.trace:
        if event["action"] == "ack" and event["kind"] == "output":
            who = "vision" if event["index"] == 0 else "manipulation"
            acks[(who, event["value"])] += 1
            print(f"t={event['t']:6.2f}  {who:<13} <- {event['value']}")
        elif event["action"] == "mdl_command":
            print(f"t={event['t']:6.2f}  motors        <- w={event['value']['w']}")
    print(f"{len(engine.trace)} events, {engine.firings} firings, "
          f"{sum(1 for e in engine.trace if e['kind'] == 'violation')} violations")
    for (who, answer), n in sorted(acks.items()):
        print(f"  {who:<13} {answer:<7} x{n}")
    return 0
