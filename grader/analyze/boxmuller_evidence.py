"""What the report shows of a Box-Muller pairing (``grader.analyze.boxmuller_pairing``): example
lines with the input each answers, the inputs no line answers, the scatter of printed against
correct values, and the finding when there is nothing to pair. Apart from the pairing itself, which
is the method; this is its evidence."""

from __future__ import annotations

import numpy as np

from grader.analyze import Finding
from grader.analyze._common import ROSOUT, STDOUT, Frames, meta_row, thin, topic
from grader.analyze.boxmuller_formulas import FORMULAS
from grader.analyze.boxmuller_pairing import BoxMullerInputParams, Inputs, Pairing, Selection


def correct_z(inp: Inputs, i: int) -> float:
    """The correct z of input ``i`` (NaN where the formula has none, e.g. u1 = 0)."""
    with np.errstate(all="ignore"):
        return float(FORMULAS["correct"][1](np.array([inp.u1[i]]), np.array([inp.u2[i]]))[0])


def examples(sel: Selection, pairing: Pairing, k: int = 5, only_unmatched: bool = False) -> list[dict]:
    inp = sel.inputs
    assert inp is not None
    v, _ = pairing.source.column(pairing.pos)
    out = []
    for j, i, m in pairing.pairs:
        if only_unmatched and m:
            continue
        out.append({"u1": float(inp.u1[i]), "u2": float(inp.u2[i]), "printed": float(v[j]),
                    "line": pairing.source.text[j][:120], "expected_z": correct_z(inp, i), "matched": bool(m)})
        if len(out) >= k:
            break
    return out


def unanswered(sel: Selection, pairing: Pairing, k: int = 5) -> tuple[int, list[dict]]:
    """Inputs counted in ``expected`` that no printed line answers: how many, and the first
    ``k`` (a node that received them printed nothing for them, or never received them)."""
    inp = sel.inputs
    assert inp is not None
    answered = {i for _, i, m in pairing.pairs if m}
    t0, cut = pairing.span
    idx = [int(i) for i in np.flatnonzero((inp.t >= t0 - 1e-9) & (inp.t <= cut)) if int(i) not in answered]
    out = [{"u1": float(inp.u1[i]), "u2": float(inp.u2[i]), "expected_z": correct_z(inp, i),
            "sent_s": round(float(inp.t[i] - inp.t[0]), 3)} for i in idx[:k]]
    return len(idx), out


def pair_series(sel: Selection, pairing: Pairing, max_points: int = 300) -> dict:
    """Printed value against the correct z of the input it answers (the report's scatter plot);
    ``formula``: the formula the pairing followed (a named mistake, or "correct")."""
    inp = sel.inputs
    assert inp is not None
    v, _ = pairing.source.column(pairing.pos)
    pairs = pairing.pairs
    keep = thin(len(pairs), max_points)
    j = np.array([pairs[k][0] for k in keep], dtype=int)
    i = np.array([pairs[k][1] for k in keep], dtype=int)
    with np.errstate(all="ignore"):
        z = FORMULAS["correct"][1](inp.u1[i], inp.u2[i]) if len(i) else np.array([])
    return {"formula": pairing.formula, "expected_z": np.round(z, 5).tolist(),
            "printed": np.round(v[j], 6).tolist() if len(j) else [],
            "matched": [bool(pairs[k][2]) for k in keep]}


def no_output_finding(frames: Frames, p: BoxMullerInputParams, sel: Selection) -> Finding | None:
    if sel.inputs is None or len(sel.inputs) == 0:
        row = meta_row(frames, p.topic)
        return Finding.error(
            f"No (u1, u2) pairs were recorded on {p.topic}, so the subscriber could not be tested "
            "(scenario problem).", {"topic": p.topic, "meta": row})
    if topic(frames, ROSOUT) is None and topic(frames, STDOUT) is None:
        return Finding.error("Neither /rosout nor /grader/stdout was recorded: the subscriber's output "
                             "cannot be checked (scenario problem).", {"n_inputs": len(sel.inputs)})
    if not sel.sources:
        return Finding.fail(
            f"Your subscriber printed no numbers while {len(sel.inputs)} pairs were published on "
            f"{p.topic}: subscribe to /random_numbers and log z with self.get_logger().info(...).",
            {"n_inputs": len(sel.inputs)})
    return None


