"""CPU probe for `benchmarks/bench_cpu.py`: every Python process started with this folder on
PYTHONPATH and ``GRADER_CPU_PROBE=DIR`` writes ``DIR/<pid>.json`` when it exits.

It records the process's own CPU (user + system, all threads, from ``getrusage``) at a few marks:
``site`` (interpreter start-up, before any of the program's code), ``rclpy`` (``import rclpy``
done, inclusive of what it imports), ``init`` (``rclpy.init`` returned), ``node`` (first
``Node.__init__`` returned: the DDS participant exists), ``finalize`` (``BagWriter.close``: the
bag's summary and metadata, recorder only) and ``exit`` (``atexit``), plus a timeline sampled every
0.25 s, so idle CPU per second can be read off. A process killed by SIGKILL or an unhandled
SIGTERM writes nothing; the benchmark counts that CPU as "not probed" (the difference to
``RUSAGE_CHILDREN``).

Commands the sandbox runs once in a jail (the colcon build, launch-file loading) are not reaped
into ``RUSAGE_CHILDREN`` (bubblewrap's PID namespace), so their CPU is read from their cgroup
when the sandbox ends them (``cpu.stat``) and kept as ``jailed_cpu_s``. Files are named by pid
and a random suffix: a scenario process in its own PID namespace reuses small pids.

Outside the benchmark (no ``GRADER_CPU_PROBE``) it does nothing.
"""

import os

_DIR = os.environ.get("GRADER_CPU_PROBE")


def jailed_cpu(end, add):
    """Wrap ``grader.sandbox.oneshot._end`` so that ``add(cpu_s)`` gets the CPU its cgroup counted."""

    def wrapped(proc, group, *args, **kwargs):
        if group is not None:
            counters = group.counters

            def counting():
                found = counters()
                if "cpu_s" in found:
                    add(found["cpu_s"])
                return found

            group.counters = counting
        return end(proc, group, *args, **kwargs)

    return wrapped

if _DIR:
    import atexit
    import importlib.abc
    import importlib.machinery
    import json
    import resource
    import sys
    import threading
    import time

    def _cpu() -> float:
        ru = resource.getrusage(resource.RUSAGE_SELF)
        return ru.ru_utime + ru.ru_stime

    _record = {"pid": os.getpid(), "ppid": os.getppid(), "argv": list(sys.orig_argv),
               "marks": {"site": [time.time(), _cpu()]}, "timeline": []}

    def _mark(name: str) -> None:
        _record["marks"].setdefault(name, [time.time(), _cpu()])

    def _wrap(obj, attr: str, mark: str, after: bool = True) -> None:
        original = getattr(obj, attr)

        def wrapper(*args, **kwargs):
            if not after:
                _mark(mark)
            try:
                return original(*args, **kwargs)
            finally:
                if after:
                    _mark(mark)

        wrapper.__wrapped__ = original
        setattr(obj, attr, wrapper)

    def _after_rclpy(module) -> None:
        _mark("rclpy")
        try:
            _wrap(module, "init", "init")
            import rclpy.node as node_mod
            _wrap(node_mod.Node, "__init__", "node")
        except Exception:  # noqa: BLE001 - a probe must never break the program
            pass

    def _after_writer(module) -> None:
        try:
            _wrap(module.BagWriter, "close", "finalize_start", after=False)
            _wrap(module.BagWriter, "close", "finalize")
        except Exception:  # noqa: BLE001
            pass

    def _after_oneshot(module) -> None:
        _record["jailed_cpu_s"] = 0.0
        try:
            module._end = jailed_cpu(module._end, lambda cpu: _record.__setitem__(
                "jailed_cpu_s", _record["jailed_cpu_s"] + cpu))
        except Exception:  # noqa: BLE001
            pass

    _HOOKS = {"rclpy": _after_rclpy, "grader.bag.writer": _after_writer,
              "grader.sandbox.oneshot": _after_oneshot}

    class _Finder(importlib.abc.MetaPathFinder):
        def find_spec(self, fullname, path, target=None):
            hook = _HOOKS.pop(fullname, None)
            if hook is None:
                return None
            spec = importlib.machinery.PathFinder.find_spec(fullname, path)
            if spec is None or spec.loader is None:
                return spec
            exec_module = spec.loader.exec_module

            def exec_and_hook(module):
                exec_module(module)
                hook(module)

            spec.loader.exec_module = exec_and_hook
            return spec

    sys.meta_path.insert(0, _Finder())

    def _sample() -> None:
        while True:
            time.sleep(0.25)
            _record["timeline"].append((round(time.time(), 3), round(_cpu(), 4)))

    threading.Thread(target=_sample, name="cpu-probe", daemon=True).start()

    def _write() -> None:
        _record["marks"]["exit"] = [time.time(), _cpu()]
        try:
            with open(os.path.join(_DIR, f"{os.getpid()}-{os.urandom(4).hex()}.json"), "w") as f:
                json.dump(_record, f)
        except OSError:
            pass

    atexit.register(_write)
