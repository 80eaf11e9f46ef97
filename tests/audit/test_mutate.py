"""grader.audit.mutate: every operator on a small node, determinism, ids, diffs and copies."""

from __future__ import annotations

import ast
import textwrap
from pathlib import Path

import pytest

from grader.audit.mutate import OPERATORS, mutants, sample, source_files

REPO = Path(__file__).resolve().parents[2]

NODE = textwrap.dedent('''\
    """A controller."""
    import math

    import rclpy
    from rclpy.node import Node


    class Controller(Node):
        def __init__(self):
            super().__init__("controller")
            self.pub = self.create_publisher(Twist, "/turtle1/cmd_vel", 10)
            self.create_subscription(Pose, "/turtle1/pose", self.on_pose, 10)
            self.create_timer(0.1, self.step)
            self.rate = self.create_rate(30.0)
            self.k = 2.0

        def on_pose(self, msg: Pose):
            e = math.atan2(msg.y, msg.x) - msg.theta
            e = math.atan2(math.sin(e), math.cos(e))
            w = math.remainder(e, 2 * math.pi)
            a = (e + math.pi) % (2 * math.pi) - math.pi
            while e > math.pi:
                e -= 2 * math.pi
            cmd = Twist()
            cmd.angular.z = -self.k * e
            self.pub.publish(cmd)
            self.get_logger().info(f"turn {e:.2f}")
            self.count += 1

        def step(self):
            try:
                self.pub.publish(Twist())
            except Exception:
                self.get_logger().error("x")


    def main():
        rclpy.init()
        rclpy.spin(Controller())


    if __name__ == "__main__":
        main()
    ''')


@pytest.fixture()
def ws(tmp_path: Path) -> Path:
    pkg = tmp_path / "ws" / "src" / "ctl"
    (pkg / "ctl").mkdir(parents=True)
    (pkg / "ctl" / "node.py").write_text(NODE)
    (pkg / "ctl" / "__init__.py").write_text("")
    (pkg / "setup.py").write_text("from setuptools import setup\nsetup(name='ctl', version='1.0')\n")
    (pkg / "test").mkdir()
    (pkg / "test" / "test_flake8.py").write_text("def test():\n    assert 1 + 1 == 2\n")
    (pkg / "package.xml").write_text("<package><name>ctl</name></package>\n")
    (tmp_path / "ws" / "expected.yaml").write_text("items: {}\n")
    return tmp_path / "ws"


def by_op(found, op):
    return [m for m in found if m.operator == op]


def test_every_operator_finds_its_sites(ws: Path) -> None:
    found = mutants(ws)
    assert [p.name for p in source_files(ws)] == ["__init__.py", "node.py"]   # no setup.py, no tests
    assert {m.operator for m in found} == set(OPERATORS)
    repl = {(m.operator, m.original.split("\n")[0], m.replacement) for m in found}
    # flip a sign: the unary minus and a difference
    assert ("flip_sign", "-self.k", "self.k") in repl
    assert any(m.original == "math.atan2(msg.y, msg.x) - msg.theta" and "+ msg.theta" in m.replacement
               for m in by_op(found, "flip_sign"))
    assert ("flip_sign", "self.count += 1", "self.count -= 1") in repl
    # scale a constant (never a QoS depth, never the timer period)
    scaled = {m.original for m in by_op(found, "scale_constant")}
    assert "2.0" in scaled and "10" not in scaled and "0.1" not in scaled
    # swap two arguments of the same kind (not a type with a topic)
    assert ("swap_args", "msg.y, msg.x", "msg.x, msg.y") in repl
    assert not any("Twist" in m.original for m in by_op(found, "swap_args"))
    # rename a topic
    assert {m.replacement for m in by_op(found, "rename_topic")} == {"'/turtle1/cmd_vel_renamed'",
                                                                    "'/turtle1/pose_renamed'"}
    # drop a publish / log / call, but not clean-up in an except block, super().__init__ or __main__
    dropped = [m.description for m in by_op(found, "drop_call")]
    assert any(d.startswith("drop the publish self.pub.publish(cmd)") for d in dropped)
    assert any(d.startswith("drop the log self.get_logger().info") for d in dropped)
    assert any(d.startswith("drop the call rclpy.spin") for d in dropped)
    assert not any("error" in d or "super()" in d or d.endswith("main()") for d in dropped)
    # every angle wrap pattern
    unwrapped = {m.original.split("\n")[0] for m in by_op(found, "remove_angle_wrap")}
    assert unwrapped == {"math.atan2(math.sin(e), math.cos(e))", "math.remainder(e, 2 * math.pi)",
                         "(e + math.pi) % (2 * math.pi)", "while e > math.pi:"}
    # timer period and rate, both ways
    assert {m.replacement for m in by_op(found, "change_timer_period")} == {"0.2", "0.05", "15.0", "60.0"}
    # nothing from the docstring or the f-string
    assert not any(m.line == 1 for m in found)
    assert not any("turn" in m.original for m in found if m.operator != "drop_call")


def test_every_mutant_parses_differs_and_has_a_diff(ws: Path) -> None:
    found = mutants(ws)
    sources = set()
    for m in found:
        text = m.mutated_source()
        ast.parse(text)
        assert text != NODE and text not in sources
        sources.add(text)
        assert m.diff.startswith(f"--- a/{m.file}\n+++ b/{m.file}\n")
        assert f"-{NODE.splitlines()[m.line - 1]}" in m.diff.splitlines()


def test_deterministic_ids_survive_moved_lines(ws: Path, tmp_path: Path) -> None:
    first, second = mutants(ws), mutants(ws)
    assert [m.summary() for m in first] == [m.summary() for m in second]
    assert len({m.id for m in first}) == len(first)
    # a comment added at the top moves every line; the ids stay
    node = ws / "src" / "ctl" / "ctl" / "node.py"
    node.write_text("# a comment\n" + NODE)
    moved = mutants(ws)
    assert [m.id for m in moved] == [m.id for m in first]
    assert [m.line for m in moved] == [m.line + 1 for m in first]


def test_write_copies_the_workspace_with_one_change(ws: Path, tmp_path: Path) -> None:
    m = next(m for m in mutants(ws, ["remove_angle_wrap"]) if "atan2" in m.original)
    dest = m.write(tmp_path / "mutant")
    changed = (dest / m.file).read_text()
    assert changed == m.mutated_source()
    assert "e = e\n" in changed or "e = (e)" in changed or "e = e" in changed
    assert (dest / "src" / "ctl" / "setup.py").read_text() == (ws / "src" / "ctl" / "setup.py").read_text()
    assert not (dest / "expected.yaml").exists()
    assert NODE == (ws / m.file).read_text()            # the original is untouched


def test_operator_subset_sample_and_errors(ws: Path) -> None:
    only = mutants(ws, ["drop_call"])
    assert only and {m.operator for m in only} == {"drop_call"}
    allm = mutants(ws)
    picked = sample(allm, 5, seed=3)
    assert len(picked) == 5 and picked == sample(allm, 5, seed=3)
    assert [m.id for m in picked] == [m.id for m in allm if m in picked]     # original order
    assert sample(allm, None) == allm
    with pytest.raises(ValueError, match="unknown mutation operator"):
        mutants(ws, ["flip"])


def test_reference_solutions_mutate() -> None:
    """Every lab's reference yields mutants, each one parsing, with unique ids."""
    for lab in ("enee467_lab3", "goal_setter", "wall_pen", "first_nodes"):
        found = mutants(REPO / "fixtures" / "submissions" / lab / "reference")
        assert len(found) >= 20, lab
        assert len({m.id for m in found}) == len(found)
