"""`workbench import`: a new campaign (CONTRACTS.md section 2) from files as test software exports them.

Each FILE is a universal file (``.uff``, ``.unv``, ``.uf``: datasets 58 and 58b, through
`workbench.io.uff`) or a tidy CSV (``sensor, frequency_hz, real, imag`` and optionally ``test_id``).
A file written by the workbench carries its test ids in the dataset headers; any other file is one
test, named by the file's stem (``run_03.uff`` is test ``run_03``). ``--design`` gives the factors
(one column per factor beside ``test_id``); without it the campaign has one factor, ``test``.

The campaign is validated by reading it back (`load_campaign`) from a scratch copy before a file is
written, so what the command writes is a campaign every other command accepts.
"""

from __future__ import annotations

import re
import tempfile
from collections.abc import Sequence
from pathlib import Path

import pandas as pd

from workbench.io.campaign import FRF_COLUMNS, Campaign, CampaignError, Factor, campaign_files, load_campaign
from workbench.io.outputs import IMPORT_STAMP
from workbench.io.uff import read_uff
from workbench.model.frame import Frame
from workbench.model.frame_file import read_frame
from workbench.model.matrix_file import is_matrix_model, read_matrix_model
from workbench.model.matrix_model import MatrixModel
from workbench.model.modal import QUANTITIES

__all__ = ["UFF_SUFFIXES", "IMPORT_STAMP", "import_campaign", "imported_files"]

UFF_SUFFIXES = (".uff", ".unv", ".uf")


def _csv_frfs(path: Path, frame: Frame | MatrixModel) -> pd.DataFrame:
    try:
        table = pd.read_csv(path, dtype={"test_id": str, "sensor": str})
    except (OSError, ValueError, pd.errors.ParserError) as exc:
        raise ValueError(f"{path}: cannot be read as CSV: {' '.join(str(exc).split())}") from None
    missing = [c for c in ("sensor", "frequency_hz", "real", "imag") if c not in table.columns]
    if missing:
        raise ValueError(f"{path}: column {missing[0]!r} is missing (a tidy FRF CSV has "
                         "test_id (optional), sensor, frequency_hz, real, imag)")
    if "test_id" not in table.columns:
        table.insert(0, "test_id", path.stem)
    known = {s.name for s in frame.sensors}
    unknown = sorted(set(table["sensor"]) - known)
    if unknown:
        raise ValueError(f"{path}: sensor {unknown[0]!r} is not a sensor of {frame.source} "
                         f"(sensors: {', '.join(sorted(known))})")
    return table[list(FRF_COLUMNS)]


def _read_file(path: Path, frame: Frame | MatrixModel, quantity: str | None) -> tuple[pd.DataFrame, str | None, str]:
    """One file's FRF table, its quantity (None for a CSV: the option says) and its reference."""
    if not path.is_file():
        raise ValueError(f"{path}: no such file")
    if path.suffix.lower() in UFF_SUFFIXES:
        return read_uff(path, frame, quantity, test_id=path.stem)
    if path.suffix.lower() == ".csv":
        return _csv_frfs(path, frame), None, "force"
    raise ValueError(f"{path}: unknown file type {path.suffix!r}: a universal file ({', '.join(UFF_SUFFIXES)}) "
                     "or a tidy .csv")


def _levels(values: pd.Series) -> dict[str, str]:
    """A factor's levels in increasing order: numerically when every value is a number."""
    unique = list(dict.fromkeys(values.astype(str)))
    try:
        unique.sort(key=float)
    except ValueError:
        pass  # names keep the order of the design
    return {v: v for v in unique}


def _factors(design: pd.DataFrame, frame: Frame | MatrixModel) -> tuple[Factor, ...]:
    """Each design column a factor: ``amplitude`` by name, a tightening of a joint it names, else other."""
    joints = set(frame.joint_names)
    factors = []
    for column in design.columns:
        if column == "test_id":
            continue
        joint = re.sub(r"^(bolt|joint)_", "", column)
        if column.lower() == "amplitude":
            factors.append(Factor(column, "amplitude", _levels(design[column])))
        elif joint in joints:
            factors.append(Factor(column, "tightening", _levels(design[column]), joint))
        else:
            factors.append(Factor(column, "other", _levels(design[column])))
    return tuple(factors)


def _design(path: Path | None, ids: list[str], frame: Frame | MatrixModel) -> tuple[pd.DataFrame, tuple[Factor, ...]]:
    if path is None:
        design = pd.DataFrame({"test_id": ids, "test": ids})
        return design, (Factor("test", "other", {i: i for i in ids}),)
    try:
        design = pd.read_csv(path, dtype=str, keep_default_na=False)
    except (OSError, ValueError, pd.errors.ParserError) as exc:
        raise ValueError(f"{path}: cannot be read as CSV: {' '.join(str(exc).split())}") from None
    if "test_id" not in design.columns:
        raise ValueError(f"{path}: column 'test_id' is missing (--design: test_id and one column per factor)")
    if len(design.columns) < 2:
        raise ValueError(f"{path}: no factor column beside test_id")
    listed = list(design["test_id"])
    for tid in listed:
        if tid not in ids:
            raise ValueError(f"{path}: test_id {tid!r} has no FRF in the imported files (tests: {', '.join(ids)})")
    for tid in ids:
        if tid not in listed:
            raise ValueError(f"{path}: test_id {tid!r} of the imported files has no row")
    return design, _factors(design, frame)


def import_campaign(files: Sequence[str | Path], frame_path: str | Path, design_path: str | Path | None = None,
                    name: str | None = None, quantity: str | None = None) -> Campaign:
    """The campaign of ``files`` on the model ``frame_path`` (module docstring), validated.

    Raises
    ------
    ValueError
        One line naming the file and the problem: unreadable, no FRF, a sensor the frame lacks,
        quantities or references that disagree, a test and sensor given twice, a design that does
        not match the tests.
    """
    frame_path = Path(frame_path)
    matrix = frame_path.is_file() and is_matrix_model(frame_path)
    frame: Frame | MatrixModel = read_matrix_model(frame_path) if matrix else read_frame(frame_path)
    if quantity is not None and quantity not in QUANTITIES:
        raise ValueError(f"--quantity: {quantity!r} is not one of {', '.join(QUANTITIES)}")
    tables: list[pd.DataFrame] = []
    seen: dict[tuple, str] = {}
    found_quantity, found_reference = quantity, None
    for raw in files:
        path = Path(raw)
        table, q, reference = _read_file(path, frame, quantity)
        if q is not None and found_quantity is not None and q != found_quantity:
            raise ValueError(f"{path}: holds {q}, where {found_quantity} was "
                             f"{'asked for' if quantity else 'in the files before'}")
        found_quantity = found_quantity or q
        if found_reference is not None and reference != found_reference:
            raise ValueError(f"{path}: FRFs over {reference}, the files before over {found_reference}")
        found_reference = reference
        table = table.assign(test_id=table["test_id"].astype(str))
        for key in table[["test_id", "sensor"]].drop_duplicates().itertuples(index=False):
            if tuple(key) in seen:
                raise ValueError(f"{path}: test {key[0]!r}, sensor {key[1]!r} was already read from {seen[tuple(key)]}")
            seen[tuple(key)] = path.name
        tables.append(table)
    if found_quantity is None:
        raise ValueError("--quantity: the CSV files do not say what they hold: receptance, mobility or accelerance")
    frf = pd.concat(tables, ignore_index=True)
    ids = list(dict.fromkeys(frf["test_id"]))
    design, factors = _design(None if design_path is None else Path(design_path), ids, frame)
    names = ", ".join(Path(f).name for f in files)
    return Campaign(name=name or f"imported from {Path(files[0]).name}" + (" and more" if len(files) > 1 else ""),
                    frame=frame, frame_file="model.toml" if matrix else "frame.toml", synthetic=False,
                    quantity=found_quantity, reference=found_reference or "force",
                    factors=factors, design=design, frf=frf, source=f"{IMPORT_STAMP} {names}")


def imported_files(campaign: Campaign, frame_path: str | Path) -> dict[str, str | bytes]:
    """The campaign's files, the frame file copied byte for byte, after reading them back as a campaign.

    Raises
    ------
    ValueError
        The written campaign would not load (the message names the file inside the campaign).
    """
    files = campaign_files(campaign)  # a matrix model's files are copied byte for byte there
    if not isinstance(campaign.frame, MatrixModel):
        files[campaign.frame_file] = Path(frame_path).read_bytes()
    with tempfile.TemporaryDirectory() as scratch:
        for fname, content in files.items():
            target = Path(scratch) / fname
            target.write_bytes(content if isinstance(content, bytes) else content.encode("utf-8"))
        try:
            load_campaign(scratch)
        except CampaignError as exc:  # name the file as the user will find it, not the scratch copy
            raise ValueError(str(exc).replace(str(scratch) + "/", "")) from None
    return files
