"""Definitions and decoding: rosbags serialises, we decode from what the bag stores; no ROS."""

from __future__ import annotations

import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import yaml

from grader.bag import cdr
from grader.bag.frames import load_bag_meta, load_frames
from grader.bag.msgdefs import (SEPARATOR, DefinitionSource, from_rosbag2_service_definition,
                                split_sections)
from grader.bag.writer import BagWriter
from grader.errors import GraderError

T0 = 1_700_000_000_000_000_000
SRC = DefinitionSource()


@pytest.fixture(scope="module")
def jazzy():
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(Stores.ROS2_JAZZY)


def local_store(*types: str):
    """A rosbags typestore built from *our* definitions (what a bag carries)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    ts = get_typestore(Stores.EMPTY)
    for t in types:
        ts.register(get_types_from_msg(SRC.full_text(t), t))
    return ts


@pytest.mark.parametrize("type_name", [
    "turtlesim/msg/Pose", "geometry_msgs/msg/Twist", "rcl_interfaces/msg/Log",
    "std_msgs/msg/Float32MultiArray", "action_msgs/msg/GoalStatusArray",
    "rcl_interfaces/msg/ParameterEvent", "turtlesim/action/RotateAbsolute_FeedbackMessage",
    "turtlesim/action/RotateAbsolute_SendGoal_Request",
    "turtlesim/action/RotateAbsolute_GetResult_Response"])
def test_definitions_hash_like_rosidl(type_name: str) -> None:
    """Our complete definitions, parsed by rosbags, hash (RIHS01) exactly as rosidl's .json says."""
    ts = local_store(type_name)
    expected = SRC.type_hash(type_name)
    assert expected.startswith("RIHS01_")
    assert ts.hash_rihs01(type_name) == expected


def test_service_event_definition_lists_each_dependency_once() -> None:
    text = SRC.full_text("turtlesim/srv/Spawn_Event")
    headers = [line for line in text.splitlines() if line.startswith("MSG: ")]
    assert headers == ["MSG: service_msgs/ServiceEventInfo", "MSG: builtin_interfaces/Time",
                       "MSG: turtlesim/srv/Spawn_Request", "MSG: turtlesim/srv/Spawn_Response"]
    types = cdr.parse_definition(text, "turtlesim/srv/Spawn_Event")
    ev = {f.name: f for f in types["turtlesim/srv/Spawn_Event"]}
    assert ev["request"].array == "bounded" and ev["request"].count == 1
    assert [f.name for f in types["turtlesim/srv/Spawn_Request"]] == ["x", "y", "theta", "name"]
    # rosbags (which files srv types under pkg/srv/msg/...) agrees on the layout
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore
    ts = get_typestore(Stores.EMPTY)
    ts.register(get_types_from_msg(text, "turtlesim/srv/Spawn_Event"))
    assert "turtlesim/srv/msg/Spawn_Request" in ts.fielddefs


def write_bag(path: Path, topics: dict[str, tuple[str, list[bytes]]], definitions: dict | None = None,
              period_ns: int = 10_000_000) -> Path:
    definitions = definitions or {}
    with BagWriter(path) as w:
        for name, (typ, _payloads) in topics.items():
            w.add_topic(name, typ, definitions[typ] if typ in definitions else SRC.full_text(typ))
        k = 0
        for name, (_typ, payloads) in topics.items():
            for i, p in enumerate(payloads):
                w.write(name, T0 + i * period_ns + k, p, T0 + i * period_ns - 1000 if i % 2 else 0)
            k += 1
    return path


def test_every_kind_of_field_flattens_as_documented(tmp_path: Path, jazzy) -> None:
    ts = jazzy
    Twist, Vector3 = ts.types["geometry_msgs/msg/Twist"], ts.types["geometry_msgs/msg/Vector3"]
    F32MA = ts.types["std_msgs/msg/Float32MultiArray"]
    Layout, Dim = ts.types["std_msgs/msg/MultiArrayLayout"], ts.types["std_msgs/msg/MultiArrayDimension"]
    Log, Time = ts.types["rcl_interfaces/msg/Log"], ts.types["builtin_interfaces/msg/Time"]
    twists = [bytes(ts.serialize_cdr(Twist(Vector3(i, 0.5, 0), Vector3(0, 0, -i)), "geometry_msgs/msg/Twist"))
              for i in range(5)]
    arrays = [bytes(ts.serialize_cdr(F32MA(Layout([Dim("pairs", n, 2)] if n else [], 0),
                                           np.arange(n, dtype=np.float32) + 0.5), "std_msgs/msg/Float32MultiArray"))
              for n in (2, 0, 3)]
    logs = [bytes(ts.serialize_cdr(Log(Time(7, 9), 20, "node", f"hello ünïcode {i}", "f.py", "fn", 42),
                                   "rcl_interfaces/msg/Log")) for i in range(3)]
    bag = write_bag(tmp_path / "b", {"/cmd_vel": ("geometry_msgs/msg/Twist", twists),
                                     "/random_numbers": ("std_msgs/msg/Float32MultiArray", arrays),
                                     "/rosout": ("rcl_interfaces/msg/Log", logs)})
    fr = load_frames(bag)
    tw = fr["/cmd_vel"]
    assert tw.index.name == "t" and tw.index.is_monotonic_increasing
    assert tw.index[0] == pytest.approx(T0 / 1e9)
    assert list(tw.columns) == ["pub_t", "linear.x", "linear.y", "linear.z", "angular.x", "angular.y", "angular.z"]
    assert tw["linear.x"].tolist() == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert tw["angular.z"].tolist() == [-0.0, -1.0, -2.0, -3.0, -4.0]
    assert tw["linear.x"].dtype == np.float64
    assert np.isnan(tw["pub_t"].iloc[0]) and tw["pub_t"].iloc[1] == pytest.approx((T0 + 10_000_000 - 1000) / 1e9)
    ra = fr["/random_numbers"]
    assert ra["data.len"].tolist() == [2, 0, 3]
    assert ra["data[0]"].tolist()[0] == 0.5 and np.isnan(ra["data[0]"].iloc[1])
    assert np.isnan(ra["data[2]"].iloc[0]) and ra["data[2]"].iloc[2] == 2.5
    assert ra["layout.dim.len"].tolist() == [1, 0, 1]
    assert ra["layout.dim[0].label"].iloc[0] == "pairs"
    lg = fr["/rosout"]
    assert lg["msg"].tolist() == [f"hello ünïcode {i}" for i in range(3)]
    assert lg["name"].iloc[0] == "node" and lg["level"].iloc[0] == 20 and lg["line"].iloc[0] == 42
    assert lg["stamp.sec"].iloc[0] == 7 and lg["stamp.nanosec"].iloc[0] == 9
    assert lg.attrs == {"topic": "/rosout", "type": "rcl_interfaces/msg/Log", "bag": str(bag),
                        "finalized": True}
    meta = load_bag_meta(bag)
    assert meta.counts == {"/cmd_vel": 5, "/random_numbers": 3, "/rosout": 3}
    assert meta.types["/rosout"] == "rcl_interfaces/msg/Log" and meta.finalized
    only = load_frames(bag, ["/rosout"])
    assert list(only) == ["/rosout"]
    with pytest.raises(GraderError, match="no topic /rosot.*topics: /cmd_vel, /random_numbers, /rosout"):
        load_frames(bag, ["/rosot"])


def test_fixed_and_generic_paths_agree(tmp_path: Path, jazzy) -> None:
    """The numpy fast path and the per-message decoder give the same frame (incl. big-endian)."""
    Pose = local_store("turtlesim/msg/Pose").types["turtlesim/msg/Pose"]
    ts = local_store("turtlesim/msg/Pose")
    rng = np.random.default_rng(1)
    vals = rng.random((200, 5)).astype(np.float32)
    le = [bytes(ts.serialize_cdr(Pose(*map(float, v)), "turtlesim/msg/Pose")) for v in vals]
    be = [bytes(ts.serialize_cdr(Pose(*map(float, v)), "turtlesim/msg/Pose", little_endian=False)) for v in vals]
    assert le[0][:2] == b"\x00\x01" and be[0][:2] == b"\x00\x00"
    bag = write_bag(tmp_path / "p", {"/le": ("turtlesim/msg/Pose", le), "/be": ("turtlesim/msg/Pose", be)})
    fr = load_frames(bag)
    text = SRC.full_text("turtlesim/msg/Pose")
    dec = cdr.message_decoder(text, "turtlesim/msg/Pose")
    generic = pd.DataFrame([dec(memoryview(p)[4:]) for p in le])
    for topic in ("/le", "/be"):
        got = fr[topic].drop(columns="pub_t").reset_index(drop=True)
        pd.testing.assert_frame_equal(got, generic, check_dtype=False)
        assert np.allclose(got["x"], vals[:, 0].astype(np.float64))


def test_service_events_and_hidden_action_types(tmp_path: Path) -> None:
    ev_t = "turtlesim/srv/Spawn_Event"
    ts = local_store(ev_t, "turtlesim/action/RotateAbsolute_FeedbackMessage")
    Ev = ts.types["turtlesim/srv/msg/Spawn_Event"]
    Info, Time = ts.types["service_msgs/msg/ServiceEventInfo"], ts.types["builtin_interfaces/msg/Time"]
    Req, Resp = ts.types["turtlesim/srv/msg/Spawn_Request"], ts.types["turtlesim/srv/msg/Spawn_Response"]
    gid = np.arange(16, dtype=np.uint8)
    events = [Ev(Info(0, Time(1, 2), gid, 5), [Req(1.5, 2.5, 0.0, "t2")], []),
              Ev(Info(2, Time(1, 3), gid, 5), [], [Resp("t2")])]
    payloads = [bytes(ts.serialize_cdr(e, "turtlesim/srv/msg/Spawn_Event")) for e in events]
    Fb = ts.types["turtlesim/action/RotateAbsolute_FeedbackMessage"]
    UUID, F = ts.types["unique_identifier_msgs/msg/UUID"], ts.types["turtlesim/action/RotateAbsolute_Feedback"]
    fbs = [bytes(ts.serialize_cdr(Fb(UUID(np.full(16, i, np.uint8)), F(0.25 * i)),
                                  "turtlesim/action/RotateAbsolute_FeedbackMessage")) for i in range(4)]
    bag = write_bag(tmp_path / "s", {"/spawn/_service_event": (ev_t, payloads),
                                     "/turtle1/rotate_absolute/_action/feedback":
                                         ("turtlesim/action/RotateAbsolute_FeedbackMessage", fbs)})
    fr = load_frames(bag)
    ev = fr["/spawn/_service_event"]
    assert ev["info.event_type"].tolist() == [0, 2]
    assert ev["request.len"].tolist() == [1, 0] and ev["response.len"].tolist() == [0, 1]
    assert ev["request[0].x"].iloc[0] == 1.5 and ev["request[0].name"].iloc[0] == "t2"
    assert ev["response[0].name"].iloc[1] == "t2" and ev["info.client_gid[15]"].iloc[0] == 15
    fb = fr["/turtle1/rotate_absolute/_action/feedback"]
    assert fb["feedback.remaining"].tolist() == [0.0, 0.25, 0.5, 0.75]
    assert fb["goal_id.uuid[3]"].tolist() == [0, 1, 2, 3]


def test_rosbag2_style_file_is_read(tmp_path: Path) -> None:
    """A bag as rosbag2 Jazzy writes it: schemas/channels inside zstd chunks, a service-event
    schema holding the ``SRV:`` service text, an action type with an empty ('unknown') schema."""
    from mcap.writer import CompressionType, Writer

    ts = local_store("turtlesim/srv/Spawn_Event", "turtlesim/msg/Pose",
                     "turtlesim/action/RotateAbsolute_FeedbackMessage")
    bag = tmp_path / "rosbag2_2025_01_01-00_00_00"
    bag.mkdir()
    srv_text = (Path(sys.prefix) / "share/turtlesim/srv/Spawn.srv").read_text()
    srv_def = f"{SEPARATOR}\nSRV: turtlesim/srv/Spawn\n{srv_text}"
    qos = [{"history": "unknown", "depth": 0, "reliability": "reliable", "durability": "volatile",
            "deadline": {"sec": 9223372036, "nsec": 854775807},
            "lifespan": {"sec": 9223372036, "nsec": 854775807}, "liveliness": "automatic",
            "liveliness_lease_duration": {"sec": 9223372036, "nsec": 854775807},
            "avoid_ros_namespace_conventions": False}]
    Pose = ts.types["turtlesim/msg/Pose"]
    Ev = ts.types["turtlesim/srv/msg/Spawn_Event"]
    Info, Time = ts.types["service_msgs/msg/ServiceEventInfo"], ts.types["builtin_interfaces/msg/Time"]
    Req = ts.types["turtlesim/srv/msg/Spawn_Request"]
    fb_t = "turtlesim/action/RotateAbsolute_FeedbackMessage"
    Fb, UUID, F = ts.types[fb_t], ts.types["unique_identifier_msgs/msg/UUID"], ts.types["turtlesim/action/RotateAbsolute_Feedback"]
    with open(bag / f"{bag.name}_0.mcap", "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD, chunk_size=512, enable_crcs=False)
        w.start(profile="ros2", library="rosbag2-like")
        ids = {}
        for topic, typ, enc, data in (
                ("/turtle1/pose", "turtlesim/msg/Pose", "ros2msg", SRC.full_text("turtlesim/msg/Pose")),
                ("/spawn/_service_event", "turtlesim/srv/Spawn_Event", "ros2msg", srv_def),
                ("/turtle1/rotate_absolute/_action/feedback", fb_t, "unknown", "")):
            sid = w.register_schema(typ, enc, data.encode())
            ids[topic] = w.register_channel(topic, "cdr", sid, {
                "offered_qos_profiles": yaml.safe_dump(qos), "topic_type_hash": SRC.type_hash(typ)})
        for i in range(50):
            w.add_message(ids["/turtle1/pose"], T0 + i * 16_000_000,
                          bytes(ts.serialize_cdr(Pose(i, 1, 0, 0, 0), "turtlesim/msg/Pose")), T0 + i * 16_000_000 - 10)
        w.add_message(ids["/spawn/_service_event"], T0 + 5,
                      bytes(ts.serialize_cdr(Ev(Info(1, Time(0, 0), np.zeros(16, np.uint8), 1),
                                                [Req(1, 2, 3, "x")], []), "turtlesim/srv/msg/Spawn_Event")), T0)
        w.add_message(ids["/turtle1/rotate_absolute/_action/feedback"], T0 + 7,
                      bytes(ts.serialize_cdr(Fb(UUID(np.zeros(16, np.uint8)), F(1.25)), fb_t)), T0)
        w.finish()
    meta = {"rosbag2_bagfile_information": {
        "version": 9, "storage_identifier": "mcap", "duration": {"nanoseconds": 49 * 16_000_000},
        "starting_time": {"nanoseconds_since_epoch": T0}, "message_count": 52,
        "topics_with_message_count": [
            {"topic_metadata": {"name": t, "type": typ, "serialization_format": "cdr",
                                "offered_qos_profiles": qos, "type_description_hash": SRC.type_hash(typ)},
             "message_count": n}
            for t, typ, n in (("/turtle1/pose", "turtlesim/msg/Pose", 50),
                              ("/spawn/_service_event", "turtlesim/srv/Spawn_Event", 1),
                              ("/turtle1/rotate_absolute/_action/feedback", fb_t, 1))],
        "compression_format": "", "compression_mode": "",
        "relative_file_paths": [f"{bag.name}_0.mcap"],
        "files": [{"path": f"{bag.name}_0.mcap", "starting_time": {"nanoseconds_since_epoch": T0},
                   "duration": {"nanoseconds": 49 * 16_000_000}, "message_count": 52}],
        "custom_data": None, "ros_distro": "jazzy"}}
    (bag / "metadata.yaml").write_text(yaml.safe_dump(meta, sort_keys=False))
    fr = load_frames(bag)
    assert fr["/turtle1/pose"]["x"].tolist() == [float(i) for i in range(50)]
    assert fr["/spawn/_service_event"]["request[0].name"].tolist() == ["x"]
    assert fr["/turtle1/rotate_absolute/_action/feedback"]["feedback.remaining"].tolist() == [1.25]
    m = load_bag_meta(bag)
    assert m.finalized and m.topics["/turtle1/pose"].offered_qos_profiles[0]["reliability"] == "reliable"
    from grader.bag.replay import plan
    p = plan(bag, remaps={"/turtle1/pose": "/replayed/pose"})
    assert len(p.times) == 52 and p.times == sorted(p.times)
    assert ("/turtle1/pose", "/replayed/pose", "turtlesim/msg/Pose", m.topics["/turtle1/pose"].offered_qos_profiles) in p.topics


def test_srv_section_conversion_matches_local_definition() -> None:
    srv_text = (Path(sys.prefix) / "share/turtlesim/srv/Spawn.srv").read_text()
    converted = from_rosbag2_service_definition(f"{SEPARATOR}\nSRV: turtlesim/srv/Spawn\n{srv_text}",
                                                "turtlesim/srv/Spawn_Event")
    a = cdr.parse_definition(converted, "turtlesim/srv/Spawn_Event")
    b = cdr.parse_definition(SRC.full_text("turtlesim/srv/Spawn_Event"), "turtlesim/srv/Spawn_Event")
    assert a == b
    assert [s[0] for s in split_sections(converted)] == ["", "MSG", "MSG", "MSG", "MSG"]


def test_empty_topic_and_corrupt_payload(tmp_path: Path) -> None:
    bag = write_bag(tmp_path / "e", {"/pose": ("turtlesim/msg/Pose", []),
                                     "/log": ("rcl_interfaces/msg/Log", [b"\x00\x01\x00\x00\x07\x00"])})
    empty = load_frames(bag, ["/pose"])["/pose"]
    assert len(empty) == 0 and list(empty.columns) == ["pub_t", "x", "y", "theta", "linear_velocity", "angular_velocity"]
    with pytest.raises(GraderError, match=r"message 0 on /log .*does not match its stored definition"):
        load_frames(bag, ["/log"])


def test_frames_module_never_imports_rclpy(tmp_path: Path) -> None:
    code = ("import sys; from grader.bag.frames import load_frames; "
            "load_frames(sys.argv[1]); assert 'rclpy' not in sys.modules, 'rclpy imported'")
    out = subprocess.run([sys.executable, "-c", code, "fixtures/bags/circle_pose"],
                         cwd=Path(__file__).resolve().parents[2], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr[-2000:]


def test_pose_payload_helper_layout() -> None:
    """Guard for the fixed layout offsets: Pose is five packed float32 after the 4-byte header."""
    types = cdr.parse_definition(SRC.full_text("turtlesim/msg/Pose"), "turtlesim/msg/Pose")
    leaves, size = cdr.fixed_layout(types, "turtlesim/msg/Pose")
    assert size == 20 and [lf.offset for lf in leaves] == [0, 4, 8, 12, 16]
    types = cdr.parse_definition("uint8 a\nfloat64 b\nuint16[3] c\nbool d\n", "p/msg/M")
    leaves, size = cdr.fixed_layout(types, "p/msg/M")
    assert [(lf.column, lf.offset) for lf in leaves] == [("a", 0), ("b", 8), ("c[0]", 16), ("c[1]", 18), ("c[2]", 20), ("d", 22)]
    body = struct.pack("<B7xdHHH?", 1, 2.5, 3, 4, 5, True)
    out = cdr.decode_fixed(np.frombuffer(body, np.uint8).reshape(1, -1), leaves)
    assert out["b"][0] == 2.5 and out["c[2]"][0] == 5 and out["d"][0]


def test_long_arrays_stay_one_column(tmp_path: Path) -> None:
    text = "float32[300] big\nuint8 k\nfloat64[] seq\n"
    body = struct.pack("<300fB3xI", *range(300), 7, 1) + struct.pack("<d", 2.5)
    bag = write_bag(tmp_path / "l", {"/l": ("p/msg/Long", [b"\x00\x01\x00\x00" + body] * 3)},
                    definitions={"p/msg/Long": text})
    df = load_frames(bag)["/l"]
    assert "big[0]" not in df.columns and df["big.len"].tolist() == [300] * 3
    assert np.array_equal(df["big"].iloc[0], np.arange(300, dtype=np.float64))
    assert df["k"].tolist() == [7] * 3 and df["seq[0]"].tolist() == [2.5] * 3 and df["seq.len"].iloc[0] == 1
