"""`iotad certs`: the certificate authority of a system spread over hosts, and one certificate per
host, for TLS links with mutual authentication (docs/hosts.md)."""
from __future__ import annotations

import argparse
from pathlib import Path

ORDER = 29

EPILOG = """\
examples (once, on the hub's machine; then copy DIR/ca.pem, HOST.pem, HOST.key and HOST.secret to each host):
  iotad certs init certs/                           a new authority: certs/ca.pem, certs/ca.key
  iotad certs host brain --dir certs/ --address 10.0.0.1
  iotad certs host arm --dir certs/ --address 10.0.0.2 --address arm.local
  iotad certs show certs/arm.pem
  iotad certs secret arm --dir certs/               only arm.secret, for a folder made before secrets

Keys are written readable by their owner only. Keep ca.key on one machine: whoever holds it can
admit a host to the system. A process without a certificate of this authority cannot open a
session with a host that listens on a tls/ endpoint. HOST.secret is what that host's agent shows
the hub of a run under access control (derived from ca.key: 'iotad run --certs' needs ca.key, or
the hosts' .secret files, in its folder)."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser(
        "certs", help="make the certificates for TLS links between a system's hosts",
        description="Make a certificate authority for a system spread over hosts, and sign a certificate "
                    "for each host: zenoh's TLS transport with mutual authentication then admits only "
                    "the hosts of this authority.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    actions = parser.add_subparsers(dest="certs_action", metavar="ACTION", required=True)
    init = actions.add_parser("init", help="make a certificate authority in DIR (ca.pem, ca.key)")
    init.add_argument("dir", metavar="DIR")
    init.add_argument("--name", default="iotad", help="the authority's name (default: iotad)")
    init.add_argument("--days", type=_days, default=3650, help="valid for this many days (default: 3650)")
    init.add_argument("--force", action="store_true",
                      help="replace an authority already in DIR (every host certificate it signed stops working)")
    host = actions.add_parser("host", help="sign a certificate for host NAME (NAME.pem, NAME.key, NAME.secret in DIR)")
    host.add_argument("name", metavar="NAME", help="the host's name, as in the system file's [hosts.NAME]")
    host.add_argument("--dir", default="certs", help="the authority's folder (default: certs)")
    host.add_argument("--address", action="append", default=[], metavar="ADDR",
                      help="an IP address or DNS name the host is reached at (repeat for several)")
    host.add_argument("--days", type=_days, default=825, help="valid for this many days (default: 825)")
    host.add_argument("--force", action="store_true", help="replace the host's certificate and key")
    secret = actions.add_parser("secret", help="write host NAME's agent secret (NAME.secret in DIR) from the "
                                               "authority's key, without a new certificate")
    secret.add_argument("name", metavar="NAME", help="the host's name, as in the system file's [hosts.NAME]")
    secret.add_argument("--dir", default="certs", help="the authority's folder (default: certs)")
    show = actions.add_parser("show", help="say what a certificate holds (names, issuer, expiry)")
    show.add_argument("files", nargs="+", metavar="FILE")
    parser.set_defaults(func=run)


def _days(text: str) -> int:
    from iotad.cli import positive_int
    return positive_int(text)


def run(args: argparse.Namespace) -> int:
    from iotad.cli import CliError
    from iotad.machine import certificates

    try:
        if args.certs_action == "init":
            path = certificates.init_authority(args.dir, args.name, args.days, args.force)
            print(f"made a certificate authority: {path} (its key {path.with_name('ca.key')} stays on this machine)")
        elif args.certs_action == "host":
            from iotad.machine import agent_secret

            files = certificates.issue_host(args.dir, args.name, args.address, args.days, args.force)
            secret = agent_secret.write(args.dir, args.name)  # its agent's proof under access control
            print(f"signed {files.certificate} and its key {files.key} for host {args.name!r}, and wrote its "
                  f"agent's secret {secret}; copy them with {files.authority} to that host")
        elif args.certs_action == "secret":
            from iotad.machine import agent_secret
            from iotad.machine.certificates import AUTHORITY_KEY

            if not (Path(args.dir) / AUTHORITY_KEY).is_file():  # else derive would read the secret it writes
                raise certificates.CertificateError(f"no authority's key {Path(args.dir) / AUTHORITY_KEY}: "
                                                    "run this where the authority is")
            print(f"wrote {agent_secret.write(args.dir, args.name)}: host {args.name!r}'s agent secret; copy it "
                  "beside that host's key")
        else:
            for path in args.files:
                print(certificates.describe(path))
    except certificates.CertificateError as exc:
        raise CliError(str(exc)) from None
    except (OSError, ValueError) as exc:
        raise CliError(f"certs {args.certs_action}: {exc}") from None
    return 0
