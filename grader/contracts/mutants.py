"""The names of the mutation audit's operators (``grader rubric audit``): a rubric's
``equivalent_mutants`` name mutants by them, so the rubric loader checks those ids against the
same tuple the audit applies (``grader.audit.mutate``), without reaching up to the audit."""

from __future__ import annotations

OPERATORS: tuple[str, ...] = ("flip_sign", "scale_constant", "swap_args", "rename_topic", "drop_call",
                              "remove_angle_wrap", "change_timer_period")
