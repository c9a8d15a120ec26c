"""The hub's side of a system spread over hosts: `iotad run SYSTEM.toml` on the hub's machine asks
the agent of every other host (`iotad agent`, iotad/launcher/hosts/agent.py) to run that host's part,
serves the files the system file names by their sha256 (iotad/launcher/hosts/code_by_hash.py), relays
the agents' lines, notices an agent that disappears (and gives it its part again when it comes
back during the run) and a part that its agent starts again after it was killed (the agent is
its part's supervisor: iotad/launcher/hosts/agent.py), and stops them all at the end.

It talks to the agents through its own client session of the hub, so it starts once the hub
listens and needs nothing from the launcher but the hub's endpoint."""
from __future__ import annotations

import json
import threading
import time
from pathlib import Path
from typing import Callable

from iotad.launcher.hosts.agent_lines import KEPT, HeardLines
from iotad.launcher.hosts.code_by_hash import named_files
from iotad.launcher.fleet_wire import AGENT_PREFIX, CODE_PREFIX, agent_key, digest
from iotad.launcher.options import RunOptions
from iotad.launcher.system.system_model import System


class FleetError(Exception):
    """A host whose agent did not answer or refused its part: the run cannot start whole."""


class Fleet:
    """The agents of `hosts`, each ordered to run its part of the checked `system` as its
    `RunOptions` in `orders` say (a typed order, JSON on the wire: no command line)."""

    def __init__(self, system: System, hosts: list[str], hub: list[str], orders: dict[str, RunOptions], *,
                 tls=None, env: dict[str, str] | None = None, say: Callable[[str], None] = print,
                 start_timeout: float = 30.0):
        self.path = Path(system.path)
        self.text = system.text
        self.hosts, self.hub, self.tls = list(hosts), list(hub), tls
        self.host_orders = dict(orders)  # host -> the options its launcher runs with (its recording)
        self.env, self.say, self.start_timeout = dict(env or {}), say, start_timeout
        self.session = None
        self.exits: dict[str, int] = {}
        self.lost: list[str] = []  # hosts whose agent is gone now
        self.returns: dict[str, int] = {}  # host -> how many times it came back after it was lost
        self.restarts: dict[str, list[dict]] = {}  # host -> its part's restarts by its agent: each its exit
        # told ("lost" | "back" | "resumed" | "exited" | "restarting", host) from a zenoh thread: the launcher
        # marks that host's nodes (or, for a part that ended by itself, decides the run's fate)
        self.notify: Callable[[str, str], None] | None = None
        self._stop = None
        self._closing = False
        self._rejoining: set[str] = set()
        self._ran_on: dict[str, bool] = {}  # host -> its agent said its part was running already
        # the files the system names, served by hash: the bytes hashed are the bytes served
        files = named_files(system.declaration)
        self._code = {item["sha256"]: Path(item["path"]).read_bytes() for item in files}
        self._order_base = {"system": self.text, "path": str(self.path), "digest": digest(self.text),
                            "files": files, "env": self.env}
        self._access = None
        self._asked_to_stop: set[str] = set()  # a host that exits after this was stopped, not failed
        self._present: set[str] = set()
        self._started: set[str] = set()
        self._early_exits: dict[str, dict] = {}  # host -> its part's exit, heard before its order's answer
        self._changed = threading.Condition()
        self._declared: list = []
        self._heard: dict[str, HeardLines] = {host: HeardLines() for host in self.hosts}
        # taken from deciding which lines to print to printing them: a live line must not come
        # out between the lines of an answer it follows
        self._printing = threading.Lock()

    def start(self, access=None, stop=None, *, say: Callable[[str], None] | None = None,
              notify: Callable[[str, str], None] | None = None) -> None:
        """Give each host its part as soon as its agent is there, waiting up to `start_timeout` for
        them all; raises `FleetError` naming the hosts that did not take it (the ones that did are
        stopped). `access` (iotad/launcher/access/access_control.py): under access control, this session's
        user and each host's credentials, which go in that host's order only. `stop` (a flag with
        `is_set()`: Ctrl-C) ends the wait at once: the hosts started by then are the caller's to
        stop (`stop()`), as at the end of a run. `say` prints its lines, `notify(event, host)` hears a host
        lost or back (the launcher's: given here, not set from outside)."""
        from iotad.node_host.transport import open_session

        if say is not None:
            self.say = say
        if notify is not None:
            self.notify = notify
        self._stop = stop
        self.session = open_session([], self.hub, mode="client", connect_timeout=self.start_timeout,
                                    credentials=access.fleet_credentials() if access else False, tls=self.tls)
        self._access = access
        # the named files first: an agent asks for them while it takes its order
        self._declared.append(self.session.declare_queryable(f"{CODE_PREFIX}/*", self._on_code))
        self._declared.append(self.session.liveliness().declare_subscriber(
            f"{AGENT_PREFIX}/*", self._on_agent, history=True))
        for part in ("log", "exit"):
            self._declared.append(self.session.declare_subscriber(f"{AGENT_PREFIX}/*/{part}", self._on_message))
        deadline = time.monotonic() + self.start_timeout
        refused: dict[str, str] = {}
        while not self._stopped():
            with self._changed:
                ready = [h for h in self.hosts if h in self._present and h not in self._started and h not in refused]
            for host in ready:
                error = self._order(host)
                if error is not None:
                    refused[host] = error
            waiting = [h for h in self.hosts if h not in self._started and h not in refused]
            if not waiting or time.monotonic() >= deadline:
                break
            with self._changed:  # in slices: a Ctrl-C is seen within 0.1 s
                self._changed.wait(min(0.1, max(0.0, deadline - time.monotonic())))
        if self._stopped():
            return
        missing = [host for host in self.hosts if host not in self._started and host not in refused]
        if missing or refused:
            self.stop()
            self.close()
            if missing:
                guarded = access is not None and access.fleet_credentials() is not False
                raise FleetError(f"no agent answered for host(s) {', '.join(missing)} within {self.start_timeout:g} s: "
                                 f"start 'iotad agent --name HOST --connect {self.hub[0]}' there (docs/hosts.md)"
                                 + ("; this run is under access control: an agent needs --certs DIR with its "
                                    "HOST.secret, and says on its own console why the hub does not admit it"
                                    if guarded else ""))
            raise FleetError("host(s) refused their part: " + "; ".join(f"{h}: {e}" for h, e in refused.items()))

    def _stopped(self) -> bool:
        return self._stop is not None and self._stop.is_set()

    def _order(self, host: str, interruptible: bool = True) -> str | None:
        """Give `host` its part; None when its agent runs it, else why not."""
        # the hub admits only the agent of `host` to serve this key: its credentials go to it alone
        order = dict(self._order_base, credentials=self._access.host_part(host) if self._access else {},
                     run=self.host_orders[host].to_json())
        answer = self._ask(f"{agent_key(host)}/run", json.dumps(order).encode(), interruptible=interruptible)
        if not answer.get("ok"):
            return answer.get("error", "no answer")
        with self._changed:
            self._started.add(host)
            self.exits.pop(host, None)  # a host back after it was lost: its earlier run is over
            early = self._early_exits.pop(host, None)
        if early is not None and early.get("run") == answer.get("pid"):
            self._exited(host, early)  # this part exited before its agent's answer came
        self._ran_on[host] = bool(answer.get("already"))
        how = "already runs its part" if answer.get("already") else "runs its nodes"
        self.say(f"host {host}: its agent {how} (pid {answer.get('pid')})")
        for line in answer.get("fetched") or []:
            self.say(f"host {host}: {line}")
        return None

    def _on_code(self, query) -> None:
        """A named file's bytes, by its sha256; nothing else is served."""
        sha = str(query.key_expr).rsplit("/", 1)[-1]
        data = self._code.get(sha)
        if data is None:
            query.reply_err(f"no file of this run has sha256 {sha}".encode())
        else:
            query.reply(query.key_expr, data)

    def _ask(self, key: str, payload: bytes | None = None, timeout: float = 10.0, interruptible: bool = False) -> dict:
        """The agent's answer on `key`. A query that no queryable is known for yet ends at once
        with no reply (the agent's declaration may still be on its way to the hub): asked again
        until `timeout`, or until the run stops when `interruptible`."""
        deadline = time.monotonic() + timeout
        while not (interruptible and self._stopped()):
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
        return {"ok": False, "error": "the run is stopping"}

    def _host_of(self, key: str) -> str:
        return str(key).split("/")[2]

    def _on_agent(self, sample) -> None:
        import zenoh

        host = self._host_of(sample.key_expr)
        event = None
        with self._changed:
            if sample.kind == zenoh.SampleKind.PUT:
                self._present.add(host)
                if host in self.lost and host not in self._rejoining and not self._closing and not self._stopped():
                    self._rejoining.add(host)  # its token seen twice (history, live): one new order
                    event = "back"
            else:
                self._present.discard(host)
                if host in self._started and host not in self.exits and host not in self._asked_to_stop \
                        and host not in self.lost:
                    self.lost.append(host)
                    event = "lost"
                    self.say(f"host {host} LOST: its agent is gone (network or machine); its nodes are down "
                             "until it comes back")
            self._changed.notify_all()
        if event == "back":
            # its part again, as a local launcher restarts a node; not on this zenoh thread, which
            # would wait for the agent's answer that only a zenoh thread can deliver
            threading.Thread(target=self._rejoin, args=(host,), daemon=True, name=f"fleet-{host}-back").start()
        elif event == "lost" and self.notify is not None:
            self.notify("lost", host)

    def _rejoin(self, host: str) -> None:
        self.say(f"host {host}: its agent is back; giving it its part again")
        error = self._order(host, interruptible=False)
        with self._changed:
            self._rejoining.discard(host)
        if error is not None:
            self.say(f"host {host}: its agent is back but refused its part: {error}")
            return
        with self._changed:
            if host in self.lost:
                self.lost.remove(host)
            self.returns[host] = self.returns.get(host, 0) + 1
            self._changed.notify_all()
        if self.notify is not None:
            # "resumed": an agent cut off a while (the network), whose part ran on meanwhile
            self.notify("resumed" if self._ran_on.get(host) else "back", host)
        if self._ran_on.get(host) and self._heard.setdefault(host, HeardLines()).want_tail(None, None):
            self._catch_up(host)  # what its run printed while it was cut off (on this thread of its own)

    def _on_message(self, sample) -> None:
        host = self._host_of(sample.key_expr)
        try:
            payload = json.loads(sample.payload.to_bytes())
        except ValueError:
            return
        if not isinstance(payload, dict):
            return
        heard = self._heard.setdefault(host, HeardLines())
        if str(sample.key_expr).endswith("/log"):
            with self._printing:
                lines, ask = heard.live(payload.get("run"), payload.get("n"), str(payload.get("line", "")))
                self._print(host, lines)
            if ask:  # lines before this one were not heard (a cut): the agent keeps them
                self._catching_up(host)
        elif isinstance(payload.get("lines"), int) and heard.want_tail(payload.get("run"), payload["lines"]):
            # the exit counts lines not heard: they are printed before the exit is taken
            self._catching_up(host, then=lambda: self._exited(host, payload))
        else:
            self._exited(host, payload)

    def _exited(self, host: str, payload: dict) -> None:
        try:
            code = int(payload.get("code", -1))
        except (TypeError, ValueError):
            code = -1
        restart = payload.get("restart")
        with self._changed:
            if host not in self._started and not self._closing:
                # the part exited before the answer to its order reached this hub: taken with it
                self._early_exits[host] = payload
                return
            if isinstance(restart, dict):
                # killed, and started again by its agent: no exit of the host's part, which goes
                # on (at the end of the run, the stop asked of its agent cancels the restart)
                self.restarts.setdefault(host, []).append({"code": code, **restart})
                if self._closing or host in self._asked_to_stop:
                    return
                by_itself = None
            else:
                self.exits[host] = code
                # its part ended by itself (not asked to stop): the launcher hears it at once, so
                # that a part that fails as it starts ends the run now, not at its --until
                by_itself = host in self._started and host not in self._asked_to_stop and not self._closing
                self._changed.notify_all()
        if by_itself is None and self.notify is not None:
            self.notify("restarting", host)
        elif by_itself and self.notify is not None:
            self.notify("exited", host)

    def _print(self, host: str, lines: list[tuple[str, bool]]) -> None:
        for text, late in lines:
            self.say(f"[{host}] (late) {text}" if late else f"[{host}] {text}")

    def _catching_up(self, host: str, then: Callable[[], None] | None = None) -> None:
        # not on this zenoh thread: the agent's answer needs it
        threading.Thread(target=self._catch_up, args=(host, then), daemon=True, name=f"fleet-{host}-lines").start()

    def _catch_up(self, host: str, then: Callable[[], None] | None = None) -> None:
        """The lines of `host`'s run that were not heard live, from its agent, in their order."""
        heard = self._heard.setdefault(host, HeardLines())
        try:
            while True:
                answer = self._ask(f"{agent_key(host)}/lines?after={heard.after()}", timeout=5.0)
                with self._printing:
                    if not isinstance(answer.get("lines"), list):
                        lines, missing = heard.unanswered()
                        if missing:
                            self.say(f"[{host}] ({missing} line(s) here were not heard: sent while it was cut off, "
                                     f"and its agent did not give them: {answer.get('error', 'no answer')})")
                        self._print(host, lines)
                        return
                    lines, dropped, again = heard.answered(answer)
                    if dropped:
                        self.say(f"[{host}] ({dropped} line(s) sent while it was cut off are lost: its agent keeps "
                                 f"the last {KEPT})")
                    self._print(host, lines)
                if not again:
                    return
        finally:
            if then is not None:
                then()

    def wait(self, timeout: float) -> dict[str, int]:
        """Until every started host's run has exited (or `timeout`): their exit statuses."""
        deadline = time.monotonic() + timeout
        with self._changed:
            while not self._started <= set(self.exits) | set(self.lost) and time.monotonic() < deadline:
                self._changed.wait(max(0.0, deadline - time.monotonic()))
        return dict(self.exits)

    def stop(self, grace: float = 20.0, hurry: threading.Event | None = None) -> dict[str, int]:
        """Ask every host still running to stop (as Ctrl-C would there) and wait for them: all
        at once, each until its agent answers, its agent is gone (a host cut off: its agent
        stops its part when it finds the hub gone), `grace` s pass, or `hurry` is set (a second
        Ctrl-C)."""
        self._closing = True  # an agent that comes back now gets no part
        hosts = sorted(self._started - set(self.exits) - set(self.lost))
        answered: set[str] = set()

        def ask(host: str) -> None:
            answer = self._ask(f"{agent_key(host)}/stop", timeout=grace)
            with self._changed:
                if answer.get("ok") and answer.get("code") is not None:
                    self.exits.setdefault(host, int(answer["code"]))
                answered.add(host)
                self._changed.notify_all()

        for host in hosts:
            self._asked_to_stop.add(host)
            threading.Thread(target=ask, args=(host,), daemon=True, name=f"fleet-{host}-stop").start()
        deadline = time.monotonic() + grace
        with self._changed:
            while time.monotonic() < deadline and not (hurry is not None and hurry.is_set()) and \
                    any(h not in answered and h not in self.exits and h in self._present for h in hosts):
                self._changed.wait(0.1)
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
        back = f"; lost {self.returns[host]} time(s), back each time" if self.returns.get(host) else ""
        if self.restarts.get(host):
            back += f"; killed {len(self.restarts[host])} time(s), started again by its agent"
        return f"exit {code}" + (" (stopped by this run" + back + ")" if host in self._asked_to_stop else back)

    def close(self) -> None:
        for item in self._declared:
            try:
                item.undeclare()
            except Exception:  # noqa: BLE001
                pass
        self._declared.clear()
        if self.session is not None:
            from iotad.node_host.session_close import close_session

            close_session(self.session)  # an agent that is cut off is not waited for
            self.session = None
