"""Exchanges with the systems instructors already grade in (Gradescope, LMS gradebooks)."""
