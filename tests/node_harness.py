"""Helpers for multi-process node tests: a hub session, node processes that are always stopped,
and bounded polling (never sleep-and-hope)."""
from __future__ import annotations

import json
import queue
import signal
import subprocess
import sys
import time
from pathlib import Path

from iotad.node_host import wire
from iotad.node_host.transport import free_port, open_session

ROOT = Path(__file__).resolve().parents[1]
ECHO = f"{ROOT / 'examples' / 'echo.py'}"


def wait_for(condition, timeout: float = 10.0, interval: float = 0.01, what: str = "condition"):
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        result = condition()
        if result:
            return result
        time.sleep(interval)
    raise AssertionError(f"timed out after {timeout}s waiting for {what}")


class Hub:
    """The test's own zenoh peer: it listens where nodes and tools connect, and collects samples."""

    def __init__(self):
        self.endpoint = f"tcp/127.0.0.1:{free_port()}"
        self.session = open_session([self.endpoint])
        self.samples: queue.SimpleQueue = queue.SimpleQueue()
        self.seen: list[tuple[str, object, tuple | None]] = []

    def subscribe(self, *keys: str) -> None:
        for key in keys:
            self.session.declare_subscriber(key, self._on_sample)

    def _on_sample(self, sample) -> None:
        try:
            value = wire.decode(sample.payload.to_bytes())
        except wire.WireError:
            value = "<malformed>"
        meta = None if sample.attachment is None else wire.decode_attachment(sample.attachment.to_bytes())
        key = str(sample.key_expr)
        if key.endswith("/@trace") and isinstance(value, list):  # a burst: one entry per event
            for event in value:
                self.samples.put((key, event, meta))
            return
        self.samples.put((key, value, meta))

    def drain(self) -> list:
        while True:
            try:
                self.seen.append(self.samples.get_nowait())
            except queue.Empty:
                return self.seen

    def values(self, key: str) -> list:
        return [value for k, value, _ in self.drain() if k == key]

    def wait_value(self, key: str, predicate, timeout: float = 10.0, what: str = ""):
        def found():  # a 1-tuple, so that a falsy value (0, None) still counts as found
            return next(((v,) for v in self.values(key) if predicate(v)), None)
        return wait_for(found, timeout, what=what or f"a matching sample on {key}")[0]

    def close(self) -> None:
        self.session.close()


class Node:
    """A node process started from a config dict; `stop()` always ends it (SIGTERM, then kill)."""

    def __init__(self, config: dict):
        self.config = config
        self.process = subprocess.Popen([sys.executable, "-m", "iotad.node_host", "--config-json", json.dumps(config)],
                                        cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE)

    @property
    def base(self) -> str:
        return f"iota/{self.config['system']}/{self.config['path']}"

    def stop(self, timeout: float = 5.0) -> int:
        """Stopped as its launcher stops it (SIGINT: exit 0); killed if it does not stop."""
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGINT)
            try:
                self.process.wait(timeout)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        for pipe in (self.process.stdout, self.process.stderr):
            if pipe is not None and not pipe.closed:
                pipe.close()
        return self.process.returncode


def node_config(hub: Hub, path: str, ref: str, system: str = "test", **extra) -> dict:
    config = {"system": system, "path": path, "source": {"kind": "python", "ref": ref},
              "listen": ["tcp/127.0.0.1:0"], "connect": [hub.endpoint], "heartbeat_period": 0.1}
    config.update(extra)
    return config


def wait_ready(hub: Hub, node: Node, timeout: float = 15.0) -> None:
    """A heartbeat proves the engine loop runs and (declared before it) the node's subscribers."""
    hub.wait_value(f"{node.base}/@heartbeat", lambda v: True, timeout, what=f"{node.base} heartbeat")
