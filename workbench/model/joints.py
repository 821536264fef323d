"""Joint moduli set on a model or a frame: the one place that moves joints.

`model_at_moduli` gives an assembled model whose joint zones sit at other moduli without
re-meshing (the identification's candidate means, the Bayesian forward table's reference point).
`joint_scale` is the same move as the ``gamma`` of ``Model.stiffness`` (eq. 3-4) for code that
solves at a point without copying the model (the nominal fit's evaluations, SMR1's sensitivities).
`frame_with_joint_models` writes identified means and CoVs into a frame (section 5 transfer).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any, Protocol, TypeVar

import numpy as np

from workbench.model.assembly import Model
from workbench.model.frame import Frame
from workbench.model.matrix_model import MatrixModel

__all__ = ["joint_scale", "model_at_moduli", "frame_with_joint_models"]


FrameOrMatrices = TypeVar("FrameOrMatrices", Frame, MatrixModel)


class Jointed(Protocol):
    """Anything with joints in a fixed order: a frame, an assembled frame, a matrix model."""

    @property
    def joints(self) -> Sequence[Any]: ...


def joint_scale(frame: Jointed, moduli_pa: np.ndarray) -> np.ndarray:
    """Per joint ``Y_j / Y_file_j``: the ``gamma`` of ``Model.stiffness`` that puts joint j at ``moduli_pa[j]``.

    Parameters
    ----------
    frame : the frame the model was assembled from, or a matrix model (its joints' file moduli, Pa).
    moduli_pa : (n_joints,) joint moduli, Pa, in the frame's joint order.

    Raises
    ------
    ValueError
        Not one finite positive modulus per joint.
    """
    moduli = np.asarray(moduli_pa, float)
    n = len(frame.joints)
    if moduli.shape != (n,) or not np.all(np.isfinite(moduli)) or np.any(moduli <= 0):
        raise ValueError(f"moduli_pa: expected {n} finite positive values (one per joint), got {moduli_pa}")
    return moduli / np.array([j.youngs_modulus for j in frame.joints], float)


def model_at_moduli(model: Model, moduli_pa: np.ndarray) -> Model:
    """``model`` with its joint zones at the moduli ``moduli_pa`` (n_joints,), Pa, without re-meshing.

    Exactly the model assembled from the frame with those joint moduli: a joint zone's stiffness
    is linear in its modulus, and the Timoshenko shear parameter does not depend on it. Its
    ``gamma`` is then relative to the new moduli (the nominal point of SMR and of eq. 9).
    """
    scale = joint_scale(model.frame, moduli_pa)
    owner = model.mesh.element_joint
    factor = np.where(owner >= 0, scale[np.maximum(owner, 0)], 1.0)
    data = replace(model.elements, axial=model.elements.axial * factor, bending=model.elements.bending * factor)
    joints = tuple(replace(j, youngs_modulus=float(j.youngs_modulus * s)) for j, s in zip(model.frame.joints, scale))
    return replace(model, frame=replace(model.frame, joints=joints), elements=data,
                   stiffness_joints=tuple((s * k).tocsr() for s, k in zip(scale, model.stiffness_joints)))


def frame_with_joint_models(frame: FrameOrMatrices, models: Mapping[str, tuple[float, float]]) -> FrameOrMatrices:
    """Copy of ``frame`` with joint models given per joint group or per joint (section 5 transfer).

    The paper identifies one model per joint family on the one-bolt frames (Table 4: vertical
    24 GPa, CoV 0.09; horizontal 73.5 GPa, CoV 0.22) and predicts the two- and four-bolt frames
    with them; the bundled frames name those families by their joints' ``group``.

    Parameters
    ----------
    frame : the frame to predict, or a matrix model (its joint matrices are scaled to the new means).
    models : ``{name: (youngs_modulus_pa, cov)}``, ``name`` a joint group, or a joint name (which
        wins over its group's entry). Joints that no key names keep the file's values.

    Returns
    -------
    Frame
        The same frame with the new joint means (Pa) and CoVs (of the Gamma law, eq. 8-9).

    Raises
    ------
    ValueError
        A key naming no group or joint (the message lists the known names), or a modulus that is
        not finite and positive, or a CoV that is not finite and non-negative.
    """
    names = set(frame.joint_names)
    groups = {j.group for j in frame.joints}
    for key, (modulus, cov) in models.items():
        if key not in names and key not in groups:
            known = ", ".join(sorted(groups | names)) or "none"
            raise ValueError(f"{frame.source}: joint models: no joint group or joint named {key!r} (known: {known})")
        if not (np.isfinite(modulus) and modulus > 0 and np.isfinite(cov) and cov >= 0):
            raise ValueError(f"joint models: {key!r}: expected a finite positive modulus and a finite "
                             f"cov >= 0, got ({modulus}, {cov})")
    joints = []
    for joint in frame.joints:
        named = joint.name if joint.name in models else joint.group if joint.group in models else None
        if named is None:
            joints.append(joint)
            continue
        modulus, cov = models[named]
        joints.append(replace(joint, youngs_modulus=float(modulus), cov=float(cov)))
    if isinstance(frame, MatrixModel):  # its joint matrices are at the file's means: they move with them
        ratio = np.array([new.youngs_modulus / old.youngs_modulus for new, old in zip(joints, frame.joints)])
        moved = frame.scaled(ratio)
        return replace(moved, joints=tuple(joints))  # the CoVs too, and the means exactly as given
    return replace(frame, joints=tuple(joints))
