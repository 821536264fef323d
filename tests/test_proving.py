"""The proving ground (workbench/proving/): no shared physics with the workbench, its numerics against closed
forms, same seed -> same bytes, mechanisms that move the frequencies the physical way, and campaigns that
the workbench's circle fit reads.

Measured when written (numbers the asserts below guard with margin):

- simply supported Timoshenko beam, L/t = 5, 60 elements: modes 1-4 off the closed form by 1.0e-5, 1.2e-4,
  4.3e-4, 9.8e-4; error falling as h^2.00 (the element's shear strain is constant: its energy error is
  O(h^2)); L/t = 100: below 3e-7, and the exact Timoshenko frequencies within 0.27 % of Euler-Bernoulli's;
- cantilever, L/t = 5: 1.4e-6 to 5.8e-4 off the exact Timoshenko roots; L/t = 100: below 2e-7;
- Euler-Bernoulli limit (phi = 0): cantilever error falling as h^4;
- bundled two-bolt frame, first 10 modes: 6e-6 from the workbench's Euler-Bernoulli model with the
  proving ground's beams made Euler-Bernoulli (a mesh three times finer), 2.2e-5 from the workbench's
  Timoshenko model, and Timoshenko 0.06 % to 0.86 % below the workbench's Euler-Bernoulli frame;
- a dashpot's FRF by the augmented modal basis: 4e-6 from a full-dof direct solve.
"""

from __future__ import annotations

import ast
import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

from workbench.io.campaign import campaign_files
from workbench.model.frame import member_length
from workbench.model.frame_file import parse_frame, read_frame
from workbench.proving.article import Article, Dashpot, Softening
from workbench.proving.beams import BeamSet, assemble, beam_local, beam_matrices, damped_modes, frf, solve_modes
from workbench.proving.campaigns import CampaignSettings, simulate_campaign
from workbench.proving.cases import (
    DAMPING_FOOTPRINTS,
    FAINT,
    FOOTPRINTS,
    KINDS,
    LINE_SPACINGS_HZ,
    MEASUREMENTS,
    CaseSpec,
    case_campaign,
    case_mix,
    design_of,
    drawn_measurements,
    expected_verdict,
    reached_level,
)
from workbench.proving.fem import discretise
from workbench.proving.footprint import EDGE_SHARE, article_frequencies, calibrate, footprint, measurable_top_hz
from workbench.proving.frames import BUNDLED, FRAME_NAMES, proving_frame
from workbench.proving.mechanisms import EFFECTS, NONE, OUTSIDE, VARIANTS, vocabulary_mechanism
from workbench.proving.outside import OUTSIDE_VARIANTS, outside_mechanism

REPO = Path(__file__).resolve().parents[1]
PROVING = REPO / "workbench" / "proving"
# the workbench code under test: the proving ground must not share its physics (an inverse crime)
FORBIDDEN = ("workbench.rig", "workbench.model.assembly", "workbench.model.elements", "workbench.model.modal",
             "workbench.model.joints", "workbench.model.pattern", "workbench.model.structure",
             "workbench.model.generate", "workbench.uq", "workbench.diagnose", "workbench.identify",
             "workbench.extraction", "workbench.workflow")
# paper_frames: the bundled frame files' text, built (geometry and materials, no physics), as the files held it
ALLOWED = ("workbench.model.frame", "workbench.model.frame_file", "workbench.model.paper_frames",
           "workbench.io.campaign", "workbench.progress", "workbench.proving")
PANDAS_MODULES = ("campaigns.py", "cases.py")

E, NU, RHO, KAPPA = 210e9, 0.3, 7850.0, 5.0 / 6.0
G = E / (2 * (1 + NU))


# ------------------------------------------------------------------------------------- the guard

def _imports(path: Path) -> list[str]:
    """Every module ``path`` imports, relative imports resolved, function-level ones included."""
    package = ["workbench", "proving"]
    out = []
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out += [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package[:len(package) - node.level + 1] + ([base] if base else []))
            out.append(base)
            out += [f"{base}.{a.name}" for a in node.names]
    return out


def test_the_proving_ground_imports_none_of_the_physics_it_judges():
    modules = sorted(PROVING.glob("*.py"))
    assert len(modules) >= 8
    breaches = []
    for path in modules:
        for target in _imports(path):
            if target.startswith(FORBIDDEN) or target.split(".")[0] == "workbench" and target != "workbench" and (
                    not target.startswith(ALLOWED)):
                breaches.append(f"{path.name} imports {target}")
            if target.split(".")[0] == "pandas" and path.name not in PANDAS_MODULES:
                breaches.append(f"{path.name} imports pandas (only {', '.join(PANDAS_MODULES)} may)")
    assert breaches == []


def test_the_guard_catches_a_forbidden_import(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("from workbench.model.assembly import assemble\nfrom ..rig import effects\n")
    targets = _imports(bad)
    assert "workbench.model.assembly" in targets and "workbench.rig" in targets


def test_the_vocabulary_is_the_diagnosis_vocabulary():
    from workbench.rig.effects import EFFECTS as RIG_EFFECTS  # the test may read the registry; the package may not

    assert set(EFFECTS) | {NONE, OUTSIDE} == set(RIG_EFFECTS)


# ------------------------------------------------------------------------------------- closed forms

def _beam(length: float, thickness: float, supports: list[dict], element_length: float = 0.01):
    width = 0.02
    return parse_frame({
        "name": "beam", "element_length": element_length,
        "materials": {"steel": {"youngs_modulus": E, "density": RHO, "poisson_ratio": NU}},
        "sections": {"s": {"area": width * thickness, "second_moment": width * thickness**3 / 12,
                           "shear_coefficient": KAPPA}},
        "points": {"a": [0.0, 0.0], "b": [length, 0.0]},
        "members": [{"name": "m", "start": "a", "end": "b", "material": "steel", "section": "s"}],
        "supports": supports}), width * thickness, width * thickness**3 / 12


PINNED = [{"point": "a", "ux": "fixed", "uy": "fixed"}, {"point": "b", "uy": "fixed"}]
CLAMPED = [{"point": "a", "ux": "fixed", "uy": "fixed", "rz": "fixed"}]
CANTILEVER_ROOTS = np.array([1.87510407, 4.69409113, 7.85475744, 10.99554073])  # beta L, Euler-Bernoulli


def _simply_supported(n: int, length: float, area: float, inertia: float) -> float:
    """Closed-form Timoshenko frequency of mode n, Hz: w = sin(k x), theta = cos(k x) in the two equations."""
    k, kga = n * math.pi / length, KAPPA * G * area
    a2 = RHO * area * RHO * inertia
    a1 = -(RHO * area * (E * inertia * k**2 + kga) + RHO * inertia * kga * k**2)
    a0 = kga * E * inertia * k**4
    return math.sqrt((-a1 - math.sqrt(a1**2 - 4 * a2 * a0)) / (2 * a2)) / (2 * math.pi)


def _cantilever_determinant(w: float, length: float, area: float, inertia: float) -> float:
    """Boundary determinant of the exact Timoshenko cantilever at omega ``w`` (below the second spectrum)."""
    kga, ei = KAPPA * G * area, E * inertia
    # the characteristic equation in mu = lambda^2 of w, theta ~ exp(lambda x): c2 mu^2 + c1 mu + c0 = 0
    c2, c1 = kga * ei, (kga * RHO * inertia + RHO * area * ei) * w**2
    c0 = RHO * area * w**2 * (RHO * inertia * w**2 - kga)
    root = math.sqrt(c1**2 - 4 * c2 * c0)
    al, be = math.sqrt((-c1 + root) / (2 * c2)), math.sqrt((c1 + root) / (2 * c2))
    ra, q = (kga * al**2 + RHO * area * w**2) / (kga * al), (RHO * area * w**2 - kga * be**2) / (kga * be)
    ch, sh, c, s = (math.cosh(al * length), math.sinh(al * length), math.cos(be * length), math.sin(be * length))
    # w = C1 cosh + C2 sinh + C3 cos + C4 sin; rows: w(0), theta(0), theta'(L), w'(L) - theta(L)
    m = np.array([[1, 0, 1, 0], [0, ra, 0, -q], [ra * al * ch, ra * al * sh, q * be * c, q * be * s],
                  [(al - ra) * sh, (al - ra) * ch, -(be + q) * s, (be + q) * c]])
    return float(np.linalg.det(m) / ch)


def _cantilever(count: int, length: float, area: float, inertia: float) -> np.ndarray:
    eb = CANTILEVER_ROOTS[:count] ** 2 * math.sqrt(E * inertia / (RHO * area)) / length**2
    grid = np.linspace(0.5 * eb[0], 1.3 * eb[-1], 4000)
    v = np.array([_cantilever_determinant(w, length, area, inertia) for w in grid])
    change = np.flatnonzero(np.sign(v[:-1]) != np.sign(v[1:]))
    return np.array([brentq(_cantilever_determinant, grid[i], grid[i + 1], args=(length, area, inertia))
                     for i in change[:count]]) / (2 * math.pi)


def _bending(frame, exact: np.ndarray, **kwargs) -> np.ndarray:
    d = discretise(Article(frame, **kwargs))
    f = solve_modes(d.system.stiffness, d.system.mass, 3 * exact.size + 4).frequency_hz
    return np.array([f[np.argmin(np.abs(f - e))] for e in exact])  # the axial modes are left aside


def test_element_stiffness_carries_the_shear_correction():
    length, ei, kga = np.array([0.05]), np.array([3.0]), np.array([4e4])
    phi = 12 * ei / (kga * length**2)
    k, _ = beam_local(length, np.array([1e6]), ei, kga, np.array([1.0]), np.array([1e-5]))
    np.testing.assert_allclose(k[0, 1, 1], 12 * ei / ((1 + phi) * length**3), rtol=1e-12)
    np.testing.assert_allclose(k[0, 2, 2], (4 + phi) * ei / ((1 + phi) * length), rtol=1e-12)
    np.testing.assert_allclose(k[0, 2, 5], (2 - phi) * ei / ((1 + phi) * length), rtol=1e-12)
    k, m = beam_local(length, np.array([1e6]), ei, kga, np.array([1.0]), np.array([1e-5]))
    for a in (k[0], m[0]):
        np.testing.assert_allclose(a, a.T, atol=1e-12 * np.abs(a).max())
    assert np.linalg.eigvalsh(m[0]).min() > 0
    assert np.sum(np.linalg.eigvalsh(k[0]) < 1e-9 * np.abs(k[0]).max()) == 3  # the three rigid-body motions


def test_simply_supported_timoshenko_beam_against_the_closed_form():
    frame, area, inertia = _beam(0.2, 0.04, PINNED)  # L / t = 5
    exact = np.array([_simply_supported(n, 0.2, area, inertia) for n in range(1, 5)])
    error = np.abs(_bending(frame, exact) / exact - 1)
    assert np.all(error < [3e-5, 3e-4, 1e-3, 2e-3])
    euler = np.array([(n * math.pi) ** 2 * math.sqrt(E * inertia / (RHO * area)) / (2 * math.pi * 0.04) for n in
                      range(1, 5)])
    assert np.all(exact < euler * (1 - 0.05))  # stocky: shear and rotary inertia lower them by 6 % to 41 %
    slender, area, inertia = _beam(1.0, 0.01, PINNED)  # L / t = 100
    exact = np.array([_simply_supported(n, 1.0, area, inertia) for n in range(1, 5)])
    euler = np.array([(n * math.pi) ** 2 * math.sqrt(E * inertia / (RHO * area)) / (2 * math.pi) for n in range(1, 5)])
    assert np.all(np.abs(_bending(slender, exact) / exact - 1) < 1e-6)
    assert np.all(np.abs(exact / euler - 1) < 3e-3)  # tending to Euler-Bernoulli


def test_cantilever_against_the_exact_timoshenko_roots_and_euler_bernoulli():
    frame, area, inertia = _beam(0.2, 0.04, CLAMPED)
    exact = _cantilever(4, 0.2, area, inertia)
    assert np.all(np.abs(_bending(frame, exact) / exact - 1) < [1e-5, 1e-4, 5e-4, 1e-3])
    slender, area, inertia = _beam(1.0, 0.01, CLAMPED)
    exact = _cantilever(4, 1.0, area, inertia)
    euler = CANTILEVER_ROOTS**2 * math.sqrt(E * inertia / (RHO * area)) / (2 * math.pi)
    assert np.all(np.abs(_bending(slender, exact) / exact - 1) < 1e-6)
    assert np.all(np.abs(exact / euler - 1) < 3e-3)


def test_mesh_convergence_rates():
    """Timoshenko (stocky, simply supported): error ~ h^2; the phi = 0 limit (cubic Hermite): ~ h^4."""
    exact = None
    errors = []
    for element_length in (0.02, 0.01, 0.005):
        frame, area, inertia = _beam(0.2, 0.04, PINNED, element_length)
        exact = np.array([_simply_supported(n, 0.2, area, inertia) for n in (1, 3)])
        errors.append(np.abs(_bending(frame, exact) / exact - 1))
    slopes = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((slopes > 1.9) & (slopes < 2.1)), slopes
    errors = []
    length, ei, mu = 1.0, E * 0.02 * 0.01**3 / 12, RHO * 0.02 * 0.01
    euler = CANTILEVER_ROOTS[1] ** 2 * math.sqrt(ei / mu) / (2 * math.pi * length**2)
    for n in (4, 8, 16):
        beams = BeamSet(np.array([[3 * k, 3 * k + 1, 3 * k + 2, 3 * k + 3, 3 * k + 4, 3 * k + 5] for k in range(n)]),
                        np.full(n, length / n), np.ones(n), np.zeros(n), np.full(n, 1e9), np.full(n, ei),
                        np.full(n, np.inf), np.full(n, mu), np.zeros(n))
        k, m = beam_matrices(beams)
        size = 3 * (n + 1)
        free = np.arange(3, size)
        kk, mm = (assemble(a, beams.dofs, size)[free][:, free].tocsr() for a in (k, m))
        f = solve_modes(kk, mm, 6).frequency_hz
        errors.append(abs(f[np.argmin(np.abs(f - euler))] / euler - 1))
    slopes = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all((slopes > 3.8) & (slopes < 4.2)), slopes


def test_mesh_is_three_times_finer_than_the_workbench_and_twelve_per_member():
    frame = proving_frame("two_bolt")
    d = discretise(Article(frame))
    for mi, member in enumerate(frame.members):
        count = int(np.sum(d.element_member == mi))
        assert count >= 12 and count >= 3 * math.ceil(member_length(frame, member) / frame.element_length)


def test_portal_frame_against_the_workbench_model():
    from workbench.model.assembly import assemble as wb_assemble  # the test may compare; the package may not
    from workbench.model.modal import model_modes

    frame = proving_frame("two_bolt")
    euler = model_modes(wb_assemble(frame), 10).frequency_hz
    timoshenko = model_modes(wb_assemble(replace(frame, beam_theory="timoshenko")), 10).frequency_hz
    ours_eb = article_frequencies(Article(frame, shear=False, rotary_inertia=False))
    ours = article_frequencies(Article(frame))
    assert np.all(np.abs(ours_eb / euler - 1) < 5e-5)
    assert np.all(np.abs(ours / timoshenko - 1) < 1e-4)
    shift = ours / euler - 1
    assert np.all((shift < 0) & (shift > -0.015)), shift  # within 1.5 % of the workbench's Euler-Bernoulli frame


def test_dashpot_frf_against_a_full_direct_solve():
    import scipy.sparse.linalg as spla

    frame = proving_frame("two_bolt")
    joint = frame.joint("A")
    article = Article(frame, dashpots=(Dashpot((joint.member, joint.span[0]), (joint.member, joint.span[1]), "rz",
                                               0.5),))
    s = discretise(article).system
    alpha, beta = 2.0, 2e-6  # Rayleigh: exactly modal in any M- and K-orthogonal basis

    def law(f: np.ndarray) -> np.ndarray:
        return alpha / (4 * np.pi * f) + beta * np.pi * f

    f = np.array([20.0, 129.0, 300.0, 550.0, 900.0, 1200.0])
    reduced = frf(s, solve_modes(s.stiffness, s.mass, 20, max_hz=3750.0), f, law, "receptance")
    load = np.zeros(s.size)
    load[s.excitation] = 1.0
    k, m, c = s.stiffness.tocsc(), s.mass.tocsc(), s.damping.tocsc()
    direct = np.array([spla.spsolve((k - w**2 * m + 1j * w * (alpha * m + beta * k + c)).tocsc(), load)[s.responses]
                       for w in 2 * np.pi * f]).T
    assert np.max(np.abs(reduced - direct) / np.abs(direct).max(axis=0)) < 1e-4
    modes = solve_modes(s.stiffness, s.mass, 10)
    _, with_dashpot = damped_modes(s, modes, np.full(10, 0.004))
    assert np.all(with_dashpot[:6] >= 0.004 - 1e-9) and with_dashpot.max() > 0.0045


def test_misfit_is_solved_statically_into_self_equilibrated_forces():
    frame = proving_frame("two_bolt")
    mech = vocabulary_mechanism(frame, "axial_prestress", np.random.default_rng(0), "beam", "misfit_tie")
    article = mech.build(Article(frame), 5e-4)
    d = discretise(article)
    beam = d.member_axial_force([m.name for m in frame.members].index("beam"))
    k_tie = mech.parameters(5e-4)["rod_axial_stiffness"]
    assert beam < 0 and abs(beam / (-k_tie * 5e-4) - 1) < 0.05  # the wire takes the misfit, the beam its force


# ------------------------------------------------------------------------------------- determinism

SMALL = CampaignSettings(f_max_hz=300.0, df_hz=0.5)


def test_same_seed_same_bytes_other_seed_other_bytes():
    spec = CaseSpec(0, 123, "two_bolt", "joint_damping", "medium")
    first, truth1 = case_campaign(spec, SMALL)
    second, truth2 = case_campaign(spec, SMALL)
    other, _ = case_campaign(replace(spec, seed=124), SMALL)
    files = campaign_files(first)
    assert files == campaign_files(second)
    assert json.dumps(truth1, sort_keys=True) == json.dumps(truth2, sort_keys=True)
    assert files["frf.csv"] != campaign_files(other)["frf.csv"]
    assert list(first.frf.columns) == ["test_id", "sensor", "frequency_hz", "real", "imag"]
    assert first.frf["test_id"].tolist()[0] == 1 and first.frame.joints[0].cov == 0.0


def test_case_mix_is_reproducible_and_covers_every_kind():
    mix = case_mix(30, 5)
    assert mix == case_mix(30, 5) and mix[:12] == case_mix(12, 5)
    kinds = {s.kind if s.secondary is None else "combined" for s in mix[:len(KINDS)]}
    assert kinds == set(KINDS)
    assert {s.level for s in mix if s.kind not in (NONE, "identification")} == {"small", "medium", "large"}
    assert {s.frame for s in mix} <= set(FRAME_NAMES)
    assert expected_verdict(OUTSIDE) == "unexplained" and expected_verdict("identification") == NONE


def test_an_exported_quantity_carries_the_noise_of_the_sensed_one():
    """An accelerometer's receptance is its accelerance over (i w)^2, noise included, line by line; a receptance
    sensed as such has its noise at each curve's receptance RMS instead, above it at the top of the band."""
    spec = CaseSpec(0, 123, "two_bolt", "added_mass", "medium")
    sensed, _ = case_campaign(spec, SMALL)
    exported, truth = case_campaign(spec, replace(SMALL, quantity="receptance", sensed="accelerance"))
    direct, _ = case_campaign(spec, replace(SMALL, quantity="receptance"))
    assert exported.quantity == "receptance" and truth["sensed"] == "accelerance"
    f = sensed.frf["frequency_hz"].to_numpy()
    h_acc = sensed.frf["real"].to_numpy() + 1j * sensed.frf["imag"].to_numpy()
    h_rec = exported.frf["real"].to_numpy() + 1j * exported.frf["imag"].to_numpy()
    h_dir = direct.frf["real"].to_numpy() + 1j * direct.frf["imag"].to_numpy()
    lines = f > 0
    assert np.allclose(h_rec[lines] * (2j * np.pi * f[lines]) ** 2, h_acc[lines], rtol=1e-12, atol=0.0)
    assert np.all(h_rec[~lines] == 0.0)
    # the top 10 % of the band, line-to-line roughness (noise and the curve's slope; 3.6 times on this case)
    top = f > 0.9 * f.max()
    rough_exported = np.median(np.abs(np.diff(h_rec[top])))
    rough_direct = np.median(np.abs(np.diff(h_dir[top])))
    assert rough_direct > 2.0 * rough_exported


def test_drawn_measurements_change_only_the_measurement_and_cover_the_lab_mix():
    mix = [s for s in case_mix(400, 5) if s.kind != "identification"]
    drawn = drawn_measurements(mix, 5)
    assert drawn == drawn_measurements(mix, 5) and drawn != drawn_measurements(mix, 6)
    fixed = CaseSpec(0, 0, "two_bolt", NONE)
    assert all(replace(d, quantity=fixed.quantity, sensed=fixed.sensed, df_hz=fixed.df_hz) == s
               for d, s in zip(drawn, mix))
    assert {(d.sensed, d.quantity) for d in drawn} == set(MEASUREMENTS)
    assert {d.df_hz for d in drawn} == set(LINE_SPACINGS_HZ)
    spec = drawn[0]
    settings = spec.settings()
    assert (settings.quantity, settings.sensed, settings.df_hz) == (spec.quantity, spec.sensed, spec.df_hz)


def test_paper_designs():
    factors, tests = design_of("paper", proving_frame("two_bolt"))
    assert len(tests) == 18 and [f.joint for f in factors[1:]] == ["A", "B"]
    assert tests[1] == {"amplitude": "low", "bolt_A": "1", "bolt_B": "2"}
    factors, tests = design_of("paper", proving_frame("four_bolt"))
    assert len(tests) == 17 and tests[-1]["bolt_D"] == "2" and tests[1]["bolt_A"] == "3"
    _, tests = design_of("blind", proving_frame("two_bolt"))
    assert [t["amplitude"] for t in tests] == ["low", "high"] * 4


# ------------------------------------------------------------------------------------- mechanisms

@pytest.fixture(scope="module")
def two_bolt():
    frame = proving_frame("two_bolt")
    return frame, Article(frame), article_frequencies(Article(frame))


def _shift(article: Article, reference: np.ndarray) -> np.ndarray:
    f = article_frequencies(article, 14)
    return np.array([f[np.argmin(np.abs(np.log(f / r)))] / r - 1 for r in reference])


@pytest.mark.parametrize("variant", ["spread_mass", "eccentric_mass"])
def test_added_mass_lowers(two_bolt, variant):
    frame, base, f0 = two_bolt
    mech = vocabulary_mechanism(frame, "added_mass", np.random.default_rng(1), variant=variant)
    shift = _shift(mech.build(base, 0.05), f0)
    assert np.all(shift <= 1e-9) and shift.min() < -1e-3


@pytest.mark.parametrize("effect, variant, low, high, sign", [
    ("support_compliance", "coupled_support", 0.01, 1.0, -1),  # a looser clamp lowers
    ("stinger_stiffness", "stinger_rod", 1e3, 5e4, 1),  # a stiffer suspension raises
    ("axial_prestress", "misfit_strut", 1e-8, 1e-4, 1),  # tension raises
    ("axial_prestress", "misfit_tie", 1e-8, 1e-3, -1),  # compression lowers
    ("joint_stiffness_shift", "joint_hinge", 1e-4, 1.0, -1),
    ("joint_stiffness_shift", "joint_subzone_soft", 1e-4, 1.0, -1),
    ("joint_stiffness_shift", "joint_subzone_stiff", 1e-4, 1.0, 1),
])
def test_mechanisms_move_frequencies_the_physical_way(two_bolt, effect, variant, low, high, sign):
    frame, base, _ = two_bolt
    mech = vocabulary_mechanism(frame, effect, np.random.default_rng(2), variant=variant)
    shift = _shift(mech.build(base, high), article_frequencies(mech.build(base, low)))
    assert np.all(sign * shift >= -1e-7), shift
    assert np.max(sign * shift) > 5e-4, shift


def test_tension_raises_the_bending_modes_of_that_member_most(two_bolt):
    frame, base, _ = two_bolt
    mech = vocabulary_mechanism(frame, "axial_prestress", np.random.default_rng(2), "beam", "misfit_strut")
    d = discretise(mech.build(base, 1e-8))
    modes = solve_modes(d.system.stiffness, d.system.mass, 10)
    shift = _shift(mech.build(base, 1e-4), modes.frequency_hz)
    # modes the beam's bending dominates: the mid-beam sensor (uy) moves most of all sensors
    motion = modes.shapes[d.system.responses] ** 2
    beam_bending = motion[[s.name for s in frame.sensors].index("mid_beam")] / motion.sum(axis=0) > 0.5
    assert beam_bending.any() and np.all(shift > -1e-9)
    assert shift[beam_bending].max() == shift.max()


def test_amplitude_softening_is_zero_at_the_lowest_level_and_lowers_at_the_highest(two_bolt):
    frame, base, f0 = two_bolt
    law = Softening("A", 0.05, 0.6)
    assert law.factor(1.0) == 1.0 and law.factor(5.0) == pytest.approx(0.95)
    assert law.factor(3.0) < 1 - 0.05 * 0.5  # sub-linear: more than half the drop half the way up
    mech = vocabulary_mechanism(frame, "amplitude_softening", np.random.default_rng(3))
    article = mech.build(base, 0.1)
    np.testing.assert_array_equal(article_frequencies(article, amplitude=1.0), f0)
    assert np.all(article_frequencies(article, amplitude=5.0) <= f0 + 1e-9)


def test_temperature_lowers_every_frequency(two_bolt):
    frame, base, f0 = two_bolt
    d = discretise(base, {j.name: j.youngs_modulus for j in frame.joints}, 1.0 - 3e-4 * 5.0)
    warm = solve_modes(d.system.stiffness, d.system.mass, 10).frequency_hz
    # every modulus 0.15 % lower (5 K): at most sqrt(1 - 1.5e-3) - 1 = -7.5e-4, less where springs carry energy
    shift = warm / f0 - 1
    assert np.all((shift < 0) & (shift >= math.sqrt(1 - 1.5e-3) - 1 - 1e-12))


@pytest.mark.parametrize("variant", OUTSIDE_VARIANTS)
def test_outside_mechanisms_build_and_grow(two_bolt, variant):
    frame, base, f0 = two_bolt
    mech = outside_mechanism(frame, np.random.default_rng(4), variant)
    lo, hi = mech.bounds
    small = np.max(np.abs(_shift(mech.build(base, lo), f0)))
    large = np.max(np.abs(_shift(mech.build(base, lo ** 0.25 * hi ** 0.75), f0)))
    assert small < large and large > 1e-3


def test_calibration_hits_the_footprint(two_bolt):
    frame, base, _ = two_bolt
    mech = vocabulary_mechanism(frame, "joint_stiffness_shift", np.random.default_rng(5), "A", "joint_hinge")
    x, reached = calibrate(base, mech, 0.01)
    assert abs(reached / 0.01 - 1) <= 0.05 and mech.parameters(x)["factor"] < 1
    stocky = vocabulary_mechanism(frame, "shear_deformation", np.random.default_rng(5))
    x, reached = calibrate(base, stocky, 0.01)
    assert abs(reached / 0.01 - 1) <= 0.05 and x > 1 and stocky.nominal(frame, x).beam_theory == "euler-bernoulli"


def test_the_footprint_counts_only_the_modes_the_band_holds(two_bolt):
    # a shift above the campaign's band is never measured: a "large" case must be large in the band
    frame, base, _ = two_bolt
    mech = vocabulary_mechanism(frame, "support_compliance", np.random.default_rng(5))
    x = mech.bounds[0] ** 0.5 * mech.bounds[1] ** 0.5
    f0, f1 = article_frequencies(base), article_frequencies(mech.build(base, x))
    f_max = 0.5 * (f0[2] + f0[3])
    expected = float(np.max(np.abs(f1[:3] / f0[:3] - 1.0)))  # the first three modes, in order
    assert footprint(base, mech, x, f_max_hz=f_max) == pytest.approx(expected, rel=1e-9)
    assert footprint(base, mech, x) == pytest.approx(float(np.max(np.abs(f1 / f0 - 1.0))), rel=1e-9)
    x, reached = calibrate(base, mech, 0.01, f_max_hz=f_max)
    assert abs(reached / 0.01 - 1) <= 0.05
    assert np.max(np.abs(article_frequencies(mech.build(base, x))[:3] / f0[:3] - 1.0)) == pytest.approx(reached)


def test_the_footprint_skips_a_mode_whose_resonance_the_band_cuts(two_bolt):
    # a mode just under the band's top has its half-power band cut: no extraction reads it, so a case's
    # footprint must not sit there (seeds 24-27: "large" joint damping carried by a mode 1.6 % under the top)
    frame, base, _ = two_bolt
    mech = vocabulary_mechanism(frame, "support_compliance", np.random.default_rng(5))
    x = mech.bounds[0] ** 0.5 * mech.bounds[1] ** 0.5
    f0, f1 = article_frequencies(base), article_frequencies(mech.build(base, x))
    shift = np.abs(f1 / f0 - 1.0)
    cut, held = f0[3] * (1.0 + 0.5 * EDGE_SHARE), f0[3] * (1.0 + 2.0 * EDGE_SHARE)
    assert footprint(base, mech, x, f_max_hz=cut) == pytest.approx(float(shift[:3].max()), rel=1e-9)
    assert footprint(base, mech, x, f_max_hz=held) == pytest.approx(float(shift[:4].max()), rel=1e-9)
    assert measurable_top_hz(1250.0) == pytest.approx(1250.0 / (1.0 + EDGE_SHARE))


def test_the_measurable_margin_holds_the_proving_grounds_largest_damping():
    # the half-power half-width of a mode at the band's top, at the nuisances' largest damping level and trend
    # plus the large damping rung, must fit in the margin the footprint leaves
    from workbench.proving.nuisances import NuisanceSettings
    nuisances, top_hz = NuisanceSettings(), CampaignSettings().f_max_hz
    largest = nuisances.damping_range[1] * (top_hz / 100.0) ** nuisances.damping_trend_range[1]
    assert largest + DAMPING_FOOTPRINTS["large"] <= EDGE_SHARE


def test_a_case_is_read_at_the_rung_its_footprint_reached():
    for ladder, channel in ((FOOTPRINTS, "frequency"), (DAMPING_FOOTPRINTS, "damping")):
        for level, value in ladder.items():
            assert reached_level(value, channel) == level
            assert reached_level(value * 1.5, channel) == level  # nearer its own rung than the next (x 3.33, x 3)
        assert reached_level(ladder["medium"] * 2.0, channel) == "large"  # sqrt(1/3 * 1) apart: past the middle
        assert reached_level(0.49 * ladder["small"], channel) == FAINT
        assert reached_level(0.51 * ladder["small"], channel) == "small"
    assert reached_level(float("nan"), "frequency") == FAINT


def test_a_wire_tie_capped_by_its_strength_is_faint_not_medium():
    # the stocky portal's members are so stiff that a tie pulled to its strength moves the band's modes by
    # about 0.1 %: the case asks for 1 %, and its truth and score must say what it reached
    _, truth = case_campaign(CaseSpec(0, 1, "stocky_portal", "axial_prestress", "medium", "misfit_tie",
                                             "right_column"))
    primary = truth["primary"]
    assert primary["target_footprint"] == 0.01 and primary["footprint"] < 0.5 * FOOTPRINTS["small"]
    assert reached_level(primary["footprint"], primary["channel"]) == FAINT
    shift = np.asarray(truth["article_hz"]) / article_frequencies(Article(proving_frame("stocky_portal"))) - 1.0
    assert np.max(np.abs(shift[:7])) < 0.5 * FOOTPRINTS["small"]  # the article itself: no 1 % anywhere in the band


def test_every_variant_is_known():
    assert sum(len(v) for v in VARIANTS.values()) == 12 and set(VARIANTS) == set(EFFECTS)


@pytest.mark.parametrize("name", BUNDLED)
def test_bundled_frames_are_the_repository_files(name):
    # built, not read (an installed package has no frames/ beside it), and yet what the file says in every field
    built = proving_frame(name)
    read = read_frame(REPO / "frames" / f"{name}.toml")
    assert replace(built, source="") == replace(read, source="")


def test_the_installed_package_builds_every_frame(tmp_path):
    # outside the repository, the package as installed (`pip install .` copies no frames/): validate-diagnosis
    # read frames/*.toml beside the package and failed on every install but an editable one
    code = ("from workbench.proving.frames import FRAME_NAMES, proving_frame; "
            "print(len([proving_frame(n) for n in FRAME_NAMES]))")
    done = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == str(len(FRAME_NAMES))


# ------------------------------------------------------------------------------------- the workbench reads it

def test_no_effect_campaign_gives_the_article_frequencies_through_the_circle_fit():
    from workbench.workflow.measured import measured_modes  # the consumer; the package never imports it

    frame = proving_frame("two_bolt")
    nominal = replace(frame, beam_theory="timoshenko", joints=tuple(replace(j, cov=0.0) for j in frame.joints))
    factors, tests = design_of("blind", frame)
    laws = {j.name: (j.youngs_modulus, 0.02) for j in frame.joints}
    campaign, truth = simulate_campaign(nominal, Article(frame), factors, tests[:3], laws, 7,
                                        CampaignSettings(f_max_hz=600.0))
    measured = measured_modes(campaign, None, "diagnose")
    true = np.array([t["frequency_hz"] for t in truth["tests"]])
    found = measured.frequency_hz
    assert found.shape == (3, 6)
    rel = np.abs(found / true[:, :6] - 1)
    assert np.nanmax(rel) < 5e-4  # the nuisances' scatter between tests is 2e-4 to 1e-3
    assert np.all(np.isfinite(found))


def test_a_campaigns_manufacturing_record_rebuilds_its_as_built_frame():
    # a benchmark's diagnosis fits the as-built frame from the truth's record (benchmarks/bayes_bias_source.py):
    # the record must give back the frame the campaign was simulated on, and each member's I move as b t^3
    from workbench.proving.nuisances import NuisanceSettings, built_frame, perturb_frame

    frame = proving_frame("four_bolt")
    built, record = perturb_frame(frame, NuisanceSettings(), np.random.default_rng(7))
    assert built_frame(frame, json.loads(json.dumps(record))) == built  # through JSON, as the truth is stored
    for member in frame.members:
        b, t = record["sections"][member.name]["width_factor"], record["sections"][member.name]["thickness_factor"]
        nominal, made = frame.sections[member.section], built.sections[f"{member.section}@{member.name}"]
        assert math.isclose(made.second_moment / nominal.second_moment, b * t**3, rel_tol=1e-12)
        assert 0.98 < b * t**3 < 1.02 and (b, t) != (1.0, 1.0)
