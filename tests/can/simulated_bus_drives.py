"""Simulated drives of both families answering on an in-process python-can bus ("virtual"), in a
thread, for the tests of `iotad can`: ODrive axes (sim/odrive_axis.py) and CiA 402 drives
(sim/cia402_drive.py) with motors that hold still. Use as a context manager: the thread stops.
An ODrive axis sends its cyclic Heartbeat every `heartbeat_period` (0: none, as a peer whose
cyclic messages are off: then only a remote request tells its state)."""
from __future__ import annotations

import threading
import time

from iotad.can import canopen as co
from iotad.can import odrive
from iotad.can.bus import open_bus
from iotad.can.frame import FrameError
from sim.cia402_drive import Cia402Drive
from sim.odrive_axis import AxisConfig, OdriveAxis

STEP = 0.005


class BusDrives:
    def __init__(self, channel: str, odrives=(1, 2), cia402=(5, 6), heartbeat_period: float = 0.1):
        self.channel = channel
        self.heartbeat_period = heartbeat_period
        self.axes = {n: OdriveAxis(n, AxisConfig()) for n in odrives}
        self.drives = {n: Cia402Drive(n, AxisConfig()) for n in cia402}
        self.stop = threading.Event()
        self.lock = threading.Lock()
        self.bus = open_bus("virtual", channel)
        self.thread = threading.Thread(target=self._serve, daemon=True)

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stop.set()
        self.thread.join(5)
        self.bus.shutdown()

    def _serve(self):
        start = time.monotonic()
        next_step = next_beat = 0.0
        while not self.stop.is_set():
            got = self.bus.recv_frame(timeout=0.001)
            now = time.monotonic() - start
            with self.lock:
                if got is not None:
                    self._handle(got[1], now)
                while now >= next_step:
                    for axis in self.axes.values():
                        axis.update(0.0, 0.0, next_step, STEP)
                    for drive in self.drives.values():
                        drive.update(0.0, 0.0, next_step, STEP)
                    next_step += STEP
                if self.heartbeat_period and now >= next_beat:
                    for axis in self.axes.values():
                        self.bus.send_frame(axis.heartbeat())
                    next_beat = now + self.heartbeat_period
                for drive in self.drives.values():
                    for frame in drive.outbox:
                        if not (frame.id & 0x780 in (co.HEARTBEAT, co.TPDO[0], co.TPDO[1])):  # keep the bus quiet
                            self.bus.send_frame(frame)
                    drive.outbox.clear()

    def _handle(self, frame, now):
        for drive in self.drives.values():
            drive.handle(frame, now)
        if frame.id >> 5 in self.axes and not (frame.id & 0x780 == co.RSDO and frame.id & 0x7F in self.drives):
            try:
                message = odrive.decode(frame, as_axis=True)
            except FrameError:
                return
            for answer in self.axes[message.node_id].handle(message, now):
                self.bus.send_frame(answer)
