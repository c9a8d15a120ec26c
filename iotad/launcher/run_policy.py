"""The firing policy of a virtual run: `--policy NAME` (or `--seed N`, short for `random:N`) for
the system, and the policy a `[[node]]` declares for itself (`policy = "latest"`), which holds
for that node whatever the run's (docs/stress.md)."""
from __future__ import annotations

from typing import Any

from iotad.kernel.policy import Eager, PerNode, PolicyError, Random, make_policy, parse_policy


def run_policy(system: Any, name: str | None = None, seed: int | None = None) -> Any:
    """The policy of a virtual run of `system`; `PolicyError` (one line) for a bad name, or a
    `--seed` beside a policy that is not random or has another seed."""
    if name is None:
        default = Eager() if seed is None else Random(seed)
    else:
        default = parse_policy(name)
        if seed is not None:
            if not isinstance(default, Random):
                raise PolicyError(f"--seed {seed} is the seed of the random policy, not of {name!r}")
            if ":" in name and default.seed != seed:
                raise PolicyError(f"--policy {name} and --seed {seed} name two seeds; give one")
            default = Random(seed)
    own = {node.name: make_policy(node.policy, node.seed or 0)
           for node in system.nodes.values() if getattr(node, "policy", None) is not None}
    return PerNode(default, own, root=system.name) if own else default
