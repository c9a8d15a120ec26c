"""What the launcher knows of one node it runs: its state (`NodeState`), its process, its restart
policy and the counts the summary reports (`NodeRun`)."""
from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from iotad.launcher.processes import Child, RestartPolicy
from iotad.launcher.system.system_file import NodeSpec


class NodeState(StrEnum):
    """A node's life in a run. A StrEnum: it prints (status table, lines) as its value."""

    WAITING = "waiting"      # not started yet: a node it starts `after` is not live
    STARTING = "starting"    # its process runs, its liveliness token not seen yet
    RUNNING = "running"      # live
    LOST = "lost"            # its token vanished (or it was killed) while its process runs
    BACKOFF = "backoff"      # it exited; its restart is due at `restart_at`
    STOPPING = "stopping"    # the run stops it
    STOPPED = "stopped"      # stopped by the run
    EXITED = "exited"        # ended by itself with status 0, and not restarted
    FAILED = "failed"        # ended for good: the policy gave up, or it cannot start
    DOWN = "down"            # the run ended while it waited for its restart


FINISHED = frozenset({NodeState.STOPPED, NodeState.EXITED, NodeState.FAILED, NodeState.DOWN})


@dataclass
class NodeRun:
    """What the launcher knows of one node it runs."""

    spec: NodeSpec
    child: Child
    policy: RestartPolicy
    state: NodeState = NodeState.WAITING
    restarts: int = 0
    consecutive: int = 0          # restarts since it last ran healthy_after seconds
    restart_at: float | None = None
    down_since: float | None = None  # when it exited, while it waits for its restart (backoff)
    down_at_end: float = 0.0      # state "down": seconds it had been down when the run ended
    live_since: float | None = None
    lost_since: float | None = None
    last_beat: float | None = None
    killed_for: str | None = None  # why the launcher killed it (stale heartbeat...), reported on exit
    last_code: int | None = None
    went_live: bool = False       # its liveliness token was seen at least once
    failures: int = 0             # exits with a failure status, not counting the run's stop

    @property
    def name(self) -> str:
        return self.spec.name

    @property
    def finished(self) -> bool:
        return self.state in FINISHED


__all__ = ["FINISHED", "NodeRun", "NodeState"]
