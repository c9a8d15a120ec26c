"""The hub's side of a system spread over hosts: `iotad run SYSTEM.toml` on the hub's machine asks
the agent of every other host (`iotad agent`, iotad/launcher/agent.py) to run that host's part,
relays their lines, notices an agent that disappears, and stops them all at the end.

It talks to the agents through its own client session of the hub, so it starts once the hub
listens and needs nothing from the launcher but the hub's endpoint."""
from __future__ import annotations

import json
import threading
import time
from pathlib import Path
from typing import Callable

from iotad.launcher.agent import AGENT_PREFIX, agent_key, digest


class FleetError(Exception):
    """A host whose agent did not answer or refused its part: the run cannot start whole."""


class Fleet:
    """The agents of `hosts`, each given `args` (the launcher's options) and the system file."""

    def __init__(self, system_path: str | Path, hosts: list[str], hub: list[str], args: list[str], *,
                 tls=None, env: dict[str, str] | None = None, say: Callable[[str], None] = print,
                 start_timeout: float = 30.0, host_args: dict[str, list[str]] | None = None):
        self.path = Path(system_path).resolve()
        self.text = self.path.read_text(encoding="utf-8")
        self.hosts, self.hub, self.args, self.tls = list(hosts), list(hub), list(args), tls
        self.host_args = {host: list(extra) for host, extra in (host_args or {}).items()}  # one host's own (its recording)
        self.env, self.say, self.start_timeout = dict(env or {}), say, start_timeout
        self.session = None
        self.exits: dict[str, int] = {}
        self.lost: list[str] = []
        self._asked_to_stop: set[str] = set()  # a host that exits after this was stopped, not failed
        self._present: set[str] = set()
        self._started: set[str] = set()
        self._changed = threading.Condition()
        self._declared: list = []

    def start(self, access=None) -> None:
        """Wait for every host's agent (up to `start_timeout`) and give each its part; raises
        `FleetError` naming the hosts that did not take it (the ones that did are stopped).
        `access` (iotad/launcher/access_control.py): under access control, this session's user
        and each host's credentials, which go in that host's order only."""
        from iotad.host.transport import open_session

        self.session = open_session([], self.hub, mode="client", connect_timeout=self.start_timeout,
                                    credentials=access.fleet_credentials() if access else False, tls=self.tls)
        self._declared.append(self.session.liveliness().declare_subscriber(
            f"{AGENT_PREFIX}/*", self._on_agent, history=True))
        for part in ("log", "exit"):
            self._declared.append(self.session.declare_subscriber(f"{AGENT_PREFIX}/*/{part}", self._on_message))
        deadline = time.monotonic() + self.start_timeout
        with self._changed:
            while not set(self.hosts) <= self._present and time.monotonic() < deadline:
                self._changed.wait(max(0.0, deadline - time.monotonic()))
        missing = [host for host in self.hosts if host not in self._present]
        if missing:
            self.close()
            guarded = access is not None and access.fleet_credentials() is not False
            raise FleetError(f"no agent answered for host(s) {', '.join(missing)} within {self.start_timeout:g} s: "
                             f"start 'iotad agent --name HOST --connect {self.hub[0]}' there (docs/hosts.md)"
                             + ("; this run is under access control: an agent needs --certs DIR with its "
                                "HOST.secret, and says on its own console why the hub does not admit it"
                                if guarded else ""))
        refused = []
        for host in self.hosts:
            # the hub admits only the agent of `host` to serve this key: its credentials go to it alone
            order = json.dumps({"system": self.text, "path": str(self.path), "digest": digest(self.text),
                                "args": self.args + self.host_args.get(host, []), "env": self.env,
                                "credentials": access.host_part(host) if access else {}}).encode()
            answer = self._ask(f"{agent_key(host)}/run", order)
            if answer.get("ok"):
                self._started.add(host)
                self.say(f"host {host}: its agent runs its nodes (pid {answer.get('pid')})")
            else:
                refused.append(f"{host}: {answer.get('error', 'no answer')}")
        if refused:
            self.stop()
            raise FleetError("host(s) refused their part: " + "; ".join(refused))

    def _ask(self, key: str, payload: bytes | None = None, timeout: float = 10.0) -> dict:
        """The agent's answer on `key`. A query that no queryable is known for yet ends at once
        with no reply (the agent's declaration may still be on its way to the hub): asked again
        until `timeout`."""
        deadline = time.monotonic() + timeout
        while True:
            try:
                for reply in self.session.get(key, payload=payload, timeout=max(0.1, deadline - time.monotonic())):
                    try:
                        return json.loads(reply.ok.payload.to_bytes())
                    except (AttributeError, ValueError):
                        return {"ok": False, "error": "a malformed answer"}
            except Exception as exc:  # noqa: BLE001 - the hub session is closing
                return {"ok": False, "error": str(exc)}
            if time.monotonic() >= deadline:
                return {"ok": False, "error": f"no answer in {timeout:g} s"}
            time.sleep(0.1)

    def _host_of(self, key: str) -> str:
        return str(key).split("/")[2]

    def _on_agent(self, sample) -> None:
        import zenoh

        host = self._host_of(sample.key_expr)
        with self._changed:
            if sample.kind == zenoh.SampleKind.PUT:
                self._present.add(host)
            else:
                self._present.discard(host)
                if host in self._started and host not in self.exits and host not in self._asked_to_stop:
                    self.lost.append(host)
                    self.say(f"host {host} LOST: its agent is gone (network or machine); its nodes are down "
                             "until it comes back")
            self._changed.notify_all()

    def _on_message(self, sample) -> None:
        host = self._host_of(sample.key_expr)
        try:
            payload = json.loads(sample.payload.to_bytes())
        except ValueError:
            return
        if str(sample.key_expr).endswith("/log"):
            self.say(f"[{host}] {payload.get('line', '')}")
        else:
            with self._changed:
                self.exits[host] = int(payload.get("code", -1))
                self._changed.notify_all()

    def wait(self, timeout: float) -> dict[str, int]:
        """Until every started host's run has exited (or `timeout`): their exit statuses."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while not self._started <= set(self.exits) | set(self.lost) and time.monotonic() < deadline:
                self._changed.wait(max(0.0, deadline - time.monotonic()))
        return dict(self.exits)

    def stop(self, grace: float = 20.0) -> dict[str, int]:
        """Ask every host still running to stop (as Ctrl-C would there) and wait for them."""
        for host in sorted(self._started - set(self.exits) - set(self.lost)):
            self._asked_to_stop.add(host)
            answer = self._ask(f"{agent_key(host)}/stop", timeout=grace)
            if answer.get("ok") and answer.get("code") is not None:
                with self._changed:
                    self.exits.setdefault(host, int(answer["code"]))
        return self.wait(2.0)

    def failures(self) -> list[str]:
        """Hosts whose part ended badly: lost, or exited non-zero before it was asked to stop."""
        failed = [f"{host}: lost" for host in self.lost]
        failed += [f"{host}: exit {code}" for host, code in sorted(self.exits.items())
                   if code != 0 and host not in self._asked_to_stop]
        return failed

    def outcome(self, host: str) -> str:
        """How `host`'s part ended, in words, for the run's summary."""
        code = self.exits.get(host)
        if host in self.lost:
            return "LOST (its agent disappeared)"
        if code is None:
            return "no exit status (its agent did not answer)"
        return f"exit {code}" + (" (stopped by this run)" if host in self._asked_to_stop else "")

    def close(self) -> None:
        for item in self._declared:
            try:
                item.undeclare()
            except Exception:  # noqa: BLE001
                pass
        self._declared.clear()
        if self.session is not None:
            self.session.close()
            self.session = None
