"""The per-package build cache: the instructor's packages (a rubric's ``support:``) are built
once, in a build of their own, and every submission with an untouched copy takes that build."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from grader.runner import ProcessSpec, RosGraph
from grader.workspace import build_workspace
from grader.workspace.package_cache import package_keys
from grader.workspace.source import find_packages

WS = Path(__file__).parent / "ws"
SUPPORT = {"demo_interfaces": WS / "src" / "demo_interfaces"}


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
def test_support_package_is_built_once_and_taken_by_each_submission(tmp_path: Path) -> None:
    cache = tmp_path / "cache"
    first = build_workspace(WS, cache_dir=cache, support=SUPPORT)
    shared_from = first.packages["demo_interfaces"].reused_from
    assert first.ok and shared_from and Path(shared_from) != first.root, "built apart, then taken"
    assert not first.packages["demo_nodes"].reused_from
    events = (first.root / "log" / "latest_build" / "events.log").read_text()
    assert "(demo_interfaces) JobStarted" not in events and "(demo_nodes) JobStarted" in events
    # a copy in the submission's own build area: what its build does there stays there
    ours, shared = first.install / "demo_interfaces", Path(shared_from) / "install" / "demo_interfaces"
    assert ours.is_dir() and not ours.is_symlink()
    lib = next(ours.glob("lib/*.so"))
    lib.write_bytes(b"overwritten by a hostile setup.py")
    assert (shared / "lib" / lib.name).read_bytes() != b"overwritten by a hostile setup.py"
    package_sh = (ours / "share" / "demo_interfaces" / "package.sh").read_text()
    assert str(ours) in package_sh and str(shared) not in package_sh

    student = _copy_ws(tmp_path / "student")
    _append(student / "src" / "demo_nodes" / "demo_nodes" / "hello.py", "# a student's edit\n")
    second = build_workspace(student, cache_dir=cache, support=SUPPORT)
    assert second.ok and second.packages["demo_interfaces"].reused_from == shared_from
    # demo_nodes was built against the taken package, and its node uses the custom action type
    with RosGraph(tmp_path / "run", prefixes=second.prefixes()) as graph:
        proc = graph.start(ProcessSpec("make_goal", second.argv("demo_nodes", "make_goal"),
                                       untrusted=True))
        assert proc.wait(30) == 0, proc.errors()
    assert "made goal 2.0,7.0" in proc.output()

    # packages built in a student's workspace are never offered to others (its other packages'
    # build code could have changed them): the index names the support build only
    index = [json.loads(f.read_text()) for f in (cache / "packages").glob("*.json")]
    assert index and {e["root"] for e in index} == {shared_from}
    assert {e["name"] for e in index} == {"demo_interfaces"}
