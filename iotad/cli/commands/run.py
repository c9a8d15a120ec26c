"""`iotad run SYSTEM.toml`: check a system file, then run each IOTA as its own process around a
zenoh hub, supervise them (restarts, liveliness, heartbeats), record, and stop them all on Ctrl-C.
With --virtual, run every IOTA of the same file in this one process in virtual time instead."""
from __future__ import annotations

import argparse
import sys

from iotad.cli import byte_size, load_checked, port, positive_float, seed

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
    parser.add_argument("--format", type=int, choices=(1, 2), default=2, dest="recording_format",
                        help="with --virtual: the recording's format; 2 (default) records each CAN bus's frames "
                             "in bursts, 1 as an event per frame and receiver (iotad.can.virtual_bus.CanBus)")
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
    parser.add_argument("--strict", action="store_true",
                        help="end the run non-zero (exit 1) on any violation (a node's exception included) or a "
                             "node that never went live, as [system] strict = true does")
    parser.add_argument("--policy", metavar="NAME",
                        help="with --virtual: when in its window each action fires: eager (default), latest, "
                             "random or random:SEED (--seed N is random:N); a node's own policy in the system "
                             "file holds for that node (docs/stress.md)")
    parser.add_argument("--goals", action="store_true",
                        help="with --virtual: exit 1 when a goal of the system file's [goals] is missed "
                             "(without it the verdicts are printed, the exit status is the run's)")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    system = load_checked(args.system_file)  # iotad.cli's: the check's errors, one block
    if args.check:
        inputs = sum(1 for b in system.bindings)
        buses = f", {len(system.buses)} CAN bus(es)" if system.buses else ""
        print(f"{system.file}: ok: system {system.name!r}, {len(system.nodes)} nodes, "
              f"{inputs} channel bindings, {len(system.external)} external inputs{buses}")
        from iotad.launcher.access.host_access import hub_policy
        from iotad.launcher.access.host_router import HostRouter

        others = list(dict.fromkeys(n.host for n in system.nodes.values() if n.host and n.host != system.hub_host))
        if others:  # as `launcher.access.decision` decides for the run
            print(f"access control of {system.name}: on when its hub starts the other hosts through their agents "
                  "over tls/ endpoints with --certs; off with --insecure or --local; tcp/ links, and a --host "
                  "launcher the hub's agent did not start, are refused without --insecure (docs/hosts.md)")
        from iotad.launcher.access.ros2_peers import grants_for

        policy = hub_policy(system, others)
        policy.grants += grants_for(system, args.certs)  # the ROS 2 machines 'iotad certs ros2' made there
        print("\n".join(policy.lines()))
        for host in others:  # another host's nodes log in to its router only, with the same rights
            print("\n".join(HostRouter.policy_of(system, host).lines(f"the router of host {host}")))
        return 0
    if args.no_record and args.record_to:
        from iotad.cli import CliError

        # one of the two is a mistake: a run the user expects recorded would leave no file
        raise CliError(f"-o {args.record_to} names the recording, and --no-record says there is none: give one of them")
    if args.virtual:
        return virtual(system, args)
    for option, value in (("inputs", args.inputs), ("seed", args.seed), ("policy", args.policy),
                          ("goals", args.goals or None)):
        if value is not None:
            from iotad.cli import CliError

            raise CliError(f"--{option} goes with --virtual")
    return launch(system, args)


def virtual(system, args: argparse.Namespace) -> int:
    """`--virtual`: the library's `run_virtual`, its errors as one line."""
    from iotad.cli import CliError
    from iotad.virtual.virtual_run import VirtualOptions, VirtualRunError, run_virtual

    if args.max_size is not None or args.max_duration is not None:
        raise CliError("--max-size and --max-duration split a real-time run's recording, not a --virtual one")
    if args.until is None:
        raise CliError("--virtual needs --until SECONDS (virtual time; the run is as fast as the machine allows)")
    for option in ("host", "port", "origin", "log_dir"):
        if getattr(args, option) is not None:
            raise CliError(f"--{option.replace('_', '-')} is for processes over zenoh, not --virtual")
    if args.goals and not system.goals:
        raise CliError(f"--goals: {system.file} has no [goals] table (docs/stress.md)")
    options = VirtualOptions(until=args.until, seed=args.seed, record_to=args.record_to, force=args.force,
                             no_record=args.no_record, inputs=args.inputs, plain=args.plain,
                             strict=args.strict, recording_format=args.recording_format,
                             policy=args.policy, goals=args.goals)
    try:
        return run_virtual(system, options)
    except VirtualRunError as exc:
        raise CliError(str(exc)) from None


def options_of(args: argparse.Namespace):
    """The library's options of a real-time run, from `iotad run`'s command line."""
    from iotad.launcher.options import RunOptions

    return RunOptions(host=args.host, port=args.port, until=args.until, after_live=args.after_live, origin=args.origin,
                      log_dir=args.log_dir, plain=args.plain, record_to=args.record_to, no_record=args.no_record,
                      force=args.force, max_size=args.max_size, max_duration=args.max_duration, local=args.local,
                      certs=args.certs, agent_timeout=args.agent_timeout, insecure=args.insecure,
                      strict=args.strict)


def launch(system, args: argparse.Namespace) -> int:
    """Run `system` in real time as `args` say (the library's `run_real_time`); errors as one line."""
    from iotad.cli import CliError
    from iotad.launcher.run.run_system import RunError, run_real_time

    if args.view is not None:
        _view_port_free(args.view)
    view = None
    if args.view is not None:
        def view(launcher, hub: str):
            import os

            from iotad.cli.viewer_process import ViewerProcess
            from iotad.node_host.credentials import ENV

            if launcher.access is not None and launcher.access.tools_file():
                os.environ[ENV] = launcher.access.tools_file()  # the viewer reads with the tools' credentials
            return ViewerProcess(hub, system.name, args.view)
    try:
        return run_real_time(system, options_of(args), view=view)
    except RunError as exc:
        raise CliError(str(exc)) from None


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
