"""The node host: one IOTA as one process on zenoh (docs/internals.md "Node host").

One engine thread runs the IOTA under a `HostClock`; zenoh callbacks only enqueue raw samples.
Outputs go out from an engine sink on pre-declared publishers (msgpack payload, attachment
`[seq, send_time_ns]`); every event goes to `@trace` (in bursts, one sample each, at a lower zenoh priority than
outputs, after an explicit `start` event that says when the engine started); a liveliness token, a heartbeat driven by
the engine thread and an `@spec` queryable let tools see the node. `close()` stops the engine
and closes the session: an unclosed session with callback subscribers hangs the interpreter.
"""
from __future__ import annotations

import math
import os
import socket
import sys
import threading
import time
from pathlib import Path
from typing import Any

import zenoh

from iotad.node_host import wire
from iotad.kernel.compose import Composite, flatten
from iotad.kernel.engine import INPUT_REFUSALS, Engine
from iotad.node_host.can_port import CAN_RX_BURST, CAN_TX, CAN_TX_BURST, TX_BURSTS, CanPort
from iotad.node_host.channel_table import ChannelTable, build, plain_params
from iotad.node_host.host_clock import HostClock, RawInput
from iotad.node_host.node_config import ConfigError, NodeConfig
from iotad.node_host.peer_restart import PEER_RESTART, watch_for_host
from iotad.node_host.session_close import close_session
from iotad.kernel.model import param_values
from iotad.kernel.policy import make_policy
from iotad.node_host.transport import open_session


def _log_fault(event: dict) -> None:
    """An exception of the node's own code, with its traceback, in the node's log (its stderr)."""
    value = event.get("value")
    if event["kind"] == "violation" and isinstance(value, dict) and value.get("traceback"):
        print(f"t={event['t']:.4f} {event['iota']}.{event['action']}: {value.get('message')}\n"
              f"{value['traceback'].rstrip()}", file=sys.stderr, flush=True)


class SpecLoadError(Exception):
    """The IOTA named by the config could not be loaded or instantiated; `str()` says why."""


def load_root(config: NodeConfig) -> tuple[Any, str]:
    """The root IOTA (an instance or a `Composite`) and its source text, as the config names it."""
    source = config.source
    if source["kind"] == "esprit":
        path = Path(source["file"])
        try:
            from iotad import esprit# lazily: a Python-only node needs no grammar
        except ImportError as exc:
            raise SpecLoadError(f"{path}: ESPRIT support is not available ({exc})") from None
        try:
            root = esprit.load_iota(str(path), iota=source.get("iota"), name=config.name, **config.params)
        except getattr(esprit, "EspritError", ()) as exc:
            raise SpecLoadError(str(exc)) from None
        except OSError as exc:
            raise SpecLoadError(f"{path}: {exc.strerror or exc}") from None
        except Exception as exc:  # noqa: BLE001 - unknown params and the like: say so, no traceback
            raise SpecLoadError(f"{path}: {type(exc).__name__}: {exc}") from None
        return root, _read_text(path)
    from iotad.kernel.python_loader import LoadError, load_object

    ref = source["ref"]
    try:
        factory = load_object(ref)
    except LoadError as exc:
        raise SpecLoadError(str(exc)) from None
    try:
        root = factory(config.name, **config.params)
    except Exception as exc:  # noqa: BLE001
        from iotad.kernel.code_fault import fault_text, fault_traceback

        # the line that raised, and its traceback, in the node's log: init() is the user's code
        raise SpecLoadError(f"{ref}: cannot instantiate with params {config.params}: "
                            f"{fault_text(exc)}\n{fault_traceback(exc).rstrip()}") from None
    if not (hasattr(root, "iota_spec") or isinstance(root, Composite)):
        raise SpecLoadError(f"{ref}: {type(root).__name__} is not an IOTA")
    return root, _python_text(ref, factory)


def _read_text(path: Path) -> str:
    try:
        return path.read_text()
    except OSError:
        return ""


def _python_text(ref: str, factory: Any) -> str:
    where = ref.rsplit(":", 1)[0]
    if where.endswith(".py"):
        return _read_text(Path(where))
    import inspect

    try:
        return inspect.getsource(inspect.getmodule(factory))
    except (OSError, TypeError):
        return ""


class NodeHost:
    def __init__(self, config: NodeConfig, root: Any, text: str = ""):
        self.config, self.root, self.text = config, root, text
        self.flat = flatten(root)
        self.table: ChannelTable = build(config, self.flat)  # ConfigError before any session opens
        self._trace_buffer: list[dict] = []
        self.clock = HostClock(config.time_unit, config.origin, heartbeat_period=config.heartbeat_period,
                               on_heartbeat=self._heartbeat, on_malformed=self._malformed,
                               flush=self._flush_trace, pending=self._trace_buffer.__len__,
                               trace_period=config.trace_period, input_queue=config.input_queue,
                               on_overflow=self._overflow)
        self.engine = Engine(root, self.clock, make_policy(config.policy, config.seed), record=False,
                             sinks=[self._publish_output, self._trace_buffer.append, _log_fault],
                             deadline_tolerance=config.deadline_tolerance / config.time_unit,
                             input_tolerance=config.arrival_tolerance / config.time_unit)
        self.session: zenoh.Session | None = None
        self._declared: list[Any] = []
        self._ports: dict[tuple, list] = {}  # engine (path, channel, index) -> [publisher, seq, key]
        self._thread: threading.Thread | None = None
        self._settle: Any = None
        self._go = threading.Event()  # the start gate opened (or the node is closing)
        self._closing = False
        self.error: BaseException | None = None
        self.can: CanPort | None = None
        self._can_source = None  # the engine (path, channel, index) of the root's can_tx
        self._can_burst_source = None  # ... of its can_tx_burst: an instant's frames in one output
        if config.can is not None:
            if hasattr(root, "can_bus_name"):  # a station that names its bus in what it reports
                root.can_bus_name = config.can["bus"]
            if TX_BURSTS in getattr(getattr(root, "iota_spec", None), "params", ()) and TX_BURSTS not in config.params:
                root.tx_bursts = True  # a station that can send either way: an instant's frames in one output
            self._can_source = next((p.source for p in self.table.outputs if p.name == CAN_TX), None)
            self._can_burst_source = next((p.source for p in self.table.outputs if p.name == CAN_TX_BURST), None)
            listen_only = bool(config.can.get("listen_only"))  # a bus logger: it hears, never sends
            if (self._can_source is None and not listen_only) or not any(p.name == "can_rx" for p in self.table.inputs):
                raise ConfigError(f"{config.path}: sits on CAN bus {config.can['bus']!r} but has no "
                                  f"can_tx output and can_rx input")
            self.can = CanPort(config.can, self.clock.post, self.clock.now,
                               burst=any(p.name == CAN_RX_BURST for p in self.table.inputs))
        # the ROS 2 bridge (iotad/ros2/bridge.py) says what its port speaks; no other IOTA has one
        self.ros2 = None
        ros2_config = getattr(root, "ros2_port", None)
        if ros2_config is not None:
            from iotad.ros2.port import Ros2Port
            self.ros2 = Ros2Port(ros2_config, self.clock.post, RawInput, wire.encode, wire.encode_attachment,
                                 self.clock.now)
            self.engine.sinks.append(self.ros2.on_event)

    # ------------------------------------------------------------------ start and stop
    def start(self, settle: Any = None) -> None:
        """Open the session, declare every port, go live and start the engine thread. With a
        `start_gate` in the config the engine waits for the launcher's token first. `settle`, if
        given, runs on the engine thread just before the engine starts (the node process
        collects and freezes its heap there: a collection in another thread would hold the
        interpreter while the first windows run)."""
        config = self.config
        # Shared memory is off by default: it buys nothing for small messages and costs each of
        # many node processes ~2 MB (measured with 32 nodes); a config's "zenoh" may turn it on.
        extra = {"transport/shared_memory/enabled": False, **config.zenoh,
                 **(self.ros2.session_settings() if self.ros2 is not None else {})}  # a latched topic: timestamps
        self.session = session = open_session(config.listen, config.connect, extra=extra)
        base = f"{wire.PREFIX}/{config.system}/{config.path}"
        block = zenoh.CongestionControl.BLOCK
        for port in self.table.outputs:
            publisher = session.declare_publisher(port.key, express=True, congestion_control=block)
            self._declared.append(publisher)
            self._ports[port.source] = [publisher, 0, port.key]
        # The trace is for the recorder and tools: below the outputs, which real-time peers wait on.
        self._trace_pub = session.declare_publisher(wire.trace_key(config.system, config.path),
                                                    congestion_control=block, priority=zenoh.Priority.DATA_LOW)
        self._trace_seq = 0
        self._process: tuple[int, int] | None = None  # (pid, started_ns) once the engine started
        self._beat_pub = session.declare_publisher(f"{base}/{wire.HEARTBEAT}")
        self._declared += [self._trace_pub, self._beat_pub]
        if self.can is not None:
            self.can.open()  # CanPortError: the caller reports it, the node does not start
        if self.ros2 is not None:
            self._declared += self.ros2.open(session)  # undeclared with the node's own entities
        post = self.clock.post
        for port in self.table.inputs:
            for key in port.keys:
                self._declared.append(session.declare_subscriber(key, _receiver(post, port.name, port.index, key)))
        spec_key = f"{base}/{wire.SPEC}"
        spec_payload = wire.encode(self.describe())
        self._declared.append(session.declare_queryable(
            spec_key, lambda query: query.reply(spec_key, spec_payload)))
        # peers' restarts as input events, if the IOTA asks for them (iotad/node_host/peer_restart.py)
        restart_port = self.flat.external.get(PEER_RESTART)
        if restart_port is not None and restart_port[0] == "input":
            leaf = next(lf for lf in self.flat.leaves if lf.path == restart_port[1].path)
            watch = watch_for_host(session, config, leaf.iota.iota_spec.channels[restart_port[1].channel].type,
                                   self.clock.post_always)
            if watch is not None:
                self._declared.append(watch)
        if config.follow_origin is not None:  # the hub's origin on this host's clock, measured again
            self._declared.append(session.declare_subscriber(config.follow_origin, self._on_origin))
        if config.start_gate is not None:
            self._declared.append(session.liveliness().declare_subscriber(
                config.start_gate, self._on_gate, history=True))  # history: a token already there counts
        # The token last: whoever sees the node alive may rely on its subscribers being declared.
        self._declared.append(session.liveliness().declare_token(f"{base}/{wire.ALIVE}"))
        self._settle = settle
        self._thread = threading.Thread(target=self._run, name=f"engine {config.path}", daemon=True)
        self._thread.start()

    def _on_origin(self, sample: zenoh.Sample) -> None:
        try:
            origin = wire.decode(sample.payload.to_bytes())["origin"]
            if isinstance(origin, bool) or not isinstance(origin, (int, float)) or not math.isfinite(origin):
                raise TypeError(origin)
        except (wire.WireError, TypeError, KeyError):
            return  # not the launcher's: the clock keeps what it has
        self.clock.follow(float(origin))

    def _on_gate(self, sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            self._go.set()

    def _run(self) -> None:
        try:
            if not self._wait_at_gate():
                return
            if self._settle is not None:
                self._settle()
            self._start_engine()
            self.engine.run()
        except BaseException as exc:  # noqa: BLE001 - reported by the main thread
            self.error = exc
        finally:
            try:
                if self.can is not None:
                    self._can_problems(self.clock.now())  # what came since the last heartbeat
                self._flush_trace()
            except Exception:  # noqa: BLE001 - the session may be closing
                pass

    def _wait_at_gate(self) -> bool:
        """Wait for the launcher's start gate (if the config names one), heartbeating meanwhile so
        that the launcher does not take the node for frozen; False: the node was closed first."""
        if self.config.start_gate is None:
            return not self._closing
        period = self.config.heartbeat_period
        while not self._go.wait(period):
            self._beat(self.clock.now(), 0)
        return not self._closing

    def _start_engine(self) -> None:
        """Evaluate every precondition at one instant t0 and say so first on @trace: the `start`
        event gives checker and replay the exact start of the first windows."""
        clock = self.clock
        t0 = clock.now()
        clock.now = lambda: t0  # the engine's start reads the clock: let it read exactly t0
        try:
            self.engine.start()
        finally:
            del clock.now
        started_ns = time.time_ns()
        # every burst names this process from now on: a recorder that missed this start record (a
        # restart while its host was cut off) still tells the new process from the one before
        self._process = (os.getpid(), started_ns)
        self._trace_buffer.insert(0, wire.start_event(t0, self.root.instance_name, started_ns / 1e9, os.getpid()))
        self._flush_trace()

    def alive(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def close(self, timeout: float = 5.0) -> None:
        """Stop the engine, then undeclare everything and close the session. Idempotent."""
        self._closing = True
        self._go.set()  # a node still waiting at the start gate stops waiting
        if self._thread is not None:
            self.engine.stop()
            self._thread.join(timeout)
        if self.can is not None:
            self._last_can_frames()
            self.can.close()
        for entity in reversed(self._declared):
            try:
                entity.undeclare()
            except Exception:  # noqa: BLE001 - already gone with a closing session
                pass
        self._declared.clear()
        if self.session is not None:
            session, self.session = self.session, None
            # peers on a host that is cut off are not waited for: the node stops in time for
            # its launcher's SIGINT patience, and exits cleanly
            problem = close_session(session)
            if problem:
                print(f"{self.config.path}: {problem}", file=sys.stderr, flush=True)

    # ------------------------------------------------------------------ engine-thread work
    def _publish_output(self, event: dict) -> None:
        """Publish an output; note on the event (which the trace sink gets next) what went on the
        wire: key, sequence and send time of an output; of an input from outside, the key it
        arrived on and the sender's attachment. A recorder rebuilds every message from these."""
        kind = event["kind"]
        if kind == "input" or kind == "violation":
            raw = self.clock.current_input
            # an input refused (bad_value, switching_time) names what it refused the same way, so
            # that a recorder counts that message as seen, not as a gap in its sender's sequence
            if raw is not None and (kind == "input" or (event["action"] == raw.name and event["index"] == raw.index
                                                       and isinstance(event.get("value"), dict)
                                                       and event["value"].get("violation") in INPUT_REFUSALS)):
                self.clock.current_input = None  # the one external input event of this step
                event["key"] = raw.key
                attachment = wire.decode_attachment(raw.attachment)
                if attachment is not None:
                    event["seq"], event["send_ns"] = attachment
            return
        if kind != "output":
            return
        port = self._ports.get((event["iota"], event["action"], event["index"]))
        if port is None:
            return  # an output of a component that the root does not expose
        seq = port[1]
        port[1] = seq + 1
        send_ns = time.time_ns()
        if self.can is not None and (event["iota"], event["action"], event["index"]) == self._can_source:
            # the frame first: the bus is the latency-critical path (a motor setpoint's frames go
            # out one firing each), the zenoh copy is for watchers and the recorder
            problem = self.can.send(event["value"])
            if problem is not None:
                self._report(event["t"], CAN_TX, None, "can_send_failed", problem)
        elif self.can is not None and (event["iota"], event["action"], event["index"]) == self._can_burst_source:
            # an instant's frames as one output (iotad.can.burst_bus): on a real bus, one by one in order
            for problem in self.can.send_all(event["value"] or ()):
                self._report(event["t"], CAN_TX_BURST, None, "can_send_failed", problem)
        port[0].put(wire.encode(event["value"]), attachment=wire.encode_attachment(seq, send_ns))
        event["key"], event["seq"], event["send_ns"] = port[2], seq, send_ns

    def _last_can_frames(self) -> None:
        """Frames the IOTA asks to send as it stops (`final_can_frames()`, e.g. a motor node's
        Estop), sent on the bus after the engine stopped and before the bus closes."""
        final = getattr(self.root, "final_can_frames", None)
        if final is None or self.can.bus is None:
            return
        try:
            frames = list(final())
        except Exception:  # noqa: BLE001 - a stopping node: send what we can, never raise here
            return
        for value in frames:
            self.can.send(value)

    def _flush_trace(self) -> None:
        buffer = self._trace_buffer
        if not buffer:
            return
        # One sample per burst (docs/internals.md "Wire"): a receiver is woken once per burst, not
        # per event; seq counts events, so a receiver sees how many it missed.
        seq = self._trace_seq
        self._trace_pub.put(wire.encode_burst(buffer), attachment=wire.encode_attachment(seq, None, self._process))
        self._trace_seq = seq + len(buffer)
        buffer.clear()

    def _can_problems(self, t: float) -> None:
        """What the CAN reader saw that no IOTA can take (error frames, CAN FD frames, a bus that
        fails), as violations on can_rx: at most one of each kind per heartbeat period."""
        for violation, message, count in self.can.take_problems():
            self._report(t, "can_rx", None, violation, message, count=count)

    def _heartbeat(self, t: float, backlog: int) -> None:
        if self.can is not None:
            self._can_problems(t)
        if self.ros2 is not None:
            for channel, violation, message, count in self.ros2.take_problems():
                self._report(t, channel, None, violation, message, count=count)
        self._beat(t, backlog)

    def _beat(self, t: float, backlog: int) -> None:
        self._beat_pub.put(wire.encode({"t": t, "firings": self.engine.firings, "queue": backlog,
                                        "restarts": self.config.restarts}))

    def _overflow(self, t: float, channel: str, index: int | None, count: int, first: float, last: float) -> None:
        label = channel if index is None else f"{channel}[{index}]"
        self._report(t, channel, index, "input_overflow",
                     f"input queue full ({self.config.input_queue} inputs): {count} input(s) on {label} dropped "
                     f"between t={first:.6f} and t={last:.6f}", dropped=count)

    def _malformed(self, t: float, raw: RawInput, message: str) -> None:
        self._report(t, raw.name, raw.index, "malformed_payload", f"input {raw.name}: {message}; dropped")

    def _report(self, t: float, channel: str, index: int | None, violation: str, message: str, **extra: Any) -> None:
        """A violation the host itself saw, recorded in order with the node's events."""
        event = {"t": t, "iota": self.root.instance_name, "action": channel, "index": index,
                 "kind": "violation", "value": {"violation": violation, "message": message, **extra}}
        for sink in self.engine.sinks:
            sink(event)

    # ------------------------------------------------------------------ introspection
    def describe(self) -> dict:
        config = self.config
        params = config.params if isinstance(self.root, Composite) else param_values(self.root)
        source = dict(config.source)
        neighbours = {}
        if source.get("kind") == "python" and not isinstance(self.root, Composite):
            source["module"] = type(self.root).__module__  # replay resolves its relative imports there
            where = str(source.get("ref", "")).rpartition(":")[0]
            if where.endswith(".py") and self.text:
                from iotad.kernel.python_loader import neighbour_sources

                # the modules beside it that it imports, for a check where that folder is gone
                neighbours = neighbour_sources(where)
        return {"system": config.system, "path": config.path, "source": source, "text": self.text,
                **({"neighbours": neighbours} if neighbours else {}),
                "params": plain_params(params), "channels": self.table.described,
                "time_unit": config.time_unit, "origin": self.clock.origin_wall, "pid": os.getpid(),
                "trace": wire.trace_key(config.system, config.path), "started": time.time(),
                # the system file's host, else this machine's name: where the node runs, for ls and top
                "host": config.host or socket.gethostname()}


def _receiver(post, name: str, index: int | None, key: str):
    """A zenoh callback for one input key: copy the bytes out and enqueue; decoding is the engine's."""
    def receive(sample: zenoh.Sample) -> None:
        attachment = sample.attachment
        post(RawInput(name, index, sample.payload.to_bytes(),
                      None if attachment is None else attachment.to_bytes(), key))
    return receive


__all__ = ["ConfigError", "NodeHost", "SpecLoadError", "load_root"]
