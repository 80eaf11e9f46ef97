"""Reading a CSV that a person saved from a spreadsheet: the encodings Excel writes, its
separators, with a line number for every row.

Spreadsheets are where TAs fill in scores and where rosters come from, so the ways they save a
CSV are handled explicitly instead of producing a confusing error later (a header cell
``\\ufeffsubmission`` that "does not exist", an accent turned into a crash):

* "CSV UTF-8" (UTF-8 with a byte-order mark): accepted, the mark is dropped;
* plain "CSV" on Windows (Windows-1252) and "Unicode Text" (UTF-16): refused with the lines
  concerned and the menu entry to use instead, rather than guessing an encoding and putting
  a wrong character into a student's comment;
* a workbook (.xlsx) saved under a .csv name: refused, with how to export it;
* ``;`` or tab as the separator (Excel in comma-decimal locales): detected from the header.
"""

from __future__ import annotations

import csv
import io
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from grader.scores.errors import ScoresError

BOM = "\ufeff"
SAVE_AS = 'save it from the spreadsheet as "CSV UTF-8 (Comma delimited)"'
DELIMITERS = (",", ";", "\t")


@dataclass(frozen=True)
class Table:
    """A CSV file as cells: the header and each non-blank row with the line it starts on."""

    name: str                                  # the file name, for messages
    header: list[str]                          # cells stripped of surrounding spaces
    header_line: int
    rows: list[tuple[int, list[str]]]          # (line number, cells stripped), blank rows left out
    delimiter: str


def read_table(path: str | os.PathLike[str], *,
               has_key: Callable[[list[str]], bool] = lambda _header: True) -> Table:
    """Decode and split ``path``; ``has_key(header)`` picks the separator whose header holds the
    column the caller needs (``,`` when none does). Raises ScoresError for an unusable file."""
    path = Path(path)
    name = path.name
    text = _decode(path, name)
    first = next((line for line in text.splitlines() if line.strip()), None)
    if first is None:
        raise ScoresError(name, ["the file is empty"])
    delimiter = next((d for d in DELIMITERS if has_key(_cells(first, d))), ",")
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=delimiter)
    header: list[str] | None = None
    header_line = 0
    rows: list[tuple[int, list[str]]] = []
    try:
        while True:
            start = reader.line_num + 1
            try:
                record = next(reader)
            except StopIteration:
                break
            cells = [c.strip() for c in record]
            if not any(cells):
                continue
            if header is None:
                header, header_line = cells, start
            else:
                rows.append((start, cells))
    except csv.Error as exc:
        raise ScoresError(name, [f"line {reader.line_num}: not readable as CSV ({exc})"]) from None
    assert header is not None
    return Table(name=name, header=header, header_line=header_line, rows=rows, delimiter=delimiter)


def _cells(line: str, delimiter: str) -> list[str]:
    try:
        return [c.strip() for c in next(csv.reader([line], delimiter=delimiter))]
    except (csv.Error, StopIteration):
        return []


def _decode(path: Path, name: str) -> str:
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ScoresError(name, [f"cannot read {path} ({exc.strerror or exc})"]) from None
    if data.startswith(b"PK\x03\x04"):
        raise ScoresError(name, ["this is a spreadsheet workbook (.xlsx), not a CSV file: "
                                 + SAVE_AS])
    if data.startswith((b"\xff\xfe", b"\xfe\xff")) or b"\x00" in data[:4096]:
        raise ScoresError(name, ['the file is UTF-16 text (Excel\'s "Unicode Text"): ' + SAVE_AS])
    bad: list[int] = []
    first_byte = 0
    for number, raw in enumerate(data.split(b"\n"), 1):
        try:
            raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            if not bad:
                first_byte = raw[exc.start]
            bad.append(number)
    if bad:
        where = _lines(bad)
        raise ScoresError(name, [
            f"{where}: not UTF-8 text (byte 0x{first_byte:02x} on line {bad[0]}); Excel's plain "
            f'"CSV (Comma delimited)" writes Windows-1252: {SAVE_AS}'])
    text = data.decode("utf-8").lstrip(BOM)        # "CSV UTF-8" starts with a byte-order mark
    if BOM in text:
        lines = [n for n, line in enumerate(text.split("\n"), 1) if BOM in line]
        raise ScoresError(name, [
            f"{_lines(lines)}: a byte-order mark (U+FEFF) inside the file, where it hides in a cell: "
            "were two CSV files pasted together? Delete it (or copy the cells into a new sheet)"])
    return text


def _lines(numbers: list[int], limit: int = 12) -> str:
    shown = ", ".join(str(n) for n in numbers[:limit])
    more = f" and {len(numbers) - limit} more" if len(numbers) > limit else ""
    return f"line{'s' if len(numbers) > 1 else ''} {shown}{more}"
