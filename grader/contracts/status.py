"""The statuses of a finding and of a scored item: the one vocabulary from analyzer to report."""

from __future__ import annotations

#: pass (full credit), partial (some), fail (none), error (the analysis was impossible)
STATUSES = ("pass", "partial", "fail", "error")
