"""Whether a run is under access control, and how (docs/access-control.md): decided from the
checked system and the run's options (`RunOptions`), before anything starts. Raises
`AccessRefused`, one line, for a run that would be open without being asked to be."""
from __future__ import annotations

import os

from iotad.launcher.options import AccessOptions, RunOptions
from iotad.launcher.system.system_file import System


class AccessRefused(Exception):
    """A run refused by its access control before it starts, said in one line."""


def access_for(system: System, options: RunOptions):
    """Access control for this run (docs/access-control.md): on unless --insecure. A system spread
    over hosts has it when the hub starts the other hosts through their agents over TLS (the hub
    hands each agent its host's credentials) and on each host's launcher its agent starts. Where
    no one could hand the other launchers their credentials (tcp/ links, no --certs, a launcher
    started by hand with --host), the run is refused unless --insecure says to run it open: a
    system on a network is secured by default, not by remembering a flag."""
    from iotad.machine.agent_secret import derive
    from iotad.machine.certificates import ENV_DIR, CertificateError
    from iotad.node_host.credentials import ENV, CredentialsError, load
    from iotad.launcher.fleet_wire import launcher_user

    if options.insecure:
        return AccessOptions.off("--insecure")
    hosts = [node.host for node in system.nodes.values() if node.host]
    if not hosts:  # --certs: the ROS 2 peers 'iotad certs ros2' made there log in too (docs/ros2.md)
        from iotad.launcher.access.ros2_peers import peer_grants
        try:
            peer_grants(system, options.certs)  # their passwords, or one line saying what is missing
        except CertificateError as exc:
            raise AccessRefused(str(exc)) from None
        return AccessOptions(certs=options.certs or None)
    if options.host is not None:
        given = os.environ.get(ENV)
        try:
            own = load(given) if given else None
        except CredentialsError as exc:
            raise AccessRefused(str(exc)) from None
        if own is not None and own.user == launcher_user(options.host):
            return AccessOptions(given=given)  # started by this host's agent, for the hub's run
        raise AccessRefused(f"--host {options.host}: no credentials from the hub, so this host's nodes would run without "
                       "access control: start this host through its agent ('iotad agent', started by the hub's "
                       "'iotad run'; docs/hosts.md), or give --insecure here and to the hub's launcher to run "
                       "the system open")
    if options.local:
        return AccessOptions.off("--local")
    certs = options.certs or os.environ.get(ENV_DIR)
    plain = [endpoint for endpoint in system.listen if not endpoint.startswith(("tls/", "quic/"))]
    if not certs or plain:
        how = f"listens on {', '.join(plain)}" if plain else "has no --certs DIR"
        raise AccessRefused(f"{system.name} spreads over hosts and its hub {how}: its agents could be neither admitted "
                       "nor sent their credentials safely, so access control would be off. Link the hosts by "
                       "tls/ endpoints and give --certs DIR ('iotad certs'; docs/hosts.md), run every host "
                       "here with --local, or give --insecure to run the system open")
    others = list(dict.fromkeys(host for host in hosts if host != system.hub_host))
    try:
        for host in others:
            derive(certs, host)  # every agent's secret, or one line saying which is missing
    except CertificateError as exc:
        raise AccessRefused(str(exc)) from None
    return AccessOptions(hosts=tuple(others), certs=str(certs))
