"""rmw_zenoh's wire format (ROS 2 Jazzy): data keys, liveliness tokens, the attachment, GIDs.

Since rmw_zenoh a ROS 2 system is a zenoh system; any zenoh session that uses the same key
expressions, CDR payloads, attachments and liveliness tokens is part of its graph. What this
module writes is what rmw_zenoh's design document (docs/design.md of ros2/rmw_zenoh, the
branch of Jazzy and later) specifies:

- data key `<domain_id>/<fully qualified name without its leading slash>/<dds type>/<type hash>`,
  the DDS type name `pkg::msg::dds_::Name_` and the REP-2016 hash `RIHS01_<64 hex>`;
- liveliness tokens `@ros2_lv/<domain>/<session id>/<node id>/<entity id>/<kind>/<enclave>/
  <namespace>/<node>[/<topic>/<type>/<hash>/<qos>]`, every name "mangled" (`/` -> `%`), kinds NN
  (node), MP (publisher), MS (subscription);
- attachment: sequence number (int64 little-endian), source timestamp (int64 ns since the UNIX
  epoch, little-endian), one byte holding the GID's length (16), the 16-byte GID;
- GID: XXH3-128 of the entity's liveliness token, as rmw_zenoh's `Entity` computes it for every
  entity, remote ones included (its low 64 bits, then its high 64 bits, each little-endian).
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

import xxhash

ADMIN_SPACE = "@ros2_lv"
NODE, PUBLISHER, SUBSCRIPTION = "NN", "MP", "MS"
GID_SIZE = 16
_ATTACHMENT = struct.Struct("<qqB")
# QoS of every entity the bridge declares: reliable, volatile, keep last 10 (rclcpp's default
# profile). rmw_zenoh writes a field only where it differs from its own defaults; the design
# document's listener on `chatter`, with exactly this profile, carries "::,10:,:,:,,".
DEFAULT_QOS = "::,10:,:,:,,"
# A transient-local entity: durability 1 (RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL; rmw_zenoh's
# default is volatile, 2, so it is written) and keep last 1, as robot_state_publisher and tf2's
# static broadcaster declare theirs: a late subscriber gets the latest message.
LATCHED_QOS = ":1:,1:,:,:,,"
LATCHED_DEPTH = 1


def qos_token(transient_local: bool) -> str:
    return LATCHED_QOS if transient_local else DEFAULT_QOS


def cache_queryable_key(session_id: str, key: str) -> str:
    """Where a transient-local publisher's cache answers: rmw_zenoh's publication cache takes the
    session id as its queryable prefix, `<session id>/<data key>`; its subscribers ask `*/<data key>`
    when they start and `<session id>/<data key>` when a new publisher's token appears, and accept
    replies on the data key itself."""
    return f"{session_id}/{key}"


def advanced_keys(key: str) -> str:
    """Every key of zenoh's advanced publishers and subscribers of a data key (their liveliness
    tokens, cache queryables and queries: `<data key>/@adv/pub/...`, `<data key>/@adv/sub/...`),
    which rmw_zenoh's later releases use for transient local."""
    return f"{key}/@adv/**"


def cache_query_key(key: str) -> str:
    """What a transient-local subscriber asks as it starts: every publication cache of the key."""
    return f"*/{key}"


class Ros2NameError(ValueError):
    """A topic, node or type name ROS 2 would refuse."""


def dds_type_name(ros_type: str) -> str:
    """`sensor_msgs/msg/JointState` -> `sensor_msgs::msg::dds_::JointState_` (rmw_zenoh's type name)."""
    parts = ros_type.split("/")
    if len(parts) != 3 or not all(parts):
        raise Ros2NameError(f"{ros_type!r} is not a ROS 2 type name such as sensor_msgs/msg/JointState")
    package, kind, name = parts
    return f"{package}::{kind}::dds_::{name}_"


def ros_type_name(dds_name: str) -> str:
    """The inverse of `dds_type_name`."""
    parts = dds_name.split("::")
    if len(parts) != 4 or parts[2] != "dds_" or not parts[3].endswith("_"):
        raise Ros2NameError(f"{dds_name!r} is not a DDS type name such as std_msgs::msg::dds_::String_")
    return f"{parts[0]}/{parts[1]}/{parts[3][:-1]}"


def check_topic(topic: str) -> str:
    """A fully qualified topic name (`/joint_states`, `/robot1/cmd_vel`), or Ros2NameError."""
    if not isinstance(topic, str) or not topic.startswith("/") or topic.endswith("/") or "//" in topic:
        raise Ros2NameError(f"{topic!r} is not a fully qualified ROS 2 topic name such as \"/joint_states\"")
    for token in topic[1:].split("/"):
        if not (token[0].isalpha() or token[0] == "_") or not all(c.isalnum() or c == "_" for c in token):
            raise Ros2NameError(f"{topic!r}: {token!r} is not a ROS 2 name token (letters, digits, _; "
                                f"not starting with a digit)")
    return topic


def mangle(name: str) -> str:
    """rmw_zenoh's mangling of a name inside a liveliness token: every `/` becomes `%`."""
    return name.replace("/", "%")


def data_key(domain: int, topic: str, ros_type: str, type_hash: str) -> str:
    """The key expression a message of `ros_type` on `topic` is put on."""
    return f"{domain}/{check_topic(topic).strip('/')}/{dds_type_name(ros_type)}/{type_hash}"


@dataclass(frozen=True)
class Node:
    """One ROS 2 node of a zenoh session, as the graph sees it."""

    domain: int
    session_id: str   # the zenoh session's id, as zenoh writes it (hex)
    name: str
    namespace: str = "/"
    node_id: int = 0
    enclave: str = "/"

    def token(self) -> str:
        """The node's liveliness token (kind NN)."""
        return "/".join([ADMIN_SPACE, str(self.domain), self.session_id, str(self.node_id), str(self.node_id),
                         NODE, mangle(self.enclave), mangle(self.namespace), self.name])

    def entity_token(self, entity_id: int, kind: str, topic: str, ros_type: str, type_hash: str,
                     qos: str = DEFAULT_QOS) -> str:
        """The liveliness token of a publisher (MP) or subscription (MS) of this node."""
        return "/".join([ADMIN_SPACE, str(self.domain), self.session_id, str(self.node_id), str(entity_id),
                         kind, mangle(self.enclave), mangle(self.namespace), self.name, mangle(check_topic(topic)),
                         dds_type_name(ros_type), type_hash, qos])


def gid_of(token: str) -> bytes:
    """The 16-byte GID of the entity with this liveliness token, as rmw_zenoh makes it: XXH3-128 of
    the token, the 128-bit value's low half then its high half, each copied from memory on a
    little-endian machine, i.e. the whole value little-endian. A ROS 2 program compares the GID in
    a message's attachment with the one its graph cache computed from the publisher's token."""
    return xxhash.xxh3_128_intdigest(token.encode()).to_bytes(GID_SIZE, "little")


def encode_attachment(sequence: int, timestamp_ns: int, gid: bytes) -> bytes:
    if len(gid) != GID_SIZE:
        raise ValueError(f"a GID has {GID_SIZE} bytes, got {len(gid)}")
    return _ATTACHMENT.pack(sequence, timestamp_ns, GID_SIZE) + gid


def decode_attachment(data: bytes | None) -> tuple[int, int, bytes] | None:
    """(sequence, source timestamp ns, GID) of an attachment; None where it is not one."""
    if data is None or len(data) < _ATTACHMENT.size:
        return None
    sequence, stamp, size = _ATTACHMENT.unpack_from(data)
    gid = bytes(data[_ATTACHMENT.size:_ATTACHMENT.size + size])
    if len(gid) != size:
        return None
    return sequence, stamp, gid
