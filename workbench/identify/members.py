"""A frame's manufacturing tolerances in the Laplace likelihood's forward model.

The members' sections and the materials are known to a tolerance (`workbench.model.tolerance`), and
a member's error changes both a test's frequencies and how they share their energy with the joints,
which is what the joints' level is learnt from (`reports/estimators_proving.md`, section 7). So the
tolerances enter each test's Rayleigh quotient where they act: with the factors' logs ``m`` (P,),

    lambda_tk(z, m) = c_tk + sum_p C_tkp m_p + sum_j (L_tkj + sum_p D_tkjp m_p) exp(z_tj - zbar_tj),

first order in ``m`` about the nominal frame at each test's anchor, ``C`` and ``D`` the derivatives of
the rest and joint energies (eq. 5). The same ``m`` holds in every test (one article), so ``m`` is a
shared latent of `workbench.identify.laplace.LaplaceLikelihood`, integrated with the discrepancy. Its
prior is the tolerance the user states.

The derivatives are forward differences of exact solves (one frame per factor, moved by
`MEMBER_STEP`): the energies' derivatives need the eigenvectors' (the eigenvalue's alone is a
quadratic form), and a frame has a few factors, so P extra solves per test cost less than the
adjoint algebra would take to write and check. Cost: each (re-)anchoring assembles P + 1 frames and
solves each test P + 1 times (the four-bolt frame, P = 8, 17 tests: 3.2 s on a busy machine); an identification with
tolerances re-anchors once more, and took 42-58 s against about 20 s without (`reports/estimators_proving.md`,
section 8).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from workbench.identify.anchored import AnchoredForward, forward_at
from workbench.model.assembly import Model, assemble
from workbench.model.modal import Modes
from workbench.model.structure import Structure
from workbench.model.tolerance import Tolerances, frame_with_factors, tolerance_factors

__all__ = ["MEMBER_STEP", "MemberFactors", "member_factors", "with_member_derivatives"]

MEMBER_STEP = 1e-3  # log-factor step: truncation ~1e-3 of a derivative, far above the solves' rounding


@dataclass(frozen=True)
class MemberFactors:
    """The latent manufacturing factors of a frame: their names, prior sds (P,), the frame at the factors'
    expansion point ``centre`` (P,) (``base``) and one model per factor moved from it by `MEMBER_STEP`
    (joints at the same moduli as the nominal model's).
    """

    names: tuple[str, ...]
    prior_sd: np.ndarray
    moved: tuple[Structure, ...]
    base: Structure
    centre: np.ndarray

    @property
    def count(self) -> int:
        return len(self.names)


def member_factors(model: Structure, tolerances: Tolerances, centre: np.ndarray | None = None) -> MemberFactors:
    """The factors of ``model``'s frame under ``tolerances``, expanded about ``centre`` (P,) in their logs
    (default the drawing, 0: ``model`` itself).

    Why a centre: the first-order terms err by the square of the distance from it, 5e-4 of a frequency
    three tolerances away, which is tens of times a circle fit's scatter; the identification expands
    them again where the posterior puts the factors (`workbench.identify.laplace.LaplaceLikelihood.reanchored`).

    Raises
    ------
    ValueError
        ``model`` is a matrix model: it has no members to move.
    """
    if not isinstance(model, Model):
        raise ValueError(f"{model.source}: tolerances: a matrix model has no members or materials to give "
                         "tolerances to (only a frame has)")
    names, sd = tolerance_factors(model.frame, tolerances)
    centre = np.zeros(len(names)) if centre is None else np.asarray(centre, float)
    base = model if not np.any(centre) else assemble(frame_with_factors(model.frame, centre))
    step = MEMBER_STEP * np.eye(len(names))
    return MemberFactors(names, sd, tuple(assemble(frame_with_factors(model.frame, centre + s)) for s in step),
                         base, centre)


def with_member_derivatives(forward: AnchoredForward, factors: MemberFactors, nominal: Modes,
                            modes: np.ndarray) -> AnchoredForward:
    """``forward`` with the derivatives ``C`` (T, K, P) and ``D`` (T, K, r, P) of its rest and joint
    energies in the factors' logs at its anchors (module docstring), (rad/s)^2. ``forward`` must be
    ``factors.base``'s (the frame at the factors' centre).

    The forward model's error that `workbench.identify.anchored.forward_error` reports is at the centre;
    the terms in ``m`` err by about 1e-5 of a frequency at twice the tolerance (`tests/test_members.py`).
    """
    rest = np.empty(forward.rest.shape + (factors.count,))
    joints = np.empty(forward.joints.shape + (factors.count,))
    for p, moved in enumerate(factors.moved):
        at = forward_at(moved, nominal, modes, forward.anchor)
        rest[..., p] = (at.rest - forward.rest) / MEMBER_STEP
        joints[..., p] = (at.joints - forward.joints) / MEMBER_STEP
    return replace(forward, rest_grad=rest, joints_grad=joints)
