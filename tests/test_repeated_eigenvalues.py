"""Repeated eigenvalues (issue 19): a square frame's symmetric pairs and a free-free beam's rigid modes.

Before, SMR2 and the adaptive strategy wrote inf and nan there and Pert2 absurd values, all with
exit 0. Now SMR works on the shared subspace, judged against Monte Carlo full solves (whose tracking
orders a split pair by frequency), and Pert2 refuses naming the modes.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import dump_toml, error_lines, run_cli

from workbench.model.assembly import assemble
from workbench.model.frame_file import parse_frame
from workbench.model.modal import model_modes, shared_eigenvalues
from workbench.uq.smr import propagate
from workbench.uq.stochastic import joint_model, monte_carlo

L = 0.4
SQUARE = {
    "name": "square frame, a joint mid-span on each side", "element_length": 0.02,
    "materials": {"al": {"youngs_modulus": 70e9, "density": 2700.0}},
    "sections": {"s": {"area": 2.4e-4, "second_moment": 1.28e-9}},
    "points": {"a": [0.0, 0.0], "b": [L, 0.0], "c": [L, L], "d": [0.0, L]},
    "members": [{"name": n, "start": s, "end": e, "material": "al", "section": "s"}
                for n, s, e in (("ab", "a", "b"), ("bc", "b", "c"), ("cd", "c", "d"), ("da", "d", "a"))],
    "joints": [{"name": f"J{n}", "member": n, "span": [0.18, 0.22], "youngs_modulus": 30e9, "cov": 0.1}
               for n in ("ab", "bc", "cd", "da")],
    "supports": [{"point": p, "ux": "fixed", "uy": "fixed"} for p in "abcd"],
    "excitation": {"point": "a", "dof": "rz"},
    "sensors": [{"name": "corner", "point": "b", "dof": "rz"}],
}


@pytest.fixture(scope="module")
def square():
    frame = parse_frame(SQUARE)
    return assemble(frame), joint_model(frame)


@pytest.fixture(scope="module")
def square_mc(square):
    model, joints = square
    return model, joints, monte_carlo(model, joints, 8, 2000, seed=3)  # 20 s: the slow checks only


def test_the_square_frame_has_symmetric_pairs():
    # four-fold symmetry: two-dimensional irreducible representations, so pairs of equal eigenvalues
    groups = shared_eigenvalues(model_modes(assemble(parse_frame(SQUARE)), 8), 8)
    assert [list(g) for g in groups] == [[1, 2], [5, 6]]


@pytest.mark.slow
@pytest.mark.parametrize("method", ["smr1", "smr2", "adaptive"])
def test_smr_on_the_shared_subspace_agrees_with_monte_carlo(square_mc, method):
    model, joints, mc = square_mc
    result = propagate(model, joints, method, count=8)
    mean_se, std_se = mc.standard_errors()
    assert np.all(np.isfinite(result.mean_hz)) and np.all(np.isfinite(result.std_hz))
    # the pair splits: lower and upper partner, as Monte Carlo sees them (tracked within the subspace)
    assert result.mean_hz[1] < result.mean_hz[2] and mc.moments.mean_hz[1] < mc.moments.mean_hz[2]
    assert mc.min_mac.min() > 0.9
    # SMR1-level accuracy at CoV 0.1 (its std error is up to 1.9 D_k = 2 % on distinct modes)
    np.testing.assert_allclose(result.mean_hz, mc.moments.mean_hz, rtol=2e-3)
    assert np.all(np.abs(result.std_hz - mc.moments.std_hz) <= 0.1 * mc.moments.std_hz + 4 * std_se)


def test_rigid_body_modes_of_a_free_free_beam_are_zero_with_no_spread():
    frame = parse_frame({**{k: v for k, v in SQUARE.items() if k not in ("supports", "joints")},
                         "points": {"a": [0.0, 0.0], "b": [0.5, 0.0]},
                         "members": [{"name": "m", "start": "a", "end": "b", "material": "al", "section": "s"}],
                         "joints": [{"name": "J", "member": "m", "span": [0.2, 0.24], "youngs_modulus": 30e9,
                                     "cov": 0.1}],
                         "excitation": {"point": "a", "dof": "uy"},
                         "sensors": [{"name": "end", "point": "b", "dof": "uy"}]})
    model = assemble(frame)
    mc = monte_carlo(model, joint_model(frame), 5, 400, seed=1)
    for method in ("smr1", "smr2", "adaptive"):
        result = propagate(model, joint_model(frame), method, count=5)
        assert result.mean_hz[:3] == pytest.approx([0, 0, 0], abs=1e-3)
        np.testing.assert_allclose(result.mean_hz[3:], mc.moments.mean_hz[3:], rtol=3e-3)


def test_pert2_refuses_a_repeated_eigenvalue_naming_the_modes(tmp_path):
    (tmp_path / "square.toml").write_text(dump_toml(SQUARE))
    code, err = run_cli(["propagate", str(tmp_path / "square.toml"), "--method", "pert2", "--count", "8",
                         "--out", str(tmp_path / "out")])
    assert code == 2
    [line] = error_lines(err)
    assert "modes 2 and 3" in line and "--method" in line
    assert not (tmp_path / "out").exists()


def test_smr1_solves_past_its_last_mode_only_when_a_pair_straddles_the_cut(square, monkeypatch):
    from workbench.uq import smr

    model, joints = square
    assert model.size > smr.DENSE_LIMIT  # the Sturm-count path, not the dense one
    full = propagate(model, joints, "smr1", count=8)
    solved = []
    real = smr.sensitivities
    monkeypatch.setattr(smr, "sensitivities", lambda *a, **k: solved.append(k.get("extra", smr.EXTRA_MODES))
                        or real(*a, **k))
    # modes 6 and 7 (1-based) share an eigenvalue: cut between them, the pair is solved whole
    cut = smr.smr1(model, joints, 6)
    assert solved == [0, smr.EXTRA_MODES]
    np.testing.assert_allclose(cut.mean_hz, full.mean_hz[:6], rtol=1e-12)
    np.testing.assert_allclose(cut.std_hz, full.std_hz[:6], rtol=1e-9)
    # cut after mode 5, nothing shared: no extra mode, the same moments, no proximity factor for the last
    solved.clear()
    safe = smr.smr1(model, joints, 5)
    assert solved == [0]
    np.testing.assert_allclose(safe.mean_hz, full.mean_hz[:5], rtol=1e-12)
    np.testing.assert_allclose(safe.std_hz, full.std_hz[:5], rtol=1e-9)
    assert safe.proximity is not None and np.isnan(safe.proximity[-1]) and np.all(np.isfinite(safe.proximity[:-1]))
