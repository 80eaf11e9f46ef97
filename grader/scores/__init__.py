"""Manual scores and gradebooks (see grader.scores.store for the per-submission record)."""
