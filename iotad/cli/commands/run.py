"""`iotad run SYSTEM.toml`: check a system file, then run each IOTA as its own process around a
zenoh hub, supervise them (restarts, liveliness, heartbeats), record, and stop them all on Ctrl-C.
With --virtual, run every IOTA of the same file in this one process in virtual time instead."""
from __future__ import annotations

import argparse
import sys

from iotad.cli import port, positive_float, seed
from iotad.cli.commands.record import byte_size

ORDER = 20

EPILOG = """\
examples:
  iotad run examples/figure2.toml --until 20     run the Figure 2 demo for 20 s, then summarise
  iotad run --check examples/figure2.toml        only check the file (exit 2 on an error)
  iotad run sys.toml --host arm --port 7500      run the nodes of host "arm" of a multi-host system
  iotad run examples/figure2.toml --until 20 -o recordings/fig2.mcap --plain
  iotad run examples/figure2.toml -o recordings/fig2.mcap --max-size 100M --max-duration 600
                                                 a long run: fig2_0.mcap, fig2_1.mcap... read as one
  iotad run examples/figure2.toml --virtual --until 60     the same IOTAs in one process, virtual time
  iotad run examples/arm_can.toml --until 8 --after-live   8 s from the moment every node is live

The system file format (nodes, bindings, endpoints, time_unit, restart policies, hosts) is
docs/system-file.md. --until is wall-clock seconds from the launch (--after-live: from the moment
every node is live); spec times are in the spec's time units, time_unit seconds each. Exit
status: 0 when every node stopped cleanly, 1 when a node failed or the recording was lost, 2 for a
bad system file or option, 130 on Ctrl-C.

A node whose process exits, whose liveliness token vanishes or whose heartbeat stops is
restarted by its restart policy (never | on-failure | always, backoff doubling, max_restarts).
Ctrl-C sends SIGINT to every node, then SIGTERM, then SIGKILL; nodes also die with the launcher
if it is killed. Events go to iota/<system>/@launcher; the recording to recordings/.

While it runs: 'iotad ls', 'iotad echo KEY', 'iotad hz KEY', 'iotad pub KEY VALUE' (another
terminal). Afterwards: 'iotad info FILE', 'iotad check FILE', 'iotad replay FILE --node PATH',
'iotad plot FILE -o OUT.png'.

--virtual: one process, no zenoh, no real CAN: every node is instantiated here, bound as the file
says, each [[can]] bus is the modelled 1 Mbit/s bus (bit times, arbitration by id), and the
engine runs as fast as the machine allows up to --until virtual seconds (required). The
recording has the same format as a real-time run's, so info, check, replay, plot and export read
both; on a machine with two cores or more a second process writes it, beside the engine.
External inputs can be fed with --inputs SCRIPT.jsonl (times in spec units). Ctrl-C stops a
virtual run after the step in progress and finishes its recording; a second Ctrl-C stops it at
once (exit 130; the recording says the run broke off)."""


def register(sub: argparse._SubParsersAction) -> None:
    parser = sub.add_parser("run", help="run a system file: one process per IOTA, supervised",
                            description=__doc__, epilog=EPILOG,
                            formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("system_file", metavar="SYSTEM.toml",
                        help="the system file (docs/system-file.md; example: examples/figure2.toml)")
    parser.add_argument("--check", action="store_true",
                        help="check the file (nodes, channels, bindings) and exit: 0 fine, 2 errors")
    parser.add_argument("--until", type=positive_float, metavar="SECONDS",
                        help="stop everything after SECONDS of wall-clock time (default: run until Ctrl-C); with --virtual, "
                             "SECONDS of virtual time, and required")
    parser.add_argument("--after-live", action="store_true",
                        help="count --until from the moment every node is first live, not from the launch, "
                             "so that start-up (imports, PyBullet worlds; 10-30 s in user-mode Linux) is not "
                             "counted (no effect with --virtual, where everything starts at 0)")
    parser.add_argument("--port", type=port, metavar="PORT",
                        help="hub port instead of the system file's (0: any free port; default: the file's "
                             "[system.endpoints] listen, else 7447)")
    parser.add_argument("--host", metavar="NAME",
                        help="run only the nodes with host = NAME, by hand (multi-host systems: one launcher per "
                             "host); without it, a system spread over hosts runs this machine as the hub host and "
                             "every other host through its 'iotad agent' (docs/hosts.md)")
    parser.add_argument("--local", action="store_true",
                        help="a system spread over hosts: run every host's nodes on this machine (no agents)")
    parser.add_argument("--certs", metavar="DIR",
                        help="a system spread over hosts linked by TLS: the folder with ca.pem and this host's "
                             "HOST.pem, HOST.key ('iotad certs'); its nodes, recorder and agents' sessions use them")
    parser.add_argument("--agent-timeout", type=positive_float, default=None, metavar="SECONDS",
                        help="how long to wait for the other hosts' agents (default: the system's start_timeout)")
    parser.add_argument("--no-record", action="store_true", help="run without a recorder (no recording)")
    parser.add_argument("--insecure", action="store_true",
                        help="no access control: any process reaching the hub may publish on any key "
                             "(default: each node authenticated, writing only its outputs; docs/access-control.md). "
                             "A system spread over hosts linked without TLS runs only with it (docs/hosts.md)")
    parser.add_argument("-o", "--record-to", metavar="FILE",
                        help="recording file (default recordings/<system>-<time>.mcap); an existing "
                             "recording is kept: see --force")
    parser.add_argument("--force", action="store_true",
                        help="replace a recording already at -o FILE (default: refuse, so that none is lost)")
    parser.add_argument("--max-size", type=byte_size, default=None, metavar="SIZE",
                        help="split the recording: a new file once one holds SIZE bytes (100M, 1G; see 'iotad record')")
    parser.add_argument("--max-duration", type=positive_float, default=None, metavar="S",
                        help="split the recording: a new file once one spans S seconds")
    parser.add_argument("--origin", type=positive_float, metavar="WALLTIME",
                        help="wall-clock time (time.time()) that is t=0 for every node (default: now, "
                             "or the hub launcher's for a --host that does not hold the hub)")
    parser.add_argument("--log-dir", metavar="DIR",
                        help="keep node configs and logs in DIR (default: a temp dir, removed unless a node failed)")
    parser.add_argument("--plain", action="store_true", help="plain event lines even on a terminal")
    parser.add_argument("--view", nargs="?", type=port, const=8765, metavar="WS_PORT",
                        help="also serve the system to Foxglove (iotad view) on ws://127.0.0.1:WS_PORT (default 8765)")
    parser.add_argument("--virtual", action="store_true",
                        help="run every node in this process in virtual time (needs --until, in virtual seconds)")
    parser.add_argument("--inputs", metavar="SCRIPT.jsonl",
                        help="with --virtual: input script for external inputs ({\"t\", \"iota\", \"action\", "
                             "\"index\", \"value\"} a line; \"iota\" names the node, or leave it out and "
                             "name an external input as `external` does: {\"action\": \"motor.estop\"})")
    parser.add_argument("--seed", type=seed, default=None, metavar="N",
                        help="with --virtual: fire at random times within each window (policy random(N)); default: "
                             "every action at the earliest time its window allows (eager)")
    parser.add_argument("--policy", metavar="NAME",
                        help="with --virtual: when in its window each action fires: eager (default), latest, "
                             "random or random:SEED (--seed N is random:N); a node's own policy in the system "
                             "file holds for that node (docs/stress.md)")
    parser.add_argument("--goals", action="store_true",
                        help="with --virtual: exit 1 when a goal of the system file's [goals] is missed "
                             "(without it the verdicts are printed, the exit status is the run's)")
    parser.set_defaults(func=run)


def load_checked(path: str):
    """The system, checked; a `CliError` listing every problem otherwise."""
    from iotad.cli import CliError
    from iotad.launcher.system_file import SystemFileError, load_system

    try:
        return load_system(path)
    except SystemFileError as exc:
        raise CliError(str(exc) if len(exc.errors) == 1 else
                       f"{len(exc.errors)} problems in the system file:\n" + str(exc)) from None


def run(args: argparse.Namespace) -> int:
    system = load_checked(args.system_file)
    if args.check:
        inputs = sum(1 for b in system.bindings)
        buses = f", {len(system.buses)} CAN bus(es)" if system.buses else ""
        print(f"{system.file}: ok: system {system.name!r}, {len(system.nodes)} nodes, "
              f"{inputs} channel bindings, {len(system.external)} external inputs{buses}")
        from iotad.launcher.host_access import hub_policy
        from iotad.launcher.host_router import HostRouter

        others = list(dict.fromkeys(n.host for n in system.nodes.values() if n.host and n.host != system.hub_host))
        if others:  # as `access_for` decides for the run
            print(f"access control of {system.name}: on when its hub starts the other hosts through their agents "
                  "over tls/ endpoints with --certs; off with --insecure or --local; tcp/ links, and a --host "
                  "launcher the hub's agent did not start, are refused without --insecure (docs/hosts.md)")
        print("\n".join(hub_policy(system, others).lines()))
        for host in others:  # another host's nodes log in to its router only, with the same rights
            print("\n".join(HostRouter.policy_of(system, host).lines(f"the router of host {host}")))
        return 0
    if args.no_record and args.record_to:
        from iotad.cli import CliError

        # one of the two is a mistake: a run the user expects recorded would leave no file
        raise CliError(f"-o {args.record_to} names the recording, and --no-record says there is none: give one of them")
    if args.virtual:
        from iotad.cli.virtual_run import run_virtual

        if args.max_size is not None or args.max_duration is not None:
            from iotad.cli import CliError

            raise CliError("--max-size and --max-duration split a real-time run's recording, not a --virtual one")

        if args.goals and not system.goals:
            from iotad.cli import CliError

            raise CliError(f"--goals: {system.file} has no [goals] table (docs/stress.md)")
        return run_virtual(system, args)
    for option, value in (("inputs", args.inputs), ("seed", args.seed), ("policy", args.policy),
                          ("goals", args.goals or None)):
        if value is not None:
            from iotad.cli import CliError

            raise CliError(f"--{option} goes with --virtual")
    return launch(system, args)


def defaults(**given) -> argparse.Namespace:
    """`iotad run`'s options as its command line leaves them by default, `given` ones replaced:
    for a command that launches a system of its own (`iotad demo`), so that `launch` reads every
    option it knows without guessing which ones a caller set."""
    parser = argparse.ArgumentParser(add_help=False)
    register(parser.add_subparsers())
    args = parser.parse_args(["run", "SYSTEM.toml"])
    unknown = set(given) - set(vars(args))
    if unknown:
        raise TypeError(f"no such option of 'iotad run': {', '.join(sorted(unknown))}")
    vars(args).update(given)
    return args


def launch(system, args: argparse.Namespace, summary_hook=None) -> int:
    import os
    from pathlib import Path

    from iotad.cli import CliError, claim_recording, drop_empty_claim

    if args.host is not None and args.host not in {n.host for n in system.nodes.values()}:
        hosts = sorted({n.host for n in system.nodes.values() if n.host}) or ["none declared"]
        raise CliError(f"{system.file}: no node has host = {args.host!r} (hosts: {', '.join(hosts)})")
    if args.until is not None and args.until <= 0:
        raise CliError("--until must be a positive number of seconds")
    if args.log_dir:
        log_dir = Path(args.log_dir)
        try:
            log_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise CliError(f"--log-dir {args.log_dir}: cannot create it: {exc.strerror or exc}") from None
        if not os.access(log_dir, os.W_OK):
            raise CliError(f"--log-dir {args.log_dir}: not writable")
    if args.no_record and (args.max_size or args.max_duration):
        raise CliError("--max-size and --max-duration split the recording: not with --no-record")
    if args.record_to and Path(args.record_to).is_dir():
        raise CliError(f"-o {args.record_to}: is a directory; name the .mcap file to write")
    if args.view is not None:
        _view_port_free(args.view)
    record_to = args.record_to
    claimed = None  # the recording's name, created empty here so that no other run takes it
    if record_to and not args.no_record and not args.force and not system.opens_hub(args.host):
        # another host's part: a launcher started again in the same run (its agent came back)
        # records the rest of it beside the first part, never over it; `iotad merge` takes both
        from iotad.launcher.recording_paths import unused_recording_path

        try:
            record_to = claimed = str(unused_recording_path(record_to, claim=True))
        except OSError as exc:
            raise CliError(f"-o {args.record_to}: cannot create it: {exc.strerror or exc}") from None
    elif record_to and not args.no_record:
        if claim_recording(record_to, args.force):
            claimed = record_to
    elif not args.no_record and system.opens_hub(args.host):
        # a new name: recordings/<system>-<date>-<time>.mcap, -2 in the same second (another
        # host's launcher started by hand records only where -o tells it to)
        import time

        from iotad.launcher.recording_paths import unused_recording_path

        stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(args.origin or time.time()))
        try:
            record_to = claimed = str(unused_recording_path(Path("recordings") / f"{system.name}-{stamp}.mcap",
                                                            claim=True))
        except OSError as exc:
            raise CliError(f"cannot create recordings/ here: {exc.strerror or exc}") from None
    try:
        return _launch(system, args, record_to, summary_hook)
    finally:
        drop_empty_claim(claimed)  # the run stopped before its recorder wrote anything


def _launch(system, args: argparse.Namespace, record_to: str | None, summary_hook=None) -> int:
    from iotad.cli import CliError
    from iotad.host.transport import free_port, reachable
    from iotad.launcher.options import LaunchOptions, RecordingOptions
    from iotad.launcher.supervision import Launcher, LauncherError

    if not args.local:
        from iotad.host.zenoh_runtime import use_for

        # before this process's first session, and inherited by its nodes and recorder: a host
        # cut off longer than zenoh's lease must not leave them without a thread to receive on
        use_for(system, args.host or system.hub_host)
    port = args.port
    if port == 0:
        port = free_port()
    _use_certificates(system, args)
    access = access_for(system, args)
    # each other host records its own part, under access control too (its launcher is its nodes'
    # router: iotad/launcher/host_router.py; docs/hosts.md, "The recording")
    fleet, host = _fleet_for(system, args, port, record_to, insecure=not access.enabled)
    launch = LaunchOptions(host=host, port=port, until=args.until, after_live=args.after_live,
                           origin=args.origin, log_dir=args.log_dir, live_table=False if args.plain else None)
    recording = None if args.no_record or record_to is None else RecordingOptions(
        record_to, force=args.force, max_size=args.max_size, max_duration=args.max_duration)
    launcher = Launcher(system, launch, recording, access, fleet=fleet)
    viewer = None
    try:
        if args.view is not None and system.opens_hub(args.host):
            import os

            from iotad.cli.viewer_process import ViewerProcess
            from iotad.host.credentials import ENV

            if launcher.access is not None and launcher.access.tools_file():
                os.environ[ENV] = launcher.access.tools_file()  # the viewer reads with the tools' credentials
            hub = system.listen[0] if port is None else f"tcp/127.0.0.1:{port}"
            viewer = ViewerProcess(reachable(hub), system.name, args.view)
        code = launcher.run()
    except LauncherError as exc:
        raise CliError(str(exc)) from None
    except KeyboardInterrupt:
        launcher.discard()  # Ctrl-C before the launcher's own handling took over: leave nothing behind
        raise
    finally:
        if viewer is not None:
            viewer.stop()
        if launcher.access is not None:
            launcher.access.close()
    where = f" (host {launcher.host}" + (f"; hosts {', '.join(fleet.hosts)} through their agents" if fleet else "") + ")"
    print(f"summary of {system.name}" + (where if launcher.host else "") + ":")
    for line in launcher.summary():
        print(line)
    if fleet is not None and fleet.host_args and launcher.recorder is not None:
        from iotad.launcher.host_recording import host_recording_path

        others = [str(host_recording_path(record_to, host)) for host in fleet.hosts]
        print(f"  each other host recorded its part on its own machine: {', '.join(others)}; "
              f"join them with: iotad merge {record_to} {' '.join(others)} -o MERGED.mcap")
    if summary_hook is not None:
        code = summary_hook(launcher, code)
    if sys.stdout is not None:  # None when the shell closed it (>&-)
        sys.stdout.flush()
    return code


def _use_certificates(system, args: argparse.Namespace) -> None:
    """--certs: this host's certificates, checked now and handed to every process of the run."""
    if not args.certs:
        return
    from iotad.cli import CliError
    from iotad.host.certificates import CertificateError, use

    host = args.host or system.hub_host
    if host is None:
        raise CliError("--certs links the hosts of a system spread over hosts; this system names no host")
    try:
        use(args.certs, host)
    except CertificateError as exc:
        raise CliError(str(exc)) from None


def _fleet_for(system, args: argparse.Namespace, port: int | None, record_to: str | None = None,
               insecure: bool = False):
    """(the agents of the other hosts or None, the host this launcher runs). A system spread over
    hosts, started without --host or --local, runs here as its hub host and everywhere else
    through each host's agent; each of them records its own part beside the hub's recording
    `record_to` (`host_recording_path`: split.mcap -> split.arm.mcap, on that host). `insecure`:
    the run is open (--insecure), and so are the launchers the agents start for it."""
    hosts = [n.host for n in system.nodes.values() if n.host]
    if args.host is not None or args.local or not hosts:
        return None, args.host
    from iotad.host.transport import reachable
    from iotad.launcher.fleet import Fleet
    from iotad.launcher.system_file import with_port

    hub = [reachable(e) for e in (with_port(system.listen, port) if port is not None else system.listen)]
    others = sorted(set(hosts) - {system.hub_host}, key=hosts.index)
    agent_args = (["--no-record"] if record_to is None else []) + (["--port", str(port)] if port is not None else []) \
        + (["--insecure"] if insecure else [])
    host_args = {}
    if record_to is not None:
        from iotad.launcher.host_recording import host_recording_path

        split = (["--max-size", str(args.max_size)] if args.max_size is not None else []) \
            + (["--max-duration", repr(float(args.max_duration))] if args.max_duration is not None else [])
        host_args = {host: ["-o", str(host_recording_path(record_to, host)), *(["--force"] if args.force else []), *split]
                     for host in others}
    fleet = Fleet(system.path, others, hub, agent_args, host_args=host_args,
                  start_timeout=args.agent_timeout or system.start_timeout)
    return fleet, system.hub_host


def _view_port_free(port: int) -> None:
    """--view's port, refused before anything starts when another program holds it (the viewer
    would fail alone, after the run had started, and the run would go on without it)."""
    import socket

    from iotad.cli import CliError

    with socket.socket() as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the server binds: not refused for TIME_WAIT
        try:
            probe.bind(("127.0.0.1", port))
        except OSError as exc:
            raise CliError(f"--view {port}: cannot serve there: {exc.strerror or exc} (another 'iotad view'?); "
                           "choose another port") from None


def access_for(system, args: argparse.Namespace):
    """Access control for this run (docs/access-control.md): on unless --insecure. A system spread
    over hosts has it when the hub starts the other hosts through their agents over TLS (the hub
    hands each agent its host's credentials) and on each host's launcher its agent starts. Where
    no one could hand the other launchers their credentials (tcp/ links, no --certs, a launcher
    started by hand with --host), the run is refused unless --insecure says to run it open: a
    system on a network is secured by default, not by remembering a flag."""
    import os

    from iotad.cli import CliError
    from iotad.host.agent_secret import derive
    from iotad.host.certificates import ENV_DIR, CertificateError
    from iotad.host.credentials import ENV, CredentialsError, load
    from iotad.launcher.host_access import launcher_user
    from iotad.launcher.options import AccessOptions

    if args.insecure:
        return AccessOptions.off("--insecure")
    hosts = [node.host for node in system.nodes.values() if node.host]
    if not hosts:
        return AccessOptions()
    if args.host is not None:
        given = os.environ.get(ENV)
        try:
            own = load(given) if given else None
        except CredentialsError as exc:
            raise CliError(str(exc)) from None
        if own is not None and own.user == launcher_user(args.host):
            return AccessOptions(given=given)  # started by this host's agent, for the hub's run
        raise CliError(f"--host {args.host}: no credentials from the hub, so this host's nodes would run without "
                       "access control: start this host through its agent ('iotad agent', started by the hub's "
                       "'iotad run'; docs/hosts.md), or give --insecure here and to the hub's launcher to run "
                       "the system open")
    if args.local:
        return AccessOptions.off("--local")
    certs = args.certs or os.environ.get(ENV_DIR)
    plain = [endpoint for endpoint in system.listen if not endpoint.startswith(("tls/", "quic/"))]
    if not certs or plain:
        how = f"listens on {', '.join(plain)}" if plain else "has no --certs DIR"
        raise CliError(f"{system.name} spreads over hosts and its hub {how}: its agents could be neither admitted "
                       "nor sent their credentials safely, so access control would be off. Link the hosts by "
                       "tls/ endpoints and give --certs DIR ('iotad certs'; docs/hosts.md), run every host "
                       "here with --local, or give --insecure to run the system open")
    others = list(dict.fromkeys(host for host in hosts if host != system.hub_host))
    try:
        for host in others:
            derive(certs, host)  # every agent's secret, or one line saying which is missing
    except CertificateError as exc:
        raise CliError(str(exc)) from None
    return AccessOptions(hosts=tuple(others), certs=str(certs))
