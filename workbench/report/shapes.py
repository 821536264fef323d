"""The report's mode shapes and MAC: measured modal constants at the sensors against the nominal model's.

The numbers come from `workbench.workflow.report_inputs.shape_comparison`; the figures from
`workbench.report.plots` (`shape_figure`, `mac_figure`); this module writes the section's HTML and
registers its tables (`workbench.report.tables.Tables`).
"""

from __future__ import annotations

import html

import numpy as np

from workbench.report.pieces import absent, html_figure
from workbench.report.plots import mac_figure, shape_figure
from workbench.report.tables import Tables
from workbench.workflow.report_inputs import ShapeComparison, shape_comparison, usable_constants
from workbench.workflow.study import Study

__all__ = ["study_shapes", "shapes_section"]

CAPTION = ("Measured modal constants (receptance form, 1/kg) at each sensor: every test's complex vector of a mode "
           "turned to its dominant phase (the rotation that puts the most of its energy on the real axis), its "
           "real part kept, and the tests averaged (signed alike; a sensor's fit with too few points or cut by "
           "the band's edge is left out); the model's counterpart is phi(sensor) phi(excitation) of the nominal "
           "modes (joints at their mean). Both scaled to a peak of 1.")


def study_shapes(study: Study) -> tuple[ShapeComparison | None, str]:
    """The study's shape comparison, or None with the reason it is absent."""
    ex = study.extraction
    if ex is None:
        return None, "no circle fit of FRFs in this report, so no measured modal constants per sensor."
    sensors = next(iter(ex.sets.values())).responses
    comparison = shape_comparison(study.campaign, study.data, sensors, constants=usable_constants(ex))
    if comparison is None:
        return None, ("the tests do not share one set of at least two sensors, or the frame has no excitation: "
                      "no shape to compare.")
    return comparison, ""


def shapes_section(study: Study, tables: Tables, prefix: str) -> str:
    """The section's HTML: shape figure, MAC figure, the MAC table and the shapes table.

    Parameters
    ----------
    study : a campaign's study; tables : the page's tables, to which ``{prefix}mac`` and
        ``{prefix}shapes`` are added.
    """
    shapes, reason = study_shapes(study)
    if shapes is None:
        return absent(reason)
    model_cols = [f"model {m} ({f:.1f} Hz) MAC (-)" for m, f in zip(shapes.model_modes, shapes.model_hz)]
    mac_rows = [(int(m), *(float(v) for v in row)) for m, row in zip(shapes.modes, shapes.mac)]
    mac_table = tables.add(f"{prefix}mac", ["measured mode", *model_cols], mac_rows,
                           ["", *(".3f",) * len(model_cols)], left=0)
    shape_rows = []
    for k, m in enumerate(shapes.modes):
        model = shapes.model[shapes.paired[k]]
        for s, sensor in enumerate(shapes.sensors):
            shape_rows.append((int(m), int(shapes.model_modes[shapes.paired[k]]), sensor,
                               float(shapes.measured[k, s]), float(model[s]), int(shapes.tests[k])))
    shape_table = tables.add(f"{prefix}shapes", ["measured mode", "model mode", "sensor",
                                                 "measured constant, real (1/kg)", "model constant (1/kg)",
                                                 "tests averaged"],
                             shape_rows, ["", "", "", ".4g", ".4g", ""], left=0)
    diagonal = [float(shapes.mac[k, shapes.paired[k]]) for k in range(shapes.modes.size)]
    worst = int(np.nanargmin(diagonal)) if np.isfinite(diagonal).any() else 0
    note = (f"MAC of each measured mode with the model mode it is paired with (by order): "
            f"{', '.join(f'{d:.2f}' for d in diagonal)}; lowest for mode {shapes.modes[worst]}. A MAC near 1 off "
            "the pairing would say the modes are paired wrongly.")
    return (html_figure(shape_figure(shapes), CAPTION, "measured and model mode shapes at the sensors")
            + html_figure(mac_figure(shapes), "MAC matrix, measured modes (rows) against the nominal model's "
                           "elastic modes (columns), on the sensors' modal constants (real parts as in the shapes "
                           "figure).", "MAC matrix test against model")
            + mac_table + f'<p class="note">{html.escape(note)}</p>' + shape_table)
