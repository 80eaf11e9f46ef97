"""`python -m benchmarks` (what `make bench` runs): every benchmark, one after the other."""

import runpy
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent

for script in ("bench_sim.py", "bench_bag.py", "bench_grade.py", "bench_report.py", "bench_flake.py",
               "bench_cpu.py", "bench_post.py", "bench_scale.py", "bench_timescale.py", "bench_class.py", "bench_similarity.py"):
    print(f"\n===== {script} =====", flush=True)
    sys.argv = [str(HERE / script)]
    try:
        runpy.run_path(str(HERE / script), run_name="__main__")
    except SystemExit as exc:
        if exc.code not in (0, None):
            print(f"{script} exited {exc.code}")
