"""The test article of the proving ground: a frame record plus the physical parts its nominal file leaves out.

An `Article` is a `workbench.model.frame.Frame` (only data: points, members, joints, supports, masses,
springs, excitation, sensors) and the parts a mechanism adds (`workbench.proving.mechanisms`): zones of a
member with other properties, hinges with a rotational spring, extra nodes, rods and bars joined to the
frame, matrices to the ground at a node (a coupled support, an eccentric mass, a shaker armature),
dashpots, and the amplitude laws of the joints. `workbench.proving.fem.discretise` turns it into the
proving ground's own finite element system. Records only here.
"""

from __future__ import annotations

from dataclasses import dataclass

from workbench.model.frame import Frame

__all__ = ["Anchor", "Matrix3", "Zone", "Hinge", "ExtraNode", "Rod", "Attachment", "Dashpot", "Softening", "Article"]

Anchor = str | tuple[str, float]
"""A place on the article: a point of the frame, an `ExtraNode`'s name, or ``(member, distance from its start, m)``."""
Matrix3 = tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]


@dataclass(frozen=True)
class Zone:
    """A stretch ``span`` (m from the member's start) of a member with changed properties.

    Factors multiply what the element has there (the member's, or the joint's modulus inside a joint);
    ``mass_per_length`` (kg/m) and ``rotary_per_length`` (kg.m) are added to its inertia.
    """

    member: str
    span: tuple[float, float]
    stiffness_factor: float = 1.0  # E and G
    area_factor: float = 1.0
    inertia_factor: float = 1.0
    mass_per_length: float = 0.0
    rotary_per_length: float = 0.0


@dataclass(frozen=True)
class Hinge:
    """The member cut at ``station`` (m) and joined by a rotational spring ``stiffness`` (N.m/rad): the
    translations stay continuous, the rotation jumps (a crack, a slipping lap).
    """

    member: str
    station: float
    stiffness: float


@dataclass(frozen=True)
class ExtraNode:
    """A node off the frame's members (a shaker armature), at ``xy`` (m)."""

    name: str
    xy: tuple[float, float]


@dataclass(frozen=True)
class Rod:
    """A straight part joined to the article between two anchors: ``elements`` Timoshenko beams, or one
    pin-ended bar when ``bar``. ``misfit`` (m): its stress-free length minus the distance between the anchors.
    """

    name: str
    start: Anchor
    end: Anchor
    youngs_modulus: float  # Pa
    density: float  # kg/m3
    area: float  # m2
    second_moment: float = 0.0  # m4
    shear_coefficient: float = 0.9
    poisson_ratio: float = 0.3
    elements: int = 4
    bar: bool = False
    misfit: float = 0.0


@dataclass(frozen=True)
class Attachment:
    """Matrices from one node to the ground on its (ux, uy, rz): stiffness (N/m, N/rad, N.m/rad), mass (kg,
    kg.m, kg.m2), damping (N.s/m ...); ``fixed`` dofs are removed.
    """

    anchor: Anchor
    stiffness: Matrix3 | None = None
    mass: Matrix3 | None = None
    damping: Matrix3 | None = None
    fixed: tuple[str, ...] = ()


@dataclass(frozen=True)
class Dashpot:
    """A viscous link between dof ``dof`` of two anchors, N.s/m (N.m.s/rad on rz)."""

    a: Anchor
    b: Anchor
    dof: str
    coefficient: float


@dataclass(frozen=True)
class Softening:
    """A joint's modulus falling with the excitation amplitude ratio ``a`` (1 = the lowest level).

    ``Y(a) = Y (1 - drop * ((a - 1) / (top - 1)) ** exponent)`` for ``a >= 1``, zero at ``a = 1``;
    ``exponent`` < 1: sub-linear, microslip spreading over the contact as the load grows.
    """

    joint: str
    drop: float
    exponent: float = 0.6
    top: float = 5.0

    def factor(self, amplitude: float) -> float:
        """The joint modulus' factor at amplitude ratio ``amplitude``."""
        x = max(amplitude - 1.0, 0.0) / (self.top - 1.0)
        return 1.0 - self.drop * x**self.exponent


@dataclass(frozen=True)
class Article:
    """A tested article: ``frame`` and the parts its mechanisms add (module docstring).

    ``excitation`` (anchor, dof) moves the force off the frame's excitation point (a stinger's far end).
    ``shear`` False and ``rotary_inertia`` False give Euler-Bernoulli members (for comparisons only: a
    real article is Timoshenko).
    """

    frame: Frame
    zones: tuple[Zone, ...] = ()
    hinges: tuple[Hinge, ...] = ()
    nodes: tuple[ExtraNode, ...] = ()
    rods: tuple[Rod, ...] = ()
    attachments: tuple[Attachment, ...] = ()
    dashpots: tuple[Dashpot, ...] = ()
    softening: tuple[Softening, ...] = ()
    excitation: tuple[Anchor, str] | None = None  # where the force goes in, when not the frame's (a shaker's coil)
    shear: bool = True
    rotary_inertia: bool = True
