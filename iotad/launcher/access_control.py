"""Running a system under access control: the hub's zenoh options (user-password authentication
plus the `access_control` rules derived by `iotad.launcher.access_policy`), each child's
credentials, and the lines the launcher shows about it. `AccessControl.off(why)` is the same
object for a run without it (`iotad run --insecure`), which only warns."""
from __future__ import annotations

import os
from typing import Any

from iotad.host.credentials import ENV, CredentialStore
from iotad.launcher.access_policy import RECORDER_USER, TOOLS_USER, Policy, derive, node_user
from iotad.launcher.system_file import System


class AccessControl:
    def __init__(self, system: System, enabled: bool = True, why_off: str = ""):
        self.enabled, self.why_off = enabled, why_off
        self.policy: Policy | None = derive(system) if enabled else None
        self.store: CredentialStore | None = None
        if self.policy is not None:
            # the tools' file says where they may publish: `iotad pub` refuses the rest itself
            self.store = CredentialStore(self.policy.users(),
                                         may_publish={TOOLS_USER: self.policy.grant(TOOLS_USER).publish})

    @classmethod
    def off(cls, system: System, why: str) -> "AccessControl":
        return cls(system, enabled=False, why_off=why)

    def hub_options(self) -> dict[str, Any]:
        """Keyword arguments of `transport.open_session` for the hub's session."""
        if self.store is None:
            return {"credentials": False}
        return {"credentials": self.store.hub(), "extra": {"access_control": self.policy.acl()}}

    def env_for(self, user: str) -> dict[str, str] | None:
        """A child's environment: the launcher's plus where its credentials are."""
        if self.store is None:
            return None
        return {**os.environ, ENV: str(self.store.file_of(user))}

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
        return [f"access control: on ({users} users, default deny; credentials in {self.store.folder}, "
                f"removed at the end; 'iotad run --check' prints the policy)"]

    def summary_lines(self) -> list[str]:
        if self.store is None:
            return [f"  access control: OFF ({self.why_off})"]
        # zenoh 1.10 keeps no count of the messages its access control refuses: it only writes a
        # TRACE log line per decision (allowed ones too), which the Python API does not expose.
        return ["  access control: on; refused publications: not counted (zenoh 1.10 does not expose "
                "them; see docs/access-control.md)"]

    def close(self) -> None:
        if self.store is not None:
            self.store.remove()


__all__ = ["AccessControl"]
