"""Checks of a campaign's tables (CONTRACTS.md section 2): one-line refusals naming file, line and problem.

Kept apart from `workbench.io.campaign`, which reads and writes the files, so that each check is
found in one place.
"""

from __future__ import annotations

from pathlib import Path
from typing import NoReturn

import numpy as np
import pandas as pd

__all__ = ["CampaignError", "fail", "line_of", "check_duplicates", "check_tests", "integer_ids", "check_flat_curves",
           "check_values", "RULES"]

RULES = {"integer >= 1": lambda v: (v >= 1) & (v == np.round(v)), "positive": lambda v: v > 0,
         "not negative": lambda v: v >= 0, "in [0, 1)": lambda v: (v >= 0) & (v < 1)}


class CampaignError(ValueError):
    """A campaign breaks the contract; one line: ``file: [line N: ]problem``."""


def fail(path: Path | str, problem: str, line: int | None = None) -> NoReturn:
    """Raise `CampaignError` ``"{path}: line {line}: {problem}"`` (the line when known)."""
    where = f"line {line}: " if line is not None else ""
    raise CampaignError(f"{path}: {where}{problem}")


def line_of(path: Path, row: int) -> int | None:
    """Line in the file of data row ``row`` (header on line 1); None for parquet."""
    return None if path.suffix == ".parquet" else row + 2


def check_duplicates(table: pd.DataFrame, keys: list[str], path: Path) -> None:
    """Refuse a row that repeats an earlier one on ``keys``."""
    dup = table.duplicated(keys, keep="first")
    if dup.any():
        row = int(np.flatnonzero(dup)[0])
        what = ", ".join(f"{k} = {table[k].iloc[row]}" for k in keys)
        fail(path, f"duplicated row ({what})", line_of(path, row))


def check_tests(table: pd.DataFrame, path: Path, design_ids: set[str], design_file: Path) -> None:
    """Refuse a test_id that design.csv does not list."""
    unknown = ~table["test_id"].isin(design_ids)
    if unknown.any():
        row = int(np.flatnonzero(unknown)[0])
        fail(path, f"test_id {table['test_id'].iloc[row]} is not in {design_file.name}", line_of(path, row))


def integer_ids(*tables: pd.DataFrame | None) -> None:
    """Make test_id integers in every table when each is an integer written canonically (read as text).

    Only a lossless conversion is made: ``001``, ``01`` and ``1`` are three tests (CONTRACTS.md
    section 2), so one id with a leading zero or a sign keeps every id a string.
    """
    present = [t for t in tables if t is not None]
    values = pd.concat([t["test_id"] for t in present]) if present else pd.Series([], dtype=str)
    if len(values) and values.str.fullmatch(r"0|[1-9]\d*").all():
        for t in present:
            t["test_id"] = t["test_id"].astype(np.int64)


def check_flat_curves(frf: pd.DataFrame, path: Path | str) -> None:
    """Refuse an FRF with no resonance to fit: fewer than 3 lines, or all values equal (zeros included).

    A dead channel or a failed export gives such curves; a circle fit on them would return numbers
    that mean nothing.
    """
    curves = frf.groupby(["test_id", "sensor"], sort=False)
    spread = curves["real"].agg(np.ptp) + curves["imag"].agg(np.ptp)
    lines = curves.size()
    flat = spread[(spread == 0) | (lines < 3)]
    if len(flat):
        test, sensor = flat.index[0]
        count = int(lines[(test, sensor)])
        problem = f"only {count} frequency lines" if count < 3 else "the FRF is constant (all zero?)"
        fail(path, f"test {test}, sensor {sensor}: {problem}: no resonance to fit")


def check_values(table: pd.DataFrame, path: Path, rules: dict[str, str]) -> None:
    """Check each ``column: rule`` of `RULES` on every row of ``table``."""
    for column, rule in rules.items():
        ok = RULES[rule](table[column].to_numpy())
        if not ok.all():
            row = int(np.flatnonzero(~ok)[0])
            fail(path, f"{column} = {table[column].iloc[row]:g} must be {rule}", line_of(path, row))
