"""Report rendering cost: CPU time to render each submission's report.html (figures included),
and the class view, on a batch regraded offline from the committed real Lab 3 bags.

The target is under 1 s of CPU per report on a 2-core machine, and the replay player (issue 39)
adds at most 1 s of CPU per submission: its data taken from the frames the analysis already has in
memory (``replay.js`` of every scenario) plus the player's part of the page, printed side by side
with the page without it. matplotlib's import and its
first figure (font cache, ~0.5-1 s) are paid once per process and printed separately; each
report is rendered ``N`` times (default 3) and the median is reported.

    .venv/bin/python benchmarks/bench_report.py [N]
"""

from __future__ import annotations

import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from grader.grading.analysis import scenario_frames  # noqa: E402
from grader.grading.outputs import effective_params  # noqa: E402
from grader.report.replay import replay_data, replay_script, replays  # noqa: E402
from grader.report import load_results, render_html, render_index  # noqa: E402
from grader.report.index import read_docs  # noqa: E402
from grader.rubric.load import load_rubric  # noqa: E402
from grader.testing.batch import LAB3_BAGS, recorded_batch  # noqa: E402

TARGET_S = 1.0


def cpu() -> float:
    return time.process_time()


def main() -> int:
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    rubric = load_rubric(REPO / "rubrics" / "enee467_lab3.yaml")
    params = effective_params(rubric)
    with tempfile.TemporaryDirectory(prefix="bench-report-") as tmp:
        out = Path(tmp)
        t0 = cpu()
        import grader.report.figures._mpl  # noqa: F401  (matplotlib import: once per process)
        print(f"matplotlib import: {cpu() - t0:.2f} s CPU (once per process)")
        t0 = cpu()
        recorded_batch(LAB3_BAGS, out, rubric)      # analysis + the first render of every report
        print(f"regrade of {len(list(out.glob('*/result.json')))} submissions from their bags, reports "
              f"included: {cpu() - t0:.1f} s CPU (includes the first figure's font set-up)\n")
        results = load_results(out, rubric)
        rows = []
        for sid, result in sorted(results.items()):
            times, size = [], 0
            for _ in range(runs):
                t0 = cpu()
                size = len(render_html(result, sid, params=params))
                times.append(cpu() - t0)
            rows.append((sid, statistics.median(times), max(times), size))
        width = max(len(r[0]) for r in rows)
        print(f"{'submission':<{width}}  median CPU  max CPU   size")
        for sid, med, worst, size in rows:
            flag = "" if med < TARGET_S else "  over target"
            print(f"{sid:<{width}}  {med:8.3f} s  {worst:6.3f} s  {size / 1024:5.0f} kB{flag}")
        item_scenarios = {item.id: list(item.scenario) for item in rubric.items}
        print(f"\n{'submission':<{width}}  replay data  page without  page with player  added     data size")
        added_all = []
        for sid, result in sorted(results.items()):
            shown = replays(out / sid)
            frames = {sc: scenario_frames(out / sid / "scenarios" / sc) for sc in shown}    # in memory at analysis
            t0 = cpu()
            size = sum(len(replay_script(replay_data(f, sc))) for sc, f in frames.items())
            data_s = cpu() - t0
            t0 = cpu()
            render_html(result, sid, params=params)
            without = cpu() - t0
            t0 = cpu()
            render_html(result, sid, params=params, replays=shown, item_scenarios=item_scenarios)
            with_player = cpu() - t0
            added = data_s + max(0.0, with_player - without)
            added_all.append(added)
            print(f"{sid:<{width}}  {data_s:9.3f} s  {without:10.3f} s  {with_player:14.3f} s  {added:6.3f} s  "
                  f"{size / 1024:6.0f} kB ({len(shown)} scenarios)")
        print(f"replay player: at most {max(added_all):.3f} s CPU added per submission (target <= {TARGET_S:g} s)")
        t0 = cpu()
        render_index(results, docs=read_docs(out, list(results)))
        print(f"\nclass view (index.html, {len(results)} submissions): {cpu() - t0:.3f} s CPU")
        meds = [r[1] for r in rows]
        print(f"per report: median {statistics.median(meds):.3f} s, slowest {max(meds):.3f} s CPU "
              f"(target < {TARGET_S:g} s)")
        return 0 if max(meds) < TARGET_S and max(added_all) <= TARGET_S else 1


if __name__ == "__main__":
    sys.exit(main())
