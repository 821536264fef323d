"""One interface over the two kinds of structure the numerics take: a frame and a matrix model.

An assembled frame (`workbench.model.assembly.Model`) and a matrix model exported by another code
(`workbench.model.matrix_model.MatrixModel`, CONTRACTS.md section 4) share the paper's eq. (3)-(4),
``K(gamma) = K_rest + sum_j gamma_j K_j``, with the same attributes (``mass``, ``stiffness_rest``,
``stiffness_joints``, ``joints``, ``joint_names``, ``source``, ``size``, ``stiffness(gamma)``). What
differs is how each computes its modes and the joint energies ``lambda_kj`` of eq. (5): a frame
from its elements' deformations (no cancellation, `workbench.model.assembly.element_energies`), a
matrix model as quadratic forms on each joint's own rows. The functions here choose; SMR, Monte
Carlo, the FRF band and the identification call them and never ask which kind they hold.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from workbench.model.assembly import Model, assemble
from workbench.model.assembly import joint_energies as frame_energies
from workbench.model.frame import Frame
from workbench.model.joints import joint_scale, model_at_moduli
from workbench.model.matrix_model import MatrixModel
from workbench.model.modal import FRFSet, Modes, modal_frf, model_modes, solve_modes

__all__ = ["Structure", "structure_of", "structure_modes", "structure_energies", "structure_at_moduli",
           "sensor_dofs", "excitation_dof", "response_dofs", "receptance_constants", "structure_frf"]

Structure = Model | MatrixModel


def structure_modes(model: Structure, count: int = 10, gamma: np.ndarray | None = None,
                    method: str = "auto") -> Modes:
    """First ``count`` modes with joint parameters ``gamma`` (None: every joint at its mean).

    Returns
    -------
    Modes
        Eigenvalues in (rad/s)^2, increasing, and mass-normalised shapes on the free dofs.
    """
    if isinstance(model, Model):
        return model_modes(model, count, gamma, method)
    return solve_modes(model.stiffness(gamma), model.mass, count, method)


def structure_energies(model: Structure, shapes: np.ndarray,
                       others: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """``x^T K_rest y`` (n_shapes,) and ``x^T K_j y`` (n_joints, n_shapes): the ``lambda_kj`` of eq. (5).

    ``shapes`` (x) and ``others`` (y, default x) are (n, n_shapes) on the free dofs.
    """
    if isinstance(model, Model):
        return frame_energies(model, shapes, others)
    return model.energies(shapes, others)


def structure_at_moduli(model: Structure, moduli_pa: np.ndarray) -> Structure:
    """``model`` with its joints' means at ``moduli_pa`` (n_joints,), Pa: ``gamma`` is then relative to them."""
    if isinstance(model, Model):
        return model_at_moduli(model, moduli_pa)
    return model.scaled(joint_scale(model, moduli_pa))


def structure_of(frame: Frame | MatrixModel) -> Structure:
    """A frame assembled (eq. 3-4), or a matrix model as it is: what a campaign's ``frame`` names."""
    return frame if isinstance(frame, MatrixModel) else assemble(frame)


def sensor_dofs(model: Structure) -> np.ndarray:
    """The sensors' dofs (n_sensors,), in the file's order.

    Raises
    ------
    ValueError
        The model has no sensor (one line naming its file).
    """
    if isinstance(model, Model):
        if not model.frame.sensors:
            raise ValueError(f"{model.source}: sensors: the frame has no [[sensors]]")
        return np.array([model.dof(s.point, s.dof) for s in model.frame.sensors])
    if not model.sensors:
        raise ValueError(f"{model.source}: sensors: the model has no [[sensors]]")
    return np.array([s.dof for s in model.sensors])


def excitation_dof(model: Structure) -> int | None:
    """The excited dof, or None when the model has no excitation."""
    if isinstance(model, Model):
        e = model.frame.excitation
        return None if e is None else model.dof(e.point, e.dof)
    return model.excitation


def response_dofs(model: Structure) -> tuple[np.ndarray, int, tuple[str, ...]]:
    """The sensors' dofs, the excitation's dof and the sensor names, in the file's order.

    Raises
    ------
    ValueError
        The model has no excitation or no sensor (one line naming its file).
    """
    excitation = excitation_dof(model)
    if excitation is None:
        raise ValueError(f"{model.source}: excitation: the model has no [excitation] table")
    sensors = sensor_dofs(model)
    names = tuple(s.name for s in (model.frame.sensors if isinstance(model, Model) else model.sensors))
    return sensors, excitation, names


def receptance_constants(model: Structure, shapes: np.ndarray, sensors: Sequence[str] = ()) -> np.ndarray:
    """Receptance modal constants ``phi(s) phi(excitation)`` (n_modes, n_sensors), 1/kg, of the mass-normalised
    ``shapes`` (n_free_dofs, n_modes) at ``sensors`` (names, in that order; the model's own when empty).

    Raises
    ------
    ValueError
        As `response_dofs`; a name that is not one of the model's sensors.
    """
    rows, excitation, names = response_dofs(model)
    if sensors:
        unknown = [s for s in sensors if s not in names]
        if unknown:
            raise ValueError(f"{model.source}: sensors: {', '.join(unknown)} not among the model's {', '.join(names)}")
        rows = rows[[names.index(s) for s in sensors]]
    return (shapes[rows] * shapes[excitation][None, :]).T


def structure_frf(model: Structure, modes: Modes, frequency_hz: np.ndarray, quantity: str = "accelerance",
                  damping_ratios: np.ndarray | None = None) -> FRFSet:
    """FRFs at the model's sensors for its excitation by modal superposition.

    ``damping_ratios`` defaults to the model's ``[damping]`` table (the last value repeats).
    """
    responses, excitation, names = response_dofs(model)
    if damping_ratios is None:
        damping_ratios = np.array(model.damping_ratio(modes.count))
    values = modal_frf(modes, frequency_hz, responses, excitation, damping_ratios, quantity)
    return FRFSet(np.asarray(frequency_hz, float), values, names, quantity)
