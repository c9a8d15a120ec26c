"""A system run in real time, as the library does it: with its options (`options.RunOptions`:
what `iotad run` parses, and what the hub's run orders each other host's agent to run), the
access control `access.decision` decides for it, the other hosts' agents it starts (`Fleet`), the
recording's name it claims, and the launcher it runs. Raises `RunError`, one line for the user;
the CLI only prints it."""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path
from typing import Any, Callable

from iotad.launcher.options import RunOptions
from iotad.launcher.system.system_file import System, with_port


class RunError(Exception):
    """A run that cannot start (or go on) as asked, said in one line."""


def run_real_time(system: System, options: RunOptions, *, view: Callable[[Any, str], Any] | None = None,
                  summary_hook: Callable[[Any, int], int] | None = None) -> int:
    """Run `system` (checked) as `options` say until it ends; its exit status (0: every node
    stopped cleanly). `view(launcher, hub)`: started once the launcher is built, on the hub's
    host, and stopped (`.stop()`) after the run; `summary_hook(launcher, code)` may change the status."""
    from iotad.launcher.run.recording_paths import RecordingClaimError, claim_recording, drop_empty_claim

    if options.host is not None and options.host not in {n.host for n in system.nodes.values()}:
        hosts = sorted({n.host for n in system.nodes.values() if n.host}) or ["none declared"]
        raise RunError(f"{system.file}: no node has host = {options.host!r} (hosts: {', '.join(hosts)})")
    if options.until is not None and options.until <= 0:
        raise RunError("--until must be a positive number of seconds")
    if options.log_dir:
        log_dir = Path(options.log_dir)
        try:
            log_dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise RunError(f"--log-dir {options.log_dir}: cannot create it: {exc.strerror or exc}") from None
        if not os.access(log_dir, os.W_OK):
            raise RunError(f"--log-dir {options.log_dir}: not writable")
    if options.no_record and (options.max_size or options.max_duration):
        raise RunError("--max-size and --max-duration split the recording: not with --no-record")
    if options.record_to and Path(options.record_to).is_dir():
        raise RunError(f"-o {options.record_to}: is a directory; name the .mcap file to write")
    record_to = options.record_to
    claimed = None  # the recording's name, created empty here so that no other run takes it
    if record_to and not options.no_record and not options.force and not system.opens_hub(options.host):
        # another host's part: a launcher started again in the same run (its agent came back)
        # records the rest of it beside the first part, never over it; `iotad merge` takes both
        from iotad.launcher.run.recording_paths import unused_recording_path

        try:
            record_to = claimed = str(unused_recording_path(record_to, claim=True))
        except OSError as exc:
            raise RunError(f"-o {options.record_to}: cannot create it: {exc.strerror or exc}") from None
    elif record_to and not options.no_record:
        try:
            if claim_recording(record_to, options.force):
                claimed = record_to
        except RecordingClaimError as exc:
            raise RunError(str(exc)) from None
    elif not options.no_record and system.opens_hub(options.host):
        # a new name: recordings/<system>-<date>-<time>.mcap, -2 in the same second (another
        # host's launcher started by hand records only where -o tells it to)
        from iotad.launcher.run.recording_paths import unused_recording_path

        stamp = time.strftime("%Y%m%d-%H%M%S", time.localtime(options.origin or time.time()))
        try:
            record_to = claimed = str(unused_recording_path(Path("recordings") / f"{system.name}-{stamp}.mcap",
                                                            claim=True))
        except OSError as exc:
            raise RunError(f"cannot create recordings/ here: {exc.strerror or exc}") from None
    try:
        return _launch(system, options, record_to, view, summary_hook)
    finally:
        drop_empty_claim(claimed)  # the run stopped before its recorder wrote anything


def _launch(system: System, options: RunOptions, record_to: str | None, view, summary_hook) -> int:
    from iotad.node_host.transport import free_port, reachable
    from iotad.launcher.options import LaunchOptions, RecordingOptions
    from iotad.launcher.run.supervision import Launcher, LauncherError

    home = system.hosts_keeping_traces()
    if (options.strict or system.strict) and home and system.opens_hub(options.host):
        # a strict run's verdict counts the violations the hub hears on the nodes' traces
        keeps = "keeps its" if len(home) == 1 else "keep their"
        raise RunError(f"a strict run judges every node's violations at the hub, but {', '.join(home)} {keeps} "
                       "traces home ([hosts.NAME] traces = \"home\"): run it without strict, or judge it after "
                       "the run with iotad merge and iotad check")

    if not options.local:
        from iotad.node_host.zenoh_runtime import use_for

        # before this process's first session, and inherited by its nodes and recorder: a host
        # cut off longer than zenoh's lease must not leave them without a thread to receive on
        use_for(system, options.host or system.hub_host)
    port = options.port
    if port == 0:
        port = free_port()
    _use_certificates(system, options)
    from iotad.launcher.access.decision import AccessRefused, access_for

    try:
        access = access_for(system, options)
    except AccessRefused as exc:
        raise RunError(str(exc)) from None
    # each other host records its own part, under access control too (its launcher is its nodes'
    # router: iotad/launcher/access/host_router.py; docs/hosts.md, "The recording")
    fleet, host = fleet_for(system, options, port, record_to, insecure=not access.enabled)
    launch = LaunchOptions(host=host, port=port, until=options.until, after_live=options.after_live,
                           origin=options.origin, log_dir=options.log_dir, live_table=False if options.plain else None)
    recording = None if options.no_record or record_to is None else RecordingOptions(
        record_to, force=options.force, max_size=options.max_size, max_duration=options.max_duration)
    launcher = Launcher(system, launch, recording, access, fleet=fleet)
    viewer = None
    try:
        if view is not None and system.opens_hub(options.host):
            hub = system.listen[0] if port is None else f"tcp/127.0.0.1:{port}"
            viewer = view(launcher, reachable(hub))
        code = launcher.run()
    except LauncherError as exc:
        raise RunError(str(exc)) from None
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
    if fleet is not None and fleet.host_orders and recording is not None:
        from iotad.launcher.hosts.host_recording import host_files, join_command

        # every file written: the hub's parts (a restarted recorder goes on in split_1.mcap...),
        # and each host's, with the files its launcher said its restarted recorders went on in
        heard = launcher.nodes.host_files if launcher.nodes is not None else {}
        others = {host: host_files(record_to, host, heard.get(host)) for host in fleet.hosts}
        hub_files = (launcher.recorder.recordings if launcher.recorder is not None else []) or [record_to]
        print(f"  each other host recorded its part on its own machine: "
              f"{', '.join(str(f) for files in others.values() for f in files)}; "
              f"join them with: {join_command(hub_files, others)}")
    if summary_hook is not None:
        code = summary_hook(launcher, code)
    if options.strict or system.strict:
        from iotad.launcher.strict_verdict import strict_failures

        failures = strict_failures(sum(launcher.tally.violations.values()),
                                   [r.name for r in launcher.runs.values() if not r.went_live])
        for line in failures:
            print(f"  strict: {line}")
        code = code or (1 if failures else 0)
    if sys.stdout is not None:  # None when the shell closed it (>&-)
        sys.stdout.flush()
    return code


def _use_certificates(system: System, options: RunOptions) -> None:
    """--certs: this host's certificates, checked now and handed to every process of the run."""
    if not options.certs:
        return
    from iotad.machine.certificates import CertificateError, use

    # a system on one machine whose hub listens on tls/ for ROS 2 machines (docs/ros2.md) shows
    # the certificate of host "hub" ('iotad certs host hub')
    host = options.host or system.hub_host or "hub"
    try:
        use(options.certs, host)
    except CertificateError as exc:
        raise RunError(str(exc)) from None


def fleet_for(system: System, options: RunOptions, port: int | None, record_to: str | None = None,
              insecure: bool = False):
    """(the agents of the other hosts or None, the host this launcher runs). A system spread over
    hosts, started without --host or --local, runs here as its hub host and everywhere else
    through each host's agent; each of them records its own part beside the hub's recording
    `record_to` (`host_recording_path`: split.mcap -> split.arm.mcap, on that host). `insecure`:
    the run is open (--insecure), and so are the launchers the agents start for it."""
    hosts = [n.host for n in system.nodes.values() if n.host]
    if options.host is not None or options.local or not hosts:
        return None, options.host
    from iotad.node_host.transport import reachable
    from iotad.launcher.hosts.fleet import Fleet

    hub = [reachable(e) for e in (with_port(system.listen, port) if port is not None else system.listen)]
    others = sorted(set(hosts) - {system.hub_host}, key=hosts.index)
    orders = {}
    for host in others:  # what each host's agent runs: its part, recorded on its own machine
        recorded = {}
        if record_to is not None:
            from iotad.launcher.hosts.host_recording import host_recording_path

            recorded = dict(record_to=str(host_recording_path(record_to, host)), force=options.force,
                            max_size=options.max_size, max_duration=options.max_duration)
        orders[host] = RunOptions(host=host, plain=True, no_record=record_to is None, port=port,
                                  insecure=insecure, **recorded)
    fleet = Fleet(system, others, hub, orders, start_timeout=options.agent_timeout or system.start_timeout)
    return fleet, system.hub_host
