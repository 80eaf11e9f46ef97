"""The per-package build cache: a package built once (the lab's interface package, untouched by
most students) is taken from that build by the next submission instead of built again."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from grader.runner import ProcessSpec, RosGraph
from grader.workspace import build_workspace
from grader.workspace.package_cache import package_keys
from grader.workspace.source import find_packages

WS = Path(__file__).parent / "ws"


def _copy_ws(dest: Path) -> Path:
    shutil.copytree(WS, dest, ignore=shutil.ignore_patterns("build", "install", "log", "__pycache__"))
    return dest


def _append(path: Path, text: str) -> None:
    with open(path, "a") as f:
        f.write(text)


def _keys(ws: Path) -> dict[str, str]:
    return package_keys(find_packages(ws / "src"), extra="x")


def test_a_package_key_covers_its_sources_and_its_dependencies_not_its_place(tmp_path: Path) -> None:
    base = _keys(_copy_ws(tmp_path / "a"))
    assert _keys(_copy_ws(tmp_path / "elsewhere")) == base
    nodes_changed = _copy_ws(tmp_path / "b")
    _append(nodes_changed / "src" / "demo_nodes" / "demo_nodes" / "hello.py", "# changed\n")
    keys = _keys(nodes_changed)
    assert keys["demo_interfaces"] == base["demo_interfaces"] and keys["demo_nodes"] != base["demo_nodes"]
    iface_changed = _copy_ws(tmp_path / "c")
    (iface_changed / "src" / "demo_interfaces" / "action" / "Note.txt").write_text("not an interface\n")
    keys = _keys(iface_changed)
    # demo_nodes depends on demo_interfaces: built against other sources, it is another build
    assert keys["demo_interfaces"] != base["demo_interfaces"] and keys["demo_nodes"] != base["demo_nodes"]


@pytest.mark.slow
@pytest.mark.ros
def test_unchanged_package_is_taken_from_the_earlier_build_and_works(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    first = build_workspace(WS, cache_dir=cache)
    assert first.ok and not any(p.reused_from for p in first.packages.values())

    student = _copy_ws(tmp_path / "student")
    _append(student / "src" / "demo_nodes" / "demo_nodes" / "hello.py", "# a student's edit\n")
    second = build_workspace(student, cache_dir=cache)
    assert second.ok and second.digest != first.digest
    assert second.packages["demo_interfaces"].reused_from == str(first.root)
    assert not second.packages["demo_nodes"].reused_from
    events = (second.root / "log" / "latest_build" / "events.log").read_text()
    assert "(demo_interfaces) JobStarted" not in events and "(demo_nodes) JobStarted" in events
    # a real folder of the new build area, its files hard links to the first build's
    ours, theirs = second.install / "demo_interfaces", first.install / "demo_interfaces"
    assert ours.is_dir() and not ours.is_symlink()
    lib = next(ours.glob("lib/*.so"))
    assert os.stat(lib).st_ino == os.stat(theirs / "lib" / lib.name).st_ino
    package_sh = (ours / "share" / "demo_interfaces" / "package.sh").read_text()
    assert str(ours) in package_sh and str(theirs) not in package_sh

    # demo_nodes was built against the taken package, and its node uses the custom action type
    with RosGraph(tmp_path / "run", prefixes=second.prefixes()) as graph:
        proc = graph.start(ProcessSpec("make_goal", second.argv("demo_nodes", "make_goal")))
        assert proc.wait(30) == 0, proc.errors()
    assert "made goal 2.0,7.0" in proc.output()

    # another workspace whose every package was built before: all taken, colcon not run
    third = _copy_ws(tmp_path / "third")
    shutil.rmtree(third / "src" / "demo_nodes")
    all_taken = build_workspace(third, cache_dir=cache)
    assert all_taken.ok and all(p.reused_from for p in all_taken.packages.values())
    assert not (all_taken.root / "log").exists()
    assert "reused from an earlier build" in all_taken.build_log.read_text()
