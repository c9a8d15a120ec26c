"""The live view's latched state: the latest message of each topic that is sent rarely (the arm's
URDF and meshes, Buggy's arena, the conveyor's belt and bin), sent again to every viewer as it
subscribes, however late and as often as it reconnects.

foxglove-sdk's server sends a message only to the clients subscribed when it is logged: the URDF,
logged once when the arm's first joint state arrives, never reached a viewer that connected later.
So `iotad view` keeps the latest message of each such topic (`keep`), hears each subscription
(`Subscriptions`, a foxglove `ServerListener`, which only queues it: logging from within the
server's callback is not safe), and logs the kept message again from its own loop (`resend`).
Other clients of the topic get it once more too: the same latest state, harmless.
"""
from __future__ import annotations

import threading
from typing import Any, Callable

from iotad.recording.foxglove_scene import ARENA, ARM_MODEL, CONVEYOR, ROBOT_DESCRIPTION

LATCHED_TOPICS = (ROBOT_DESCRIPTION, ARM_MODEL, ARENA, CONVEYOR)


class LatchedScene:
    """The latest (channel, message, stamp) of each latched topic."""

    def __init__(self, topics: tuple[str, ...] = LATCHED_TOPICS):
        self.topics = set(topics)
        self._latest: dict[str, tuple[Any, Any, int]] = {}
        self._lock = threading.Lock()
        self.resent = 0

    def keep(self, topic: str, channel: Any, message: Any, stamp_ns: int) -> None:
        if topic in self.topics:
            with self._lock:
                self._latest[topic] = (channel, message, stamp_ns)

    def resend(self, topic: str) -> bool:
        """Log the kept message of `topic` again (a viewer just subscribed); False if none is kept."""
        with self._lock:
            held = self._latest.get(topic)
        if held is None:
            return False
        channel, message, stamp_ns = held
        channel.log(message, log_time=stamp_ns)
        self.resent += 1
        return True


def subscriptions(post: Callable[[tuple], None]) -> Any:
    """A foxglove `ServerListener` that posts ("subscribed", topic) for each subscription."""
    import foxglove

    class Subscriptions(foxglove.ServerListener):
        def on_subscribe(self, client: Any, channel: Any) -> None:
            post(("subscribed", channel.topic))

    return Subscriptions()
