"""Reports of a scored Result: result.json + grades.csv (``result``), the HTML report of a
submission (``html``, figures in ``figures``, evidence in words in ``readable``), the class view
(``index``), and batch files rebuilt from the archived result.json files (``batch``)."""

from grader.report.batch import load_results, write_batch
from grader.report.html import render_html, write_html
from grader.report.index import render_index, write_index
from grader.report.result import (previous_summary, read_result, result_from_dict, result_to_dict,
                                  write_grades_csv, write_result)

__all__ = ["load_results", "previous_summary", "read_result", "render_html", "render_index",
           "result_from_dict", "result_to_dict", "write_batch", "write_grades_csv", "write_html",
           "write_index", "write_result"]
