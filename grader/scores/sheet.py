"""The TA's score sheet: a CSV with a ``submission`` column and manual-item columns, checked
against the graded results before anything is written.

Columns (the order does not matter; a filled-in copy of ``grades.csv`` is a valid sheet):

* ``submission``: the submission id (the folder name under OUT);
* ``<item>`` for a manual item (``report``, ``q1``..): points, e.g. ``7`` or ``7.5`` (``7,5``
  too when the separator is ``;``). An empty cell keeps the score merged earlier (or leaves
  the item pending); ``pending`` clears it (and its comment);
* ``<item> comment``: text shown with the item in the report (an empty cell keeps the earlier
  comment). A comment needs a score for its item;
* automatic items (``ex1.boxmuller``..., as in grades.csv) may stay as exported or be empty:
  a different value is an error, since automatic points come from the recordings;
* ``auto_total``, ``manual_total``, ``total``, ``max``, ``integrity_flags``: ignored (recomputed),
  as are grades.csv's ``submitted_at``, ``late_by``, ``time_source``, ``intake``, ``lms_id``,
  ``student``;
* ``late_penalty``: points the late policy deducts, as grades.csv shows them. A different number
  replaces the policy's penalty for that submission (``0`` waives it), an empty cell or the
  value as exported keeps what is in force, ``policy`` goes back to the policy's own penalty.

Every problem (unknown submission or column, duplicate row, a score that is not a number,
negative or over the maximum, an edited automatic score, a shifted row) is reported at once
with its line, and nothing is merged while any remains.
"""

from __future__ import annotations

import difflib
import math
import os
import re
from dataclasses import dataclass, field
from typing import Mapping

from grader.rubric.result import ItemResult, Result
from grader.scores.csvfile import Table, read_table
from grader.scores.errors import ScoresError

KEY = "submission"
CLEAR = "pending"
COMMENT_SUFFIX = " comment"
DERIVED = ("auto_total", "manual_total", "total", "max", "integrity_flags",
           "submitted_at", "late_by", "time_source", "intake", "lms_id", "student")
LATE = "late_penalty"
LATE_CLEAR = "policy"
_DECIMAL_COMMA = re.compile(r"^[+-]?\d+,\d+$")


@dataclass(frozen=True)
class Update:
    """One cell's effect on one manual item: set points, clear, or only a new comment."""

    action: str                    # "set" | "clear" | "comment"
    points: float | None = None
    comment: str | None = None     # None: keep the earlier comment


@dataclass(frozen=True)
class SheetRow:
    line: int
    submission: str
    updates: dict[str, Update] = field(default_factory=dict)
    late: Update | None = None     # the late_penalty cell: "set" (override) or "clear" (the policy's)


@dataclass(frozen=True)
class Column:
    role: str                      # "key" | "score" | "comment" | "auto" | "late" | "ignored"
    item: str = ""


def col_name(index: int) -> str:
    """Spreadsheet column letters: 0 -> A, 26 -> AA."""
    name = ""
    index += 1
    while index:
        index, rem = divmod(index - 1, 26)
        name = chr(65 + rem) + name
    return name


def read_sheet(path: str | os.PathLike[str], results: Mapping[str, Result]) -> list[SheetRow]:
    """Parse and check ``path`` against ``results`` (submission id -> Result, all one lab).
    Returns the rows to merge; raises ScoresError listing every problem."""
    table = read_table(path, has_key=lambda header: KEY in (h.casefold() for h in header))
    items = _items(results)
    problems: list[str] = []
    columns = _columns(table, items, problems)
    if columns is None:
        raise ScoresError(table.name, problems)
    rows: list[SheetRow] = []
    seen: dict[str, int] = {}
    key = next(j for j, c in enumerate(columns) if c.role == "key")
    for line, cells in table.rows:
        row = _row(table, columns, key, line, cells, results, seen, problems)
        if row is not None:
            rows.append(row)
    if problems:
        raise ScoresError(table.name, problems)
    return rows


def _items(results: Mapping[str, Result]) -> dict[str, ItemResult]:
    items: dict[str, ItemResult] = {}
    for result in results.values():
        for item in result.items:
            items.setdefault(item.id, item)
    return items


def _manual_ids(items: Mapping[str, ItemResult]) -> list[str]:
    return [i for i, item in items.items() if item.kind == "manual"]


def _suggest(name: str, choices: list[str]) -> str:
    close = difflib.get_close_matches(name, choices, n=1, cutoff=0.6) or \
        [c for c in choices if c.casefold() == name.casefold()]
    return f' (did you mean "{close[0]}"?)' if close else ""


def _columns(table: Table, items: Mapping[str, ItemResult], problems: list[str]) -> list[Column] | None:
    """The role of each header cell; None when the sheet has no submission column."""
    manual = _manual_ids(items)
    where = f"line {table.header_line}"
    keys = [j for j, h in enumerate(table.header) if h.casefold() == KEY]
    if not keys:
        shown = ", ".join(f'"{h}"' for h in table.header if h) or "nothing"
        problems.append(f'{where}: no "{KEY}" column (the header has {shown})')
        return None
    columns: list[Column] = []
    first_seen: dict[str, int] = {}
    for j, name in enumerate(table.header):
        at = f"{where}, column {col_name(j)}"
        if (name and name in first_seen) or (name.casefold() == KEY and j != keys[0]):
            problems.append(f'{at}: column "{name}" appears twice (first in column '
                            f'{col_name(first_seen.get(name, keys[0]))})')
            columns.append(Column("ignored"))
            continue
        first_seen[name] = j
        if j == keys[0]:
            columns.append(Column("key"))
        elif not name or name in DERIVED:
            columns.append(Column("ignored"))        # checked per row when unnamed
        elif name == LATE:
            columns.append(Column("late"))
        elif name in items:
            columns.append(Column("score" if items[name].kind == "manual" else "auto", name))
        elif name.casefold().endswith(COMMENT_SUFFIX):
            base = name[: -len(COMMENT_SUFFIX)].strip()
            if base in items and items[base].kind == "manual":
                columns.append(Column("comment", base))
                continue
            if base in items:
                problems.append(f'{at}: "{name}": comments go with manual items only '
                                f'({", ".join(manual)})')
            else:
                problems.append(f'{at}: "{name}" is a comment for unknown item "{base}"'
                                f'{_suggest(base, manual)}; the manual items are {", ".join(manual)}')
            columns.append(Column("ignored"))
        else:
            problems.append(f'{at}: unknown item "{name}"{_suggest(name, manual)}; the manual items '
                            f'are {", ".join(manual)}')
            columns.append(Column("ignored"))
    return columns


def _number(text: str, delimiter: str) -> float | None:
    if delimiter != "," and _DECIMAL_COMMA.match(text):
        text = text.replace(",", ".")
    try:
        value = float(text)
    except ValueError:
        return None
    return value if math.isfinite(value) else None


def _row(table: Table, columns: list[Column], key: int, line: int, cells: list[str],
         results: Mapping[str, Result], seen: dict[str, int], problems: list[str]) -> SheetRow | None:
    if len(cells) > len(columns) and any(cells[len(columns):]):
        problems.append(f"line {line}: {len(cells)} cells but the header has {len(columns)} columns "
                        "(a comma in a comment that is not inside quotes?)")
        return None
    cells = cells + [""] * (len(columns) - len(cells))
    sid = cells[key]
    if not sid:
        problems.append(f"line {line}: no submission id in column {col_name(key)}")
        return None
    if sid in seen:
        problems.append(f'line {line}: submission "{sid}" is also on line {seen[sid]}: give each '
                        "submission one row")
        return None
    seen[sid] = line
    result = results.get(sid)
    if result is None:
        problems.append(f'line {line}: unknown submission "{sid}" (no graded result for it)'
                        f"{_suggest(sid, sorted(results))}")
        return None
    by_id = {i.id: i for i in result.items}
    updates: dict[str, Update] = {}
    comments: dict[str, tuple[int, str]] = {}
    late: Update | None = None
    for j, (column, value) in enumerate(zip(columns, cells)):
        at = f"line {line}, {column.item or col_name(j)}"
        if column.role == "ignored" and value and not table.header[j]:
            problems.append(f"line {line}, column {col_name(j)}: a value in a column without a header")
        if not value or column.role in ("key", "ignored"):
            continue
        if column.role == "late":
            late = _late_cell(f"line {line}, {LATE}", value, result, table.delimiter, problems)
            continue
        item = by_id.get(column.item)
        if item is None:
            problems.append(f"{at}: submission {sid} has no item {column.item}")
        elif column.role == "comment":
            comments[column.item] = (j, value)
        elif column.role == "auto":
            _check_auto(at, item, value, table.delimiter, problems)
        elif value.casefold() == CLEAR:
            updates[item.id] = Update("clear")
        else:
            points = _number(value, table.delimiter)
            if points is None:
                problems.append(f'{at}: "{value}" is not a number (give points like 7 or 7.5, '
                                f'or "{CLEAR}" to clear the score)')
            elif points < 0:
                problems.append(f"{at}: {value} is negative (points go from 0 to {item.max_points:g})")
            elif points > item.max_points:
                problems.append(f"{at}: {value} is over the maximum of {item.max_points:g} points")
            else:
                updates[item.id] = Update("set", points=points)
    for item_id, (_j, text) in comments.items():
        update = updates.get(item_id)
        if update is not None and update.action == "set":
            updates[item_id] = Update("set", points=update.points, comment=text)
        elif update is None and by_id[item_id].points is not None:
            updates[item_id] = Update("comment", comment=text)
        else:
            problems.append(f'line {line}, {item_id} comment: a comment for {item_id}, which has no '
                            f"score (give its points in column {_column_of(columns, item_id)})")
    return SheetRow(line, sid, updates, late)


def _late_cell(at: str, value: str, result: Result, delimiter: str, problems: list[str]) -> Update | None:
    """The late_penalty cell: None when it keeps what is in force (empty, or as exported)."""
    if value.casefold() == LATE_CLEAR:
        return Update("clear") if result.late is not None and result.late.override_points is not None else None
    points = _number(value, delimiter)
    if points is None:
        problems.append(f'{at}: "{value}" is not a number (the points to deduct, 0 to waive the penalty, '
                        f'or "{LATE_CLEAR}" for the late policy\'s own)')
        return None
    if points < 0:
        problems.append(f"{at}: {value} is negative (the points deducted for lateness: 0 or more)")
        return None
    if points > result.max_score:
        problems.append(f"{at}: {value} is over the lab's {result.max_score:g} points")
        return None
    current = result.late_penalty if result.late is not None else 0.0
    if abs(points - current) < 1e-9:
        return None                   # as exported: the penalty in force stays (and stays the policy's)
    return Update("set", points=points)


def _column_of(columns: list[Column], item_id: str) -> str:
    return next((col_name(j) for j, c in enumerate(columns) if c.role == "score" and c.item == item_id),
                f'"{item_id}"')


def _check_auto(at: str, item: ItemResult, value: str, delimiter: str, problems: list[str]) -> None:
    """A copy of grades.csv carries the automatic cells: as exported they are fine."""
    if item.kind == "auto":
        number = _number(value, delimiter)
        recorded = f"{item.points:g}" if item.points is not None else ""
        if number is not None and item.points is not None and abs(number - item.points) < 1e-9:
            return
    else:
        recorded = item.status
        if value.casefold() == item.status.casefold():
            return
    problems.append(f"{at}: {item.id} is graded automatically ({item.kind}; recorded: {recorded}), "
                    f'"{value}" cannot be set by hand: leave the cell empty or as exported (to change '
                    "an automatic grade, fix the rubric and run grader regrade)")
