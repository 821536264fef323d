"""Shared test helpers: small frames built from text, in the contract's own format."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from workbench.model.frame import Frame
from workbench.model.frame_file import parse_frame

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


def shared_path(*parts: str) -> Path:
    """``../shared/<parts>``; a test that needs it fails when it is missing (CI always has ../shared),
    or skips when ``WORKBENCH_ALLOW_NO_SHARED=1`` says a checkout without it is meant."""
    path = SHARED.joinpath(*parts)
    if not path.exists():
        if os.environ.get("WORKBENCH_ALLOW_NO_SHARED") == "1":
            pytest.skip(f"{path} is absent (WORKBENCH_ALLOW_NO_SHARED=1)")
        pytest.fail(f"{path} is missing: this test needs ../shared beside the repository; set "
                    "WORKBENCH_ALLOW_NO_SHARED=1 to skip such tests", pytrace=False)
    return path


def pytest_runtest_setup(item: pytest.Item) -> None:
    """``@pytest.mark.shared("data/real/...")``: the test needs that path under ../shared (`shared_path`)."""
    for marker in item.iter_markers(name="shared"):
        shared_path(*marker.args)
