"""Test campaigns (CONTRACTS.md section 2): directory <-> validated record of tidy pandas tables.

A campaign is a directory with ``campaign.toml``, the nominal ``frame.toml`` and, when it has
tests, ``design.csv`` (one row per test), measured FRFs in long form (``frf.csv`` or
``frf.parquet``: one row per test, sensor and frequency line), optionally ``modes.csv`` (modal
parameters already extracted) or ``moments.csv`` (published moments only).

`load_campaign` rejects every malformation the contract lists with a `CampaignError` naming the
file, the row (its line in the file) and the problem; it never changes the files.
"""

from __future__ import annotations

import io
import tomllib
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from workbench.io.campaign_checks import (
    CampaignError,
    check_duplicates,
    check_flat_curves,
    check_tests,
    check_values,
    fail,
    integer_ids,
    line_of,
)
from workbench.io.outputs import write_outputs
from workbench.model.frame import Frame, FrameFileError
from workbench.model.frame_file import frame_to_toml, read_frame, toml_string
from workbench.model.matrix_file import is_matrix_model, model_files, read_matrix_model
from workbench.model.matrix_io import MatrixModelError
from workbench.model.matrix_model import MatrixModel
from workbench.model.modal import QUANTITIES, FRFSet

__all__ = ["CampaignError", "Factor", "Campaign", "FACTOR_KINDS", "FRF_COLUMNS", "MODES_COLUMNS", "MODES_OPTIONAL",
           "MOMENTS_COLUMNS", "load_campaign", "write_campaign", "campaign_files", "campaign_toml", "frf_set",
           "PAPER_AMPLITUDE_RATIOS", "amplitude_of_tests"]

FACTOR_KINDS = ("tightening", "amplitude", "other")
REFERENCES = ("force", "voltage")
FRF_COLUMNS = ("test_id", "sensor", "frequency_hz", "real", "imag")
MODES_COLUMNS = ("test_id", "mode", "frequency_hz", "damping_ratio")
# the extraction's own uncertainty and quality flags (CONTRACTS.md section 2): allowed, not read
MODES_OPTIONAL = ("frequency_hz_ci95_low", "frequency_hz_ci95_high", "damping_ratio_ci95_low",
                  "damping_ratio_ci95_high", "flags")
MOMENTS_COLUMNS = ("mode", "mean_hz", "std_hz")
_CAMPAIGN_KEYS = {"name", "description", "frame", "quantity", "reference", "synthetic", "source", "factors"}


@dataclass(frozen=True)
class Factor:
    """A column of the design: its kind, the joint it acts on (tightening) and its ordered levels."""

    name: str
    kind: str
    levels: dict[str, str]  # level key -> description, in increasing order
    joint: str | None = None


@dataclass(frozen=True)
class Campaign:
    """A validated test campaign.

    Attributes
    ----------
    name, description, source : free text from campaign.toml.
    quantity : what ``frf`` holds: receptance (m/N), mobility (m/s/N) or accelerance (m/s2/N).
    reference : "force" or "voltage" (FRF over shaker drive voltage: levels not comparable).
    synthetic : True for simulated data, False for measurements.
    frame : the nominal model of the tested article: a frame, or a matrix model (CONTRACTS.md section 4).
    factors : the design's factors, in campaign.toml order.
    design : one row per test: ``test_id`` and one column per factor (level keys as strings).
    frf : long form, columns `FRF_COLUMNS`, or None.
    modes : columns `MODES_COLUMNS`, or None.
    moments : columns `MOMENTS_COLUMNS`, or None.
    path : the directory it was loaded from (None when built in memory).
    """

    name: str
    frame: Frame | MatrixModel
    synthetic: bool
    quantity: str = "accelerance"
    reference: str = "force"
    description: str = ""
    source: str = ""
    factors: tuple[Factor, ...] = ()
    design: pd.DataFrame | None = None
    frf: pd.DataFrame | None = None
    modes: pd.DataFrame | None = None
    moments: pd.DataFrame | None = None
    frame_file: str = "frame.toml"
    path: Path | None = field(default=None, compare=False)

    @property
    def test_ids(self) -> list[Any]:
        return [] if self.design is None else self.design["test_id"].tolist()

    def factor(self, name: str) -> Factor:
        for f in self.factors:
            if f.name == name:
                return f
        raise KeyError(f"{self.path or self.name}: factors: no factor named {name!r}")


def _read_toml(path: Path) -> dict[str, Any]:
    if not path.is_file():
        fail(path, "required file is missing")
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except tomllib.TOMLDecodeError as exc:
        fail(path, f"not valid TOML: {exc}")
    except UnicodeDecodeError:
        fail(path, "not UTF-8 text")


def _read_table(path: Path, columns: tuple[str, ...], text_columns: tuple[str, ...],
                optional: tuple[str, ...] = ()) -> pd.DataFrame:
    """Read a CSV (or parquet) with exactly ``columns``, and any of the ``optional`` ones, which are
    ignored (the contract's "a reader may ignore"); numbers checked finite; rows keep file lines.
    """
    try:
        if path.suffix == ".parquet":
            table = pd.read_parquet(path)
            text = list(set(text_columns) & set(table.columns))
            table[text] = table[text].astype(str)
        else:
            with warnings.catch_warnings():
                # a row longer than the header: pandas only warns and drops the extra field
                warnings.simplefilter("error", pd.errors.ParserWarning)
                table = pd.read_csv(path, dtype={c: str for c in text_columns}, keep_default_na=False,
                                    na_values=[], skipinitialspace=True, index_col=False)
    except (pd.errors.ParserError, pd.errors.ParserWarning, pd.errors.EmptyDataError, ValueError, OSError) as exc:
        fail(path, f"cannot be read as a table: {' '.join(str(exc).split())}")
    missing = [c for c in columns if c not in table.columns]
    extra = [c for c in table.columns if c not in columns and c not in optional]
    if missing:
        fail(path, f"missing column(s) {', '.join(missing)} (expected {', '.join(columns)})")
    if extra:
        fail(path, f"unknown column(s) {', '.join(map(str, extra))} (expected {', '.join(columns)})")
    table = table[list(columns)].reset_index(drop=True)
    for column in columns:
        if column in text_columns:
            blank = table[column].astype(str).str.strip() == ""
            if blank.any():
                fail(path, f"{column} is empty", line_of(path, int(np.flatnonzero(blank)[0])))
            table[column] = table[column].astype(str).str.strip()
            continue
        values = pd.to_numeric(table[column], errors="coerce")
        bad = ~np.isfinite(values.to_numpy(dtype=float))
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            fail(path, f"{column} = {str(table[column].iloc[row])!r} is not a finite number", line_of(path, row))
        table[column] = values.astype(float)
    return table


def _parse_factors(data: Any, path: Path, frame: Frame | MatrixModel) -> tuple[Factor, ...]:
    if not isinstance(data, dict):
        fail(path, "factors: expected tables [factors.NAME]")
    factors = []
    for name, table in data.items():
        where = f"factors.{name}"
        if not isinstance(table, dict):
            fail(path, f"{where}: expected a table")
        unknown = sorted(set(table) - {"kind", "joint", "levels"})
        if unknown:
            fail(path, f"{where}.{unknown[0]}: unknown key (allowed: joint, kind, levels)")
        kind = table.get("kind")
        if kind not in FACTOR_KINDS:
            fail(path, f"{where}.kind: {kind!r} is not one of {', '.join(FACTOR_KINDS)}")
        joint = table.get("joint")
        if kind == "tightening":
            if joint is None:
                fail(path, f"{where}.joint: required for a tightening factor (the frame joint it acts on)")
            if joint not in frame.joint_names:
                fail(path, f"{where}.joint: {joint!r} is not a joint of {frame.source} "
                            f"(joints: {', '.join(frame.joint_names) or 'none'})")
        elif joint is not None:
            fail(path, f"{where}.joint: only tightening factors name a joint")
        levels = table.get("levels")
        if not isinstance(levels, dict) or not levels:
            fail(path, f"{where}.levels: expected a non-empty table of level = description")
        factors.append(Factor(name, kind, {str(k): str(v) for k, v in levels.items()}, joint))
    return tuple(factors)


def _read_settings(path: Path) -> dict[str, Any]:
    """``campaign.toml``: known keys, required keys and their types checked."""
    data = _read_toml(path)
    unknown = sorted(set(data) - _CAMPAIGN_KEYS)
    if unknown:
        fail(path, f"{unknown[0]}: unknown key (allowed: {', '.join(sorted(_CAMPAIGN_KEYS))})")
    for key in ("name", "frame", "synthetic"):
        if key not in data:
            expected = "true or false" if key == "synthetic" else "a string"
            fail(path, f"{key}: required key is missing (expected {expected})")
    for key in ("name", "frame", "description", "source"):
        if key in data and not isinstance(data[key], str):
            fail(path, f"{key}: expected a string, got {data[key]!r}")
    if not isinstance(data["synthetic"], bool):
        fail(path, f"synthetic: expected true or false, got {data['synthetic']!r}")
    quantity = data.get("quantity", "accelerance")
    if quantity not in QUANTITIES:
        fail(path, f"quantity: {quantity!r} is not one of {', '.join(QUANTITIES)}")
    reference = data.get("reference", "force")
    if reference not in REFERENCES:
        fail(path, f"reference: {reference!r} is not one of {', '.join(REFERENCES)}")
    return data


def _frf_path(directory: Path, path: Path, data: dict[str, Any]) -> Path | None:
    """``frf.csv`` or ``frf.parquet`` (not both), or None; a campaign with FRFs states its quantity."""
    frf_csv, frf_parquet = directory / "frf.csv", directory / "frf.parquet"
    if frf_csv.exists() and frf_parquet.exists():
        fail(directory, "holds both frf.csv and frf.parquet; keep one")
    frf_path = frf_csv if frf_csv.exists() else frf_parquet if frf_parquet.exists() else None
    if frf_path is not None and "quantity" not in data:
        fail(path, "quantity: required key is missing (expected receptance, mobility or accelerance)")
    return frf_path


def _read_design(design_path: Path, factors: tuple[Factor, ...]) -> pd.DataFrame:
    columns = ("test_id",) + tuple(f.name for f in factors)
    design = _read_table(design_path, columns, columns)
    check_duplicates(design, ["test_id"], design_path)
    for factor in factors:
        bad = ~design[factor.name].isin(factor.levels)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            fail(design_path, f"{factor.name} = {design[factor.name].iloc[row]!r} is not a declared "
                               f"level (levels: {', '.join(factor.levels)})", line_of(design_path, row))
    return design


def _read_frf(frf_path: Path, frame: Frame | MatrixModel, ids: set[str], design_path: Path) -> pd.DataFrame:
    """The long-form FRF table: known tests and sensors, frequencies increasing, every test present."""
    frf = _read_table(frf_path, FRF_COLUMNS, ("test_id", "sensor"))
    check_tests(frf, frf_path, ids, design_path)
    sensors = {s.name for s in frame.sensors}
    bad = ~frf["sensor"].isin(sensors)
    if bad.any():
        row = int(np.flatnonzero(bad)[0])
        fail(frf_path, f"sensor {frf['sensor'].iloc[row]!r} is not a sensor of {frame.source} "
                        f"(sensors: {', '.join(sorted(sensors)) or 'none'})", line_of(frf_path, row))
    check_duplicates(frf, ["test_id", "sensor", "frequency_hz"], frf_path)
    step = frf.groupby(["test_id", "sensor"], sort=False)["frequency_hz"].diff()
    not_increasing = (step <= 0).to_numpy()
    if not_increasing.any():
        row = int(np.flatnonzero(not_increasing)[0])
        fail(frf_path, f"frequency_hz = {frf['frequency_hz'].iloc[row]:g} does not increase within "
                        f"test {frf['test_id'].iloc[row]}, sensor {frf['sensor'].iloc[row]}",
              line_of(frf_path, row))
    if (frf["frequency_hz"] < 0).any():
        row = int(np.flatnonzero(frf["frequency_hz"] < 0)[0])
        fail(frf_path, "frequency_hz is negative", line_of(frf_path, row))
    without = sorted(ids - set(frf["test_id"].unique()), key=str)  # unique first: 0.2 s less on 420 000 rows
    if without:
        fail(frf_path, f"test {without[0]} of {design_path.name} has no rows")
    if frame.excitation is None:
        fail(frame.source, "excitation: required when a campaign has FRFs")
    return frf


def _read_modes(modes_path: Path, ids: set[str], design_path: Path) -> pd.DataFrame:
    modes = _read_table(modes_path, MODES_COLUMNS, ("test_id",), MODES_OPTIONAL)
    check_tests(modes, modes_path, ids, design_path)
    check_duplicates(modes, ["test_id", "mode"], modes_path)
    check_values(modes, modes_path, {"mode": "integer >= 1", "frequency_hz": "positive",
                                      "damping_ratio": "in [0, 1)"})
    modes["mode"] = modes["mode"].astype(np.int64)
    return modes


def _read_moments(moments_path: Path) -> pd.DataFrame:
    moments = _read_table(moments_path, MOMENTS_COLUMNS, ())
    check_duplicates(moments, ["mode"], moments_path)
    check_values(moments, moments_path, {"mode": "integer >= 1", "mean_hz": "positive",
                                          "std_hz": "not negative"})
    moments["mode"] = moments["mode"].astype(np.int64)
    return moments


def load_campaign(directory: str | Path) -> Campaign:
    """Load and validate a campaign directory (CONTRACTS.md section 2). The files are only read.

    Parameters
    ----------
    directory : the campaign directory (holding ``campaign.toml``).

    Returns
    -------
    Campaign
        The validated campaign; ``test_id`` integers when every id is one.

    Raises
    ------
    CampaignError
        One line naming the file, the line and the problem.
    """
    directory = Path(directory)
    if not directory.is_dir():
        fail(directory, "is not a campaign directory")
    path = directory / "campaign.toml"
    data = _read_settings(path)
    model_path = directory / data["frame"]
    try:
        frame = read_matrix_model(model_path) if is_matrix_model(model_path) else read_frame(model_path)
    except (FrameFileError, MatrixModelError) as exc:
        raise CampaignError(str(exc)) from None
    factors = _parse_factors(data.get("factors", {}), path, frame)
    frf_path = _frf_path(directory, path, data)
    design_path = directory / "design.csv"
    modes_path, moments_path = directory / "modes.csv", directory / "moments.csv"

    design = None
    if design_path.exists():
        design = _read_design(design_path, factors)
    elif frf_path is not None or modes_path.exists():
        fail(design_path, "required file is missing (the campaign has tests)")
    ids = set(design["test_id"]) if design is not None else set()
    frf = _read_frf(frf_path, frame, ids, design_path) if frf_path is not None else None
    modes = _read_modes(modes_path, ids, design_path) if modes_path.exists() else None
    moments = _read_moments(moments_path) if moments_path.exists() else None
    if design is None and frf is None and modes is None and moments is None:
        fail(directory, "holds neither tests (design.csv) nor moments.csv")
    integer_ids(design, frf, modes)
    return Campaign(name=data["name"], frame=frame, synthetic=data["synthetic"],
                    quantity=data.get("quantity", "accelerance"), reference=data.get("reference", "force"),
                    description=data.get("description", ""), source=data.get("source", ""),
                    factors=factors, design=design, frf=frf, modes=modes, moments=moments,
                    frame_file=data["frame"], path=directory)


def campaign_toml(campaign: Campaign) -> str:
    """The ``campaign.toml`` text of ``campaign``."""
    out = [f"name = {toml_string(campaign.name)}"]
    if campaign.description:
        out.append(f"description = {toml_string(campaign.description)}")
    out += [f"frame = {toml_string(campaign.frame_file)}", f"quantity = {toml_string(campaign.quantity)}",
            f"reference = {toml_string(campaign.reference)}",
            f"synthetic = {'true' if campaign.synthetic else 'false'}"]
    if campaign.source:
        out.append(f"source = {toml_string(campaign.source)}")
    for factor in campaign.factors:
        out += ["", f"[factors.{factor.name}]", f"kind = {toml_string(factor.kind)}"]
        if factor.joint is not None:
            out.append(f"joint = {toml_string(factor.joint)}")
        levels = ", ".join(f"{toml_string(k)} = {toml_string(v)}" for k, v in factor.levels.items())
        out.append(f"levels = {{ {levels} }}")
    return "\n".join(out) + "\n"


def _csv(table: pd.DataFrame, columns: tuple[str, ...]) -> str:
    return table[list(columns)].to_csv(index=False, float_format="%.17g", lineterminator="\n")


def _model_files(campaign: Campaign) -> dict[str, str | bytes]:
    """The frame file, or a matrix model's file and the files it names, where campaign.toml's ``frame`` says."""
    if not isinstance(campaign.frame, MatrixModel):
        return {campaign.frame_file: frame_to_toml(campaign.frame)}
    # the matrices are copied as they were read: rewriting them could only lose digits
    where = Path(campaign.frame_file).parent
    source = Path(campaign.frame.source)
    return {campaign.frame_file: source.read_bytes(),
            **{(where / name).as_posix(): path.read_bytes() for name, path in model_files(source).items()}}


def campaign_files(campaign: Campaign, frf_format: str = "csv", frf_dtype: str = "float64") -> dict[str, str | bytes]:
    """The files of ``campaign`` as a contract directory: file name -> content (see `write_campaign`)."""
    files: dict[str, str | bytes] = {"campaign.toml": campaign_toml(campaign), **_model_files(campaign)}
    if campaign.design is not None:
        files["design.csv"] = _csv(campaign.design, ("test_id",) + tuple(f.name for f in campaign.factors))
    if campaign.frf is not None:
        if frf_format == "parquet":
            files["frf.parquet"] = _frf_parquet(campaign.frf, frf_dtype)
        elif frf_format == "csv":
            files["frf.csv"] = _csv(campaign.frf, FRF_COLUMNS)
        else:
            raise ValueError(f"frf_format: {frf_format!r} is not csv or parquet")
    if campaign.modes is not None:
        files["modes.csv"] = _csv(campaign.modes, MODES_COLUMNS)
    if campaign.moments is not None:
        files["moments.csv"] = _csv(campaign.moments, MOMENTS_COLUMNS)
    return files


def _frf_parquet(frf: pd.DataFrame, frf_dtype: str) -> bytes:
    table = frf[list(FRF_COLUMNS)].copy()
    table = table.astype({"real": frf_dtype, "imag": frf_dtype})
    frequency = table["frequency_hz"].to_numpy(dtype=float)
    if np.array_equal(frequency.astype(np.float32).astype(float), frequency):
        table["frequency_hz"] = frequency.astype(np.float32)  # exact (e.g. multiples of 1/4 Hz)
    buffer = io.BytesIO()
    # gzip: noisy FRF values hardly compress, but it is the smallest of pyarrow's codecs here
    table.to_parquet(buffer, index=False, compression="gzip")
    return buffer.getvalue()


def write_campaign(campaign: Campaign, directory: str | Path, force: bool = False,
                   frf_format: str = "csv", frf_dtype: str = "float64") -> Path:
    """Write ``campaign`` as a contract directory, all files or none (`write_outputs`).

    Parameters
    ----------
    directory : the campaign directory, created when missing.
    force : replace existing files.
    frf_format : "csv" or "parquet" (smaller; the contract accepts either).
    frf_dtype : "float64" or "float32" for the parquet FRF values (float32 keeps 7 digits: for
        measured data with noise well above 1e-7 this loses nothing).

    Returns
    -------
    Path
        ``directory``.
    """
    directory = Path(directory)
    write_outputs(directory, campaign_files(campaign, frf_format, frf_dtype), force=force)
    return directory


def frf_set(campaign: Campaign, test_id: Any) -> FRFSet:
    """The FRFs of one test as arrays: sensors in the frame's order, one frequency axis.

    Raises
    ------
    CampaignError
        The test is unknown, its sensors do not share one frequency axis, or a curve has no
        resonance to fit (`check_flat_curves`).
    """
    if campaign.frf is None:
        fail(campaign.path or campaign.name, "has no FRFs (frf.csv)")
    rows = campaign.frf[campaign.frf["test_id"] == test_id]
    if rows.empty:
        fail(campaign.path or campaign.name, f"frf: no rows for test_id {test_id!r}")
    check_flat_curves(rows, campaign.path or campaign.name)
    present = set(rows["sensor"].unique())
    order = [s.name for s in campaign.frame.sensors if s.name in present]
    curves = [rows[rows["sensor"] == s] for s in order]
    axis = curves[0]["frequency_hz"].to_numpy()
    for s, c in zip(order, curves):
        if c.shape[0] != axis.size or not np.array_equal(c["frequency_hz"].to_numpy(), axis):
            fail(campaign.path or campaign.name, f"frf: test {test_id}: sensor {s} has another frequency axis")
    values = np.stack([c["real"].to_numpy() + 1j * c["imag"].to_numpy() for c in curves])
    return FRFSet(axis.astype(float), values, tuple(order), campaign.quantity)


# Paper 2.2.2: the high excitation amplitude is five times the low one.
PAPER_AMPLITUDE_RATIOS = {"low": 1.0, "high": 5.0}


def amplitude_of_tests(campaign: Campaign) -> np.ndarray | None:
    """Each test's excitation amplitude relative to the lowest level, or None without an amplitude factor.

    Level keys that are numbers (volts, newtons, ...) are taken as amplitudes; ``low`` and ``high``
    follow the paper (`PAPER_AMPLITUDE_RATIOS`).
    """
    factors = [f for f in campaign.factors if f.kind == "amplitude"]
    if not factors:
        return None
    factor = factors[0]
    assert campaign.design is not None  # load_campaign reads a design wherever there are factors
    keys = campaign.design.set_index("test_id").reindex(campaign.test_ids)[factor.name].astype(str)
    try:
        values = np.array([float(k) for k in keys])
    except ValueError:
        unknown = sorted(set(keys) - set(PAPER_AMPLITUDE_RATIOS))
        if unknown:
            fail(campaign.path or campaign.name, f"factor {factor.name}: amplitude levels {unknown} are neither "
                  f"numbers nor {'/'.join(PAPER_AMPLITUDE_RATIOS)}")
        values = np.array([PAPER_AMPLITUDE_RATIOS[k] for k in keys])
    if np.any(values <= 0) or not np.all(np.isfinite(values)):
        fail(campaign.path or campaign.name, f"factor {factor.name}: amplitude levels must be positive numbers")
    return values / values.min()
