"""The frame's geometry as a model-form error: how the measured modes move when a member end is off.

A frame file's coordinates were measured, not known. Each member end's x and y is taken as uncertain by
`workbench.diagnose.observations.GEOMETRY_SD`, independently; moving one by a small step in the nominal model
(`workbench.model.frame.moved_frame`: the points along a member and the joints' spans keep their fractions of
its length) and solving its modes again gives each measured mode's relative change, a column of the
`workbench.diagnose.observations.Discrepancy`'s ``geometry``. A bending mode moves as the inverse square of its
member's length, so half a millimetre on a 0.4 m frame is a few tenths of a percent, mode by mode: the
per-mode floor alone would read it as a gap.

Each member's **section** likewise (`section_columns`, since seed 25): its second moment of area known to
`workbench.diagnose.observations.SECOND_MOMENT_SD` and its area (mass per length and axial stiffness) to
`workbench.diagnose.observations.AREA_SD`, each member independently and the two independently of each other
(a flat bar's width and thickness would tie them; a frame's sections need not be flat bars). A bending mode
moves as the square root of I / A of the members it bends, so its columns carry a machined bar's tolerances
to the modes with the structure the per-mode floor lacks: the modes of one member move together.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, replace

import numpy as np

from workbench.diagnose.baseline import Baseline
from workbench.diagnose.observations import AREA_SD, GEOMETRY_SD, SECOND_MOMENT_SD, Allowance
from workbench.model.frame import Frame, member_ends, moved_frame
from workbench.model.modal import Modes
from workbench.model.structure import Structure, structure_modes, structure_of

__all__ = ["STEP_M", "STEP_RELATIVE", "Stepped", "stepped_models", "tolerance_columns", "geometry_columns",
           "section_columns", "column_names"]

STEP_M = 1e-4  # m, the forward difference's step: the change is linear over it to 1e-3 of itself
STEP_RELATIVE = 1e-4  # a section property's relative forward-difference step


@dataclass(frozen=True)
class Stepped:
    """The nominal model stepped along one toleranced column, solved once for every channel that reads it (the
    frequencies' columns here, the FRF levels' as-built error in `workbench.diagnose.frf_levels`).

    Attributes
    ----------
    name : the column (``<point>.x``, ``<member>.second_moment``, ...). kind : ``geometry`` or ``section``.
    factor : one stated sd over the step (scales a forward difference to one sd).
    model, modes : the stepped model and its first ``Baseline.count`` modes.
    """

    name: str
    kind: str
    factor: float
    model: Structure
    modes: Modes


def stepped_models(base: Baseline, allowance: Allowance) -> list[Stepped]:
    """The nominal model stepped along each toleranced column of ``allowance``, geometry first (the order of
    `column_names`); none for a matrix model (no geometry) or a tolerance of 0.
    """
    if not isinstance(base.frame, Frame):
        return []
    frame, (second_moment_sd, area_sd) = base.frame, allowance.section_sd
    steps = ([(name, moved, "geometry", allowance.geometry_sd_m / STEP_M) for name, moved in _geometry_steps(frame)]
             if allowance.geometry_sd_m > 0 else [])
    steps += [(name, moved, "section", sd / STEP_RELATIVE)
              for name, moved, sd in _section_steps(frame, second_moment_sd, area_sd)]
    out = []
    for name, moved, kind, factor in steps:
        model = structure_of(moved)
        out.append(Stepped(name, kind, factor, model, structure_modes(model, base.count)))
    return out


def tolerance_columns(base: Baseline, stepped: Sequence[Stepped]) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The frequencies' geometry columns (n_measured, 2 n_ends) and section columns (n_measured, k): each measured
    mode's relative frequency change per stated sd of each column of ``stepped``; None for a kind without
    columns.
    """
    def of(kind: str) -> np.ndarray | None:
        rows = [_change(base, s.modes.frequency_hz) * s.factor for s in stepped if s.kind == kind]
        return np.array(rows).T if rows else None

    return of("geometry"), of("section")


def geometry_columns(base: Baseline, sd_m: float = GEOMETRY_SD) -> np.ndarray | None:
    """(n_measured, 2 n_ends): each measured mode's relative frequency change per ``sd_m`` (m) of each member
    end's x and y, by forward differences on the nominal model; None for a matrix model (no geometry) or with
    ``sd_m`` 0.

    Each moved model's modes are paired with the baseline's paired modes by the nearest frequency in ratio
    (`_change`).
    """
    return tolerance_columns(base, stepped_models(base, Allowance(sd_m, (0.0, 0.0))))[0]


def section_columns(base: Baseline, second_moment_sd: float = SECOND_MOMENT_SD,
                    area_sd: float = AREA_SD) -> np.ndarray | None:
    """(n_measured, 2 n_members): each measured mode's relative frequency change per ``second_moment_sd`` of
    each member's second moment of area, then per ``area_sd`` of each member's area (relative sds), by forward
    differences on the nominal model (module docstring); a property whose sd is 0 has no columns (none solved);
    None for a matrix model or with both sds 0.

    A member gets its own copy of its section (``<section>@<member>``), so that members sharing a section in
    the file are toleranced independently; the area's step scales the member's mass and axial stiffness alike.
    """
    return tolerance_columns(base, stepped_models(base, Allowance(0.0, (second_moment_sd, area_sd))))[1]


def column_names(frame: Frame, second_moment_sd: float = SECOND_MOMENT_SD,
                 area_sd: float = AREA_SD) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """The names of `geometry_columns`' columns (``<point>.x``, ``<point>.y``) and of `section_columns`'
    (``<member>.second_moment``, then ``<member>.area``; a property whose sd is 0 has none), in their order.
    """
    return (tuple(name for name, _ in _geometry_steps(frame)),
            tuple(name for name, _, _ in _section_steps(frame, second_moment_sd, area_sd)))


def _geometry_steps(frame: Frame) -> Iterator[tuple[str, Frame]]:
    """Each geometry column's name and the frame with that member end moved by `STEP_M`: the one place that
    orders the columns, for them and their names.
    """
    for name in member_ends(frame):
        for axis, step in (("x", (STEP_M, 0.0)), ("y", (0.0, STEP_M))):
            yield f"{name}.{axis}", moved_frame(frame, {name: step})[0]


def _section_steps(frame: Frame, second_moment_sd: float, area_sd: float) -> Iterator[tuple[str, Frame, float]]:
    """Each section column's name, the frame with that member's property stepped by `STEP_RELATIVE` (on its own
    copy of its section), and the property's sd, in the columns' order (`_geometry_steps`).
    """
    for key, sd in (("second_moment", second_moment_sd), ("area", area_sd)):
        if sd <= 0:
            continue
        for i, member in enumerate(frame.members):
            section = frame.sections[member.section]
            own = f"{member.section}@{member.name}"
            stepped = replace(section, name=own, **{key: getattr(section, key) * (1.0 + STEP_RELATIVE)})
            members = list(frame.members)
            members[i] = replace(member, section=own)
            yield (f"{member.name}.{key}", replace(frame, sections={**frame.sections, own: stepped},
                                                     members=tuple(members)), sd)


def _change(base: Baseline, f: np.ndarray) -> np.ndarray:
    """(n_measured,) relative change of the baseline's paired modes in a stepped model of frequencies ``f``
    (Hz): each paired with its nearest mode in ratio (a small step moves no mode past its neighbour but in a
    pair closer than 1e-3, where the two are one mode to the pairing anyway).
    """
    f0 = base.modes.frequency_hz[base.pairing]
    nearest = f[np.argmin(np.abs(np.log(f[None, :] / f0[:, None])), axis=1)]
    return nearest / f0 - 1.0
