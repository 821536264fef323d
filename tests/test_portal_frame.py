"""Portal frames against independent calculations: the exact dynamic stiffness method, and a
frame file and frequencies written by another program."""

from __future__ import annotations

import json

import numpy as np
from conftest import shared_path

from workbench.model.assembly import assemble
from workbench.model.frame_file import parse_frame, read_frame
from workbench.model.modal import model_modes

try:
    from tests.reference.dynamic_stiffness import natural_frequencies_hz, portal_frame_reference
except ImportError:  # tests/ on sys.path rather than the repository root
    from reference.dynamic_stiffness import natural_frequencies_hz, portal_frame_reference


def frame_from_reference(ref: dict, element_length: float, masses=(), springs=()) -> dict:
    names = [f"n{i}" for i in range(len(ref["node_xy"]))]
    fixed = set(ref["fixed_dofs"])
    m0 = ref["members"][0]
    data = {
        "name": "reference portal", "element_length": element_length,
        "materials": {"m": {"youngs_modulus": m0["E"], "density": m0["rho"]}},
        "sections": {"s": {"area": m0["A"], "second_moment": m0["I"]}},
        "points": {n: list(map(float, xy)) for n, xy in zip(names, ref["node_xy"])},
        "members": [{"name": f"m{k}", "start": names[m["start"]], "end": names[m["end"]],
                     "material": "m", "section": "s"} for k, m in enumerate(ref["members"])],
        "supports": [{"point": names[i], **{d: "fixed" for j, d in enumerate(("ux", "uy", "rz"))
                                            if 3 * i + j in fixed}}
                     for i in range(len(names)) if any(3 * i + j in fixed for j in range(3))],
        "masses": list(masses), "springs": list(springs),
    }
    return data


def test_portal_frame_first_six_within_half_a_percent_of_exact():
    ref = portal_frame_reference()
    modes = model_modes(assemble(parse_frame(frame_from_reference(ref, 0.01))), 6)
    np.testing.assert_allclose(modes.frequency_hz, ref["frequencies_hz"][:6], rtol=5e-3)
    np.testing.assert_allclose(modes.frequency_hz, ref["frequencies_hz"][:6], rtol=1e-6)


def test_portal_with_masses_and_springs_against_exact():
    ref = portal_frame_reference()
    masses = [{"point": "n1", "mass": 0.07, "rotary_inertia": 2e-5}, {"point": "n2", "mass": 0.05}]
    springs = [{"point": "n1", "dof": "ux", "stiffness": 2e4}, {"point": "n2", "dof": "rz", "stiffness": 50.0}]
    frame = parse_frame(frame_from_reference(ref, 0.01, masses, springs))
    exact = natural_frequencies_hz(ref["node_xy"], ref["members"], ref["fixed_dofs"], 8,
                                   node_masses={1: (0.07, 2e-5), 2: (0.05, 0.0)},
                                   grounded_springs={3: 2e4, 8: 50.0})
    np.testing.assert_allclose(model_modes(assemble(frame), 8).frequency_hz, exact, rtol=1e-6)


def test_frequencies_computed_by_another_program_for_its_frame():
    example = shared_path("examples")
    truth = json.loads((example / "independent-two-test-campaign.truth.json").read_text())
    model = assemble(read_frame(example / "independent-two-test-campaign" / "frame.toml"))
    got = model_modes(model, 10).frequency_hz
    # the other program's LAPACK values carry about 1e-7 of rounding (see test_modal)
    np.testing.assert_allclose(got, truth["nominal_model_hz_at_joint_means"], rtol=1e-6)
    for test in truth["tests"]:
        gamma = np.array(test["gamma"])
        np.testing.assert_allclose(model_modes(model, 10, gamma).frequency_hz, test["frequency_hz"], rtol=1e-6)
