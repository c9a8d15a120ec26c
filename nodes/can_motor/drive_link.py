"""`DriveLink`, the motor node's interface to one axis: the hooks a drive family implements (ODrive in odrive_link.py, CiA 402 in cia402_link.py).

The node (nodes/can_motor/node.py) knows phases (UNARMED, ARMING, ARMED, FAULT, ESTOPPED),
setpoints, limits, timers and reports; a link knows its family's frames and what the drive's own
messages say. As python-can's `BusABC` leaves `send` and `_recv_internal` to each interface, the
node calls only the hooks below and never asks which family it talks to:

- routing: `frame_ids` (what the drive sends, to this link), `bus_ids` (what the family's master
  side sends: heard from elsewhere, another master is on the bus);
- `receive`: a frame from the drive; the link updates the axis and tells the node through
  `node.report`, `node.send`, `node.reject_frame` and `node.drive_enabled` (the common phase changes);
- frames for the node's decisions: `arming_frames`, `setpoint_frames`, `stop_frames` (estop),
  `idle_frames` (link watch), `poll_frames`, `tick_frames` (every tick), and, once per family,
  `bus_tick_frames` and `after_stop_frames`;
- `heartbeat_lost`: the drive fell silent for its heartbeat timeout;
- `abandon`: an arming given up (the frames that end what it had under way).

`feeds_watchdog` says whether the drive's watchdog is fed by repeated commands (ODrive: the node's
keep-alive and arm-hold frames) or watches the master some other way (CiA 402: its heartbeat
consumer watches the node's heartbeat).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, Iterable, Sequence

from iotad.can.frame import Frame

if TYPE_CHECKING:  # the node imports the links, not the other way round
    from .node import CanMotor

UNARMED, ARMING, ARMED, FAULT, ESTOPPED = "UNARMED", "ARMING", "ARMED", "FAULT", "ESTOPPED"


class Axis:
    """What the node knows about one axis; plain state, changed only by the node's actions."""

    def __init__(self, node_id: int):
        self.node_id = node_id
        self.phase = UNARMED
        self.retry = False            # the next arming is a retry: it waits arm_retry first
        self.link_stopped = False     # the link watch disarmed it: it re-arms when setpoints return
        self.lost = False
        self.beat = False             # a heartbeat's report is waiting to go out (see `lost`)
        self.heard = False            # any heartbeat ever
        self.axis_state = 0
        self.axis_error = 0
        self.procedure_result = 0
        self.trajectory_done = False
        self.active_errors = 0
        self.disarm_reason = 0
        self.error_register = 0       # CiA 402: the last EMCY's
        self.rearms = 0               # automatic re-arms in a row (auto_rearm), for the back-off and the limit
        self.armed_tick = 0           # the tick it was last armed
        self.has_position = False
        self.position = 0.0           # joint units
        self.velocity = 0.0
        self.effort = 0.0
        self.command = 0.0            # the joint-unit command the axis follows now
        self.last_sent = 0            # the tick of the last command (or arming) frame
        self.last_frame = None        # the last command frame sent while ARMED (skip_unchanged)
        self.torque_estimate = 0.0    # controller units from here on
        self.iq_measured = 0.0
        self.fet_temperature = 0.0
        self.motor_temperature = 0.0
        self.bus_voltage = 0.0
        self.bus_current = 0.0


class DriveLink:
    """The node's side of one axis of one drive family. Subclasses implement the hooks."""

    family = ""
    feeds_watchdog = False

    def __init__(self, node: "CanMotor", index: int):
        self.node = node
        self.index = index
        self.joint = node.joint_map[index]
        self.axis: Axis = node.axes[index]

    # ------------------------------------------------------------------ routing
    @staticmethod
    def node_id_of(frame_id: int) -> int:
        """The node id a frame of this family with `frame_id` comes from (for naming a stranger)."""
        raise NotImplementedError

    def frame_ids(self) -> Iterable[int]:
        """The 11-bit ids of the frames this drive sends (and this node commands it with)."""
        raise NotImplementedError

    @classmethod
    def bus_ids(cls, links: Sequence["DriveLink"]) -> frozenset:
        """Ids the family's master side sends to the bus as a whole (none by default)."""
        return frozenset()

    def receive(self, frame: Frame, value: Any) -> None:
        """A frame whose id is one of `frame_ids`."""
        raise NotImplementedError

    # ------------------------------------------------------------------ frames for the node's decisions
    def arming_frames(self) -> list[Frame]:
        """The frames that begin an arming (the axis' `command` is its hold command)."""
        raise NotImplementedError

    def heartbeat_lost(self) -> list[str]:
        """No heartbeat for the node's `lost_after` periods (the axis is LOST): the events it makes.
        By default only LOST (an ODrive's own watchdog stops it; setpoints still reach it)."""
        return ["LOST"]

    def abandon(self) -> list[Frame]:
        """An arming that timed out or was stopped: forget what was under way; the frames that end
        it on the drive's side (none by default)."""
        return []

    def setpoint_frames(self, command: float, velocity_ff: float, torque_ff: float) -> tuple[Frame, ...]:
        """The frames of one command in joint units (EncodeError if no frame holds it)."""
        raise NotImplementedError

    def stop_frames(self) -> list[Frame]:
        """An emergency stop."""
        raise NotImplementedError

    def idle_frames(self) -> list[Frame]:
        """The power stage off now (the link watch lost the setpoints' source)."""
        raise NotImplementedError

    def poll_frames(self, name: str) -> list[Frame]:
        """Remote requests for the message `name` of the node's `polls` (none by default)."""
        return []

    def tick_frames(self) -> list[Frame]:
        """What the axis gets at every tick besides setpoints and keep-alives (none by default)."""
        return []

    @classmethod
    def bus_tick_frames(cls, links: Sequence["DriveLink"], ticks: int) -> list[Frame]:
        """Once per tick for all of a family's links, after their `tick_frames` (none by default)."""
        return []

    @classmethod
    def after_stop_frames(cls, links: Sequence["DriveLink"]) -> list[Frame]:
        """Once after stop or idle frames went to a family's links (none by default)."""
        return []
