"""A ROS 2 participant that is not iotad: plain zenoh and rosbags only, speaking rmw_zenoh's
protocol for Jazzy as its design document lays it out (key expressions, CDR, attachments,
liveliness tokens). It imports nothing of iotad on purpose: it is the independent side of the
round trip in test_a_ros2_peer_sees_the_arm_and_drives_buggy.py.

    python ros2_peer.py --connect tcp/127.0.0.1:7447 --seconds 8 \
        --listen /joint_states=sensor_msgs/msg/JointState \
        --publish /cmd_vel=geometry_msgs/msg/Twist='{"linear": {"x": 0.2}, "angular": {"z": 0.5}}'

Prints one JSON object a line: {"ready": ...} once subscribed; {"topic", "key", "message",
"attachment": [seq, stamp_ns, gid_hex]} per message heard, until --seconds pass or messages have
stopped for --idle seconds; {"tokens": [...]} at the end, the
rmw_zenoh liveliness tokens seen in domain 0.

--latched TOPIC=TYPE subscribes as rmw_zenoh's transient-local subscription does (Jazzy's
rmw_subscription_data.cpp, ze_declare_querying_subscriber): a subscriber on the data key, and at
once a query of `*/<data key>`, target ALL, no consolidation, accepting replies on any key, which
every publication cache of the topic (queryable prefix: its session id) answers with what it
holds. Such a message's line says "via": "query" (from a cache) or "put" (published live).

--latched-advanced TOPIC=TYPE subscribes as a later rmw_zenoh's transient-local subscription does
(rmw_subscription_data.cpp): zenoh's advanced subscriber with history (detect late publishers,
max samples = depth 1) and subscriber detection, which asks every advanced publisher's cache of the
key; its lines say "via": "advanced".

--config FILE opens the session from a zenoh configuration file, as rmw_zenoh does with
ZENOH_SESSION_CONFIG_URI (what `iotad certs ros2` writes), instead of --connect's plain one;
--put KEY=TEXT puts raw bytes on any key (what a rogue would try). A session the hub does not
let in prints {"refused": reason} and exits with status 3.
"""
import argparse
import json
import struct
import sys
import threading
import time

import numpy as np
import zenoh
import zenoh.ext
from rosbags.typesys import Stores, get_typestore

STORE = get_typestore(Stores.ROS2_JAZZY)


def key_of(topic: str, ros_type: str, domain: int = 0) -> str:
    package, kind, name = ros_type.split("/")
    return f"{domain}/{topic.strip('/')}/{package}::{kind}::dds_::{name}_/{STORE.hash_rihs01(ros_type)}"


def plain(value):
    if hasattr(value, "__dataclass_fields__"):
        return {k: plain(getattr(value, k)) for k in value.__dataclass_fields__ if not k.startswith("__")}
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, list):
        return [plain(v) for v in value]
    return value


def build(ros_type: str, fields: dict):
    """A message of `ros_type` from nested dicts: what a ROS 2 program would fill in."""
    cls = STORE.types[ros_type]
    kwargs = {}
    for name, (nodetype, detail) in STORE.fielddefs[ros_type][1]:
        given = fields.get(name)
        if int(nodetype) == 2:
            kwargs[name] = build(detail, given or {})
        elif int(nodetype) == 1:
            kwargs[name] = given if given is not None else ("" if detail[0] == "string" else 0.0 if "float" in detail[0] else 0)
        else:
            kwargs[name] = np.array(given or [], dtype=np.float64) if detail[0][1][0] == "float64" else (given or [])
    return cls(**kwargs)


def main() -> int:
    parser = argparse.ArgumentParser()
    parser.add_argument("--connect")
    parser.add_argument("--config", help="a zenoh session configuration file (ZENOH_SESSION_CONFIG_URI)")
    parser.add_argument("--put", action="append", default=[], help="KEY=TEXT, raw")
    parser.add_argument("--seconds", type=float, default=5.0)
    parser.add_argument("--listen", action="append", default=[], help="TOPIC=TYPE")
    parser.add_argument("--latched", action="append", default=[], help="TOPIC=TYPE, transient local")
    parser.add_argument("--latched-advanced", action="append", default=[], help="TOPIC=TYPE, transient local")
    parser.add_argument("--publish", action="append", default=[], help="TOPIC=TYPE=JSON")
    parser.add_argument("--every", type=float, default=0.5, help="seconds between publications")
    parser.add_argument("--idle", type=float, default=2.0,
                        help="stop once messages stop for this long, after the first (the system ended)")
    args = parser.parse_args()

    if args.config:
        config = zenoh.Config.from_file(args.config)
    else:
        config = zenoh.Config()
        config.insert_json5("mode", '"peer"')
        config.insert_json5("connect/endpoints", json.dumps([args.connect]))
        config.insert_json5("listen/endpoints", '["tcp/127.0.0.1:0"]')
    config.insert_json5("scouting/multicast/enabled", "false")
    config.insert_json5("connect/timeout_ms", "5000")  # not let in: say so, rather than retry forever
    config.insert_json5("connect/exit_on_failure", "true")
    lock, last, tokens = threading.Lock(), [None], set()

    def say(obj):
        with lock:
            print(json.dumps(obj), flush=True)

    try:
        session = zenoh.open(config)
    except zenoh.ZError as exc:
        say({"refused": str(exc)})
        return 3
    with session:
        declared = []

        def on_sample(sample, topic, ros_type, via=None):
            raw = sample.attachment.to_bytes() if sample.attachment is not None else b""
            seq, stamp, size = struct.unpack_from("<qqB", raw)
            gid = raw[17:17 + size]
            message = STORE.deserialize_cdr(sample.payload.to_bytes(), ros_type)
            say({"topic": topic, "key": str(sample.key_expr), "message": plain(message),
                 "attachment": [seq, stamp, gid.hex()], "header": sample.payload.to_bytes()[:4].hex(),
                 **({} if via is None else {"via": via})})
            with lock:
                last[0] = time.monotonic()

        for spec in args.listen:
            topic, ros_type = spec.split("=", 1)
            declared.append(session.declare_subscriber(
                key_of(topic, ros_type), lambda sample, t=topic, r=ros_type: on_sample(sample, t, r)))
        latched, taken = {}, set()  # mangled topic -> (topic, type, key); (gid, seq) already taken
        for spec in args.latched:
            topic, ros_type = spec.split("=", 1)
            key = key_of(topic, ros_type)
            latched[topic.replace("/", "%")] = (topic, ros_type, key)
            declared.append(session.declare_subscriber(
                key, lambda sample, t=topic, r=ros_type: on_sample(sample, t, r, "put")))

        def on_reply(reply, topic, ros_type):
            # a message is the same one whichever query brought it: (publisher GID, sequence
            # number) tells, as rmw_zenoh's subscription dedups what its two queries both get
            if reply.ok is None:
                return
            raw = reply.ok.attachment.to_bytes() if reply.ok.attachment is not None else b""
            with lock:
                if raw[:8] + raw[17:] in taken:
                    return
                taken.add(raw[:8] + raw[17:])
            on_sample(reply.ok, topic, ros_type, "query")

        def ask(selector, topic, ros_type):
            session.get(selector, lambda reply: on_reply(reply, topic, ros_type), target=zenoh.QueryTarget.ALL,
                        consolidation=zenoh.ConsolidationMode.NONE, accept_replies=zenoh.ReplyKeyExpr.ANY)

        for spec in args.latched_advanced:
            topic, ros_type = spec.split("=", 1)
            declared.append(zenoh.ext.declare_advanced_subscriber(
                session, key_of(topic, ros_type), lambda sample, t=topic, r=ros_type: on_sample(sample, t, r, "advanced"),
                history=zenoh.ext.HistoryConfig(detect_late_publishers=True, max_samples=1), subscriber_detection=True))
        for topic, ros_type, key in latched.values():  # every cache of the topic, as the subscription starts
            ask(f"*/{key}", topic, ros_type)

        def on_token(sample):
            if sample.kind == zenoh.SampleKind.PUT:
                token = str(sample.key_expr)
                with lock:
                    tokens.add(token)
                # a transient-local publisher of a latched topic appeared (graph_cache.cpp): ask
                # its own cache, `<its session id>/<data key>` (the first query may have gone out
                # before this session knew of its queryable)
                parts = token.split("/")
                if len(parts) >= 13 and parts[5] == "MP" and parts[9] in latched and parts[12].split(":")[1] == "1":
                    topic, ros_type, key = latched[parts[9]]
                    ask(f"{parts[2]}/{key}", topic, ros_type)
        declared.append(session.liveliness().declare_subscriber("@ros2_lv/0/**", on_token, history=True))
        publishers = []
        gid = bytes(range(16))
        for spec in args.publish:
            topic, ros_type, fields = spec.split("=", 2)
            publishers.append((session.declare_publisher(key_of(topic, ros_type)), ros_type, json.loads(fields)))
        raw_puts = [spec.split("=", 1) for spec in args.put]
        say({"ready": True})
        deadline = time.monotonic() + args.seconds
        seq = 0
        while time.monotonic() < deadline:
            with lock:
                if last[0] is not None and time.monotonic() - last[0] > args.idle:
                    break
            for publisher, ros_type, fields in publishers:
                data = bytes(STORE.serialize_cdr(build(ros_type, fields), ros_type))
                publisher.put(data, attachment=struct.pack("<qqB", seq, time.time_ns(), 16) + gid)
            for key, text in raw_puts:
                session.put(key, text.encode())
            seq += 1
            time.sleep(args.every if publishers or raw_puts else 0.05)
        say({"tokens": sorted(tokens)})
        for entity in declared:
            entity.undeclare()
    return 0


if __name__ == "__main__":
    sys.exit(main())
