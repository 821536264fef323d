"""Importers for two real measured data sets, each into a contract campaign (CONTRACTS.md section 2).

Neither data set may be redistributed with the workbench: the functions read the MAT files from
wherever the user keeps them (``root``) and build the campaign in memory, with the nominal frame
the caller passes (the repository has them: ``frames/unesp_bert.toml``, ``frames/brake_reuss.toml``);
`workbench.io.campaign.write_campaign` writes it to a directory outside the repository::

    write_campaign(import_unesp_bert(ROOT, "frames/unesp_bert.toml"), OUT_DIR)

UNESP-BERT (SHM Lab, UNESP Ilha Solteira; GitHub ``shm-unesp/DATASET_BOLTEDBEAM``, licence
CC BY-NC-SA): a clamped two-bar aluminium beam with a two-bolt lap joint, driven by a shaker whose
amplifier voltage is the FRF reference (no force sensor: ``reference = "voltage"``). Each
``FRF.mat`` (LMS Test.Lab, MATLAB v5) holds ``FRF`` (8193 x 4 complex, Acc1..Acc4 in (m/s2)/V, SI
despite the "g/V" label) and ``FRF_Laser__X_Shaker__X`` (8193 complex, tip velocity in (m/s)/V),
lines 0 to 512 Hz at 0.0625 Hz. A campaign has one quantity, so ``channels`` chooses:

- ``"accelerometers"`` (default): accelerance-like, four sensors acc1..acc4 along the beam, which
  see both modes and their shapes; this is what modal extraction and the joint model need.
- ``"laser"``: mobility-like, one sensor at the tip (the cleanest signal, but a single point).

Brake-Reuss beam (Rice Tribomechadynamics Lab; GitHub ``mattiacenedese/BRBtesting``, repository
licence GPL-3): ``ForcedFrequencyResponses.mat`` (MATLAB v5) holds stepped-sine runs around the
first bending mode (about 80 Hz), each with 41 frequencies and the fundamental-harmonic force
amplitude (N), Accel 3 amplitude (m/s2) and phase (rad); the accelerance is
``amplitude / force * exp(i phase)`` at the drive point, one test per run.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from scipy.io import loadmat  # MATLAB v5 files: scipy.io reads them, no h5py needed

from workbench.io.campaign import FRF_COLUMNS, Campaign, Factor
from workbench.model.frame import Frame, FrameFileError
from workbench.model.frame_file import read_frame

__all__ = ["UNESP_TESTS", "UNESP_SOURCE", "BRAKE_REUSS_SOURCE", "import_unesp_bert", "import_brake_reuss"]

# which -> (folder under Data/T5Nm, excited band in Hz: lines outside it carry no excitation)
UNESP_TESTS = {
    "Rand": ("Rand", (0.0, 110.0)),
    "Chirp0to110Hz": ("Chirp/Chirp0to110Hz", (0.0, 110.0)),
    "Chirp0to40Hz": ("Chirp/Chirp0to40Hz", (0.0, 40.0)),
    "Chirp70to110Hz": ("Chirp/Chirp70to110Hz", (70.0, 110.0)),
}
UNESP_SOURCE = (
    "UNESP-BERT (BoltEd stRucTure) benchmark, SHM Lab at UNESP/Ilha Solteira, Brazil: GitHub "
    "shm-unesp/DATASET_BOLTEDBEAM, Data/T5Nm/{folder} (files as in the repository history of 2020-10-16..19). "
    "Licence CC BY-NC-SA: non-commercial use, share-alike; acknowledge the SHM Lab at UNESP/Ilha Solteira as "
    "the source, cite the benchmark as UNESP-BERT and the lab's papers, e.g. R. O. Teloli, S. da Silva, "
    "T. G. Ritto, G. Chevallier, MSSP 151 (2021) 107333, doi:10.1016/j.ymssp.2020.107333. Not redistributed "
    "with the workbench: imported from the user's copy."
)
BRAKE_REUSS_SOURCE = (
    "Brake-Reuss beam stepped-sine tests, Tribomechadynamics Lab, Rice University: GitHub "
    "mattiacenedese/BRBtesting, ForcedFrequencyResponses.mat (FRdata.{group}); repository licence GPL-3. "
    "Cite W. Chen et al., MSSP 166 (2022) 108401, doi:10.1016/j.ymssp.2021.108401 and M. Jin et al., "
    "MSSP 166 (2022) 108402, doi:10.1016/j.ymssp.2021.108402. Not redistributed with the workbench: "
    "imported from the user's copy."
)
_UNESP_CHANNELS = {"accelerometers": "accelerance", "laser": "mobility"}
_BRB_GROUPS = {"force": "ForceControl", "response": "ResponseControl"}


def _frame(frame: Frame | str | Path) -> Frame:
    """``frame``, or the frame file it names (read and validated)."""
    if isinstance(frame, Frame):
        return frame
    try:
        return read_frame(frame)
    except FrameFileError as exc:
        raise ValueError(str(exc)) from None


def _loadmat(path: Path) -> dict[str, Any]:
    if not path.is_file():
        raise ValueError(f"{path}: file not found")
    try:
        return loadmat(path, squeeze_me=True, struct_as_record=False)
    except (ValueError, NotImplementedError, OSError) as exc:  # v7.3 (HDF5) raises NotImplementedError
        raise ValueError(f"{path}: cannot be read as a MATLAB v5 file: {' '.join(str(exc).split())}") from None


def _unesp_folder(root: Path, which: str) -> Path:
    folder = UNESP_TESTS[which][0]
    for base in (root / "Data" / "T5Nm", root / "T5Nm", root):
        if (base / folder).is_dir():
            return base / folder
    raise ValueError(f"{root}: no Data/T5Nm/{folder} directory (root is the UNESP-BERT data set directory, "
                     "the one holding PROVENANCE.md and Data/)")


def _unesp_run(path: Path, channels: str, band: tuple[float, float]) -> tuple[np.ndarray, dict[str, np.ndarray], str]:
    """One FRF.mat: the kept lines, {sensor: values} and a description of the run."""
    data = _loadmat(path)
    try:
        acc, laser = data["FRF"], data["FRF_Laser__X_Shaker__X"]
        x = acc.x_values
        axis = float(x.start_value) + float(x.increment) * np.arange(int(x.number_of_values))
        values = np.atleast_2d(np.asarray(acc.y_values.values, dtype=np.complex128).T)
        names = [str(n) for n in np.atleast_1d(acc.function_record.name)]
        tip = np.asarray(laser.y_values.values, dtype=np.complex128).ravel()
        record = laser.function_record
        window = str(record.reference_channel.windows.type)
        averages = int(record.average.nr_of_averages)
        run = str(record.TL_export_properties_annotation.run_name)
    except (KeyError, AttributeError) as exc:
        raise ValueError(f"{path}: not an LMS Test.Lab FRF export as the UNESP-BERT provenance describes "
                         f"(missing {exc})") from None
    if values.shape != (4, axis.size) or tip.shape != axis.shape:
        raise ValueError(f"{path}: FRF is {values.shape[::-1]} and the laser FRF {tip.shape}, expected "
                         f"({axis.size}, 4) and ({axis.size},)")
    sensors = {}
    for name, row in zip(names, values):
        found = re.search(r"Acc(\d)", name)
        if not found:
            raise ValueError(f"{path}: FRF channel {name!r} is not Acc1..Acc4")
        sensors[f"acc{found.group(1)}"] = row
    # The accelerometer FRFs are stored in SI ((m/s2)/V) under a "g/V" label; Acc1 and the laser
    # share the tip, so |Acc1| = omega |laser| near the modes checks the unit (g would be 9.81 off).
    omega = 2 * np.pi * axis
    peak = np.argmax(np.abs(tip) * (axis > band[0]) * (axis <= band[1]))
    ratio = abs(sensors["acc1"][peak]) / (omega[peak] * abs(tip[peak]))
    if not 0.8 < ratio < 1.25:
        raise ValueError(f"{path}: |Acc1| / (omega |laser|) = {ratio:.3g} at {axis[peak]:g} Hz, expected about 1 "
                         "(accelerometer FRFs in (m/s2)/V)")
    keep = (axis > band[0]) & (axis <= band[1])  # drops 0 Hz and the unexcited lines
    if channels == "laser":
        sensors = {"laser": tip}
    description = f"H1, {averages} averages, {window.lower()} window, LMS run {run}"
    return axis[keep], {s: v[keep] for s, v in sensors.items()}, description


def import_unesp_bert(root: str | Path, frame: Frame | str | Path, which: str = "Rand",
                      channels: str = "accelerometers") -> Campaign:
    """The UNESP-BERT tests at 5 N.m of one excitation type as a campaign, one test per level.

    Parameters
    ----------
    root : the data set directory (holding ``Data/T5Nm``); only read.
    frame : the nominal model, or its frame file (the repository's ``frames/unesp_bert.toml``).
    which : ``"Rand"`` (band-limited random, 0-110 Hz, 0.05...0.30 V, 6 levels), ``"Chirp0to110Hz"``
        (5 levels, no 0.20 V), ``"Chirp0to40Hz"`` or ``"Chirp70to110Hz"`` (6 levels each).
    channels : ``"accelerometers"`` (accelerance-like, (m/s2)/V, sensors acc1..acc4) or
        ``"laser"`` (mobility-like, (m/s)/V, sensor laser at the tip).

    Returns
    -------
    Campaign
        ``reference = "voltage"`` (FRFs over the shaker-amplifier input), ``synthetic = False``,
        one factor ``amplitude`` (kind amplitude, levels "0.05" ... "0.30" V, increasing), test ids
        the folder names (``Rand0p05`` ...), lines inside the excited band only (0 Hz dropped).

    Raises
    ------
    ValueError
        A missing directory or file, an invalid frame file, or a file that is not the export the
        provenance describes.
    """
    root = Path(root)
    if which not in UNESP_TESTS:
        raise ValueError(f"which: {which!r} is not one of {', '.join(UNESP_TESTS)}")
    if channels not in _UNESP_CHANNELS:
        raise ValueError(f"channels: {channels!r} is not one of {', '.join(_UNESP_CHANNELS)}")
    model = _frame(frame)
    folder = _unesp_folder(root, which)
    band = UNESP_TESTS[which][1]
    runs = []
    for run in sorted(folder.iterdir()):
        found = re.fullmatch(r"[A-Za-z]+(\d)p(\d+)", run.name)
        if run.is_dir() and found:
            runs.append((float(f"{found.group(1)}.{found.group(2)}"), f"{found.group(1)}.{found.group(2)}", run))
    if not runs:
        raise ValueError(f"{folder}: no level folders (e.g. Rand0p05)")
    runs.sort()
    levels, tables, ids = {}, [], []
    for volts, key, run in runs:
        axis, sensors, description = _unesp_run(run / "FRF.mat", channels, band)
        levels[key] = f"{volts:.2f} V shaker-amplifier input; {description}"
        ids.append(run.name)
        for sensor, values in sensors.items():
            tables.append(pd.DataFrame({"test_id": run.name, "sensor": sensor, "frequency_hz": axis,
                                        "real": values.real, "imag": values.imag}))
    frf = pd.concat(tables, ignore_index=True)[list(FRF_COLUMNS)]
    design = pd.DataFrame({"test_id": ids, "amplitude": list(levels)})
    quantity = _UNESP_CHANNELS[channels]
    return Campaign(
        name=f"UNESP-BERT bolted beam, 5 N.m, {which} {min(levels)}-{max(levels)} V ({channels})",
        description=(f"Clamped two-bar aluminium beam with a two-bolt lap joint at 5 N.m; {which} excitation at "
                     f"{len(levels)} shaker-amplifier levels; {channels} "
                     f"({'Acc1..Acc4' if channels == 'accelerometers' else 'laser at the tip'}) over the drive "
                     f"voltage, lines {band[0]:g}-{band[1]:g} Hz. Mode 2 (about 98 Hz, when in the band) "
                     "softens as the level rises."),
        frame=model, synthetic=False, quantity=quantity, reference="voltage",
        source=UNESP_SOURCE.format(folder=UNESP_TESTS[which][0]),
        factors=(Factor("amplitude", "amplitude", levels),), design=design, frf=frf)


def _brb_runs(root: Path, group: str) -> tuple[Path, list[Any]]:
    path = root / "ForcedFrequencyResponses.mat" if root.is_dir() else root
    data = _loadmat(path)
    try:
        runs = np.atleast_1d(getattr(data["FRdata"], group))
    except (KeyError, AttributeError) as exc:
        raise ValueError(f"{path}: no FRdata.{group} (missing {exc})") from None
    return path, list(runs)


def _brb_run(path: Path, group: str, k: int, run: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sorted unique frequencies, accelerance, force and response amplitudes of one run."""
    try:
        f = np.asarray(run.frequency, dtype=float).ravel()
        force = np.asarray(run.force, dtype=float).ravel()
        amplitude = np.asarray(run.amplitude, dtype=float).ravel()
        phase = np.asarray(run.phase, dtype=float).ravel()
    except AttributeError as exc:
        raise ValueError(f"{path}: FRdata.{group}({k + 1}) lacks a field ({exc})") from None
    if not (f.size == force.size == amplitude.size == phase.size) or f.size == 0:
        raise ValueError(f"{path}: FRdata.{group}({k + 1}): frequency, force, amplitude and phase differ in length")
    if not np.all(np.isfinite(np.concatenate([f, force, amplitude, phase]))) or np.any(force <= 0):
        raise ValueError(f"{path}: FRdata.{group}({k + 1}): a NaN, infinite or non-positive force value")
    h = amplitude / force * np.exp(1j * phase)
    # Lines sorted by frequency; a frequency measured twice (none in the published file) is
    # averaged (complex mean of the accelerance, mean of the amplitudes).
    unique, inverse = np.unique(f, return_inverse=True)
    count = np.bincount(inverse)

    def mean(v: np.ndarray) -> np.ndarray:
        return np.bincount(inverse, weights=v) / count

    h = mean(h.real) + 1j * mean(h.imag)
    return unique, h, mean(force), mean(amplitude)


def import_brake_reuss(root: str | Path, frame: Frame | str | Path, control: str = "force") -> Campaign:
    """The Brake-Reuss beam stepped-sine runs of one control mode as a campaign, one test per level.

    Parameters
    ----------
    root : the directory holding ``ForcedFrequencyResponses.mat`` (or the file itself); only read.
    frame : the nominal model, or its frame file (the repository's ``frames/brake_reuss.toml``).
    control : ``"force"`` (4 force-controlled runs, mean fundamental force about 0.20, 0.49, 0.97,
        1.46 N) or ``"response"`` (8 response-controlled runs, Accel 3 about 5 ... 80 m/s2).

    Returns
    -------
    Campaign
        Accelerance of Accel 3 (sensor ``accel3``, the drive point) over the fundamental-harmonic
        force, (m/s2)/N, ``reference = "force"``, ``synthetic = False``; factor ``amplitude``
        (kind amplitude): level keys the run's mean force in N ("0.195") or mean response amplitude in
        m/s2 ("5"), increasing; test ids ``FC1``... / ``RC1``...; frequencies strictly increasing.
    """
    root = Path(root)
    if control not in _BRB_GROUPS:
        raise ValueError(f"control: {control!r} is not one of {', '.join(_BRB_GROUPS)}")
    model = _frame(frame)
    group = _BRB_GROUPS[control]
    path, runs = _brb_runs(root, group)
    prefix = "FC" if control == "force" else "RC"
    rows = []
    for k, run in enumerate(runs):
        f, h, force, amplitude = _brb_run(path, group, k, run)
        level = force.mean() if control == "force" else amplitude.mean()
        key = f"{level:.3g}" if control == "force" else f"{level:.0f}"
        text = (f"{group} run {k + 1}: fundamental force {force.mean():.3f} N (range {force.min():.3f}-"
                f"{force.max():.3f}), Accel 3 amplitude {amplitude.mean():.1f} m/s2 (range {amplitude.min():.1f}-"
                f"{amplitude.max():.1f}), {f.size} lines {f[0]:g}-{f[-1]:g} Hz")
        rows.append((level, key, f"{prefix}{k + 1}", text, f, h))
    rows.sort(key=lambda r: r[0])
    keys = [r[1] for r in rows]
    if len(set(keys)) != len(keys):
        raise ValueError(f"{path}: FRdata.{group}: two runs share the level {keys}")
    tables = [pd.DataFrame({"test_id": test, "sensor": "accel3", "frequency_hz": f, "real": h.real, "imag": h.imag})
              for _, _, test, _, f, h in rows]
    unit = "N" if control == "force" else "m/s2"
    return Campaign(
        name=f"Brake-Reuss beam, stepped sine, {control} control",
        description=(f"Free-free Brake-Reuss beam with a three-bolt lap joint; stepped-sine tests around the first "
                     f"bending mode (about 80 Hz) at {len(rows)} {control} levels ({unit}); accelerance of Accel 3 "
                     "(drive point) over the fundamental-harmonic force. Damping grows with the level."),
        frame=model, synthetic=False, quantity="accelerance", reference="force",
        source=BRAKE_REUSS_SOURCE.format(group=group),
        factors=(Factor("amplitude", "amplitude", {r[1]: r[3] for r in rows}),),
        design=pd.DataFrame({"test_id": [r[2] for r in rows], "amplitude": keys}),
        frf=pd.concat(tables, ignore_index=True)[list(FRF_COLUMNS)])
