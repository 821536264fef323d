"""A frame's manufacturing tolerances as random factors: each member's section and each material.

A frame file gives nominal sections and materials; the article on the shaker was cut and rolled
within a tolerance. A relative error of a few tenths of a percent on a flat bar's thickness is about
1 % on its bending stiffness (``I`` goes as ``b t^3``), and the joints' level that a campaign learns
from its scatter pattern amplifies that about fivefold (`reports/estimators_proving.md`, section 7).
So the identification can carry the tolerances as latent factors (`workbench.identify.members`):

    log b_i, log t_i ~ Normal(0, section_sd^2)    member i's width and thickness, as a flat bar's:
                                                   A_i scales as b_i t_i, I_i as b_i t_i^3
    log E_m, log rho_m ~ Normal(0, material_sd^2)  material m's Young's modulus and density

A section that is not a flat bar is scaled the same way (its area as one dimension times another, its
second moment as the first times the cube of the second): an assumption for a tube or an I-section. The joints' own
moduli are the joints' laws', not the material's: a joint zone keeps its modulus.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from workbench.model.frame import Frame

__all__ = ["Tolerances", "tolerance_factors", "frame_with_factors"]


@dataclass(frozen=True)
class Tolerances:
    """Relative standard deviations of a frame's manufacturing errors (module docstring).

    Attributes
    ----------
    section_sd : each member's width and thickness, relative (0.003 is 0.3 %).
    material_sd : each material's Young's modulus and density, relative.
    """

    section_sd: float = 0.003
    material_sd: float = 0.003

    def __post_init__(self) -> None:
        for name in ("section_sd", "material_sd"):
            value = getattr(self, name)
            if not (np.isfinite(value) and 0.0 < value <= 0.1):
                raise ValueError(f"tolerances: {name} {value} is not in (0, 0.1]: a relative standard deviation")

    def scaled(self, factor: float) -> Tolerances:
        """These tolerances times ``factor``: a drawing's stated too wide or too narrow (`benchmarks/`)."""
        return Tolerances(factor * self.section_sd, factor * self.material_sd)


def tolerance_factors(frame: Frame, tolerances: Tolerances) -> tuple[tuple[str, ...], np.ndarray]:
    """The latent factors' names and their prior sds (P,): each material's ``E`` and ``rho``, then each
    member's ``b`` and ``t`` (`frame_with_factors`'s order).
    """
    names: list[str] = []
    sd: list[float] = []
    for material in frame.materials:
        names += [f"{material}.youngs_modulus", f"{material}.density"]
        sd += [tolerances.material_sd] * 2
    for member in frame.members:
        names += [f"{member.name}.width", f"{member.name}.thickness"]
        sd += [tolerances.section_sd] * 2
    return tuple(names), np.array(sd)


def frame_with_factors(frame: Frame, log_factors: np.ndarray) -> Frame:
    """``frame`` with its materials and members' sections scaled by ``exp(log_factors)`` (P,), in
    `tolerance_factors`' order. Each member gets its own section (``<section>@<member>``).
    """
    factors = np.exp(np.asarray(log_factors, float))
    expected = 2 * (len(frame.materials) + len(frame.members))
    if factors.shape != (expected,):
        raise ValueError(f"{frame.source}: frame_with_factors: {factors.shape} factors for {expected} "
                         "(2 per material and member)")
    materials = {}
    for i, (name, mat) in enumerate(frame.materials.items()):
        materials[name] = replace(mat, youngs_modulus=mat.youngs_modulus * factors[2 * i],
                                  density=mat.density * factors[2 * i + 1])
    sections = dict(frame.sections)
    members = []
    offset = 2 * len(frame.materials)
    for i, member in enumerate(frame.members):
        b, t = factors[offset + 2 * i: offset + 2 * i + 2]
        sec = frame.sections[member.section]
        key = f"{member.section}@{member.name}"
        sections[key] = replace(sec, name=key, area=sec.area * b * t, second_moment=sec.second_moment * b * t**3)
        members.append(replace(member, section=key))
    return replace(frame, materials=materials, sections=sections, members=tuple(members))
