"""Helpers of the bag tests (imported as ``baghelpers``: tests/ is not a package)."""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Any

import yaml

HERE = Path(__file__).resolve().parent
TCI_SRC = HERE / "data" / "turtle_control_interfaces"

QOS_KEYS = {"history", "depth", "reliability", "durability", "deadline", "lifespan", "liveliness",
            "liveliness_lease_duration", "avoid_ros_namespace_conventions"}
ENUMS = {
    "history": {"keep_last", "keep_all", "system_default", "unknown"},
    "reliability": {"reliable", "best_effort", "system_default", "unknown", "best_available"},
    "durability": {"volatile", "transient_local", "system_default", "unknown", "best_available"},
    "liveliness": {"automatic", "manual_by_topic", "system_default", "unknown", "best_available"},
}


def start_recorder(graph: Any, out: Path, *topics: str, name: str = "recorder",
                   regex: str | None = None, env: dict | None = None, extra: tuple = ()) -> Any:
    from grader.bag.recorder import recorder_argv, wait_ready
    from grader.runner import ProcessSpec

    proc = graph.start(ProcessSpec(name=name, argv=recorder_argv(out, topics=list(topics) or None,
                                                                 regex=regex, extra=extra), env=env))
    wait_ready(proc.stdout_path, 30, proc)
    return proc


def loadgen(graph: Any, name: str, type_name: str, topics: list[str], *, rate: float, count: int,
            env: dict | None = None, extra: list[str] | None = None) -> Any:
    from grader.runner import ProcessSpec, python_argv

    argv = python_argv("grader.bag.loadgen", "--type", type_name, "--topics", *topics,
                       "--rate", str(rate), "--count", str(count), "--node-name", name,
                       *(extra or []))
    return graph.start(ProcessSpec(name=name, argv=argv, env=env))


def finish(proc: Any, timeout: float = 60) -> str:
    """Wait for a loadgen/replay process to exit 0 and return its stdout."""
    rc = proc.wait(timeout)
    assert rc == 0, f"{proc.name} exited {rc}: {proc.output()[-500:]} {proc.errors()[-1500:]}"
    return proc.output()


def stop_recorder(proc: Any) -> str:
    rc = proc.stop()
    out = proc.output()
    assert rc == 0, f"recorder exited {rc}: {out[-500:]} {proc.errors()[-1500:]}"
    assert "RECORDED" in out, out
    return out


def assert_jazzy_v9_metadata(bag_dir: Path) -> dict:
    """Check metadata.yaml against the fields ROS 2 Jazzy's rosbag2 writes (version 9)."""
    doc = yaml.safe_load((Path(bag_dir) / "metadata.yaml").read_text())
    assert set(doc) == {"rosbag2_bagfile_information"}
    info = doc["rosbag2_bagfile_information"]
    mandatory = {"version", "storage_identifier", "duration", "starting_time", "message_count",
                 "topics_with_message_count", "compression_format", "compression_mode",
                 "relative_file_paths", "files", "custom_data", "ros_distro"}
    assert mandatory <= set(info), mandatory - set(info)
    assert info["version"] == 9
    assert info["storage_identifier"] == "mcap"
    assert info["ros_distro"] == "jazzy"
    assert isinstance(info["duration"]["nanoseconds"], int) and info["duration"]["nanoseconds"] >= 0
    assert isinstance(info["starting_time"]["nanoseconds_since_epoch"], int)
    assert isinstance(info["compression_format"], str) and isinstance(info["compression_mode"], str)
    assert info["custom_data"] is None or all(isinstance(k, str) and isinstance(v, str)
                                              for k, v in info["custom_data"].items())
    total = 0
    for entry in info["topics_with_message_count"]:
        assert set(entry) == {"topic_metadata", "message_count"}
        tm = entry["topic_metadata"]
        assert set(tm) == {"name", "type", "serialization_format", "offered_qos_profiles",
                           "type_description_hash"}
        assert tm["name"].startswith("/") and re.match(r"^\w+/(msg|srv|action)/\w+$", tm["type"])
        assert tm["serialization_format"] == "cdr"
        assert isinstance(tm["offered_qos_profiles"], list), "Jazzy (v9) stores a YAML list"
        for q in tm["offered_qos_profiles"]:
            assert set(q) == QOS_KEYS
            for key, allowed in ENUMS.items():
                assert q[key] in allowed, (key, q[key])
            for key in ("deadline", "lifespan", "liveliness_lease_duration"):
                assert set(q[key]) == {"sec", "nsec"}
        h = tm["type_description_hash"]
        assert h == "" and "/srv/" in tm["type"] or re.match(r"^RIHS01_[0-9a-f]{64}$", h), h
        total += entry["message_count"]
    assert total == info["message_count"]
    assert info["relative_file_paths"] == [f["path"] for f in info["files"]]
    for f in info["files"]:
        assert (Path(bag_dir) / f["path"]).is_file()
        assert set(f) == {"path", "starting_time", "duration", "message_count"}
    assert sum(f["message_count"] for f in info["files"]) == info["message_count"]
    return info


def crash(writer: Any) -> int:
    """Leave ``writer``'s bag as a SIGKILL would: only the bytes the OS already has, no summary,
    no metadata.yaml. Returns the size of that file."""
    mcap_file = writer.path / writer.file_name
    on_disk = mcap_file.read_bytes()      # what the process handed to the OS so far
    writer.close()
    (writer.path / "metadata.yaml").unlink()
    mcap_file.write_bytes(on_disk)
    return len(on_disk)


def wait_for(predicate, timeout: float, step: float = 0.05) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(step)
    return predicate()


def cdr(typestore: Any, msg: Any, type_name: str) -> bytes:
    """Serialize with rosbags (an encoder independent of ours)."""
    return bytes(typestore.serialize_cdr(msg, type_name))
