"""The gap test along the frame's own toleranced columns (`workbench.diagnose.allowance`): its level under the
stated allowance, its power against one column built several allowances off, and its columns' names."""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2 as chi2_law
from scipy.stats import ncx2
from test_diagnosis import ONE_BOLT, _deterministic

from workbench.diagnose.allowance import allowance_evidence
from workbench.diagnose.baseline import Baseline
from workbench.diagnose.decision import GAP_LEVEL
from workbench.diagnose.geometry import column_names, geometry_columns, section_columns
from workbench.diagnose.observations import Discrepancy, Observations
from workbench.model.assembly import assemble
from workbench.model.frame import moved_frame
from workbench.model.modal import model_modes


def test_the_names_say_which_member_end_and_section_each_column_moves():
    # each named column is the modes' change when that point moves, or that member's property changes, alone
    frame = _deterministic(ONE_BOLT)
    model = assemble(frame)
    modes = model_modes(model, 6)
    base = Baseline(frame, model, modes, np.arange(6), np.ones(6), 6)
    sd = 5e-4
    geometry, sections = geometry_columns(base, sd), section_columns(base, 0.01, 0.005)
    names = column_names(frame, 0.01, 0.005)
    assert (len(names[0]), len(names[1])) == (geometry.shape[1], sections.shape[1])
    assert len(set(names[0] + names[1])) == len(names[0]) + len(names[1])
    rng = np.random.default_rng(2)
    for k in rng.choice(len(names[0]), 3, replace=False):
        point, axis = names[0][k].rsplit(".", 1)
        step = (1e-4, 0.0) if axis == "x" else (0.0, 1e-4)
        moved = model_modes(assemble(moved_frame(frame, {point: step})[0]), 6).frequency_hz
        np.testing.assert_allclose(geometry[:, k] * 1e-4 / sd, moved / modes.frequency_hz - 1.0, rtol=1e-6, atol=1e-12)
    assert names[1][0] == f"{frame.members[0].name}.second_moment"
    assert names[1][len(frame.members)] == f"{frame.members[0].name}.area"
    assert column_names(frame, 0.01, 0.0)[1] == tuple(f"{m.name}.second_moment" for m in frame.members)


def _campaign(columns: np.ndarray, names: tuple[str, ...], se: float) -> Observations:
    n_cond, n_modes = 2, columns.shape[0]
    f = np.tile(np.linspace(50.0, 900.0, n_modes), (n_cond, 1))
    d = Discrepancy(0.001, 0.0, 0.2, geometry=columns, geometry_names=names)
    return Observations(np.array([1.0, 5.0]), f, f * se, np.tile(np.eye(n_modes) * se ** 2, (n_cond, 1, 1)),
                        None, None, d)


def test_the_allowance_test_keeps_its_level_and_finds_a_column_built_off():
    # residuals drawn from the stated errors themselves (each column's factor ~ N(0, 1), the per-mode error, the
    # measurement) are flagged in at most GAP_LEVEL of the campaigns; one column's factor at 4.5 stated sds is
    # flagged at least as often as Bonferroni's bound over the columns says (non-central chi-square, one dof),
    # and that column named
    rng = np.random.default_rng(5)
    n_modes, k, se = 8, 6, 3e-4
    columns = 2e-3 * rng.standard_normal((n_modes, k))
    names = tuple(f"p{j}.x" for j in range(k))
    obs = _campaign(columns, names, se)
    f = obs.frequency_hz
    present, cov = obs.joint_covariance(np.ones(n_modes, bool))
    w = np.linalg.inv(cov)
    off = np.tile(columns[:, 2], 2)
    noncentral = 4.5 ** 2 * (off @ w @ off)  # the drop's non-centrality along column 2 at 4.5 sds
    draws, flagged, named = 200, {"null": 0, "off": 0}, 0
    for _ in range(draws):
        factor = rng.standard_normal(k)
        shared = columns @ factor + 1e-3 * rng.standard_normal(n_modes)  # as built and per-mode: both levels
        noise = shared[None, :] + se * rng.standard_normal((2, n_modes))
        for case, rel in (("null", noise), ("off", noise + 4.5 * columns[:, 2][None, :])):
            result = allowance_evidence(obs, f / (1.0 + rel))  # the model predicts f; the campaign measured f (1 + rel)
            hit = result["p_value"] < GAP_LEVEL
            flagged[case] += hit
            named += bool(case == "off" and hit and result["direction"] == "p2.x")
    assert flagged["null"] / draws <= GAP_LEVEL + 3 * np.sqrt(GAP_LEVEL / draws)
    bonferroni = ncx2.sf(chi2_law.isf(GAP_LEVEL / k, 1), 1, noncentral)
    assert 0.3 < bonferroni < 0.95  # a case the test can fail either way
    assert flagged["off"] / draws >= bonferroni - 3 * np.sqrt(bonferroni * (1 - bonferroni) / draws)
    assert named >= 0.8 * flagged["off"]
    assert allowance_evidence(_campaign(np.zeros((n_modes, 0)), (), se), f) is None
