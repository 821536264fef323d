"""The FRF-level channel's as-built error (`workbench.diagnose.frf_levels`, ``L L^T``) against another code's
as-built frames.

The judge is the proving ground (`workbench.proving`), whose elements, mesh and nuisance law the diagnosis does
not share: its stocky portal, a frame with two modes 8 % apart, built within the allowance the diagnosis states
(each member end's x and y off by 0.5 mm, each bar's width and thickness by 0.3 %), its modal constants solved
by its own FEM, read exactly (no extraction error) against the workbench's nominal model. Two close modes mix
their shapes under such errors and their levels at the sensors move by several percent; the floor alone reads
that as a contradiction of the nominal model itself, the as-built columns hold it.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.stats import chi2 as chi2_law

from workbench.diagnose.baseline import Baseline
from workbench.diagnose.frf_levels import LEVEL_ALPHA, MeasuredLevels, as_built_constants, level_test, track
from workbench.diagnose.geometry import stepped_models
from workbench.diagnose.observations import DEFAULT_ALLOWANCE
from workbench.model.structure import receptance_constants, response_dofs, structure_modes, structure_of
from workbench.proving.article import Article
from workbench.proving.beams import solve_modes
from workbench.proving.fem import discretise
from workbench.proving.frames import proving_frame
from workbench.proving.geometry import perturb_geometry
from workbench.proving.nuisances import NuisanceSettings, perturb_frame

MODES = 8


def _proving_constants(article: Article) -> tuple[np.ndarray, np.ndarray]:
    """The proving ground's receptance modal constants (modes, sensors) of ``article`` and its frequencies, Hz."""
    d = discretise(article, {j.name: j.youngs_modulus for j in article.frame.joints})
    modes = solve_modes(d.system.stiffness, d.system.mass, MODES + 3)
    return (modes.shapes[d.system.responses] * modes.shapes[d.system.excitation]).T, modes.frequency_hz


def test_an_as_built_frame_within_the_allowance_does_not_contradict_its_nominal_levels():
    frame = replace(proving_frame("stocky_portal"), beam_theory="timoshenko")
    model = structure_of(frame)
    modes = structure_modes(model, MODES + 3)
    sensors = tuple(response_dofs(model)[2])
    nominal = receptance_constants(model, modes.shapes, sensors)
    base = Baseline(frame, model, modes, np.arange(MODES), np.ones(MODES + 3), MODES + 3)
    as_built = as_built_constants(nominal, modes.frequency_hz, sensors, stepped_models(base, DEFAULT_ALLOWANCE))
    as_built = as_built[:, :MODES]
    rng = np.random.default_rng(1)
    with_columns, floor_only = [], []
    for _ in range(20):
        built, _ = perturb_frame(proving_frame("stocky_portal"), NuisanceSettings(), rng)
        article, _ = perturb_geometry(Article(built), DEFAULT_ALLOWANCE.geometry_sd_m, rng)
        constants, hz = _proving_constants(article)
        constants = constants[track(nominal[:MODES], modes.frequency_hz[:MODES], constants, hz)]
        a0 = nominal[:MODES]
        level = np.abs(np.einsum("ij,ij->i", constants, a0)) / np.einsum("ij,ij->i", a0, a0)
        measured = MeasuredLevels(level, np.full(MODES, 1e-3), np.ones(MODES), np.ones((MODES, len(sensors)), bool))
        for out, columns in ((with_columns, as_built), (floor_only, None)):
            test = level_test(measured, a0, a0, np.arange(1, MODES + 1), columns)
            assert test is not None
            out.append(test.nominal_chi2)
    dof = MODES - 1
    # with the as-built columns the nominal levels always stand; with the floor alone the close modes' mixing
    # passes the 1 % level in some frames, and the chi-square is ten times larger on average
    assert max(with_columns) < chi2_law.isf(LEVEL_ALPHA, dof)
    assert np.mean(with_columns) < dof and np.mean(floor_only) > 5 * np.mean(with_columns)
    assert max(floor_only) > chi2_law.isf(LEVEL_ALPHA, dof)
