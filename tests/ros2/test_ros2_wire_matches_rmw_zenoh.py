"""What the bridge puts on the wire is rmw_zenoh's format for ROS 2 Jazzy, held against values
rmw_zenoh's design document (docs/design.md of ros2/rmw_zenoh) prints and against rosbags, an
implementation of CDR and of REP-2016 type hashes that is not iotad's."""
import struct

import pytest
import xxhash
from rosbags.typesys import Stores, get_typestore

from channels.joints import JOINT_STATES
from iotad.kernel.types import Enum, Float, Struct
from iotad.ros2 import messages, rmw_zenoh
from iotad.ros2.mapping import MappingError, parse

STORE = get_typestore(Stores.ROS2_JAZZY)
# Quoted from rmw_zenoh's design document ("Topic and Service name mapping to Zenoh key
# expressions" and "Graph Cache"), the demo_nodes_cpp talker and listener:
DOC_STRING_HASH = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18"
DOC_CHATTER_KEY = "0/chatter/std_msgs::msg::dds_::String_/" + DOC_STRING_HASH
DOC_NAMESPACED_KEY = "0/robot1/chatter/std_msgs::msg::dds_::String_/" + DOC_STRING_HASH
DOC_LISTENER_NODE = "@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/0/NN/%/%/listener"
DOC_LISTENER_SUB = ("@ros2_lv/2/aac3178e146ba6f1fc6e6a4085e77f21/0/10/MS/%/%/listener/%chatter/"
                    "std_msgs::msg::dds_::String_/" + DOC_STRING_HASH + "/::,10:,:,:,,")
DOC_TALKER_PUB_PREFIX = ("@ros2_lv/2/8b20917502ee955ac4476e0266340d5c/0/10/MP/%/%/talker/%chatter/"
                         "std_msgs::msg::dds_::String_/" + DOC_STRING_HASH + "/")


def test_data_keys_and_type_hash_are_the_documented_ones():
    assert messages.type_hash("std_msgs/msg/String") == DOC_STRING_HASH
    assert rmw_zenoh.data_key(0, "/chatter", "std_msgs/msg/String", DOC_STRING_HASH) == DOC_CHATTER_KEY
    assert rmw_zenoh.data_key(0, "/robot1/chatter", "std_msgs/msg/String", DOC_STRING_HASH) == DOC_NAMESPACED_KEY
    assert rmw_zenoh.dds_type_name("sensor_msgs/msg/JointState") == "sensor_msgs::msg::dds_::JointState_"
    assert rmw_zenoh.ros_type_name("sensor_msgs::msg::dds_::JointState_") == "sensor_msgs/msg/JointState"
    # every supported type hashes as rosbags' own REP-2016 implementation does
    for ros_type in messages.SUPPORTED:
        assert messages.type_hash(ros_type) == STORE.hash_rihs01(ros_type)


def test_liveliness_tokens_are_laid_out_as_documented():
    node = rmw_zenoh.Node(2, "aac3178e146ba6f1fc6e6a4085e77f21", "listener")
    assert node.token() == DOC_LISTENER_NODE
    assert node.entity_token(10, rmw_zenoh.SUBSCRIPTION, "/chatter", "std_msgs/msg/String",
                             DOC_STRING_HASH) == DOC_LISTENER_SUB
    talker = rmw_zenoh.Node(2, "8b20917502ee955ac4476e0266340d5c", "talker")
    publisher = talker.entity_token(10, rmw_zenoh.PUBLISHER, "/chatter", "std_msgs/msg/String", DOC_STRING_HASH)
    assert publisher.startswith(DOC_TALKER_PUB_PREFIX)  # the talker's depth is 7, ours 10
    # a namespaced topic is mangled, slash for percent
    assert "/%robot1%chatter/" in talker.entity_token(1, "MP", "/robot1/chatter", "std_msgs/msg/String", DOC_STRING_HASH)


def test_attachment_bytes_parse_as_rmw_zenoh_lays_them_out():
    gid = bytes(range(100, 116))
    data = rmw_zenoh.encode_attachment(41, 1_700_000_000_123_456_789, gid)
    # int64 LE sequence, int64 LE ns timestamp, 1 byte GID length (16), the 16 GID bytes
    assert len(data) == 8 + 8 + 1 + 16
    assert struct.unpack_from("<q", data, 0)[0] == 41
    assert struct.unpack_from("<q", data, 8)[0] == 1_700_000_000_123_456_789
    assert data[16] == 16 and data[17:] == gid
    assert rmw_zenoh.decode_attachment(data) == (41, 1_700_000_000_123_456_789, gid)
    assert rmw_zenoh.decode_attachment(data[:10]) is None
    assert rmw_zenoh.decode_attachment(data[:20]) is None  # a GID cut short


# rmw_zenoh_cpp/src/detail/liveliness_utils.cpp, Entity::Entity (ros2/rmw_zenoh), quoted:
#   simplified_XXH128_hash_t keyexpr_gid =
#     simplified_XXH3_128bits(this->liveliness_keyexpr_.c_str(), this->liveliness_keyexpr_.length());
#   memcpy(this->gid_, &keyexpr_gid.low64, sizeof(keyexpr_gid.low64));
#   memcpy(this->gid_ + sizeof(keyexpr_gid.low64), &keyexpr_gid.high64, sizeof(keyexpr_gid.high64));
# where liveliness_keyexpr_ is the whole token, "@ros2_lv/..." included, and the two halves are
# copied from memory of a little-endian machine. simplified_XXH3_128bits is XXH3_128bits with the
# default secret (simplified_xxhash3.cpp); its reference value for the empty input is
# { low64 = 0x6001C324468D497F, high64 = 0x99AA06D3014798D8 } (xxHash's own sanity checks).
XXH3_128_OF_NOTHING = (0x6001C324468D497F, 0x99AA06D3014798D8)


def rmw_zenoh_gid(token: str) -> bytes:
    """The GID as rmw_zenoh's code above makes it: low64 then high64, each little-endian."""
    digest = xxhash.xxh3_128(token.encode()).digest()  # xxHash's canonical form: high64, low64 big-endian
    high, low = struct.unpack(">QQ", digest)
    return struct.pack("<Q", low) + struct.pack("<Q", high)


def test_gids_are_xxh3_128_of_the_token_as_rmw_zenoh_lays_them_out():
    high, low = struct.unpack(">QQ", xxhash.xxh3_128(b"").digest())
    assert (low, high) == XXH3_128_OF_NOTHING  # the hash library is XXH3-128 with the default secret
    talker = rmw_zenoh.Node(2, "8b20917502ee955ac4476e0266340d5c", "talker")
    for token in (DOC_LISTENER_NODE, DOC_LISTENER_SUB, talker.token(),
                  talker.entity_token(10, rmw_zenoh.PUBLISHER, "/chatter", "std_msgs/msg/String", DOC_STRING_HASH)):
        assert rmw_zenoh.gid_of(token) == rmw_zenoh_gid(token)
        assert len(rmw_zenoh.gid_of(token)) == rmw_zenoh.GID_SIZE
    # the byte order matters: the canonical (big-endian) digest is not the GID
    assert rmw_zenoh.gid_of(DOC_LISTENER_SUB) != xxhash.xxh3_128(DOC_LISTENER_SUB.encode()).digest()


def test_a_mapped_joint_state_is_cdr_that_rosbags_decodes():
    mapping = parse({"channel": "arm.joint_states", "topic": "/joint_states", "type": "sensor_msgs/msg/JointState",
                     "direction": "out", "frame_id": "link_base",
                     "fields": {"name": {"value": ["j1", "j2", "j3", "j4", "j5", "j6"]},
                                "position": "position", "velocity": "velocity"}}, JOINT_STATES, "[[ros2]] #1")
    value = {"position": [0.1, 0.2, 0.3, 0.4, 0.5, 0.6], "velocity": [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
             "effort": [0.0] * 6, "stamp": 2.5}
    data = mapping.to_cdr(value, 1_700_000_001_250_000_000)
    assert data[:4] == b"\x00\x01\x00\x00"  # CDR little-endian encapsulation header
    message = STORE.deserialize_cdr(data, "sensor_msgs/msg/JointState")
    assert message.name == ["j1", "j2", "j3", "j4", "j5", "j6"]
    assert message.position.tolist() == value["position"] and message.velocity.tolist() == value["velocity"]
    assert message.effort.tolist() == []  # not mapped: an empty sequence, as ROS allows
    assert (message.header.stamp.sec, message.header.stamp.nanosec) == (1_700_000_001, 250_000_000)
    assert message.header.frame_id == "link_base"
    assert mapping.key == ("0/joint_states/sensor_msgs::msg::dds_::JointState_/"
                           + STORE.hash_rihs01("sensor_msgs/msg/JointState"))


def test_twist_tf_pose_and_scalars_map_both_ways():
    drive = Struct("drive", speed=Float, turn=Float, why=Enum("doing", "WANDER", "FOLLOW", "EAT", "AVOID"))
    twist = parse({"channel": "buggy.conscious", "topic": "/cmd_vel", "type": "geometry_msgs/msg/Twist",
                   "direction": "in", "fields": {"speed": "linear.x", "turn": "angular.z", "why": {"value": "WANDER"}}},
                  drive, "e")
    data = bytes(STORE.serialize_cdr(STORE.types["geometry_msgs/msg/Twist"](
        linear=STORE.types["geometry_msgs/msg/Vector3"](x=0.2, y=0.0, z=0.0),
        angular=STORE.types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=-0.7)), "geometry_msgs/msg/Twist"))
    assert twist.from_cdr(data) == {"speed": 0.2, "turn": -0.7, "why": "WANDER"}
    pose_type = Struct("pose", x=Float, y=Float, heading=Float)
    pose = parse({"channel": "body.pose", "topic": "/buggy/pose", "type": "geometry_msgs/msg/PoseStamped",
                  "direction": "out", "frame_id": "arena", "fields": {"pose.position.x": "x", "pose.position.y": "y"}},
                 pose_type, "e")
    decoded = STORE.deserialize_cdr(pose.to_cdr({"x": 1.5, "y": -2.0, "heading": 0.0}, 7), "geometry_msgs/msg/PoseStamped")
    assert (decoded.pose.position.x, decoded.pose.position.y, decoded.header.frame_id) == (1.5, -2.0, "arena")
    tf = parse({"channel": "body.pose", "topic": "/tf", "type": "tf2_msgs/msg/TFMessage", "direction": "out",
                "fields": {"transforms[0].header.frame_id": {"value": "arena"},
                           "transforms[0].child_frame_id": {"value": "buggy"},
                           "transforms[0].transform.translation.x": "x",
                           "transforms[0].transform.rotation.w": {"value": 1.0}}}, pose_type, "e")
    decoded = STORE.deserialize_cdr(tf.to_cdr({"x": 3.0, "y": 0.0, "heading": 0.0}, 9), "tf2_msgs/msg/TFMessage")
    (transform,) = decoded.transforms
    assert (transform.child_frame_id, transform.transform.translation.x, transform.header.stamp.nanosec) == ("buggy", 3.0, 9)
    scalar = parse({"channel": "a.b", "topic": "/level", "type": "std_msgs/msg/Float64", "direction": "out"}, Float, "e")
    assert STORE.deserialize_cdr(scalar.to_cdr(0.25, 0), "std_msgs/msg/Float64").data == 0.25
    back = parse({"channel": "a.c", "topic": "/level", "type": "std_msgs/msg/Float64", "direction": "in"}, Float, "e")
    assert back.from_cdr(scalar.to_cdr(0.25, 0)) == 0.25


@pytest.mark.parametrize("raw, said", [
    ({"type": "sensor_msgs/msg/Nope"}, "unknown ROS 2 message type"),
    ({"topic": "joint_states"}, "not a fully qualified ROS 2 topic name"),
    ({"direction": "sideways"}, "direction must be"),
    ({"domain": 300}, "domain must be a ROS_DOMAIN_ID"),
    ({"fields": {"position": "nope"}}, "no field 'nope'"),
    ({"fields": {"nope": "position"}}, "has no field 'nope'"),
    ({"fields": {"name": "position"}}, "do not fit"),
    ({"fields": {"header": "stamp"}}, "is a message: map its fields one by one"),
    ({"fields": {"header.frame_id": {"value": 3}}}, "a string, not 3"),
    ({"colour": "red"}, "unknown key(s) colour"),
])
def test_a_mapping_that_cannot_work_is_refused_with_a_reason(raw, said):
    table = {"channel": "arm.joint_states", "topic": "/joint_states", "type": "sensor_msgs/msg/JointState",
             "direction": "out", "fields": {"position": "position"}, **raw}
    with pytest.raises(MappingError, match=None) as caught:
        parse(table, JOINT_STATES, "[[ros2]] #1")
    assert said in str(caught.value) and str(caught.value).startswith("[[ros2]] #1")


def test_a_message_that_is_not_cdr_of_its_type_is_an_error_not_a_crash():
    back = parse({"channel": "a.c", "topic": "/level", "type": "std_msgs/msg/Float64", "direction": "in"}, Float, "e")
    with pytest.raises(messages.MessageError, match="not CDR of std_msgs/msg/Float64"):
        back.from_cdr(b"\x00\x01")
