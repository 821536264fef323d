"""The command line's argument types and shared option groups (`workbench.cli` stays the commands).

Each type raises `argparse.ArgumentTypeError`, which argparse turns into one line on standard error and exit 2
(the contract's bad-input rule).
"""

from __future__ import annotations

import argparse
import math

from workbench.diagnose.observations import DEFAULT_ALLOWANCE, Allowance
from workbench.model.tolerance import Tolerances

__all__ = ["positive_int", "length_sd", "section_sd", "allowance_options", "allowance", "tolerances"]


def positive_int(text: str) -> int:
    """A count, 1 or more."""
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def length_sd(text: str) -> float:
    """A standard deviation of a length, m, 0 to 0.1."""
    value = float(text)
    if not math.isfinite(value) or value < 0.0 or value > 0.1:
        raise argparse.ArgumentTypeError(f"must be a standard deviation in metres, 0 to 0.1, got {text}")
    return value


def section_sd(text: str) -> tuple[float, float]:
    """``I_SD,A_SD``: relative sds of each member's second moment of area and area, each 0 to 0.5."""
    try:
        sds = tuple(float(v) for v in text.split(","))
    except ValueError:
        sds = ()
    if len(sds) != 2 or not all(math.isfinite(v) and 0.0 <= v <= 0.5 for v in sds):
        raise argparse.ArgumentTypeError(f"must be two relative standard deviations I_SD,A_SD, each 0 to 0.5, "
                                         f"got {text}")
    return sds[0], sds[1]


def allowance_options(p: argparse.ArgumentParser) -> None:
    """The frame's stated tolerances a diagnosis reads its gap against (`workbench.diagnose.observations`);
    `allowance` makes the record of them.
    """
    default = DEFAULT_ALLOWANCE
    p.add_argument("--geometry-sd-m", type=length_sd, default=default.geometry_sd_m, metavar="SD",
                   help="how well the frame's member ends are known, m, each of x and y (default "
                        f"{default.geometry_sd_m:g}: measured with a rule; 0: the file's geometry taken as exact)")
    p.add_argument("--section-sd", type=section_sd, default=default.section_sd, metavar="I_SD,A_SD",
                   help="how well each member's second moment of area and area are known, relative (default "
                        f"{default.section_sd[0]:g},{default.section_sd[1]:g}: a machined bar; 0,0: the file's "
                        "sections taken as exact)")


def allowance(args: argparse.Namespace) -> Allowance:
    """The `Allowance` of `allowance_options`' parsed values."""
    return Allowance(args.geometry_sd_m, args.section_sd)


def tolerances(text: str) -> Tolerances:
    """``SD`` or ``SECTION_SD,MATERIAL_SD``: a frame's relative manufacturing tolerances
    (`workbench.model.tolerance.Tolerances`).
    """
    try:
        sds = [float(v) for v in text.split(",")]
        if len(sds) not in (1, 2):
            raise ValueError("give one or two relative sds")
        return Tolerances(sds[0], sds[-1])
    except ValueError as error:
        raise argparse.ArgumentTypeError(f"{text!r}: {error}") from None
