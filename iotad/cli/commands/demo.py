"""`iotad demo`: the paper's Figure 2 scheduler arbitrating two requesters, each IOTA its own
process over zenoh (examples/figure2.toml), with a summary of who got COMMIT, ABORT and REJECT.
`--virtual` runs the same three IOTAs in one process in virtual time instead."""
from __future__ import annotations

import argparse
import socket
from collections import Counter
from pathlib import Path

from iotad.cli import port, positive_float

ORDER = 5
EXAMPLES = Path(__file__).resolve().parents[3] / "examples"
ANSWERS = ("COMMIT", "ABORT", "REJECT")

EPILOG = """\
examples:
  iotad demo                  20 s over zenoh, recorded to recordings/
  iotad demo --virtual        the same IOTAs in virtual time: instant, deterministic

Exit 0 when COMMIT, ABORT and REJECT all happened. Same as 'iotad run examples/figure2.toml
--until 20' plus that answer check. Then look at the recording the summary names:
'iotad info FILE', 'iotad check FILE', 'iotad plot FILE -o fig2.png'."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("demo", help="run the Figure 2 scheduler with two requesters and summarise",
                            description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter,
                            epilog=EPILOG)
    parser.add_argument("--until", type=positive_float, default=None, metavar="T",
                        help="how long to run: wall-clock seconds (default 20); with --virtual, virtual "
                             "time units (default 30)")
    parser.add_argument("--virtual", action="store_true", help="one process, virtual time, no zenoh")
    parser.add_argument("--port", type=port, default=None,
                        help="hub port (default 7447 when free, else any free port)")
    parser.add_argument("--no-record", action="store_true", help="do not record to recordings/")
    parser.add_argument("--plain", action="store_true", help="plain event lines even on a terminal")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    return run_virtual(args) if args.virtual else run_processes(args)


def run_processes(args: argparse.Namespace) -> int:
    from iotad.cli import CliError, load_checked
    from iotad.node_host.transport import DEFAULT_HUB_ENDPOINT
    from iotad.launcher.options import RunOptions
    from iotad.launcher.run.run_system import RunError, run_real_time

    system = load_checked(str(EXAMPLES / "figure2.toml"))
    port = args.port
    if port is None:
        default = int(DEFAULT_HUB_ENDPOINT.rsplit(":", 1)[1])
        port = default if _port_free(default) else 0
    options = RunOptions(until=args.until or 20.0, port=port, no_record=args.no_record, plain=args.plain)
    try:
        return run_real_time(system, options, summary_hook=_answers)
    except RunError as exc:
        raise CliError(str(exc)) from None


def _answers(launcher, code: int) -> int:
    """Acks per requester (through the bindings), and whether all three answers happened."""
    system = launcher.system
    print("answers per requester:")
    seen: set[str] = set()
    with launcher.tally.lock:
        values = {k: Counter(v) for k, v in launcher.tally.values.items()}
    from iotad.node_host import wire
    for binding in system.bindings:
        if binding.target.channel != "ack":
            continue
        source = binding.source
        counts = values.get(wire.channel_key(system.name, source.node, source.channel, source.index), Counter())
        seen.update(k for k in counts if k in ANSWERS)
        shown = "  ".join(f"{answer} x{counts[answer]}" for answer in ANSWERS if counts[answer])
        print(f"  {binding.target.node:<14} {shown or 'no answer'}")
    missing = [a for a in ANSWERS if a not in seen]
    if code == 130:
        return code
    if missing:
        print(f"missing answers: {', '.join(missing)} (a loaded machine can shift the timings)")
        return code or 1
    print("COMMIT, ABORT and REJECT all happened over zenoh")
    return code


def _port_free(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind(("127.0.0.1", port))
            return True
        except OSError:
            return False


def run_virtual(args: argparse.Namespace) -> int:
    """The three IOTAs of examples/figure2.toml composed in one process, in virtual time."""
    from iotad.kernel.compose import Composite
    from iotad.kernel.engine import Engine
    from iotad.cli import load_checked
    from iotad.launcher.system.system_file import instantiate

    system = load_checked(str(EXAMPLES / "figure2.toml"))
    components = [instantiate(node) for node in system.nodes.values()]
    binds = [(str(b.source), str(b.target)) for b in system.bindings]
    engine = Engine(Composite(system.name, *components, bind=binds))
    engine.run(args.until or 30.0)
    acks = Counter()
    receivers = {str(b.source): b.target.node for b in system.bindings}
    for event in engine.trace:
        if event["action"] == "ack" and event["kind"] == "output":
            who = receivers.get(f"{event['iota'].rsplit('/', 1)[-1]}.ack[{event['index']}]", "?")
            acks[(who, event["value"])] += 1
            print(f"t={event['t']:6.2f}  {who:<13} <- {event['value']}")
        elif event["action"] == "mdl_command":
            print(f"t={event['t']:6.2f}  motors        <- w={event['value']['w']}")
    print(f"{len(engine.trace)} events, {engine.firings} firings, "
          f"{sum(1 for e in engine.trace if e['kind'] == 'violation')} violations")
    for (who, answer), n in sorted(acks.items()):
        print(f"  {who:<13} {answer:<7} x{n}")
    return 0
