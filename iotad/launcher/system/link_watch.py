"""Which nodes watch the link to their inputs' source: a node whose IOTA has a `link_timeout`
parameter, left unset in the system file, gets `[system] link_timeout` when one of its bound inputs
comes from a node on another host.

Why only then: on one host a source and its reader live and die together (the launcher sees both),
and a watch could only add false trips on a loaded machine, and change recordings that exist.
Across hosts a cut network leaves the reader running with nobody telling it what to do; for a
CAN motor node (nodes/can_motor/node.py) that would mean motors held armed, fed by its own
keep-alive, for as long as the partition lasts.
"""
from __future__ import annotations

from typing import Any

LINK_TIMEOUT = "link_timeout"  # the parameter's name, in every IOTA that watches its link


def link_params(system: Any, node: str) -> dict[str, float]:
    """{"link_timeout": seconds} for the node host's params when `node` watches its link, else {}."""
    spec = system.nodes[node]
    if LINK_TIMEOUT not in spec.param_names or LINK_TIMEOUT in spec.params or not system.link_timeout:
        return {}
    if spec.host is None or not any(system.nodes[source].host != spec.host for source in sources_of(system, node)):
        return {}
    return {LINK_TIMEOUT: float(system.link_timeout)}


def sources_of(system: Any, node: str) -> set[str]:
    """The nodes whose outputs are bound to an input of `node`."""
    return {b.source.node for b in system.bindings if b.target.node == node and b.source.node in system.nodes}
