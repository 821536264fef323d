"""Candidate designs `workbench design` scores (CONTRACTS.md section 3).

A design is a level matrix: one row per test, one column per joint (the joint's tightening factor),
levels ``1 .. level_count`` in increasing tightening. The families are the paper's (a full factorial,
Table 5; a two-level factorial with a centre point, Table 6; one defective bolt at a time, Table 7;
a tightening sweep, section 4.2), each repeated whole to reach larger sizes, and one optimal
selection from the full factorial.

The optimal selection is J2-optimal (Xu 2002, Technometrics 44(4): "An algorithm for constructing
orthogonal and nearly-orthogonal arrays with mixed levels and small runs"): among subsets of the
full factorial's runs it minimises ``J2 = sum_(s<t) delta_st^2``, ``delta_st`` the number of joints
at the same level in tests ``s`` and ``t``. J2 is smallest exactly when every joint takes each level
equally often and every pair of joints each pair of levels equally often (an orthogonal array of
strength 2), so the joints' moduli in the campaign spread over their law and stay uncorrelated:
what moment matching's independent-joint model needs. Written here because no library on the
package index selects such subsets (pyDOE2 builds full and fractional two-level designs only).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from workbench.plan.designs import full_factorial, one_defective_at_a_time, sweep_preloads, two_level_factorial

__all__ = ["Design", "PAPER_LEVELS", "FAMILIES", "candidate_designs", "j2", "j2_selection", "design_sizes"]

# paper section 2.2.1: the three tightening levels of every multi-bolt campaign
PAPER_LEVELS = ("hand-tight, preload < 100 N", "1800 N", "about 6000 N")
MAX_CANDIDATES = 3**7  # runs the J2 selection chooses from
FAMILIES = ("full_factorial", "two_level_centre", "one_defective", "sweep", "j2_optimal")


@dataclass(frozen=True)
class Design:
    """A candidate campaign: ``levels[t, j]`` is joint ``j``'s tightening level in test ``t``.

    Attributes
    ----------
    name : unique among the candidates, e.g. ``two_level_centre_x2``.
    family : one of `FAMILIES`.
    levels : (n_tests, n_joints) int, 1 .. ``level_count``.
    level_names : what each level means in the lab (campaign.toml's level descriptions).
    """

    name: str
    family: str
    levels: np.ndarray
    level_names: tuple[str, ...]

    @property
    def tests(self) -> int:
        return int(self.levels.shape[0])

    @property
    def level_count(self) -> int:
        return len(self.level_names)


def _matrix(rows: list[dict[str, str]], names: list[str]) -> np.ndarray:
    return np.array([[int(row[n]) for n in names] for row in rows], dtype=int).reshape(len(rows), len(names))


def design_sizes(low: int, high: int) -> list[int]:
    """Sizes tried for the families that take any size: every size to 20, then about 20 % apart."""
    sizes = set(range(low, min(high, 20) + 1))
    n = 20
    while n < high:
        n = int(np.ceil(n * 1.2))
        sizes.add(min(n, high))
    return sorted(s for s in sizes if low <= s <= high)


def j2(levels: np.ndarray) -> int:
    """Xu's J2 of a level matrix: sum over pairs of tests of the squared number of coinciding levels."""
    same = (levels[:, None, :] == levels[None, :, :]).sum(axis=2)
    upper = np.triu_indices(levels.shape[0], 1)
    return int((same[upper] ** 2).sum())


def j2_selection(candidates: np.ndarray, size: int, seed: int, starts: int = 6) -> np.ndarray:
    """``size`` distinct rows of ``candidates`` with the smallest J2 found: row exchange from random starts.

    Each pass tries every (row in, row out) swap and takes the best that lowers J2, until none does
    (Fedorov's exchange with J2 as the criterion); the best of ``starts`` seeded starts is kept.
    """
    n = candidates.shape[0]
    if not 1 <= size <= n:
        raise ValueError(f"j2_selection: size {size} is outside 1..{n}")
    coincide = (candidates[:, None, :] == candidates[None, :, :]).sum(axis=2)  # (n, n)
    sq = coincide.astype(float) ** 2
    rng = np.random.default_rng(seed)
    best, best_score = None, np.inf
    for _ in range(starts):
        chosen = rng.choice(n, size, replace=False)
        while True:
            inside = np.zeros(n, bool)
            inside[chosen] = True
            # J2 change when chosen[a] leaves and candidate c enters:
            # - sum_s sq[chosen[a], s] (s in design, s != a) + sum_s sq[c, s] (s in design, s != a)
            load = sq[:, chosen].sum(axis=1)  # (n,) sum over the design's rows
            leave = load[chosen] - sq[chosen, chosen]  # (size,)
            enter = load[None, :] - sq[chosen][:, :]  # (size, n): design without row a
            delta = enter - leave[:, None]
            delta[:, inside] = np.inf
            a, c = np.unravel_index(np.argmin(delta), delta.shape)
            if delta[a, c] >= -1e-9:
                break
            chosen = chosen.copy()
            chosen[a] = c
        score = j2(candidates[chosen])
        if score < best_score:
            best, best_score = np.sort(chosen), score
    assert best is not None
    return candidates[best]


def _repeated(name: str, family: str, block: np.ndarray, names: tuple[str, ...], budget: int) -> list[Design]:
    out = []
    for times in range(1, budget // block.shape[0] + 1):
        label = name if times == 1 else f"{name}_x{times}"
        out.append(Design(label, family, np.tile(block, (times, 1)), names))
    return out


def candidate_designs(n_joints: int, budget: int, low: int = 3, seed: int = 0) -> list[Design]:
    """Every candidate within ``budget`` tests (and at least ``low``) for ``n_joints`` joints.

    Each family's block is repeated whole (``_x2``, ``_x3``, ...) while it fits the budget; the sweep
    (every joint at the same preload, test after test, preloads by `sweep_preloads`) and the
    J2-optimal selection from the full factorial take every size in `design_sizes`.
    """
    if n_joints < 1:
        raise ValueError("candidate_designs: no joint to plan for")
    bolts = [f"j{j}" for j in range(n_joints)]
    blocks: dict[str, np.ndarray] = {}
    if 3**n_joints <= budget:
        blocks["full_factorial"] = _matrix(full_factorial({b: ["1", "2", "3"] for b in bolts}), bolts)
    if 2**n_joints + 1 <= budget:
        blocks["two_level_centre"] = _matrix(two_level_factorial(bolts, "1", "3", centre="2"), bolts)
    if n_joints + 3 <= budget:
        blocks["one_defective"] = _matrix(one_defective_at_a_time(bolts, "3", "1", ["3", "1", "2"]), bolts)
    if 3**n_joints <= MAX_CANDIDATES:
        runs = _matrix(full_factorial({b: ["1", "2", "3"] for b in bolts}), bolts)
    else:  # beyond seven joints the full factorial is not enumerable: a seeded sample of its runs
        runs = np.unique(np.random.default_rng(seed).integers(1, 4, size=(MAX_CANDIDATES, n_joints)), axis=0)
    designs: list[Design] = []
    for family, block in blocks.items():
        if block.shape[0] >= low:
            designs += _repeated(family, family, block, PAPER_LEVELS, budget)
    for size in design_sizes(max(low, 3), budget):
        preloads = sweep_preloads(size)
        names = tuple(f"{p:.0f} N" for p in preloads)
        designs.append(Design(f"sweep_{size}", "sweep", np.repeat(np.arange(1, size + 1)[:, None], n_joints, 1), names))
    for size in design_sizes(max(low, 3), min(budget, runs.shape[0])):
        designs.append(Design(f"j2_optimal_{size}", "j2_optimal", j2_selection(runs, size, seed), PAPER_LEVELS))
    return designs
