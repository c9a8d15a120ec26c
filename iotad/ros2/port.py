"""The ROS 2 port of the bridge's node host: rmw_zenoh publishers, subscriptions and liveliness
tokens on the node's own zenoh session (docs/ros2.md).

Out: every input event of an `out_k` channel (the engine's sink sees it) becomes one CDR message
on mapping k's data key, with rmw_zenoh's attachment. A transient-local mapping keeps its latest
message for the subscribers that join later, answered as both generations of rmw_zenoh ask: a
publication cache (a queryable on `<session id>/<data key>`, replies on the data key: Jazzy's
first releases) and zenoh's advanced publisher with a cache and publisher detection (its
`<data key>/@adv/...` keys: later releases, whose transient-local subscription is an advanced
subscriber). A constant mapping (the robot's `robot_description`) is published once, as the port
opens, and kept there. In: every sample on mapping k's data key is
decoded (CDR, then the mapping) and posted to the engine as input `ros_k`, so the engine orders,
times and checks it like any input. What cannot be converted is counted and recorded as a
violation once per heartbeat period (`take_problems`), never raised in zenoh's threads.
"""
from __future__ import annotations

import threading
import time
from typing import Any, Callable

from iotad.kernel.types import to_plain
from iotad.ros2 import rmw_zenoh
from iotad.ros2.mapping import Mapping
from iotad.ros2.messages import MessageError

NOT_SENT = "ros2_not_sent"           # an out value the mapping could not turn into its message
NOT_TAKEN = "ros2_message_unusable"  # an in message that is not CDR of its type, or does not fit the input


class Ros2Port:
    """`post` takes each `RawInput` for the engine thread; `encode` is the wire's payload encoder,
    `attachment` the wire's attachment encoder, `raw_input` the RawInput class (the host's)."""

    def __init__(self, config: dict[str, Any], post: Callable, raw_input: Callable, encode: Callable,
                 attachment: Callable, now: Callable[[], float]):
        self.node_name = config["node"]
        self.mappings = [Mapping.from_plain(m) for m in config["mappings"]]
        self.post, self.raw_input, self.encode, self.attachment, self.now = post, raw_input, encode, attachment, now
        self._out: dict[str, list] = {}  # out_k -> [mapping, publisher, seq, gid, cache]
        self._caches: list[list] = []     # per latched out mapping: its latest (payload, attachment)s
        self._declared: list[Any] = []
        self._problems: dict[tuple, list] = {}
        self._lock = threading.Lock()
        self.sent = self.received = 0

    def open(self, session: Any) -> list[Any]:
        """Declare the node, its publishers, subscriptions and their tokens on `session`; what
        was declared, for the node host to undeclare with its own entities."""
        session_id = str(session.zid())
        nodes: dict[int, rmw_zenoh.Node] = {}
        liveliness = session.liveliness()
        for number, mapping in enumerate(self.mappings):
            node = nodes.get(mapping.domain)
            if node is None:
                node = nodes[mapping.domain] = rmw_zenoh.Node(mapping.domain, session_id, self.node_name)
                self._declared.append(liveliness.declare_token(node.token()))
            kind = rmw_zenoh.PUBLISHER if mapping.direction == "out" else rmw_zenoh.SUBSCRIPTION
            token = node.entity_token(number + 1, kind, mapping.topic, mapping.ros_type, mapping.type_hash,
                                      mapping.qos)
            latched = mapping.durability == "transient_local"
            if mapping.direction == "out":
                publisher = self._advanced_publisher(session, mapping.key) if latched else \
                    session.declare_publisher(mapping.key)
                self._declared.append(publisher)
                cache = None
                if latched:
                    cache = []
                    self._declared.append(session.declare_queryable(
                        rmw_zenoh.cache_queryable_key(session_id, mapping.key), self._answer(mapping, cache),
                        complete=True))
                port = [mapping, publisher, 0, rmw_zenoh.gid_of(token), cache]
                self._out[f"out_{number}"] = port
                if mapping.constant:
                    self._publish(port, None)
            else:
                receive = self._receiver(number, mapping)
                self._declared.append(session.declare_subscriber(mapping.key, receive))
                if latched:  # what the publishers' caches hold, as rmw_zenoh's querying subscriber asks
                    self._ask_caches(session, mapping, receive)
            self._declared.append(liveliness.declare_token(token))
        return self._declared

    def session_settings(self) -> dict[str, Any]:
        """What the node host's session must enable: an advanced publisher needs timestamps."""
        latched = any(m.direction == "out" and m.durability == "transient_local" for m in self.mappings)
        return {"timestamping/enabled": True} if latched else {}

    @staticmethod
    def _advanced_publisher(session: Any, key: str) -> Any:
        """As rmw_zenoh declares a transient-local publisher (rmw_publisher_data.cpp): a cache of
        the QoS depth, and publisher detection, so that advanced subscribers that start later, or
        before this publisher, ask its cache."""
        import zenoh.ext

        return zenoh.ext.declare_advanced_publisher(session, key, cache=zenoh.ext.CacheConfig(
            max_samples=rmw_zenoh.LATCHED_DEPTH), publisher_detection=True)

    def _answer(self, mapping: Mapping, cache: list):
        """The publication cache's queryable: the latest messages, on the data key itself."""
        def answer(query: Any) -> None:
            with self._lock:
                held = list(cache)
            for payload, attachment in held:
                query.reply(mapping.key, payload, attachment=attachment)
        return answer

    @staticmethod
    def _ask_caches(session: Any, mapping: Mapping, receive: Callable) -> None:
        import zenoh

        def replied(reply: Any) -> None:
            if reply.ok is not None:
                receive(reply.ok)
        session.get(rmw_zenoh.cache_query_key(mapping.key), replied, target=zenoh.QueryTarget.ALL,
                    consolidation=zenoh.ConsolidationMode.NONE, accept_replies=zenoh.ReplyKeyExpr.ANY)

    def on_event(self, event: dict) -> None:
        """The engine's sink: publish the value of each input event of an `out_k` channel."""
        if event["kind"] != "input":
            return
        port = self._out.get(event["action"])
        if port is None:
            return
        self._publish(port, to_plain(event["value"]), event["action"])

    def _publish(self, port: list, plain: Any, channel: str = "") -> None:
        mapping, publisher, seq, gid, cache = port
        stamp = time.time_ns()
        try:
            data = mapping.to_cdr(plain, stamp)
        except (MessageError, KeyError, IndexError, TypeError) as exc:
            self._problem(channel, NOT_SENT, f"{mapping.channel} -> {mapping.topic}: {exc}")
            return
        port[2] = seq + 1
        attachment = rmw_zenoh.encode_attachment(seq, stamp, gid)
        if cache is not None:
            with self._lock:
                cache.append((data, attachment))
                del cache[:-rmw_zenoh.LATCHED_DEPTH]
        publisher.put(data, attachment=attachment)
        self.sent += 1

    def _receiver(self, number: int, mapping: Mapping):
        name = f"ros_{number}"

        def receive(sample: Any) -> None:
            attachment = rmw_zenoh.decode_attachment(None if sample.attachment is None else sample.attachment.to_bytes())
            try:
                plain = mapping.from_cdr(sample.payload.to_bytes())
            except (MessageError, KeyError, IndexError, TypeError) as exc:
                self._problem(name, NOT_TAKEN, f"{mapping.topic} -> {mapping.channel}: {exc}")
                return
            self.received += 1
            wire_attachment = None if attachment is None else self.attachment(max(attachment[0], 0), attachment[1])
            self.post(self.raw_input(name, None, self.encode(plain), wire_attachment, str(sample.key_expr)))
        return receive

    def _problem(self, channel: str, violation: str, said: str) -> None:
        t = self.now()
        with self._lock:
            entry = self._problems.get((channel, violation))
            if entry is None:
                self._problems[(channel, violation)] = [1, t, t, said]
            else:
                entry[0] += 1
                entry[2] = t

    def take_problems(self) -> list[tuple[str, str, str, int]]:
        """(channel, violation, message, count) of each kind of problem since the last call."""
        with self._lock:
            problems, self._problems = self._problems, {}
        return [(channel, violation, f"{count} message(s) between t={first:.6f} and t={last:.6f}; the first: {said}",
                 count) for (channel, violation), (count, first, last, said) in problems.items()]

