"""Running a system under access control: the hub's zenoh options (user-password authentication
plus the `access_control` rules derived by `iotad.launcher.access.access_policy`), each child's
credentials, and the lines the launcher shows about it. `AccessControl.off(why)` is the same
object for a run without it (`iotad run --insecure`), which only warns."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from iotad.machine import agent_secret
from iotad.machine.agent_secret import agent_user
from iotad.node_host.credentials import ENV, Credentials, CredentialStore, GivenCredentials, load
from iotad.launcher.access.access_policy import RECORDER_USER, TOOLS_USER, Policy, derive, node_user
from iotad.launcher.access.host_access import (FLEET_USER, across_hosts_settings, host_users, hub_policy, launcher_user, router_zid,
                                        zenoh_mode)
from iotad.launcher.options import AccessOptions
from iotad.launcher.access.ros2_peers import peer_grants
from iotad.launcher.system.system_file import System


class AccessControl:
    def __init__(self, system: System, enabled: bool = True, why_off: str = "", hosts: tuple[str, ...] = (),
                 certs: str | None = None, given: str | None = None):
        """`hosts`: the other hosts of a system spread over hosts, whose agents and launchers become
        users too (their agents' passwords derived from the authority in `certs`). `given`: this
        launcher runs one host's part, with the credentials file its agent received for it (its
        launcher user's alone: its router makes its nodes' and recorder's, `route`)."""
        self.enabled, self.why_off, self.system = enabled, why_off, system
        self.policy: Policy | None = derive(system) if enabled else None
        self.store: CredentialStore | None = None
        self.own: Credentials | None = None  # a host's launcher: its own, from its agent
        self.router = None  # a host's launcher: the router of its nodes (iotad/launcher/access/host_router.py)
        self.hosts = tuple(hosts)
        if self.policy is None:
            return
        if given is not None:
            self.store = GivenCredentials(Path(given).parent)
            self.own = load(given)
            return
        # only who logs in here: the other hosts' nodes log in to their own host's router
        self.policy = hub_policy(system, list(hosts))
        agents = {agent_user(host): agent_secret.derive(certs, host) for host in hosts}
        # the ROS 2 machines that `iotad certs ros2` admitted in `certs`, with the [[ros2]] tables' rights
        peers, peer_passwords = peer_grants(system, certs)
        self.policy.grants += peers
        # the tools' file says where they may publish: `iotad pub` refuses the rest itself
        self.store = CredentialStore(self.policy.users(), passwords={**agents, **peer_passwords},
                                     may_publish={TOOLS_USER: self.policy.grant(TOOLS_USER).publish})

    @classmethod
    def of(cls, system: System, options: AccessOptions) -> "AccessControl":
        return cls(system, options.enabled, options.why_off, options.hosts, options.certs, options.given)

    @classmethod
    def off(cls, system: System, why: str) -> "AccessControl":
        return cls(system, enabled=False, why_off=why)

    def route(self, host: str) -> str:
        """Another host's launcher: its session becomes the router of `host`'s nodes and recorder
        (iotad/launcher/access/host_router.py); where they reach it."""
        from iotad.launcher.access.host_router import HostRouter

        self.router = HostRouter(self.system, host, self.own)
        return self.router.endpoint

    def hub_options(self) -> dict[str, Any]:
        """Keyword arguments of `transport.open_session` for the launcher's session: the hub's, or
        for another host's launcher the router's of its host (`route`), linked to the hub as its
        own user, or without a router that user's (a client of the hub, listening nowhere)."""
        if self.store is None:
            return {"credentials": False}
        if self.router is not None:
            return self.router.session_options()
        if self.own is not None:
            return {"credentials": self.own}
        # a router where it relays between two hosts' routers or more (`zenoh_mode`), else a peer;
        # what it forwards to another host's router goes with DROP: one cut host must not hold the
        # hub's receive tasks (`host_access.across_hosts_settings`)
        zids = [router_zid(self.store.credentials(launcher_user(host)).password) for host in self.hosts]
        return {"credentials": self.store.hub(),
                "extra": {"access_control": self.policy.acl(), **across_hosts_settings(zids)},
                "mode": zenoh_mode(self.system)}

    def host_part(self, host: str) -> dict[str, str]:
        """The credentials `host`'s agent receives (user: password): its launcher's, which its
        router shows the hub; the router makes its nodes' passwords itself."""
        if self.store is None or self.own is not None:
            return {}
        return {user: self.store.credentials(user).password for user in host_users(self.system, host)}

    def fleet_credentials(self) -> Credentials | bool:
        """The hub launcher's session with the agents: its own user, or none without access control."""
        return False if self.store is None or self.own is not None else self.store.credentials(FLEET_USER)

    def env_for(self, user: str) -> dict[str, str] | None:
        """A child's environment: the launcher's plus where its credentials are (on another host,
        those its router made). In an open run, set but empty: none, and no looking for the ones
        another run advertised for the same port (a run in another network namespace, or one
        killed before it took its pointer back), which an open hub would refuse."""
        if self.store is None:
            return {**os.environ, ENV: ""}
        store = self.router.store if self.router is not None else self.store
        return {**os.environ, ENV: str(store.file_of(user))}

    def node_env(self, path: str) -> dict[str, str] | None:
        return self.env_for(node_user(path))

    def recorder_env(self) -> dict[str, str] | None:
        return self.env_for(RECORDER_USER)

    def tools_file(self) -> str | None:
        return str(self.store.file_of(TOOLS_USER)) if self.store else None

    def opened(self, hub: list[str]) -> list[str]:
        """The hub listens: let this user's tools find their credentials; lines for the status view."""
        if self.store is None:
            return [f"warning: access control is OFF ({self.why_off}): any process that reaches the hub may "
                    "publish on any key, motor commands included"]
        self.store.advertise(hub, TOOLS_USER)
        users = len(self.policy.grants)
        peers = [g.user for g in self.policy.grants if g.role == "ROS 2 peer"]  # iotad/launcher/access/ros2_peers.py
        return [f"access control: on ({users} users, default deny; credentials in {self.store.folder}, "
                f"removed at the end; 'iotad run --check' prints the policy)"] + \
            ([f"ROS 2 machines admitted: {', '.join(peers)} (their [[ros2]] topics only)"] if peers else [])

    def summary_lines(self) -> list[str]:
        if self.store is None:
            return [f"  access control: OFF ({self.why_off})"]
        # zenoh 1.10 keeps no count of the messages its access control refuses: it only writes a
        # TRACE log line per decision (allowed ones too), which the Python API does not expose.
        return ["  access control: on; refused publications: not counted (zenoh 1.10 does not expose "
                "them; see docs/access-control.md)"]

    def close(self) -> None:
        if self.router is not None:
            self.router.close()
        if self.store is not None:
            self.store.remove()


__all__ = ["AccessControl"]
