"""Exercise 1, subscriber side: does the student's node print z = sqrt(-2 ln u1) cos(2 pi u2)?

Inputs are the (u1, u2) pairs on /random_numbers recorded in the bag (replayed by the grader, or
published by the student's own publisher). Outputs are the numbers the student's subscriber
printed: /rosout rows of its logger (``self.get_logger().info``), or, when it did not log,
``print()`` lines captured on /grader/stdout.

How outputs are paired with inputs, and why:
* Student lines are free text ("z = 0.42", "Normal: 0.42 from (0.1, 0.7)"), so every number in a
  line is a candidate; the (source, position-in-line, formula) that explains most lines wins.
* A line can only answer an input sent shortly before it (``max_lag_s``) or marginally after it
  (``lead_s``, clock skew). Among all (line, input) matches the largest set increasing in both is
  kept (longest increasing subsequence), so a few dropped or extra lines (a startup banner, a node
  started late) do not shift every later pair; the lag band is then narrowed to the lags the real
  pairs show.
* "Matches" means within what the student printed: half a unit in the last printed digit (3
  decimals -> 0.0005), plus the effect of one float32 ulp on the inputs, plus 1e-6 relative.
* Coarse printing against a fast replay matches by coincidence: the chance level is measured on
  windows shifted far away in time and the matched share is corrected for it.
When the correct formula does not explain the lines, the classic mistakes are tried (log10,
missing sqrt, sin for cos, swapped u1/u2, degrees, ...) and the best one is named in feedback.
"""

from __future__ import annotations

import math
from typing import Annotated

import numpy as np
from pydantic import Field
from scipy import stats

from grader.analyze import Finding, graded, register
from grader.analyze._common import ROSOUT, Frames, meta_row, stdout_lines, thin, topic
from grader.analyze.evidence import SHARE
from grader.analyze.boxmuller_formulas import FORMULAS
from grader.analyze.boxmuller_evidence import examples, no_output_finding, pair_series, unanswered
from grader.analyze.boxmuller_pairing import BoxMullerInputParams, _inputs, _sources, select

#: labels and units of the evidence (see grader.analyze.evidence)
EVIDENCE = {
    "exclude_loggers": ("loggers whose lines are not the student's values", ''),
    "max_lag_s": ('latest a value may be logged after its input', 's'),
    "lead_s": ('earliest before its input', 's'),
    "max_chance_full": ('chance a match in the full lag window is a coincidence, at most', ''),
    "bug_min_ratio": ('share of values a known bug must explain', SHARE),
    "max_chance": ('chance a match is a coincidence, at most', ''),
    "tail_grace_s": ('time after the last input still read', 's'),
    "bug_credit": ('credit when a known bug explains the values', SHARE),
    "max_shapiro": ('values used in the Shapiro-Wilk test, at most', ''),
    "n_inputs": ("(u1, u2) pairs published", ""),
    "source": ("output read", ""),
    "source.kind": ("where the values were found (rosout = ROS logger, stdout = print)", ""),
    "source.name": ("logger or process", ""),
    "number_position": None,
    "n_numeric_lines": ("printed lines with a number", ""),
    "matched": ("values matching the correct z", ""),
    "expected": ("values expected", ""),
    "raw_ratio": ("share matched", SHARE),
    "chance": ("share a random input would match", SHARE),
    "ratio": ("share matched, corrected for chance", SHARE),
    "lag_window_s": None,
    "matches_per_formula": None,
    "best_formula": None,
    "best_formula_text": ("formula that explains the values best", ""),
    "best_ratio": ("share explained by that formula", SHARE),
    "bug": None,
    "examples": ("examples", ""),
    "u1": ("u1", ""), "u2": ("u2", ""), "printed": ("printed", ""),
    "unanswered": ("pairs no printed line answers", ""), "sent_s": ("sent, into the replay", "s"),
    "expected_z": ("correct z", ""), "line": ("printed line", ""),
    "pairs": None,
    "pass_ratio": ("share needed", SHARE),
    "min_ratio": ("share below which matches earn nothing (chance and noise)", SHARE),
    "min_outputs": ("printed values needed", ""),
    # boxmuller_logging
    "rosout_loggers": ("ROS loggers seen", ""),
    "stdout_processes": ("processes that printed", ""),
    "logger": ("logger", ""),
    "matched_correct": ("logged values matching the correct z", ""),
    # normality
    "mean": ("mean", ""), "std": ("standard deviation", ""),
    "shapiro_W": ("Shapiro-Wilk W", ""), "shapiro_p": ("Shapiro-Wilk p-value", ""),
    "anderson_stat": ("Anderson-Darling statistic", ""), "anderson_p": ("Anderson-Darling p-value", ""),
    "mean_bound": ("largest |mean| accepted", ""), "std_bound": ("largest |std − 1| accepted", ""),
    "alpha": ("significance level", ""), "z_bound": ("standard errors allowed", ""),
    "min_samples": ("values needed", ""),
    "histogram": None, "qq": None,
}

_Share = Annotated[float, Field(ge=0, le=1)]


class BoxMullerParams(BoxMullerInputParams):
    min_outputs: int = Field(10, ge=0, description="fewer numeric lines -> not enough evidence")
    pass_ratio: float = Field(0.9, ge=0, le=1, description="matched / expected at or above this -> full credit")
    # A wrong formula matched 1 of 524 pairs by chance, and the chance estimate of that run's
    # timing made it 0 points in one run and 0.01 in another (issue 22)
    min_ratio: float = Field(0.02, ge=0, le=1,
                             description="below this (after the chance correction): no credit")
    bug_min_ratio: float = Field(0.8, ge=0, le=1,
                                 description="a named mistake must explain at least this share to be reported")
    max_chance: float = Field(0.5, ge=0, le=1, description="not passing, and a random input would match this "
                                                           "share: \"print more decimals\"")
    tail_grace_s: float = Field(2.0, ge=0, description="s: inputs in the last seconds of the bag may go unanswered")
    bug_credit: dict[str, _Share] = Field({"sin_for_cos": 0.5},
                                          description="fraction granted when the values match a named variant")


@register("boxmuller", params=BoxMullerParams, evidence={**EVIDENCE, "value": ("printed values", "")},
          expect="z = sqrt(−2 ln u1)·cos(2π u2) printed for at least {pass_ratio:.0%} of the published pairs")
def boxmuller(frames: Frames, p: BoxMullerParams) -> Finding:
    """Share of published pairs for which the student printed the correct Box-Muller z."""
    sel = select(frames, p, tail_grace_s=p.tail_grace_s)
    early = no_output_finding(frames, p, sel)
    if early:
        return early
    best, cp = sel.best, sel.correct
    assert best is not None and cp is not None and sel.inputs is not None
    ev: dict = {
        "n_inputs": len(sel.inputs),
        "source": {"kind": best.source.kind, "name": best.source.name},
        "number_position": best.pos,
        "n_numeric_lines": best.source.n_numeric,
        "matched": cp.matched, "expected": cp.expected, "raw_ratio": cp.raw_ratio,
        "chance": cp.chance, "ratio": cp.ratio, "lag_window_s": list(cp.lag_window),
        "matches_per_formula": {f: c for f, c in sel.counts.items() if c},   # on <= 300 sampled lines
        "best_formula": best.formula,
        "best_formula_text": FORMULAS[best.formula][0],
        "best_ratio": best.ratio,
    }
    shown = best if best.formula != "correct" and best.ratio >= p.bug_min_ratio else cp
    ev["pairs"] = pair_series(sel, shown)
    if best.source.n_numeric < p.min_outputs:
        ev["examples"] = examples(sel, best)
        return Finding(f"{best.source.n_numeric} lines", 0.0, "fail",
                       f"Only {best.source.n_numeric} printed value(s) for {len(sel.inputs)} published pairs: "
                       "log one z per received message.", ev)
    value = f"{cp.matched}/{cp.expected} matched"
    if cp.ratio >= p.pass_ratio:
        ev["examples"] = examples(sel, cp, 3)
        return Finding(value, 1.0, "pass",
                       f"{cp.matched} of {cp.expected} printed values match z = sqrt(-2 ln u1)·cos(2πu2).", ev)
    if best.formula != "correct" and best.ratio >= p.bug_min_ratio:
        frac = float((p.bug_credit or {}).get(best.formula, 0.0))
        ev["examples"] = examples(sel, best, 3)
        ev["bug"] = best.formula
        value = f"values follow {FORMULAS[best.formula][0]}"
        return Finding(value, frac, graded(frac), FORMULAS[best.formula][2], ev)
    if cp.chance > p.max_chance:
        ev["examples"] = examples(sel, cp, 3)
        return Finding(value, 0.0, "fail",
                       f"Your values are printed too coarsely to be checked (a random number would match "
                       f"{cp.chance:.0%} of them): print z with at least 4 decimals, e.g. f\"{{z:.6f}}\".", ev)
    wrong = examples(sel, cp, 5, only_unmatched=True)
    n_missing, missing = unanswered(sel, cp)
    ev["unanswered"] = n_missing
    ev["examples"] = wrong or missing or examples(sel, cp, 5)
    detail = ""
    if wrong:
        ex = wrong[0]
        detail = (f" For example, for u1={ex['u1']:.6g}, u2={ex['u2']:.6g} you printed {ex['printed']:.6g} "
                  f"but z = {ex['expected_z']:.6g}.")
    if cp.ratio >= p.min_ratio:
        frac = cp.ratio
        if not wrong and missing:
            # every value printed is right: the shortfall is pairs that got no line at all
            ex = missing[0]
            return Finding(value, frac, "partial",
                           f"Only {cp.matched} of {cp.expected} published pairs got a z printed: every value "
                           f"you printed is correct, but {n_missing} pairs got no line (for example u1={ex['u1']:.6g}, "
                           f"u2={ex['u2']:.6g}, sent {ex['sent_s']:.2f} s into the replay: z = {ex['expected_z']:.6g}). "
                           "Log one value for every message your callback receives.", ev)
        return Finding(value, frac, "partial",
                       f"Only {cp.matched} of {cp.expected} published pairs got a correct z printed "
                       f"(missing or wrong lines).{detail}", ev)
    few = (f" (only {cp.matched} of {cp.expected} matched: less than {p.min_ratio:.0%} more than chance "
           "alone would give)") if cp.matched else ""
    return Finding(value, 0.0, "fail",
                   f"Your printed values do not match z = sqrt(-2 ln u1)·cos(2πu2) nor a common variant of it{few}."
                   + detail, ev)


class BoxMullerLoggingParams(BoxMullerInputParams):
    tail_grace_s: float = Field(2.0, ge=0, description="s: inputs in the last seconds of the bag may go unanswered")
    min_outputs: int = Field(10, ge=0, description="numeric lines a logger needs to count as \"logs its values\"")


@register("boxmuller_logging", params=BoxMullerLoggingParams, judges=("logging",),
          evidence={**EVIDENCE, "value": ("values written by", "")},
          expect="values logged with self.get_logger().info (at least {min_outputs} lines on /rosout)")
def boxmuller_logging(frames: Frames, p: BoxMullerLoggingParams) -> Finding:
    """The subscriber reports z through ROS logging (/rosout), as the lab asks, not print().

    Why: ``self.get_logger().info`` output is visible to every ROS tool (rqt_console, /rosout,
    log files); print() only reaches the terminal.
    """
    inp = _inputs(frames, p.topic)
    if inp is None or len(inp) == 0:
        return Finding.error(f"No pairs were recorded on {p.topic}, so logging could not be tested.",
                             {"topic": p.topic})
    has_rosout = topic(frames, ROSOUT) is not None or meta_row(frames, ROSOUT) is not None
    if not has_rosout:
        return Finding.error("/rosout was not recorded, so logging cannot be checked (scenario problem).")
    srcs = _sources(frames, p)
    ros = [s for s in srcs if s.kind == "rosout"]
    ev: dict = {"rosout_loggers": sorted({s.name for s in ros}),
                "stdout_processes": sorted({s.name for s in srcs if s.kind == "stdout"})}
    if ros:
        sel = select(frames, p, ros, tail_grace_s=p.tail_grace_s)
        src = sel.best.source if sel.best else max(ros, key=lambda s: s.n_numeric)
        ev.update({"logger": src.name, "n_numeric_lines": src.n_numeric,
                   "matched_correct": sel.correct.matched if sel.correct else 0})
        if src.n_numeric >= p.min_outputs:
            return Finding(src.name, 1.0, "pass",
                           f"Values are logged through ROS logging (logger '{src.name}', {src.n_numeric} lines).", ev)
        return Finding(src.name, 0.0, "fail",
                       f"Logger '{src.name}' logged only {src.n_numeric} numeric line(s) for {len(inp)} received "
                       "pairs: log z once per message with self.get_logger().info(...).", ev)
    std = [s for s in srcs if s.kind == "stdout"]
    if std:
        s = max(std, key=lambda s: s.n_numeric)
        ev.update({"process": s.name, "n_numeric_lines": s.n_numeric, "examples": s.text[:3]})
        lines = stdout_lines(frames)
        mine = lines[lines["process"] == s.name]
        if len(mine) and mine["logger"].notna().mean() > 0.5:
            # the ROS console format: logged, but with a logger that is not a node's
            return Finding("console logger", 0.0, "fail",
                           "Your subscriber logs its values with a logger that is not its node's (they reach the "
                           "console in the ROS format but not /rosout): use self.get_logger().info(...).", ev)
        return Finding("print()", 0.0, "fail",
                       "Your subscriber prints its values with print(), which does not reach /rosout: "
                       "use self.get_logger().info(f\"{z}\") as the lab asks.", ev)
    return Finding.fail("No logged values were found: log z in sub_callback with self.get_logger().info(...).", ev)


class NormalityParams(BoxMullerInputParams):
    tail_grace_s: float = Field(2.0, ge=0, description="s: inputs in the last seconds of the bag may go unanswered")
    # Shapiro-Wilk needs 3 values, the standard deviation's standard error 2
    min_samples: int = Field(20, ge=3, description="printed values needed to test normality")
    max_shapiro: int = Field(5000, ge=3, description="values used in the Shapiro-Wilk test, at most (scipy's "
                                                     "Shapiro-Wilk is accurate up to 5000 samples)")
    alpha: float = Field(0.01, ge=0, le=1, description="Shapiro-Wilk and Anderson-Darling significance level")
    z_bound: float = Field(3.0, ge=0, description="|mean| and |std - 1| allowed in standard errors")


@register("normality", params=NormalityParams, evidence={**EVIDENCE, "value": ("printed values", "")},
          expect=("standard normal values: Shapiro-Wilk and Anderson-Darling p ≥ {alpha:g}, mean 0 and "
                  "standard deviation 1 within {z_bound:g} standard errors"))
def normality(frames: Frames, p: NormalityParams) -> Finding:
    """The printed values look standard Normal: Shapiro-Wilk and Anderson-Darling (shape) plus mean
    ~ 0 and std ~ 1 within ``z_bound`` standard errors (a Normal with the wrong scale, e.g. the log10
    bug, passes the shape tests but not this one). Half credit for each part.
    """
    sel = select(frames, p, tail_grace_s=p.tail_grace_s)
    if sel.best is not None:
        src, pos = sel.best.source, sel.best.pos
    elif sel.sources:
        src, pos = max(sel.sources, key=lambda s: (s.kind == "rosout", s.n_numeric)), -1
    else:
        early = no_output_finding(frames, p, sel)
        return early or Finding.fail("No printed values to test.")
    v, _ = src.column(pos)
    x = v[np.isfinite(v)]
    n = len(x)
    ev: dict = {"source": {"kind": src.kind, "name": src.name}, "number_position": pos, "n": n}
    if n < p.min_samples:
        return Finding(n, 0.0, "fail",
                       f"Only {n} printed value(s): at least {p.min_samples} are needed to test normality.", ev)
    mean, std = float(np.mean(x)), float(np.std(x, ddof=1))
    sw = stats.shapiro(x[: p.max_shapiro])
    try:
        ad = stats.anderson(x, "norm", method="interpolate")
        ad_stat, ad_p = float(ad.statistic), float(ad.pvalue)
    except TypeError:  # scipy < 1.17
        ad = stats.anderson(x, "norm")
        crit = dict(zip(ad.significance_level, ad.critical_values))
        ad_stat = float(ad.statistic)
        ad_p = 0.0 if ad_stat > crit.get(1.0, np.inf) else 1.0
    se_mean, se_std = 1.0 / math.sqrt(n), 1.0 / math.sqrt(2.0 * (n - 1))
    ev.update({"mean": mean, "std": std, "shapiro_W": float(sw.statistic), "shapiro_p": float(sw.pvalue),
               "anderson_stat": ad_stat, "anderson_p": ad_p,
               "mean_bound": p.z_bound * se_mean, "std_bound": p.z_bound * se_std})
    counts, edges = np.histogram(np.clip(x, -4.0, 4.0), bins=np.linspace(-4.0, 4.0, 33))
    ev["histogram"] = {"bins": edges.round(3).tolist(), "counts": counts.tolist(),
                       "reference": "normal", "xlabel": "z"}
    xs = np.sort(x)
    keep = thin(n, 300)
    ev["qq"] = {"theoretical": np.round(stats.norm.ppf((keep + 1 - 0.375) / (n + 0.25)), 4).tolist(),
                "sample": np.round(xs[keep], 4).tolist()}
    shape_ok = sw.pvalue >= p.alpha and ad_p >= p.alpha
    std_ok = abs(mean) <= p.z_bound * se_mean and abs(std - 1.0) <= p.z_bound * se_std
    frac = 0.5 * shape_ok + 0.5 * std_ok
    value = f"mean {mean:.3f}, std {std:.3f}, n {n}"
    if shape_ok and std_ok:
        return Finding(value, 1.0, "pass", f"Your {n} values look standard Normal (mean {mean:.3f}, std {std:.3f}).", ev)
    parts = []
    if not shape_ok:
        parts.append(f"the values are not Normal-shaped (Shapiro-Wilk p = {sw.pvalue:.2g}, "
                     f"Anderson-Darling p = {ad_p:.2g})")
    if not std_ok:
        parts.append(f"mean {mean:.3f} / std {std:.3f} are not those of a standard Normal (0 / 1)")
    return Finding(value, frac, graded(frac),
                   "Your values: " + " and ".join(parts) + ". Check the Box-Muller formula (†).", ev)
