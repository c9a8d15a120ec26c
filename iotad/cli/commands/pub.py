"""`iotad pub KEY JSON`: publish a value (msgpack, with the `[seq, send_time_ns]` attachment) as a
node would, e.g. to inject an input: `iotad pub iota/figure2/scheduler/req/0 '{"control": ...}'`.
The value may come from a file (`@FILE`) or standard input (`-`): an MDL program is long."""
from __future__ import annotations

import argparse
import json
import time

from iotad.cli import key_expression, nonnegative_float, nonnegative_int, positive_float

from iotad.cli.live import add_connect, tool_session

ORDER = 42

EPILOG = """\
examples (with 'iotad run examples/figure2.toml --insecure' running in another terminal):
  iotad pub iota/figure2/scheduler/req/1 \\
      '{"control": {"w": 0.7, "k": 1.0}, "epoch": 1.0, "timeout": 1.0, "priority": 9}'
  iotad pub iota/some/node/tick null --count 0 --rate 10       10 Hz until Ctrl-C
  iotad pub iota/figure2/scheduler/req/1 @request.json        the value from a file
  jq .request run.json | iotad pub iota/figure2/scheduler/req/1 -    ... or from standard input

An input channel's key is iota/<system>/<node>/<channel>[/<index>] ('iotad ls' lists them);
the node applies the value as an input event at the time it arrives, checking its type and
switching time (a violation otherwise). See also: 'iotad echo KEY' to watch the answer.

Access control, on by default in 'iotad run', lets tools publish only the inputs that the system
file's [system.debug] allow_pub lists: the hub drops anything else without telling the sender.
The run writes those keys into the tools' credentials, so this command refuses any other key
itself, with exit status 2. List the input there, or run the system with --insecure
(docs/access-control.md)."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("pub", help="publish a JSON value on a key, e.g. to inject an input into a node",
                            description=__doc__, epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("key", metavar="KEY", type=key_expression,
                        help="where to publish, e.g. iota/figure2/scheduler/req/1 (no wildcards)")
    parser.add_argument("value", metavar="VALUE",
                        help="the value as JSON ('null' for a channel without a value), @FILE for a file's JSON, "
                             "or - for standard input's")
    parser.add_argument("--count", type=nonnegative_int, default=1, metavar="N",
                        help="publish N times (default 1; 0: until Ctrl-C)")
    parser.add_argument("--rate", type=positive_float, default=1.0, metavar="HZ",
                        help="messages per second when --count is not 1 (default 1)")
    parser.add_argument("--wait", type=nonnegative_float, default=2.0, metavar="S",
                        help="wait up to S seconds for a subscriber before the first message (default 2)")
    add_connect(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import sys

    import zenoh

    from iotad.node_host import wire
    from iotad.node_host.transport import DEFAULT_HUB_ENDPOINT
    from iotad.cli import CliError
    from iotad.kernel.types import HUGE_INT

    text, origin = _value_text(args.value)
    try:
        value = json.loads(text)
    except json.JSONDecodeError as exc:
        if origin:
            raise CliError(f"{origin} is not JSON: {exc.msg} (line {exc.lineno}, column {exc.colno})") from None
        raise CliError(f"value is not JSON: {exc.msg} (quote it for the shell: '{{\"w\": 1.0}}')") from None
    except RecursionError:
        raise CliError(f"{origin or 'value'} is nested too deeply to be a channel's value") from None
    except ValueError:  # json reads no int of more than 4300 digits
        raise CliError(f"{origin or 'value'} holds an integer of thousands of digits, {HUGE_INT}") from None
    if args.rate <= 0:
        raise CliError("--rate must be positive")
    if "*" in args.key:
        raise CliError(f"{args.key}: a key to publish on has no wildcards ('*', '**')")
    try:
        payload = wire.encode(value)
    except (OverflowError, ValueError, TypeError) as exc:  # msgpack: an integer past 64 bits
        raise CliError(f"value cannot be sent: {exc} (integers are at most 64 bits)") from None
    _check_allowed(args.key, args.connect or [DEFAULT_HUB_ENDPOINT])
    session = tool_session(args)
    try:
        publisher = session.declare_publisher(args.key, congestion_control=zenoh.CongestionControl.BLOCK)
        # A put before the subscriber's declaration reached us would be lost: wait for a match.
        end = time.monotonic() + args.wait
        while not publisher.matching_status.matching and time.monotonic() < end:
            time.sleep(0.01)
        if not publisher.matching_status.matching:
            print(f"iotad pub: no subscriber matches {args.key} (yet); publishing anyway", file=sys.stderr)
        period, start, sequence = 1.0 / args.rate, time.monotonic(), 0
        while args.count == 0 or sequence < args.count:
            publisher.put(payload, attachment=wire.encode_attachment(sequence))
            sequence += 1
            if args.count and sequence >= args.count:
                break
            delay = start + sequence * period - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        publisher.undeclare()
        return 0
    finally:
        session.close()


def _value_text(value: str) -> tuple[str, str]:
    """(the JSON text, where it came from: "" for the argument itself) of VALUE: `@FILE` reads a
    file, `-` standard input; anything else is the JSON."""
    import sys

    from iotad.cli import CliError

    if value == "-":
        if sys.stdin is None or sys.stdin.isatty():
            raise CliError("VALUE is '-' but standard input is a terminal: pipe the JSON in, or give it as "
                           "the argument or as @FILE")
        return sys.stdin.read(), "standard input"
    if value.startswith("@"):
        path = value[1:]
        try:
            with open(path, encoding="utf-8") as file:
                return file.read(), path
        except FileNotFoundError:
            raise CliError(f"{value}: no such file (VALUE @FILE reads the JSON from FILE)") from None
        except IsADirectoryError:
            raise CliError(f"{value}: is a directory, not a JSON file") from None
        except UnicodeDecodeError:
            raise CliError(f"{value}: not UTF-8 text") from None
        except OSError as exc:
            raise CliError(f"{value}: cannot read it: {exc.strerror}") from None
    return value, ""


def _check_allowed(key: str, hub: list[str]) -> None:
    """Under access control the hub drops what a tool publishes outside [system.debug] allow_pub,
    and zenoh does not tell the sender: where the run wrote the tools' keys down, say it here."""
    from iotad.cli import CliError
    from iotad.node_host.credentials import CredentialsError, for_endpoints

    try:
        credentials = for_endpoints(hub)
    except CredentialsError:
        return  # the session says what is wrong with them
    allowed = None if credentials is None else credentials.may_publish
    if allowed is not None and key not in allowed:
        listed = ", ".join(allowed) if allowed else "none"
        raise CliError(f"{key}: the hub there is under access control and would drop this without a word: "
                       f"tools may publish only on the inputs its system file lists in [system.debug] allow_pub "
                       f"({listed}). List the input there, or run the system with --insecure "
                       f"(docs/access-control.md)")
