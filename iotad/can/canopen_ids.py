"""The CiA 402 (CANopen) node ids that nodes' params name, for the tools that decode a bus by family.

A bus's frames carry no protocol: an 11-bit id is CANopen or ODrive CAN Simple by the node ids
its stations use. The stations say which in their params, so `iotad candump` (a recording's or
a system file's nodes) and the bus's log (`iotad run`, its stations) read them the same way: a
motor node's joints with `protocol = "cia402"` and simulated drives' `cia402` ids. Light on
purpose (no `canopen` package): the system file's parser asks it for every bus.
"""
from __future__ import annotations

from typing import Any, Iterable


def canopen_nodes(node_params: Iterable[Any]) -> frozenset:
    """The CiA 402 node ids that nodes' params name: a motor node's joints with protocol = "cia402",
    simulated drives' `cia402` ids. Params of another shape name none (they are checked elsewhere)."""
    nodes = set()
    for params in node_params:
        if not isinstance(params, dict):
            continue
        joints = params.get("joints")
        entries = joints.values() if isinstance(joints, dict) else joints if isinstance(joints, list) else ()
        nodes |= {j.get("node_id") for j in entries if isinstance(j, dict) and j.get("protocol") == "cia402"}
        drives = params.get("cia402")
        nodes |= set(drives.values() if isinstance(drives, dict) else drives if isinstance(drives, list) else ())
    return frozenset(n for n in nodes if isinstance(n, int) and not isinstance(n, bool) and 1 <= n <= 127)
