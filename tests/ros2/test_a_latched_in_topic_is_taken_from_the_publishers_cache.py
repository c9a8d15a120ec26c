"""A transient-local `in` mapping takes what a ROS 2 publisher latched before the bridge started:
its port asks every publication cache of the topic (`*/<data key>`, replies accepted on the data
key) as rmw_zenoh's transient-local subscription does, and posts the reply as the bridge's input.
The publisher here is a plain zenoh session laid out as rmw_zenoh's publication cache (queryable
on `<its session id>/<data key>`), not iotad's code."""
import struct
import threading
import time

import zenoh
from rosbags.typesys import Stores, get_typestore

from iotad.node_host.transport import free_port
from iotad.kernel.types import Float
from iotad.ros2.mapping import parse
from iotad.ros2.port import Ros2Port

STORE = get_typestore(Stores.ROS2_JAZZY)
KEY = "0/level/std_msgs::msg::dds_::Float64_/" + STORE.hash_rihs01("std_msgs/msg/Float64")


def config(**endpoints):
    c = zenoh.Config()
    c.insert_json5("scouting/multicast/enabled", "false")
    for kind, endpoint in endpoints.items():
        c.insert_json5(f"{kind}/endpoints", f'["{endpoint}"]')
    return c


def test_the_bridge_takes_the_latched_value_published_before_it_started():
    mapping = parse({"channel": "slow.level", "topic": "/level", "type": "std_msgs/msg/Float64", "direction": "in",
                     "durability": "transient_local"}, Float, "[[ros2]] #1")
    assert mapping.key == KEY and mapping.qos == ":1:,1:,:,:,,"
    posted, arrived = [], threading.Event()

    def post(item):
        posted.append(item)
        arrived.set()

    port = Ros2Port({"node": "iotad_t", "mappings": [mapping.plain()]}, post, lambda *a: a, lambda v: v,
                    lambda seq, stamp: (seq, stamp), time.monotonic)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    latched = bytes(STORE.serialize_cdr(STORE.types["std_msgs/msg/Float64"](data=0.75), "std_msgs/msg/Float64"))
    attachment = struct.pack("<qqB", 41, 1_700_000_000_000_000_000, 16) + bytes(range(16))
    with zenoh.open(config(listen=endpoint)) as publisher:
        cache = publisher.declare_queryable(f"{publisher.zid()}/{KEY}",
                                            lambda query: query.reply(KEY, latched, attachment=attachment), complete=True)
        with zenoh.open(config(connect=endpoint)) as bridge:
            deadline = time.monotonic() + 10
            while not list(bridge.get(f"*/{KEY}", accept_replies=zenoh.ReplyKeyExpr.ANY)):  # the cache is known
                assert time.monotonic() < deadline
                time.sleep(0.05)
            declared = port.open(bridge)
            assert arrived.wait(10)
            for entity in declared:
                entity.undeclare()
        cache.undeclare()
    (name, _, value, meta, key), = posted
    assert (name, value, meta, key) == ("ros_0", 0.75, (41, 1_700_000_000_000_000_000), KEY)
