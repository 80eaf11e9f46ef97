"""Which grader made each recording a grade rests on, and which of them another grader made.

A grade is computed from its scenarios' recordings, which may be older than the grader computing
it: copied from the recording cache (made for another submission, perhaps days ago), or kept by
``grader regrade`` from the grading run after the grader was upgraded. Each recording's
``scenario.json`` notes its key and maker (``recording``: ``grader.grading.reuse.made_by``: grader
version, digest of the grader code that makes recordings, digest of the ROS 2 and Python it ran
on); a reused one also notes where it came from (``reused``). result.json keeps them all under
``recordings``, and ``recordings_by_other_grader`` lists the scenarios whose maker differs from the
grader writing the result, with why: ``grader regrade`` prints them and the instructor's report
shows them, so an instructor knows which grades rest on recordings another grader version made.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

from grader.contracts.output_folder import SCENARIO_JSON, SCENARIOS_DIR
from grader.contracts.run_records import Recording, ReusedFrom
from grader.contracts.scenario_record import RecordingNote, ScenarioRecord
from grader.grading.reuse import made_by


def scenario_recordings(sub_out: Path) -> dict[str, Recording]:
    """``{scenario: {"key", "made_by", "reused_from"?}}`` from each ``scenario.json`` of a
    graded submission (``made_by`` None: recorded by a grader that did not note it)."""
    out: dict[str, Recording] = {}
    for record_file in sorted(Path(sub_out).glob(f"{SCENARIOS_DIR}/*/{SCENARIO_JSON}")):
        try:
            record = ScenarioRecord.read(record_file)
        except (OSError, ValueError):
            continue
        noted, reused = record.recording or RecordingNote(), record.reused
        entry = Recording(key=noted.key or (reused.key if reused else None),
                          made_by=noted.made_by or (reused.made_by if reused else None))
        if reused:
            entry.reused_from = ReusedFrom.model_validate({"from": reused.from_, "recorded": reused.recorded})
        out[record_file.parent.name] = entry
    return out


def by_other_grader(recordings: Mapping[str, Recording],
                    current: dict[str, str] | None = None) -> dict[str, str]:
    """``{scenario: why}`` for every recording whose maker is not ``current`` (this grader)."""
    if current is None:
        current = made_by()
    out: dict[str, str] = {}
    for sc, entry in sorted(recordings.items()):
        maker = entry.made_by
        if not maker:
            out[sc] = "recorded by an older grader that did not note its version"
        elif maker.get("code") != current["code"]:
            out[sc] = (f"recorded by grader {maker.get('grader', '?')} with other recording code "
                       f"({maker.get('code')}; this grader: {current['grader']}, {current['code']})")
        elif maker.get("environment") != current["environment"]:
            out[sc] = (f"recorded with another ROS 2 or Python installation ({maker.get('ros')}, rclpy "
                       f"{maker.get('rclpy')}, {maker.get('rmw')}; here: {current['ros']}, rclpy "
                       f"{current['rclpy']}, {current['rmw']}, or another package version)")
    return out


def notes(other: dict[str, str], recordings: Mapping[str, Recording]) -> list[str]:
    """One line per recording another grader made, for the instructor's report and regrade."""
    lines = []
    for sc, why in other.items():
        entry = recordings.get(sc)
        origin = entry.reused_from if entry is not None else None
        source = (f" (reused from {origin.from_}'s recording of {origin.recorded})"
                  if origin else "")
        lines.append(f"scenario {sc}: its grade rests on a recording {why}{source}; "
                     "`grader grade --no-reuse` records it again with this grader")
    return lines
