"""Experimental designs built from their definitions reproduce the paper's tables 5, 6 and 7."""

from __future__ import annotations

import csv

import numpy as np
import pytest
from conftest import shared_path

from workbench.plan.designs import full_factorial, one_defective_at_a_time, sweep_preloads, two_level_factorial


def paper_table(name: str) -> list[dict[str, str]]:
    path = shared_path("paper", name)
    with open(path, newline="") as f:
        return [{k: v for k, v in row.items() if k != "test_id"} for row in csv.DictReader(f)]


def test_table5_full_factorial():
    design = full_factorial({"amplitude": ["low", "high"], "bolt_A": [1, 2, 3], "bolt_B": [1, 2, 3]})
    assert design == paper_table("table5_two_bolt_design.csv")
    assert len(design) == 18


def test_table6_two_level_factorial_with_centre_point():
    bolts = ["bolt_A", "bolt_B", "bolt_C", "bolt_D"]
    design = two_level_factorial(bolts, "1", "3", centre="2", fixed={"amplitude": "low"})
    assert design == paper_table("table6_four_bolt_low_amplitude_design.csv")
    assert len(design) == 17


def test_table7_one_defective_bolt_at_a_time():
    bolts = ["bolt_A", "bolt_B", "bolt_C", "bolt_D"]
    design = one_defective_at_a_time(bolts, good="3", defective="1", uniform=["3", "1", "2"],
                                     fixed={"amplitude": "high"})
    assert design == paper_table("table7_four_bolt_high_amplitude_design.csv")


def test_sweep_has_nine_levels_denser_at_low_tightening():
    p = sweep_preloads()
    assert p.size == 9 and p[0] == 100.0 and p[-1] == 6000.0
    steps = np.diff(p)
    assert np.all(steps > 0) and np.all(np.diff(steps) > 0)  # spacing grows with preload
    assert np.sum(p < 0.5 * p[-1]) >= 6  # most levels in the lower half
    with pytest.raises(ValueError, match="sweep_preloads"):
        sweep_preloads(1)
