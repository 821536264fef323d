"""Checks of a frame as a whole, after its tables are read: one piece, a mesh that round-off spares, SI units.

A frame that falls into two pieces, or whose members are cut into so many elements that the lowest
eigenvalues drown in round-off, is refused (`FrameFileError`); values outside the ranges a lab
article can have (a modulus of 70 Pa is 70 GPa written in GPa) only warn (`UnitsWarning`), because an
unusual structure may be meant.
"""

from __future__ import annotations

import math
import warnings

from workbench.model.frame import DOF_NAMES, Frame, FrameFileError, member_length, points_on_member

__all__ = ["UnitsWarning", "UNIT_RANGES", "MAX_ELEMENTS_PER_MEMBER", "check_frame", "units_warnings"]


class UnitsWarning(UserWarning):
    """A frame value outside the physical range of a lab article: most often a unit that is not SI."""


# field -> (low, high, SI unit, the slip the range catches). Bounds hold every lab article we know of
# with a wide margin: foams and rubbers to diamond, a 1 mm stub to a 50 m girder, a 0.1 g
# accelerometer to a 5 t mass; a value outside is a unit slip far more often than a real structure.
UNIT_RANGES: dict[str, tuple[float, float, str, str]] = {
    "youngs_modulus": (1e5, 1.5e12, "Pa", "a modulus in GPa or MPa"),
    "density": (50.0, 25_000.0, "kg/m3", "a density in g/cm3"),
    "area": (1e-9, 1.0, "m2", "an area in mm2 or cm2"),
    "second_moment": (1e-18, 1.0, "m4", "a second moment in mm4"),
    "length": (1e-3, 50.0, "m", "coordinates in mm"),
    "mass": (1e-5, 5e3, "kg", "a mass in g"),
}

# Elements of one member. The lowest eigenvalue's round-off grows as the fourth power of the count
# (K's condition number): measured on a clamped Euler-Bernoulli beam, 4200 elements give the first
# frequency within 3e-6 of the closed form, 10 000 within 4e-3, and from 15 000 round-off makes K
# indefinite. Coordinates written in mm with the default element length land far beyond.
MAX_ELEMENTS_PER_MEMBER = 5000


def check_frame(frame: Frame) -> None:
    """Refuse a frame in several pieces or with a member too finely cut; warn on values outside `UNIT_RANGES`.

    Raises
    ------
    FrameFileError
        One line naming the file, the field and the problem.
    """
    _check_one_piece(frame)
    _check_elements_per_member(frame)
    for message in units_warnings(frame):
        warnings.warn(message, UnitsWarning, stacklevel=3)


def _check_one_piece(frame: Frame) -> None:
    """Each piece of the frame is held: a member joined to nothing held would float as a free rigid body.

    One free-free piece (no supports) is a valid test set-up; two cantilevers clamped apart are too.
    """
    on_member = {m.name: set(points_on_member(frame.points, m)) for m in frame.members}
    pieces: list[set[str]] = []
    for m in frame.members:
        if any(m.name in piece for piece in pieces):
            continue
        piece, todo = {m.name}, [m.name]
        while todo:  # breadth-first over members that share a point
            here = on_member[todo.pop()]
            for other in frame.members:
                if other.name not in piece and on_member[other.name] & here:
                    piece.add(other.name)
                    todo.append(other.name)
        pieces.append(piece)
    if len(pieces) == 1:
        return
    held = {s.point for s in frame.supports if any(s.stiffness(d) is not None for d in DOF_NAMES)}
    held |= {s.point for s in frame.springs}
    for piece in pieces:
        if not any(on_member[name] & held for name in piece):
            i, m = next((i, m) for i, m in enumerate(frame.members) if m.name in piece)
            raise FrameFileError(
                f"{frame.source}: members[{i}]: member {m.name!r} ({m.start} to {m.end}) shares no point with "
                f"the rest of the frame and has no support or spring: it would float as a free rigid body "
                "(members connect only at named points)")


def _check_elements_per_member(frame: Frame) -> None:
    for i, m in enumerate(frame.members):
        length = member_length(frame, m)
        count = math.ceil(length / frame.element_length)
        if count > MAX_ELEMENTS_PER_MEMBER:
            raise FrameFileError(
                f"{frame.source}: members[{i}]: member {m.name!r} is {length:g} m long, which element_length "
                f"{frame.element_length:g} m cuts into {count} elements (at most {MAX_ELEMENTS_PER_MEMBER}, "
                "beyond which round-off swamps the lowest modes); are the coordinates in mm? They are in m")


def units_warnings(frame: Frame) -> list[str]:
    """One message per value outside `UNIT_RANGES`, naming the file and the field."""
    messages: list[str] = []

    def check(where: str, kind: str, value: float) -> None:
        low, high, unit, slip = UNIT_RANGES[kind]
        if value > 0 and not low <= value <= high:
            messages.append(f"{frame.source}: {where}: {value:g} {unit} is outside {low:g}-{high:g} {unit} "
                            f"expected of a lab article; {slip}? The frame file is in SI units")

    for name, mat in frame.materials.items():
        check(f"materials.{name}.youngs_modulus", "youngs_modulus", mat.youngs_modulus)
        check(f"materials.{name}.density", "density", mat.density)
    for name, sec in frame.sections.items():
        check(f"sections.{name}.area", "area", sec.area)
        check(f"sections.{name}.second_moment", "second_moment", sec.second_moment)
    for i, m in enumerate(frame.members):
        check(f"members[{i}] ({m.name!r}, from [points])", "length", member_length(frame, m))
    for i, j in enumerate(frame.joints):
        check(f"joints[{i}].youngs_modulus", "youngs_modulus", j.youngs_modulus)
    for i, pm in enumerate(frame.masses):
        check(f"masses[{i}].mass", "mass", pm.mass)
    return messages
