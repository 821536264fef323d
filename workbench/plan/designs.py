"""Experimental designs of the paper's campaigns, built from their definitions (tables 3, 5, 6, 7).

Each design is a list of tests, each test a dict factor -> level key (strings, as in design.csv),
in the order the paper lists them.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence

import numpy as np

__all__ = ["full_factorial", "two_level_factorial", "one_defective_at_a_time", "sweep_preloads"]


def full_factorial(factors: dict[str, Sequence[str]]) -> list[dict[str, str]]:
    """Every combination of the factors' levels; the last factor varies fastest (Table 5)."""
    names = list(factors)
    return [dict(zip(names, combo)) for combo in itertools.product(*(list(map(str, factors[n])) for n in names))]


def two_level_factorial(bolts: Sequence[str], low: str, high: str, centre: str | None = None,
                        fixed: dict[str, str] | None = None) -> list[dict[str, str]]:
    """2^n factorial on the bolts' low/high levels, ordered by the number of bolts at ``high``
    (then by which bolts, earliest first), plus an optional centre point with every bolt at
    ``centre`` (Table 6: 2^4 on levels 1/3 and an all-medium test).
    """
    fixed = dict(fixed or {})
    tests = []
    for count in range(len(bolts) + 1):
        for chosen in itertools.combinations(range(len(bolts)), count):
            tests.append({**fixed, **{b: high if i in chosen else low for i, b in enumerate(bolts)}})
    if centre is not None:
        tests.append({**fixed, **{b: centre for b in bolts}})
    return tests


def one_defective_at_a_time(bolts: Sequence[str], good: str, defective: str, uniform: Sequence[str],
                            fixed: dict[str, str] | None = None) -> list[dict[str, str]]:
    """Each bolt in turn at ``defective`` with the others ``good`` (last bolt first, as in Table 7),
    then every bolt at each level of ``uniform`` in turn (Table 7: all-high, all-low, all-medium).
    """
    fixed = dict(fixed or {})
    tests = [{**fixed, **{b: defective if b == bad else good for b in bolts}} for bad in reversed(bolts)]
    tests += [{**fixed, **{b: level for b in bolts}} for level in uniform]
    return tests


def sweep_preloads(count: int = 9, low_n: float = 100.0, high_n: float = 6000.0, power: float = 2.0) -> np.ndarray:
    """Preloads (N) of the single-bolt tightening sweep (section 4.2): ``count`` levels from ``low_n``
    to ``high_n``, spaced as ``(i / (count - 1)) ** power`` so that more of them fall at low
    tightening, where the joint stiffness changes most.
    """
    if count < 2 or not 0 < low_n < high_n or power < 1:
        raise ValueError(f"sweep_preloads: need count >= 2, 0 < low_n < high_n and power >= 1, "
                         f"got {count}, {low_n}, {high_n}, {power}")
    return low_n + (high_n - low_n) * (np.arange(count) / (count - 1)) ** power
