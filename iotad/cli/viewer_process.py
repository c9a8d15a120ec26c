"""`iotad view` as a child process of `iotad run --view`: started once the hub accepts
connections, stopped with the run (a module of its own: `run` and `view` are sibling commands)."""
from __future__ import annotations

import sys
import time


class ViewerProcess:
    """`iotad view` beside `iotad run --view`: started once the hub accepts connections (the
    launcher opens it first), stopped with the run. Its lines go to the run's output."""

    def __init__(self, endpoint: str, system: str, port: int):
        import threading

        self.endpoint, self.system, self.port = endpoint, system, port
        self.proc = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._start, name="viewer", daemon=True)
        self._thread.start()

    def _start(self) -> None:
        import socket
        import subprocess

        host, _, port = self.endpoint.removeprefix("tcp/").rpartition(":")
        deadline = time.monotonic() + 60
        while not self._stop.is_set() and time.monotonic() < deadline:
            try:
                socket.create_connection((host, int(port)), timeout=0.5).close()
                break
            except OSError:
                self._stop.wait(0.2)
        else:
            return
        self.proc = subprocess.Popen([sys.executable, "-m", "iotad", "view", "--connect", self.endpoint,
                                      "--system", self.system, "--port", str(self.port)])

    def stop(self) -> None:
        import subprocess

        self._stop.set()
        self._thread.join(5)
        if self.proc is not None and self.proc.poll() is None:
            import signal

            self.proc.send_signal(signal.SIGINT)  # a clean stop: it prints what it bridged
            try:
                self.proc.wait(5)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(5)
