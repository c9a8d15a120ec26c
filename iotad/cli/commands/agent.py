"""`iotad agent`: run on each machine of a system spread over hosts; the hub's `iotad run` gives it
that host's part of the run (docs/hosts.md)."""
from __future__ import annotations

import argparse

ORDER = 28

EPILOG = """\
examples:
  iotad agent --name arm --connect tcp/10.0.0.1:7447
  iotad agent --name arm --connect tls/10.0.0.1:7447 --certs /etc/iotad/certs

The agent waits at the hub (it keeps trying while no 'iotad run' holds it), then runs what the
hub's 'iotad run SYSTEM.toml' asks: 'iotad run SYSTEM.toml --host NAME' as its own child, its
lines relayed to the hub. Run it from a checkout of the repository (and its 'make install'): the
files the system file names (node code, specs) that this machine lacks, or holds at another
version, come from the hub by their sha256 into --workdir's cache. Ctrl-C (or
SIGTERM, as systemd sends) stops the agent and whatever it runs. docs/hosts.md has a systemd
unit for it."""


def register(sub: argparse._SubParsersAction) -> None:
    from iotad.cli import endpoint

    parser = sub.add_parser(
        "agent", help="serve one host of a system spread over hosts (started by the hub's 'iotad run')",
        description="Wait at a system's hub and run this host's nodes when the hub's 'iotad run' asks; "
                    "supervise them as a local launcher does, and stop them when the run ends.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--name", required=True, metavar="NAME",
                        help="this host's name, as in the system file's [hosts.NAME] and its nodes' host = NAME")
    parser.add_argument("--connect", required=True, type=endpoint, action="append", metavar="ENDPOINT",
                        help="the hub's endpoint, e.g. tcp/10.0.0.1:7447 or tls/10.0.0.1:7447 (repeat for several)")
    parser.add_argument("--certs", metavar="DIR",
                        help="folder with ca.pem, NAME.pem, NAME.key (iotad certs) for tls/ endpoints, and "
                             "NAME.secret, with which a run under access control admits this agent")
    parser.add_argument("--workdir", metavar="DIR",
                        help="where the files the hub sends by hash are cached (code/<sha256>/) and the "
                             "system file copies that name them written (runs/); default: a folder under "
                             "the temporary directory")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import sys

    from iotad.cli import CliError
    from iotad.machine import agent_secret
    from iotad.machine.certificates import CertificateError, use
    from iotad.launcher.hosts.agent import main

    tls, secret = None, None
    if args.certs:
        try:
            tls = use(args.certs, args.name)  # the runs it starts (launcher, nodes) use them too
            secret = agent_secret.read(args.certs, args.name)
        except CertificateError as exc:
            if tls is None:
                raise CliError(str(exc)) from None
            # certificates without a secret: admitted only by runs without access control
            print(f"agent {args.name}: warning: {exc}; only runs without access control will admit this agent",
                  file=sys.stderr)
    elif any(endpoint.startswith(("tls/", "quic/")) for endpoint in args.connect):
        raise CliError(f"{args.connect[0]} is a TLS endpoint: give --certs DIR with this host's certificate")
    return main(args.name, args.connect, tls, args.workdir, secret)
