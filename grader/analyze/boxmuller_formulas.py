"""The Box-Muller formulas a student's printed values are tested against: the lab's formula (†)
and the classic mistakes (another logarithm, a missing factor or square root, Python's operator
precedence, degrees for radians, swapped inputs...), each with the feedback that names the
mistake. ``grader.analyze.boxmuller_pairing`` pairs the printed values with their inputs and asks
which of these explains them; a new mistake is a new entry here.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np


TWO_PI = 2.0 * math.pi


def _sqrt_m2ln(u: np.ndarray) -> np.ndarray:
    out: np.ndarray = np.sqrt(-2.0 * np.log(u))
    return out


#: name -> (formula text, function, feedback when the student's values match it)
FORMULAS: dict[str, tuple[str, Callable[[np.ndarray, np.ndarray], np.ndarray], str]] = {
    "correct": ("sqrt(-2 ln u1) cos(2 pi u2)",
                lambda a, b: _sqrt_m2ln(a) * np.cos(TWO_PI * b), ""),
    "log10": ("sqrt(-2 log10 u1) cos(2 pi u2)",
              lambda a, b: np.sqrt(-2.0 * np.log10(a)) * np.cos(TWO_PI * b),
              "Your values match z computed with log10 instead of the natural log: use math.log / np.log "
              "(natural logarithm), not math.log10."),
    "log2": ("sqrt(-2 log2 u1) cos(2 pi u2)",
             lambda a, b: np.sqrt(-2.0 * np.log2(a)) * np.cos(TWO_PI * b),
             "Your values match z computed with log2 instead of the natural log: use math.log / np.log."),
    "missing_2": ("sqrt(-ln u1) cos(2 pi u2)",
                  lambda a, b: np.sqrt(-np.log(a)) * np.cos(TWO_PI * b),
                  "Your values match sqrt(-ln u1)·cos(2πu2): the factor 2 under the square root is missing; "
                  "use math.sqrt(-2 * math.log(u1))."),
    "missing_sqrt": ("-2 ln u1 cos(2 pi u2)",
                     lambda a, b: -2.0 * np.log(a) * np.cos(TWO_PI * b),
                     "Your values match -2·ln(u1)·cos(2πu2): the square root is missing; "
                     "use math.sqrt(-2 * math.log(u1))."),
    "power_precedence": ("(-2 ln u1)/2 cos(2 pi u2)",
                         lambda a, b: -np.log(a) * np.cos(TWO_PI * b),
                         "Your values match (-2·ln u1)/2·cos(2πu2): '** 1/2' is parsed as (x**1)/2 in Python; "
                         "write x ** 0.5 or math.sqrt(x)."),
    "sin_for_cos": ("sqrt(-2 ln u1) sin(2 pi u2)",
                    lambda a, b: _sqrt_m2ln(a) * np.sin(TWO_PI * b),
                    "Your values match sqrt(-2 ln u1)·sin(2πu2): that is the other Box-Muller output and is "
                    "also Normal, but the lab's formula (†) uses cos(2πu2)."),
    "swapped": ("sqrt(-2 ln u2) cos(2 pi u1)",
                lambda a, b: _sqrt_m2ln(b) * np.cos(TWO_PI * a),
                "Your values match the formula with u1 and u2 swapped: the logarithm takes u1 = msg.data[0] "
                "and the cosine takes u2 = msg.data[1]."),
    "u1_twice": ("sqrt(-2 ln u1) cos(2 pi u1)",
                 lambda a, b: _sqrt_m2ln(a) * np.cos(TWO_PI * a),
                 "Your values match a formula that uses u1 in both places: the cosine must take u2."),
    "u2_twice": ("sqrt(-2 ln u2) cos(2 pi u2)",
                 lambda a, b: _sqrt_m2ln(b) * np.cos(TWO_PI * b),
                 "Your values match a formula that uses u2 in both places: the logarithm must take u1."),
    "degrees_radians": ("sqrt(-2 ln u1) cos(radians(2 pi u2))",
                        lambda a, b: _sqrt_m2ln(a) * np.cos(np.radians(TWO_PI * b)),
                        "Your values match cos(radians(2πu2)): 2πu2 is already in radians, so do not convert it; "
                        "use math.cos(2 * math.pi * u2)."),
    "cos_360": ("sqrt(-2 ln u1) cos(360 u2)",
                lambda a, b: _sqrt_m2ln(a) * np.cos(360.0 * b),
                "Your values match cos(360·u2): math.cos expects radians, so the angle is 2·math.pi·u2, not 360·u2."),
    "missing_2_in_2pi": ("sqrt(-2 ln u1) cos(pi u2)",
                         lambda a, b: _sqrt_m2ln(a) * np.cos(math.pi * b),
                         "Your values match cos(π·u2): the angle must be 2·π·u2."),
    "missing_pi": ("sqrt(-2 ln u1) cos(2 u2)",
                   lambda a, b: _sqrt_m2ln(a) * np.cos(2.0 * b),
                   "Your values match cos(2·u2): π is missing; the angle must be 2·math.pi·u2."),
    "cos_precedence": ("sqrt(-2 ln u1) cos(2 pi) u2",
                       lambda a, b: _sqrt_m2ln(a) * b,
                       "Your values match sqrt(-2 ln u1)·cos(2π)·u2: u2 must be inside the cosine, "
                       "math.cos(2 * math.pi * u2)."),
    "negated": ("-sqrt(-2 ln u1) cos(2 pi u2)",
                lambda a, b: -_sqrt_m2ln(a) * np.cos(TWO_PI * b),
                "Your values have the wrong sign: z = +sqrt(-2 ln u1)·cos(2πu2)."),
}
