"""The zenoh router of one host of a run under access control that is not the hub's: the host's
launcher session, listening only on a unix socket in a private folder (0700), checks its own
nodes and recorder against the same credentials and rights as the hub, and is linked to the hub
over TLS as the host's launcher user (docs/hosts.md, "The recording").

Why: the host's nodes and recorder are its clients, so while the link to the hub is cut they
still reach each other and the recorder hears everything they do. The hub sees the router's
link as the launcher user, whose grant holds what the host's nodes may do and nothing more
(`iotad.launcher.access.host_access`); the host's recorder may read every key here, but the hub denies
its wider subscriptions, so only what the host's nodes read crosses the link.

Measured with zenoh 1.10 (two sessions, a unix socket and a TLS link): one `transport/auth/usrpwd`
section with `user`, `password` and `dictionary_file` authenticates the router's own link to the
hub and checks the clients that connect to it; the hub enforces the launcher user's rules on
everything relayed over that link; and on the router the link to the hub needs a subject of its
own (its certificate's common name, the hub host's name): without one the router's default deny
drops everything in both directions."""
from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

from iotad.node_host.credentials import Credentials, CredentialStore
from iotad.launcher.access.access_policy import RECORDER_USER, Grant, Policy, derive
from iotad.launcher.access.host_access import across_hosts_settings, launcher_grant, router_zid, routed_users, zenoh_mode
from iotad.launcher.system.system_file import System

# every kind of message a link carries: the hub's own access control judges them
_EVERY_MESSAGE = ["put", "delete", "declare_subscriber", "declare_queryable", "query", "reply",
                  "liveliness_token", "declare_liveliness_subscriber", "liveliness_query"]
SOCKET = "router.sock"
# No gossip from or to the router: a zenoh peer gossips its listeners' locators, and the hub passes
# them on, so every other host's router learnt this host's unix socket and tried to link to it
# directly (measured with zenoh 1.10: in vain across machines, and on one file system refused for
# want of credentials). The router's one link, to the hub, is in its `connect` endpoints, and
# nothing else is meant to reach the socket but this host's own clients.
NO_GOSSIP = {"scouting/gossip/enabled": False}


class HostRouter:
    """Credentials and rules of host `host`'s router: a user for each of the host's nodes and one
    for its recorder, with passwords made here, on the host. The hub never learns them (its
    `dictionary.txt` does not hold these users), so none of them opens a session with the hub;
    `own` (the launcher user the agent received) is what the router shows the hub."""

    def __init__(self, system: System, host: str, own: Credentials):
        self.system, self.host, self.own = system, host, own
        # a private folder (0700) that also holds the socket, whose path may be 107 bytes at most
        parent = tempfile.gettempdir() if len(tempfile.gettempdir()) < 60 else "/tmp"
        self.store = CredentialStore([*routed_users(system, host), RECORDER_USER], parent=parent)
        self.endpoint = f"unixsock-stream/{Path(self.store.folder) / SOCKET}"

    @staticmethod
    def policy_of(system: System, host: str) -> Policy:
        """The host's nodes' grants, exactly as the hub's would be, and the recorder's."""
        users = {*routed_users(system, host), RECORDER_USER}
        return Policy(system.name, [grant for grant in derive(system).grants if grant.user in users])

    def policy(self) -> Policy:
        return self.policy_of(self.system, self.host)

    def acl(self) -> dict[str, Any]:
        """zenoh's `access_control` for the router: the policy for its local clients, and for the
        link to the hub (the certificate the hub shows, named for the hub's host) every key any of
        them may use, whatever the message: the hub judges what crosses it."""
        policy = self.policy()
        keys = sorted({key for grant in [*policy.grants, launcher_grant(self.system, self.host)] for key in _keys(grant)})
        acl = policy.acl()
        acl["rules"].append({"id": "hub-link", "permission": "allow", "flows": ["ingress", "egress"],
                             "messages": list(_EVERY_MESSAGE), "key_exprs": keys})
        acl["subjects"].append({"id": "hub", "cert_common_names": [self.system.hub_host]})
        acl["policies"].append({"id": "hub", "rules": ["hub-link"], "subjects": ["hub"]})
        return acl

    def session_options(self) -> dict[str, Any]:
        """Keyword arguments of `transport.open_session` for the launcher's session as the router."""
        credentials = Credentials(self.own.user, self.own.password, str(self.store.dictionary))
        # a router, as the hub is, where the hub relays between hosts' routers (`zenoh_mode`); its
        # id is the one the hub knows it by, and what it forwards to the hub goes with DROP, so that
        # a cut link to the hub never holds the receive tasks of this host's own nodes' links, and
        # its recorder goes on hearing them (`host_access.across_hosts_settings`)
        extra = {"access_control": self.acl(), **NO_GOSSIP, "id": router_zid(self.own.password),
                 **across_hosts_settings()}
        return {"credentials": credentials, "extra": extra, "mode": zenoh_mode(self.system)}

    def close(self) -> None:
        self.store.remove()


def _keys(grant: Grant) -> list[str]:
    return [*grant.publish, *grant.subscribe, *grant.serve, *grant.ask, *grant.tokens, *grant.watch, *grant.declarations]


__all__ = ["HostRouter"]
