"""Rubric auditing: mutants of a reference solution (``mutate``) graded against a rubric (``audit``)."""
