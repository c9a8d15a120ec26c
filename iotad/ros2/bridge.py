"""The ROS 2 bridge of a system: an implicit node named `ros2` whose node host speaks rmw_zenoh.

Being an ordinary node (like a CAN bus's logger) is the point: the launcher starts and
supervises it, the recorder records it, and every value it carries is an event of its trace.
For mapping k in direction out, input `out_k` is bound from the mapped output: the node host's
ROS 2 port (`iotad.ros2.port`) publishes each value it takes as a ROS 2 message. For mapping k
in direction in, the port posts each ROS 2 message as input `ros_k`, carrying the target's
switching time (a message sooner than that is refused and recorded as a `switching_time`
violation, as any input is), and output `in_k`, bound to the target input, forwards it at once
(within `lag` seconds, else a deadline miss).
"""
from __future__ import annotations

from typing import Any

from iotad.kernel.api import Input, Iota, Output, Param
from iotad.ros2 import value_types

NODE_NAME = "ros2"  # the bridge's node path in a system (a name no [[node]] may take)


def channel_names(number: int, direction: str) -> tuple[str, ...]:
    """The bridge's channels of mapping `number`: (out_k,) for out, (ros_k, in_k) for in."""
    return (f"out_{number}",) if direction == "out" else (f"ros_{number}", f"in_{number}")


def ros2_bridge(name: str = NODE_NAME, mappings: list | None = None, switching: list | None = None,
                ros_node: str = "iotad", lag: float = 0.05) -> Iota:
    """The bridge IOTA for `mappings` (plain `Mapping`s); `switching[k]` is the switching time of
    mapping k's target input (in the system's time unit), `lag` the forwarding window."""
    mappings = list(mappings or [])
    switching = list(switching or [0.0] * len(mappings))
    # the mappings are parameters too: the node's @spec (and so a recording) holds them, and
    # replay or `iotad export --ros2` rebuild the same bridge from it
    attributes: dict[str, Any] = {"lag": Param(lag), "mappings": Param(mappings), "switching": Param(switching),
                                  "ros_node": Param(ros_node), "__module__": __name__}
    for number, mapping in enumerate(mappings):
        if mapping["channel"] is None:  # constant (robot_description): its port publishes it, no channel
            continue
        value_type = value_types.build(mapping["value_type"])
        if mapping["direction"] == "out":
            (out,) = channel_names(number, "out")
            attributes[out] = decl = Input(value_type, switching=0)
            decl.input(_taken)
            continue
        ros, forward = channel_names(number, "in")
        attributes[ros] = inbound = Input(value_type, switching=float(switching[number]))
        inbound.input(_queue(number))
        attributes[forward] = outbound = Output(value_type, switching=float(switching[number]))
        outbound.action(value=_first(number), when=_waiting(number), within=(0, "lag"))(_sent(number))

    def init(self) -> None:
        self.pending = {k: [] for k, m in enumerate(mappings) if m["direction"] == "in"}

    attributes["init"] = init
    # named as the factory: a recording of a virtual run names the class as its source, and
    # replay then finds this function, which builds the same class again from the parameters
    cls = type("ros2_bridge", (Iota,), attributes)
    bridge = cls(name, lag=lag, mappings=mappings, switching=switching, ros_node=ros_node)
    # what the node host's ROS 2 port needs: not a parameter of the IOTA, a description of its wire
    object.__setattr__(bridge, "ros2_port", {"node": ros_node, "mappings": mappings})
    return bridge


def _taken(self, value):
    """A value to publish: the port publishes it from the input event itself."""


def _queue(number: int):
    def took(self, value):
        self.pending[number].append(value)
    return took


def _first(number: int):
    return lambda self: self.pending[number][0]


def _waiting(number: int):
    return lambda self: bool(self.pending[number])


def _sent(number: int):
    def sent(self):
        self.pending[number].pop(0)
    return sent
