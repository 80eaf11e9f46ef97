"""Grading: the pipeline that ties build, scenarios, analyzers, scoring and reports together."""
