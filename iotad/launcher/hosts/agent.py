"""The agent of one host (`iotad agent --name NAME --connect ENDPOINT`): waits at the system's hub
for the run that `iotad run` on the hub's machine starts, and runs this host's part of it
(`python -m iotad.launcher.run.host_part ORDER.json`: the order's system and options, as the
library's `run_real_time` runs them) as a child it owns; stops it when told, or when the hub is
gone for longer than the run's own allowance.

Its wire, all under `iota/@agent/<name>` (an '@' chunk, so no system's `**` matches it):
- a liveliness token on the key itself: the hub's `iotad run` sees the agent, and sees it go;
- queryable `.../run`: an order (JSON) with the system file's text, its path on the hub, the files
  it names (path and sha256), the launcher's options (`run`: a `RunOptions`, typed, no command
  line) and, under access control, this host's
  launcher's credentials (written to a private folder for the run and removed after it; the
  launcher, its host's router, makes its nodes' own: iotad/launcher/access/host_router.py); the answer
  is {"ok": true, "pid": N, "fetched": [lines]} ("already": true when it runs that system
  already) or {"ok": false, "error": "..."};
- queryable `.../stop`: SIGINT to the child, as Ctrl-C would; answered once it has exited;
- publications `.../log` (each line the child prints: {"line": text, "n": its number in the run,
  "run": the child's pid}) and `.../exit` ({"code": N, "lines": how many it printed, "run": pid},
  with "restart": {"attempt": k, "of": max, "in_s": backoff} when the agent starts it again);
- queryable `.../lines?after=N`: the lines numbered past N that it still keeps (the last
  `agent_lines.KEPT`), for a hub that did not hear them live (a network cut): {"run": pid,
  "first": the first number kept, "count": lines printed, "lines": [[n, text], ...]}.

The order names every file the system file names (node code, specs) with its sha256. The agent
runs the hub's version of each: the file at the hub's path when this machine holds the same
bytes there, else the bytes fetched from the hub by hash into its cache under `--workdir`
(iotad/launcher/hosts/code_by_hash.py); its run reads the hub's system file with those names standing
for the files here. Bytes that do not hash to what the order names are refused, and so is the run.

The run is a child that dies with the agent (the parent-death signal, SIGTERM: its launcher then
stops its nodes in order): an agent that is killed takes its host's part down with it, and the
hub reports the host lost and its nodes down.

The agent is its run's supervisor, as a launcher is its nodes': a run killed by a signal that
nobody asked to stop (kill -9, a crash: its exit status negative) is started again from the same
order after a backoff, `PART_RESTARTS` times at most, as `RestartPolicy` restarts a node. Here,
not at the hub: the agent is its parent and sees the exit at once, also while its host is cut
off from the hub (when a re-sent order could not come). A run that exits with a status of its
own (2: its configuration; 1: its nodes failed for good) is not started again: the same order
would fail the same way, and the hub decides what that means for the run."""
from __future__ import annotations

import dataclasses
import json
import os
import queue
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Callable

from iotad.node_host.credentials import ENV, CredentialStore
from iotad.node_host.session_close import close_session
from iotad.launcher.hosts.agent_lines import KeptLines
from iotad.launcher.hosts.code_by_hash import CodeCache, CodeError, localize
from iotad.launcher.fleet_wire import CODE_PREFIX, agent_key, code_key, digest, launcher_user
from iotad.launcher.processes import RestartPolicy, wrapped_argv
from iotad.launcher.options import RunOptions

RUN_LOGS_KEPT = 20  # the lines of this many runs are kept under the work folder's logs/
# a run killed mid-way is started again this many times at most, 0.5 s, 1 s, 2 s... after its
# death (a launcher's start takes a second or two: a faster loop would only burn the host); a
# run that lasted healthy_after s counts its restarts from the start again
PART_RESTARTS = RestartPolicy("on-failure", max_restarts=3, backoff=0.5, backoff_max=8.0, healthy_after=30.0)


class AgentError(Exception):
    """An order the agent cannot carry out, said in one line."""


def host_part_for(order: dict, host: str, workdir: Path, fetch: Callable[[str], bytes]) -> tuple[Path, list[str]]:
    """The file of this host's part of `order` (`iotad/launcher/run/host_part.py` runs it), written in
    `workdir`, and the lines saying which named files were fetched: the system file's text and
    path as the hub sent them, where this machine has the hub's version of each file it names,
    and the options of `host`'s launcher. Raises `AgentError` when any of these cannot be had."""
    text, path = order.get("system"), order.get("path")
    if not isinstance(text, str) or not isinstance(path, str):
        raise AgentError("an order without a system file (expected 'system' text and its 'path')")
    if order.get("digest") not in (None, digest(text)):
        raise AgentError("the system file's text does not match its digest: the order was damaged")
    try:
        options = dataclasses.replace(RunOptions.from_json(order.get("run", {})), host=host)
    except ValueError as exc:
        raise AgentError(str(exc)) from None
    folder = workdir / "runs" / digest(text)[:16]
    try:
        files, fetched = localize(order.get("files", []), CodeCache(workdir), fetch)
        folder.mkdir(parents=True, exist_ok=True)
        part = folder / f"{host}.json"
        part.write_text(json.dumps({"system": text, "path": path, "files": files, "run": options.to_json()}),
                        encoding="utf-8")
    except CodeError as exc:
        raise AgentError(str(exc)) from None
    except OSError as exc:
        raise AgentError(f"cannot write the hub's files under {workdir}: {exc.strerror or exc}") from None
    return part, fetched


class Agent:
    """One host's agent: `serve()` until `stop()` (or SIGINT/SIGTERM in `main`)."""

    def __init__(self, name: str, connect: list[str], tls=None, workdir: str | Path | None = None,
                 say: Callable[[str], None] = print, python: str = sys.executable, secret: str | None = None):
        """`secret`: this host's agent secret (HOST.secret, iotad/machine/agent_secret.py), with which
        it is admitted by a hub under access control."""
        from iotad.machine.agent_secret import agent_user
        from iotad.node_host.credentials import Credentials

        self.name, self.connect, self.tls, self.say, self.python = name, list(connect), tls, say, python
        self.credentials = Credentials(agent_user(name), secret) if secret else None
        self._refusal = ""  # the last reason the hub gave for not admitting this agent, said once
        self._admitted_with = self.credentials  # how the last hub admitted it (False: without credentials)
        self._store = None  # the credentials of the run in progress (a private folder), removed after it
        self.workdir = Path(workdir) if workdir else Path(tempfile.gettempdir()) / f"iotad-agent-{name}"
        self.child: subprocess.Popen | None = None
        self._digest: str | None = None  # the system file the child runs
        self._lines = KeptLines()  # the child's lines, numbered, for a hub that missed some (a cut)
        # runs to spawn, from the threads that take orders: spawned on the thread of serve(), which
        # lives as long as the agent (the parent-death signal fires when the spawning thread ends)
        self._spawns: queue.Queue = queue.Queue()
        self._lock = threading.Lock()
        self._stopping = threading.Event()
        self.session = None
        self._launch: tuple | None = None  # (command, env, digest, path) of the run in progress: its restarts
        self._asked_stop = False  # the run in progress was asked to stop: its exit is no failure
        self._restarts = 0  # restarts of the run in progress, in all
        self._consecutive = 0  # ... since it last ran healthy_after s
        self._restart_due: subprocess.Popen | None = None  # the dead run whose restart waits its backoff

    # ------------------------------------------------------------- serving
    def serve(self) -> int:
        self.say(f"agent {self.name}: waiting for the hub at {', '.join(self.connect)}")
        try:
            while not self._stopping.is_set():
                admitted_as = self._admit()
                if self.session is None:
                    break
                self._serve_session(admitted_as)
        finally:
            self._stop_child("the agent stops")
            self._remove_credentials()
        return 0

    def _admit(self) -> str | None:
        """Open a session with the hub once a run holds it (None: the agent stopped first); the
        user it was admitted as."""
        from iotad.node_host.admission import listening
        from iotad.node_host.transport import open_session

        while not self._stopping.is_set():
            if not any(listening(endpoint) for endpoint in self.connect):
                self._refusal = ""
                self._stopping.wait(0.5)  # no run holds the hub yet
                continue
            # with its secret (a run under access control) and without (a run that has none: zenoh
            # refuses a user-password session on a hub that checks none, after the whole timeout),
            # the way the last run admitted it first
            ways = ([self.credentials] if self.credentials else []) + [False]
            for credentials in sorted(ways, key=lambda way: way is not self._admitted_with):
                try:
                    self.session = open_session([], self.connect, mode="client", connect_timeout=2.0,
                                                credentials=credentials, tls=self.tls)
                    self._admitted_with = credentials
                    return credentials.user if credentials else None
                except Exception:  # noqa: BLE001 - zenoh says only "Unable to connect"
                    continue
            self._not_admitted()
            self._stopping.wait(1.0)
        return None

    def _serve_session(self, admitted_as: str | None) -> None:
        """Serve orders until the agent stops, or until the hub is gone while no run of this host
        is in progress: the next run's hub is joined anew, since it may check credentials where
        the last did not, or the reverse (a run in progress keeps its session, which zenoh
        reconnects when the network heals)."""
        key = agent_key(self.name)
        # the queryables before the token: a hub that sees the token may ask at once
        declared = [self.session.declare_queryable(f"{key}/run", self._on_run),
                    self.session.declare_queryable(f"{key}/stop", self._on_stop),
                    self.session.declare_queryable(f"{key}/lines", self._on_lines),
                    self.session.liveliness().declare_token(key)]
        self.say(f"agent {self.name}: ready at the hub" + (f" (admitted as {admitted_as})" if admitted_as else ""))
        # the hub gone for 1 s with no run here: closed now, the next run's hub is joined sooner than
        # zenoh's own reconnection (backing off) would
        absent = 0
        try:
            next_look = time.monotonic() + 0.5
            while not self._stopping.is_set():
                try:
                    self._spawns.get(timeout=0.2)()  # a run to start, on this thread (see _spawns)
                except queue.Empty:
                    pass
                if time.monotonic() < next_look:
                    continue
                next_look = time.monotonic() + 0.5
                hub_there = any(True for _ in self.session.info.peers_zid()) or \
                    any(True for _ in self.session.info.routers_zid())
                absent = 0 if hub_there or self._running() else absent + 1
                if absent >= 2:
                    self.say(f"agent {self.name}: the hub is gone; waiting for the next run")
                    break
        finally:
            while not self._spawns.empty():  # orders taken while the agent stopped: refused
                self._spawns.get_nowait()(refuse=True)
            # a run in progress is stopped by serve() as the agent stops; none runs when a hub left
            for item in declared:
                try:
                    item.undeclare()
                except Exception:  # noqa: BLE001 - a session the hub left
                    pass
            close_session(self.session)  # a hub that is cut off is not waited for
            self.session = None

    def _running(self) -> bool:
        """A run is in progress (or waits for its restart): the hub's session is kept."""
        with self._lock:
            return self.child is not None and (self.child.poll() is None or self._restart_due is self.child)

    def stop(self) -> None:
        self._stopping.set()

    def _not_admitted(self) -> None:
        """Say once why the hub does not admit this agent, when something answers there (a hub
        that is not up yet is a wait, not an error)."""
        from iotad.node_host.admission import diagnose

        refusal = diagnose(self.connect[0], self.tls, self.credentials.user if self.credentials else None)
        if refusal.listening and refusal.reason != self._refusal:
            self.say(f"agent {self.name}: not admitted: {refusal.reason}")
        self._refusal = refusal.reason if refusal.listening else ""

    # ------------------------------------------------------------- orders
    def _on_run(self, query) -> None:
        # not on this zenoh thread: fetching named files asks the hub, whose answers need it
        threading.Thread(target=self._take_order, args=(query,), daemon=True, name=f"agent-{self.name}-order").start()

    def _take_order(self, query) -> None:
        try:
            order = json.loads(query.payload.to_bytes()) if query.payload is not None else None
            if not isinstance(order, dict):
                raise AgentError("an order must be a JSON object")
            answer = {"ok": True, **self._start(order)}
        except (AgentError, ValueError, OSError) as exc:
            answer = {"ok": False, "error": str(exc)}
            self.say(f"agent {self.name}: refused a run: {exc}")
        except Exception as exc:  # noqa: BLE001 - the session closing under a fetch...: the hub hears why
            answer = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
            self.say(f"agent {self.name}: could not take a run: {answer['error']}")
        query.reply(query.key_expr, json.dumps(answer).encode())

    def _on_stop(self, query) -> None:
        code = self._stop_child("the hub asked")
        query.reply(query.key_expr, json.dumps({"ok": True, "code": code}).encode())

    def _on_lines(self, query) -> None:
        try:
            after = int(query.parameters.get("after") or 0)
        except (TypeError, ValueError):
            after = 0  # a malformed question gets every line kept
        query.reply(query.key_expr, json.dumps(self._lines.after(after)).encode())

    def _fetch(self, sha256: str) -> bytes:
        """A named file's bytes from the hub, by hash (checked by the caller)."""
        asked = time.monotonic()
        for reply in self.session.get(code_key(sha256), timeout=10.0):
            if reply.ok is not None:
                return reply.ok.payload.to_bytes()
            raise AgentError(f"the hub refused the file sha256 {sha256[:12]}: "
                             f"{reply.err.payload.to_bytes().decode(errors='replace')}")
        if time.monotonic() - asked < 9.0:
            # no reply and no wait: the hub knows of nothing this agent may ask at that key, which
            # under access control is a policy that does not let it, or its run's fleet, have it
            raise AgentError(f"the hub sent no file for sha256 {sha256[:12]}: nothing there serves "
                             f"{CODE_PREFIX}/* to this agent (under access control, the hub's policy "
                             "must let this agent ask it and the run's fleet session serve it)")
        raise AgentError(f"the hub sent no file for sha256 {sha256[:12]} within 10 s")

    def _start(self, order: dict) -> dict:
        with self._lock:
            child = self.child
        if child is not None and child.poll() is None:
            if self._digest is not None and order.get("digest") == self._digest:
                # a hub that lost this agent a while (the network) and sees it again: the same run goes on
                return {"pid": child.pid, "already": True}
            raise AgentError(f"host {self.name} already runs a system (pid {child.pid})")
        part, fetched = host_part_for(order, self.name, self.workdir, self._fetch)
        path = order["path"]
        for line in fetched:
            self.say(f"agent {self.name}: {line}")
        command = [self.python, "-m", "iotad.launcher.run.host_part", str(part)]
        env = dict(os.environ)
        env.update({k: v for k, v in (order.get("env") or {}).items() if isinstance(v, str)})
        env.pop(ENV, None)
        given = order.get("credentials") or {}
        if not isinstance(given, dict) or not all(isinstance(v, str) for v in [*given, *given.values()]):
            raise AgentError("an order's 'credentials' must map user names to passwords")
        if given:
            if launcher_user(self.name) not in given:
                raise AgentError(f"an order's credentials lack this host's launcher ({launcher_user(self.name)})")
            launcher = {launcher_user(self.name): given[launcher_user(self.name)]}
            with self._lock:
                self._remove_credentials()
                # a private folder (0700, files 0600) for the run's launcher, removed after it; any
                # other user an order names is not written: the launcher makes its nodes' own
                self._store = CredentialStore([], passwords=launcher)
            env[ENV] = str(self._store.file_of(launcher_user(self.name)))
        done = threading.Event()
        result: dict = {}

        def spawn(refuse: bool = False) -> None:
            try:
                with self._lock:
                    if refuse:
                        raise AgentError(f"agent {self.name} is stopping")
                    if self.child is not None and self.child.poll() is None:
                        raise AgentError(f"host {self.name} already runs a system (pid {self.child.pid})")
                    self.child = subprocess.Popen(wrapped_argv(command, signal.SIGTERM), stdout=subprocess.PIPE,
                                                  stderr=subprocess.STDOUT, text=True, env=env,
                                                  start_new_session=True)
                    self.child.started_at = time.monotonic()  # a run that lasted is restarted at once
                    self._digest = order.get("digest")
                    self._lines.start(self.child.pid)
                    self._launch = (command, env, order.get("digest"), path)
                    self._asked_stop, self._restarts, self._consecutive, self._restart_due = False, 0, 0, None
                    result["child"] = self.child
            except (AgentError, OSError) as exc:
                result["error"] = exc
            finally:
                done.set()

        self._spawns.put(spawn)
        while not done.wait(0.2):
            if self._stopping.is_set() and self._spawns.empty() and not done.is_set():
                raise AgentError(f"agent {self.name} is stopping")
        if "error" in result:
            error = result["error"]
            raise error if isinstance(error, AgentError) else AgentError(f"cannot start the run: {error}")
        child = result["child"]
        self.say(f"agent {self.name}: runs {path} (pid {child.pid})")
        self._follow(child)
        return {"pid": child.pid, "fetched": fetched}

    def _follow(self, child: subprocess.Popen) -> None:
        log = self._log_file(child.pid)
        threading.Thread(target=self._relay, args=(child, log), daemon=True, name=f"agent-{self.name}-log").start()

    def _log_file(self, pid: int):
        """The file this host keeps its run's lines in (the hub gets them too, but not during a
        cut longer than the agent keeps lines for); None, said once, if it cannot be written."""
        path = self.workdir / "logs" / f"run-{pid}.log"
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            kept = sorted(path.parent.glob("run-*.log"), key=lambda p: p.stat().st_mtime)
            for old in kept[:-(RUN_LOGS_KEPT - 1)]:  # the last runs' only: a host runs many
                old.unlink(missing_ok=True)
            log = path.open("w", encoding="utf-8", buffering=1)  # line by line: a killed agent loses none
        except OSError as exc:
            self.say(f"agent {self.name}: cannot keep the run's lines in {path}: {exc.strerror or exc}")
            return None
        self.say(f"agent {self.name}: the run's lines go to the hub and to {path}")
        return log

    def _relay(self, child: subprocess.Popen, log=None) -> None:
        """The child's lines to the hub (and to `log`), then its exit status."""
        printed = 0
        for line in child.stdout:
            text = line.rstrip("\n")
            printed = self._lines.add(text)
            if log is not None:
                try:
                    log.write(text + "\n")
                except OSError:
                    log = None  # a full disk: the hub still gets them
            self._publish("log", {"line": text, "n": printed, "run": child.pid})
        if log is not None:
            log.close()
        code = child.wait()
        restart = self._restart_after(child, code)
        with self._lock:
            if self.child is child and restart is None:
                self._remove_credentials()
        exit_ = {"code": code, "lines": printed, "run": child.pid}
        self._publish("exit", exit_ if restart is None else {**exit_, "restart": restart})
        if restart is None:
            self.say(f"agent {self.name}: the run exited with {code}")
            return
        self.say(f"agent {self.name}: the run was killed (exit {code}); starting it again in {restart['in_s']:g} s "
                 f"(restart {restart['attempt']} of {restart['of']})")
        if not self._stopping.wait(restart["in_s"]):
            self._spawns.put(lambda refuse=False: self._respawn(child, refuse))

    def _restart_after(self, child: subprocess.Popen, code: int) -> dict | None:
        """The restart due for `child`, which exited with `code` ({"attempt", "of", "in_s"}), or
        None: it was asked to stop, exited with a status of its own, or has had its restarts."""
        with self._lock:
            if self.child is not child or self._asked_stop or self._stopping.is_set() or code >= 0 \
                    or self._launch is None or not PART_RESTARTS.wants_restart(code, self._restarts):
                return None
            if time.monotonic() - getattr(child, "started_at", 0.0) >= PART_RESTARTS.healthy_after:
                self._consecutive = 0
            delay = PART_RESTARTS.delay(self._consecutive)
            self._restarts += 1
            self._consecutive += 1
            self._restart_due = child
            return {"attempt": self._restarts, "of": PART_RESTARTS.max_restarts, "in_s": delay}

    def _respawn(self, dead: subprocess.Popen, refuse: bool = False) -> None:
        """Start the run that `dead` was again, from its order (on the thread of serve()), unless it
        was stopped, or a new order started another, meanwhile."""
        with self._lock:
            if self._restart_due is not dead or self.child is not dead or self._asked_stop or refuse:
                if self._restart_due is dead:
                    self._restart_due = None
                    self._remove_credentials()
                return
            self._restart_due = None
            command, env, _, path = self._launch
            try:
                child = subprocess.Popen(wrapped_argv(command, signal.SIGTERM), stdout=subprocess.PIPE,
                                         stderr=subprocess.STDOUT, text=True, env=env, start_new_session=True)
            except OSError as exc:
                self._remove_credentials()
                self.say(f"agent {self.name}: cannot start the run again: {exc}")
                self._publish("exit", {"code": -1, "lines": 0, "run": dead.pid,
                                       "error": f"cannot start the run again: {exc}"})
                return
            child.started_at = time.monotonic()
            self.child = child
            self._lines.start(child.pid)
        self.say(f"agent {self.name}: runs {path} again (pid {child.pid})")
        self._follow(child)

    def _publish(self, part: str, payload: dict) -> None:
        # session.put, not a publisher declared once: after the hub of an earlier run closed and
        # the next one's opened, a publisher declared before did not reach the new subscribers
        try:
            self.session.put(f"{agent_key(self.name)}/{part}", json.dumps(payload).encode())
        except Exception:  # noqa: BLE001 - the session is closing: the hub is gone anyway
            pass

    def _remove_credentials(self) -> None:
        if self._store is not None:
            self._store.remove()
            self._store = None

    def _stop_child(self, why: str, grace: float = 15.0) -> int | None:
        """SIGINT (the launcher stops its nodes in order), then SIGKILL to the group past `grace`."""
        with self._lock:
            child = self.child
            self._asked_stop = True  # its exit is no failure: not started again
            if self._restart_due is child:
                self._restart_due = None
                self._remove_credentials()
        if child is None:
            return None
        if child.poll() is None:
            self.say(f"agent {self.name}: stopping the run ({why})")
            try:
                os.killpg(child.pid, signal.SIGINT)
                return child.wait(grace)
            except subprocess.TimeoutExpired:
                os.killpg(child.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        return child.wait()


def main(name: str, connect: list[str], tls=None, workdir: str | None = None, secret: str | None = None) -> int:
    agent = Agent(name, connect, tls, workdir, secret=secret)
    previous = {sig: signal.signal(sig, lambda signum, frame: agent.stop()) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        return agent.serve()
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
