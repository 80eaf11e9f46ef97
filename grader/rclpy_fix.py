"""rclpy's MultiThreadedExecutor as current Jazzy has it, in the grader's own environment.

The only Jazzy rclpy on the wheel index (7.1.6) has ros2/rclpy issue 1452: the spin thread of a
``MultiThreadedExecutor`` yields a task it has already handed to the thread pool, before a worker
has started it, and hands it over again; while such a task waits, the executor never waits for
new work. A node that receives messages (``/clock``, poses) then takes a whole core while idle
(``benchmarks/bench_executor.py``: 1.01-1.03 CPU s per s against 0.03-0.09 for the
SingleThreadedExecutor), so a correct Lab 3 action server cannot keep pace with simulated time
and starves the simulator on a small machine. Later Jazzy releases carry the upstream fix
(pull request 1547), so students' own machines do not spin; grading on the wheel must not
either.

Our change (``apply``), three edits of the installed ``rclpy/executors.py``, each marked with
``MARK``. The MultiThreadedExecutor flags a task as queued when it submits it, and the worker
clears the flag when it starts the task; ``_wait_for_ready_callbacks`` does not yield a task
that is still queued (a coroutine task that ran a step and waits again is yielded as before).
Then the spin thread waits for the worker to start the task, at most
``_GRADER_START_WAIT_S`` (10 ms), before it waits for work again: until the task has taken
its message the subscription's reader still has data, the wait set wakes at once with nothing
to hand out (counted: 2,300-8,000 such wake-ups in 3 s), and that loop holds the GIL the
worker needs to start. The bound keeps a saturated pool from blocking the spin thread.
Measured with a 100 Hz subscription on a MultiThreadedExecutor, six runs each: 0.11-0.14 CPU
s per s and every message taken (350 of 350) with the change, against 0.23-1.16 and as few as
66 of 350 without it (SingleThreadedExecutor: 0.09).

Detected by behaviour (``busy_loop_present``), not by version: with every pool thread held,
two ``spin_once`` calls on a node with a ready timer submit the same task twice where the bug
is. A system ROS install is never edited (``grader setup``/``make bootstrap`` apply it to the
wheels in the grader's venv only); ``grader doctor`` says which of the three states it found.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

MARK = "# grader: ros2/rclpy#1452 (grader/rclpy_fix.py)"

#: (what the installed file says, what it says after the fix), each found exactly once
_EDITS = (
    ("                    if (not task.executing() and not task.done() and\n",
     f"                    {MARK}: a task still queued in a thread pool is not yielded again\n"
     "                    if (not task.executing() and not task.done() and\n"
     "                            not getattr(task, '_grader_queued', False) and\n"),
    ("            self._executor.submit(handler)\n",
     f"            {MARK}: queued until a worker starts it\n"
     "            handler._grader_queued = True\n"
     "            handler._grader_started = _grader_threading.Event()\n"
     "            self._executor.submit(_grader_run_queued, handler)\n"
     "            handler._grader_started.wait(_GRADER_START_WAIT_S)\n"),
    ("class MultiThreadedExecutor(Executor):\n",
     f"import threading as _grader_threading  {MARK}\n"
     "_GRADER_START_WAIT_S = 0.01\n\n\n"
     "def _grader_run_queued(task):\n"
     "    task._grader_queued = False\n"
     "    task._grader_started.set()\n"
     "    task()\n\n\n"
     "class MultiThreadedExecutor(Executor):\n"),
)

#: run by the target Python: holds the pool, spins twice, prints how many times the ready
#: timer's task was submitted (1: fixed or never broken, 2: the busy loop)
_PROBE = """
import json, threading, rclpy
from rclpy.executors import MultiThreadedExecutor
rclpy.init()
node = rclpy.create_node('grader_executor_probe')
node.create_timer(0.001, lambda: None)
executor = MultiThreadedExecutor(num_threads=2)
executor.add_node(node)
gate = threading.Event()
for _ in range(2):
    executor._executor.submit(gate.wait)
for _ in range(2):
    executor.spin_once(timeout_sec=0.3)
submitted = list(executor._futures)
gate.set()
print(json.dumps({'submitted': len(submitted), 'distinct': len({id(t) for t in submitted})}))
executor.shutdown()
rclpy.shutdown()
"""


class RclpyFixError(Exception):
    """The installed rclpy cannot be probed or changed (the message says why)."""


def executors_file(python: str = sys.executable) -> Path:
    """``rclpy/executors.py`` as ``python`` imports it."""
    done = subprocess.run([python, "-c", "import rclpy.executors as e; print(e.__file__)"],
                          capture_output=True, text=True, timeout=60)
    if done.returncode != 0:
        raise RclpyFixError("rclpy is not importable: " + (done.stderr.strip().splitlines() or ["?"])[-1])
    return Path(done.stdout.strip())


def busy_loop_present(python: str = sys.executable, env: dict[str, str] | None = None) -> bool:
    """Whether ``python``'s MultiThreadedExecutor hands a queued task to its pool again."""
    done = subprocess.run([python, "-c", _PROBE], capture_output=True, text=True, timeout=60, env=env)
    lines = [line for line in done.stdout.splitlines() if line.startswith("{")]
    if done.returncode != 0 or not lines:
        raise RclpyFixError("the executor probe failed: " + (done.stderr.strip().splitlines() or ["no output"])[-1])
    counts = json.loads(lines[-1])
    return bool(counts["submitted"] > counts["distinct"])


def is_patched(path: Path) -> bool:
    return MARK in path.read_text()


def apply(path: Path) -> bool:
    """Make the edits in ``path`` (True), or nothing when they are there already (False);
    RclpyFixError when the file is not the one the edits were written for."""
    text = path.read_text()
    if MARK in text:
        return False
    for old, new in _EDITS:
        if text.count(old) != 1:
            raise RclpyFixError(f"{path} is not the rclpy 7.1.x executors.py this fix was written for "
                                f"({old.strip()!r} found {text.count(old)} times); left as it is")
        text = text.replace(old, new)
    path.write_text(text)
    for cached in path.parent.glob("__pycache__/executors.*.pyc"):
        cached.unlink(missing_ok=True)
    return True


def ensure_fixed(python: str, env: dict[str, str] | None = None) -> str:
    """Probe ``python``'s rclpy and fix it where the busy loop is; returns what was done."""
    path = executors_file(python)
    if not busy_loop_present(python, env):
        return "patched" if is_patched(path) else "not needed"
    apply(path)
    if busy_loop_present(python, env):
        raise RclpyFixError(f"{path}: the MultiThreadedExecutor still submits a queued task again after the fix")
    return "applied"


def state(python: str = sys.executable) -> tuple[str, str]:
    """``(state, sentence)`` for ``grader doctor``: ``fixed`` (our change), ``ok`` (an rclpy that
    never had the bug, or carries the upstream fix), ``busy`` (the bug is there), ``unknown``."""
    try:
        path = executors_file(python)
        busy = busy_loop_present(python)
    except (RclpyFixError, OSError, subprocess.SubprocessError) as exc:
        return "unknown", f"could not probe the MultiThreadedExecutor: {exc}"
    if busy:
        return "busy", ("its MultiThreadedExecutor busy-loops (ros2/rclpy issue 1452): `grader setup` "
                        "(`make bootstrap` in a checkout) fixes it in the grader's own environment; a system "
                        "ROS install is left as it is")
    if is_patched(path):
        return "fixed", "MultiThreadedExecutor fixed in this environment (the grader's change for ros2/rclpy#1452)"
    return "ok", "MultiThreadedExecutor waits when idle (no ros2/rclpy#1452 busy loop)"
