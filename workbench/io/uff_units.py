"""Units of a UFF dataset 58, from its axis labels and the file's units dataset 164 (CONTRACTS.md section 3).

Test software states units in two places: the units dataset 164 (a length and a force factor for
the whole file) and the axis labels of each record (record 8 abscissa, 9 ordinate numerator, 10
ordinate denominator: ``Hz``, ``mm/s^2``, ``g``, ``lbf``...). A record with neither is SI, the
format's default. Where a label and dataset 164 both speak, they must agree; labels that contradict
each other, or a units label that names no unit we know, are refused rather than guessed.
pyuff reads both places but converts nothing, hence this module.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any

__all__ = ["G_STANDARD", "Units", "file_units", "record_units"]

G_STANDARD = 9.80665  # m/s2 per g
_LENGTH = {"m": 1.0, "mm": 1e-3, "cm": 1e-2, "um": 1e-6, "µm": 1e-6, "in": 0.0254, "ft": 0.3048}
_FORCE = {"n": 1.0, "kn": 1e3, "mn": 1e-3, "lbf": 4.4482216152605, "lb": 4.4482216152605}
_ANGLE = {"rad": 1.0, "deg": math.pi / 180.0}
_PER_TIME = {"receptance": "", "mobility": "/s", "accelerance": "/s2"}
_FREQUENCY = {"hz": 1.0, "rad/s": 1.0 / (2.0 * math.pi), "rpm": 1.0 / 60.0, "cpm": 1.0 / 60.0}
_SILENT = {"", "none", "-", "?", "unknown"}


@dataclass(frozen=True)
class Units:
    """What multiplies a record's values into SI: ordinate numerator, denominator (force), abscissa (Hz)."""

    response: float = 1.0
    force: float = 1.0
    frequency: float = 1.0


def _normal(label: Any) -> str:
    text = str(label or "").strip().lower().replace(" ", "").replace("(", "").replace(")", "")
    text = text.replace("**", "").replace("^", "").replace("²", "2").replace("sec", "s")
    return re.sub(r"/s/s$", "/s2", text)


def file_units(sets: list[dict[str, Any]]) -> tuple[float, float] | None:
    """The SI factors ``(length, force)`` of the file's (last) units dataset 164, or None without one.

    Dataset 164 gives how many file units make one SI unit (mm: length 1000), so SI = value / factor.
    """
    found = None
    for dset in sets:
        if dset.get("type") == 164:
            found = (1.0 / float(dset["length"]), 1.0 / float(dset["force"]))
    return found


def _response_factor(text: str, quantity: str, rotation: bool) -> float | None:
    """SI factor of a numerator label, None when it states nothing, NaN when no unit matches."""
    if text in _SILENT:
        return None
    suffix = _PER_TIME[quantity]
    units = _ANGLE if rotation else _LENGTH
    for unit, factor in units.items():
        if text == unit + suffix:
            return factor
    if not rotation and quantity == "accelerance" and text == "g":
        return G_STANDARD
    return math.nan


def record_units(dset: dict[str, Any], quantity: str, rotation: bool, from_file: tuple[float, float] | None,
                 voltage: bool) -> Units | str:
    """The record's SI factors, or the one-line problem (a label unknown, or contradicting dataset 164).

    Parameters
    ----------
    dset : the pyuff dictionary of a dataset 58.
    quantity : receptance, mobility or accelerance (from the ordinate's specific data type).
    rotation : the response is a rotation (rad, not m).
    from_file : `file_units` of the file.
    voltage : the denominator is a drive voltage: no force unit applies.
    """
    numerator = _normal(dset.get("ordinate_axis_units_lab"))
    denominator = _normal(dset.get("orddenom_axis_units_lab"))
    if "/" in numerator and denominator in _SILENT:  # "g/N", "m/s2/N": the whole FRF unit in record 9
        head, _, tail = numerator.rpartition("/")
        if tail in _FORCE:
            numerator, denominator = head, tail
    response = _response_factor(numerator, quantity, rotation)
    force = None if voltage or denominator in _SILENT else _FORCE.get(denominator, math.nan)
    abscissa = _normal(dset.get("abscissa_axis_units_lab"))
    frequency = 1.0 if abscissa in _SILENT else _FREQUENCY.get(abscissa, math.nan)
    if response is not None and math.isnan(response):
        return (f"ordinate units label {dset.get('ordinate_axis_units_lab')!r} is not a unit of "
                f"{'rotational ' if rotation else ''}{quantity} known here")
    if force is not None and math.isnan(force):
        return f"denominator units label {dset.get('orddenom_axis_units_lab')!r} is not a force unit known here"
    if math.isnan(frequency):
        return f"abscissa units label {dset.get('abscissa_axis_units_lab')!r} is not a frequency unit (Hz)"
    if from_file is not None:
        length_si, force_si = from_file
        if response is not None and not rotation and numerator != "g" and not math.isclose(response, length_si,
                                                                                            rel_tol=1e-6):
            return (f"ordinate units label {dset.get('ordinate_axis_units_lab')!r} contradicts the units dataset "
                    f"164 (length unit {length_si:g} m)")
        if force is not None and not math.isclose(force, force_si, rel_tol=1e-6):
            return (f"denominator units label {dset.get('orddenom_axis_units_lab')!r} contradicts the units "
                    f"dataset 164 (force unit {force_si:g} N)")
        response = response if response is not None else (1.0 if rotation else length_si)
        force = force if force is not None else force_si
    return Units(response if response is not None else 1.0, 1.0 if voltage or force is None else force, frequency)
