"""Measured modes paired with the model's by their shapes (MAC), when the test measured shapes.

Every estimator compares measured mode ``i`` with model mode ``measured.modes[i]``. By default that
is the i-th mode found, which is right only when the test found every mode of the model, in order.
A missed or merged mode, or a mode of the rig that the model lacks, shifts the order and makes an
estimator fit one mode's frequency with another's (seen in the field: a modulus at its search
bound). When the circle fit gave modal constants at the sensors (`MeasuredModes.modal_constants`,
``phi_s phi_e``), `pair_by_mac` pairs each measured mode with the model mode of the same shape
instead, one to one, among the model modes within `FREQUENCY_WINDOW` in frequency, and refuses when a
measured mode resembles none of them.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.optimize import linear_sum_assignment

from workbench.extraction.records import MeasuredModes
from workbench.model.modal import RIGID_HZ, mac
from workbench.model.structure import Structure, excitation_dof, response_dofs, structure_modes

__all__ = ["MIN_PAIR_MAC", "EXTRA_CANDIDATES", "FREQUENCY_WINDOW", "mean_mac", "pair_by_mac"]

MIN_PAIR_MAC = 0.5  # below this a measured mode is not any model mode (frozen: see tests/test_pairing.py)
EXTRA_CANDIDATES = 4  # model modes solved beyond the highest measured one
MAX_RIGID = 6  # and room for a free structure's rigid-body modes
FREQUENCY_WINDOW = 0.3  # candidates within this relative distance in frequency: a few sensors cannot tell
#                         a low mode from a high one by shape alone (the paper's 5 sensors: MAC 0.99 between them)


def mean_mac(measured: MeasuredModes, model_constants: np.ndarray) -> np.ndarray:
    """(n_measured, n_model) MAC of each measured mode with each model mode, averaged over the tests.

    ``model_constants`` (n_sensors, n_model): the model's ``phi_s phi_e`` at the frame's sensors.
    Sensors whose fitted constant is not finite in a test (an unusable fit) are left out of that
    test; a test and mode with fewer than 2 such sensors is left out of the average.
    """
    constants = measured.modal_constants
    if constants is None:
        raise ValueError(f"{measured.source}: no measured modal constants to pair modes by MAC")
    table = np.zeros((constants.shape[1], model_constants.shape[1]))
    counts = np.zeros(constants.shape[1])
    for per_test in constants:  # (n_modes, n_sensors)
        for i, shape in enumerate(per_test):
            use = np.isfinite(shape)
            if use.sum() >= 2:
                table[i] += mac(shape[use][:, None], model_constants[use])[0]
                counts[i] += 1
    with np.errstate(invalid="ignore"):
        return table / counts[:, None]


def pair_by_mac(model: Structure, measured: MeasuredModes, min_mac: float = MIN_PAIR_MAC) -> MeasuredModes:
    """``measured`` with ``modes`` set to the model modes of the same shape (MAC), one to one.

    The model's modes are those of its file (joints at their mean). A measured mode is never a
    rigid-body mode (below `RIGID_HZ`): where the numbers would put one on a free structure's rigid
    modes, every number moves past them (the Brake-Reuss beam's first measured mode is its model's
    fourth). Without modal constants, or with fewer than two sensors, that is all.

    Raises
    ------
    ValueError
        A measured mode's best available model mode has a MAC below ``min_mac`` (its shape is none
        of the model's), naming the mode, its frequency and the MAC.
    """
    count = min(int(np.max(measured.modes)) + EXTRA_CANDIDATES + MAX_RIGID, model.size - 2)
    modes = structure_modes(model, count)
    rigid = int(np.sum(modes.frequency_hz < RIGID_HZ))
    if rigid and np.any(np.asarray(measured.modes) <= rigid):
        measured = replace(measured, modes=np.asarray(measured.modes) + rigid)
    drive = excitation_dof(model)
    if measured.modal_constants is None or drive is None:
        return measured
    sensors, _, names = response_dofs(model)
    if measured.sensors:  # the campaign's sensors by name: a model may have more (UNESP-BERT's laser)
        unknown = [s for s in measured.sensors if s not in names]
        if unknown:
            raise ValueError(f"{measured.source}: sensor {unknown[0]!r} is not a sensor of {model.source} "
                             f"({', '.join(names)})")
        sensors = sensors[[names.index(s) for s in measured.sensors]]
    table = mean_mac(measured, modes.shapes[sensors] * modes.shapes[drive])
    near = np.abs(modes.frequency_hz[None, :] / np.asarray(measured.mean_hz)[:, None] - 1.0) <= FREQUENCY_WINDOW
    table = np.where(near, table, 0.0)
    found = np.isfinite(table).all(axis=1)
    rows, cols = linear_sum_assignment(-np.where(found[:, None], table, 0.0))
    paired = np.asarray(measured.modes).copy()
    for i, j in zip(rows, cols):
        if not found[i]:
            continue  # no usable shape: the mode keeps its place
        if table[i, j] < min_mac:
            best = int(np.argmax(table[i]))
            taken = [int(r) for r, c in zip(rows, cols) if c == best and r != i]
            why = (f"its best match, model mode {best + 1} (MAC {table[i, best]:.2f}), is measured mode "
                   f"{taken[0] + 1}'s (MAC {table[taken[0], best]:.2f}): two measured modes of one shape"
                   if taken else f"its best MAC there is {table[i, best]:.2f}, under {min_mac}")
            raise ValueError(
                f"{measured.source}: measured mode {i + 1} ({measured.mean_hz[i]:.1f} Hz) pairs with no mode of "
                f"{model.source} within {100 * FREQUENCY_WINDOW:.0f} % in frequency: {why}; check the sensors' "
                "names and directions, or give modes.csv with the model's mode numbers")
        paired[i] = j + 1
    return replace(measured, modes=paired)
