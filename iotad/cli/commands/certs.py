"""`iotad certs`: the certificate authority of a system spread over hosts, and one certificate per
host, for TLS links with mutual authentication (docs/hosts.md)."""
from __future__ import annotations

import argparse
from pathlib import Path

ORDER = 29

EPILOG = """\
examples (once, on the hub's machine; then copy DIR/ca.pem, HOST.pem, HOST.key and HOST.secret to each host):
  iotad certs init certs/ --system split.toml       a new authority, named after system split: certs/ca.pem, certs/ca.key
  iotad certs host brain --dir certs/ --address 10.0.0.1
  iotad certs host arm --dir certs/ --address 10.0.0.2 --address arm.local
  iotad certs show certs/arm.pem
  iotad certs secret arm --dir certs/               only arm.secret, for a folder made before secrets
  iotad certs ros2 rviz --dir certs/ --connect tls/10.0.0.1:7447
                                                    a ROS 2 machine: ros2-rviz.pem, .key and .json5 (rmw_zenoh's
                                                    ZENOH_SESSION_CONFIG_URI); 'iotad run --certs certs/' admits it

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
    named = init.add_mutually_exclusive_group()
    named.add_argument("--system", metavar="FILE", help="name the authority after this system file's [system] name")
    named.add_argument("--name", help="the system the authority is named after (default: the folder DIR is in)")
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
    ros2 = actions.add_parser("ros2", help="admit a ROS 2 machine NAME: its certificate and rmw_zenoh's session "
                                           "configuration (ros2-NAME.pem, .key, .json5 in DIR)")
    ros2.add_argument("name", metavar="NAME", help="the ROS 2 machine's name (its user on the hub is ros2-NAME)")
    ros2.add_argument("--dir", default="certs", help="the authority's folder (default: certs)")
    ros2.add_argument("--connect", action="append", required=True, metavar="ENDPOINT",
                      help="the hub's tls/ endpoint as the ROS 2 machine reaches it (repeat for several)")
    ros2.add_argument("--files-at", metavar="DIR",
                      help="where ca.pem and the peer's certificate and key will lie on the ROS 2 machine "
                           "(default: DIR, as an absolute path)")
    ros2.add_argument("--days", type=_days, default=825, help="valid for this many days (default: 825)")
    ros2.add_argument("--force", action="store_true", help="replace the peer's certificate, key and configuration")
    show = actions.add_parser("show", help="say what a certificate holds (names, issuer, expiry)")
    show.add_argument("files", nargs="+", metavar="FILE")
    parser.set_defaults(func=run)


def _days(text: str) -> int:
    from iotad.cli import positive_int
    return positive_int(text)


def _authority_name(args: argparse.Namespace) -> str:
    """The system an authority is named after: the system file's name, the one given, or the
    folder that holds DIR (a project's `certs/` folder sits in the project)."""
    if args.name:
        return args.name
    if args.system:
        from iotad.cli import CliError
        from iotad.launcher.system.declaration import read_toml  # the one reader of a system file's TOML
        try:
            name = read_toml(args.system).get("system", {}).get("name")
        except (OSError, ValueError) as exc:
            raise CliError(f"certs init: {args.system}: {exc}") from None
        if not isinstance(name, str) or not name:
            raise CliError(f"certs init: {args.system} has no [system] name")
        return name
    return Path(args.dir).resolve().parent.name or "iotad"


def run(args: argparse.Namespace) -> int:
    from iotad.cli import CliError
    from iotad.machine import certificates

    try:
        if args.certs_action == "init":
            name = _authority_name(args)
            path = certificates.init_authority(args.dir, name, args.days, args.force)
            print(f"made a certificate authority, {certificates.authority_name(name)!r}: {path} "
                  f"(its key {path.with_name('ca.key')} stays on this machine)")
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
        elif args.certs_action == "ros2":
            from iotad.launcher.access.ros2_peers import make_peer, peer_user

            path = make_peer(args.dir, args.name, args.connect, args.files_at, args.days, args.force)
            print(f"wrote {path} (rmw_zenoh's session configuration, with the password of user "
                  f"{peer_user(args.name)!r}) and signed {Path(args.dir) / (peer_user(args.name) + '.pem')} and its key; "
                  f"copy them with {Path(args.dir) / 'ca.pem'} to the ROS 2 machine, and run the system with "
                  f"--certs {args.dir} (docs/ros2.md)")
        else:
            for path in args.files:
                print(certificates.describe(path))
    except certificates.CertificateError as exc:
        raise CliError(str(exc)) from None
    except (OSError, ValueError) as exc:
        raise CliError(f"certs {args.certs_action}: {exc}") from None
    return 0
