"""Shared test helpers: small frames built from text, in the contract's own format."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from workbench.model.frame import Frame, parse_frame

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"

ALUMINIUM = {"youngs_modulus": 70e9, "density": 2700.0, "poisson_ratio": 0.33}


def bar_section(width: float = 0.03, thickness: float = 0.008) -> dict:
    """A flat bar bending about its thin direction; kappa = 5/6 (rectangle)."""
    return {"area": width * thickness, "second_moment": width * thickness**3 / 12, "shear_coefficient": 5 / 6}


def straight_beam(length: float, supports: list[dict], *, element_length: float = 0.01,
                  theory: str = "euler-bernoulli", section: dict | None = None,
                  axial_force: float = 0.0) -> Frame:
    """A beam along x from point 'a' to point 'b'."""
    member = {"name": "beam", "start": "a", "end": "b", "material": "al", "section": "s"}
    if axial_force:
        member["axial_force"] = axial_force
    return parse_frame({
        "name": "straight beam", "beam_theory": theory, "element_length": element_length,
        "materials": {"al": dict(ALUMINIUM)}, "sections": {"s": section or bar_section()},
        "points": {"a": [0.0, 0.0], "b": [length, 0.0]},
        "members": [member], "supports": supports,
    })


CLAMP = {"ux": "fixed", "uy": "fixed", "rz": "fixed"}


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20201206)
