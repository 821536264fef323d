"""FRF exchange with modal-test software: Universal File Format dataset 58, through pyuff.

Dataset 58 ("function at nodal DOF") is what modal-test software (LMS Test.Lab, ME'scope,
Siemens Simcenter, pyuff itself) exports an FRF as: a header of 11 records and the complex ordinate
values, one dataset per response/reference pair. `export_frfs` writes every test x sensor FRF of
a campaign as one dataset each; `import_frfs` reads them back into the contract's long-form FRF
table (CONTRACTS.md section 2: ``test_id, sensor, frequency_hz, real, imag``); `campaign_from_uff`
wraps the table into a `Campaign`.

How the workbench fills a dataset 58 (and reads its own files back):

========================  ======================================================================
record / field            value
========================  ======================================================================
id1                       ``workbench frf: <quantity> over <reference>`` (marks our files)
id2                       ``test_id=<test_id>``
id3                       ``NONE`` (the creation date: left out so that files are reproducible)
id4                       ``sensor=<sensor name>``
id5                       the campaign's name (cut to 80 characters)
function type             4 (frequency response function); function id 1, 2, ... in file order
response node, direction  frame point index + 1 (the order of ``[points]`` in the frame file),
                          direction ``ux`` -> 1 (+X), ``uy`` -> 2 (+Y), ``rz`` -> 6 (+Z rotation)
reference node, direction the frame's ``[excitation]`` point and dof, coded the same way
ordinate data type        6, complex double precision
abscissa                  even (``abscissa_spacing = 1``, minimum and increment in the header) when
                          ``minimum + k * increment`` rebuilds every line bit for bit, else uneven
                          (every line stored)
ordinate specific type    8 displacement (receptance), 11 velocity (mobility), 12 acceleration
                          (accelerance)
denominator               13 excitation force; for ``reference = "voltage"`` 0 with axis label
                          ``Voltage`` and units ``V``
abscissa specific type    18 frequency, Hz
========================  ======================================================================

Files are written in the binary variant "58b" by default: the ordinates (and an uneven
abscissa) are stored as IEEE float64, so a round trip keeps every value exactly. The ASCII
variant (``binary=False``) keeps 12 significant digits of the ordinates (pyuff's ``E20.12``
format) and 6 of an uneven abscissa (``E13.5``).

Reading a file written by other software, a dataset is mapped to a sensor by its response
``(node, |direction|)``: through ``sensor_map`` when given, else through the frame's own
numbering above. A negative direction code (-X, -Y, -Z rotation) on the response or the
reference flips the FRF's sign, so that the table is in the frame's +x, +y, +rz axes. A
dataset 164 (units) and the records' axis labels (``mm/s^2``, ``g``, ``lbf``, ``rad/s``) convert them
to SI (`workbench.io.uff_units`); contradicting labels are refused. Datasets of other types
(geometry 15/2411, ...) are ignored.

With `campaign` and the report this is one of the modules that import pandas: it builds
campaign tables (STYLE.md layering).
"""

from __future__ import annotations

import math
import re
import tempfile
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NoReturn, cast

import numpy as np
import pandas as pd
import pyuff

from workbench.io.campaign import FRF_COLUMNS, Campaign, Factor
from workbench.io.outputs import write_file
from workbench.io.uff_nodes import DIRECTION_CODES, sensor_lookup, uff_points
from workbench.io.uff_units import file_units, record_units
from workbench.model.frame import Frame
from workbench.model.matrix_model import MatrixModel
from workbench.model.modal import QUANTITIES

__all__ = [
    "DIRECTION_CODES",
    "ORDINATE_TYPES",
    "FORCE_TYPE",
    "FREQUENCY_TYPE",
    "export_frfs",
    "import_frfs",
    "read_uff",
    "uff_quantity",
    "campaign_from_uff",
]

ORDINATE_TYPES = {"receptance": 8, "mobility": 11, "accelerance": 12}  # displacement, velocity, acceleration
FORCE_TYPE = 13  # excitation force (record 10, ordinate denominator)
FREQUENCY_TYPE = 18  # record 8, abscissa
FRF_FUNCTION_TYPE = 4
_MARK = "workbench frf"
_ID_WIDTH = 80
_UNITS = {"receptance": ("m", "rad"), "mobility": ("m/s", "rad/s"), "accelerance": ("m/s2", "rad/s2")}


def _even_axis(axis: np.ndarray) -> bool:
    """True when the header's ``%13.5e`` minimum and increment rebuild ``axis`` exactly."""
    if axis.size < 2:
        return False  # pyuff needs two lines to form an increment
    start, step = float(f"{axis[0]:.5e}"), float(f"{axis[1] - axis[0]:.5e}")
    return bool(np.array_equal(start + np.arange(axis.size) * step, axis))


def _id_field(text: str, what: str) -> str:
    if len(text) > _ID_WIDTH or "\n" in text or "\r" in text:
        raise ValueError(f"export_frfs: {what} {text!r} does not fit a UFF id line "
                         f"({_ID_WIDTH} characters, one line)")
    return text


def export_frfs(campaign: Campaign, path: str | Path, binary: bool = True) -> Path:
    """Write every test x sensor FRF of ``campaign`` as one UFF dataset 58 (see the module notes).

    Parameters
    ----------
    campaign : a campaign with FRFs (``campaign.frf`` long form, ``campaign.quantity`` in
        receptance m/N, mobility m/s/N or accelerance m/s2/N; rotational sensors in rad, rad/s,
        rad/s2 per N).
    path : the ``.uff`` file; written whole or not at all (`workbench.io.outputs.write_outputs`),
        an existing file is replaced.
    binary : True (default) for dataset 58b, exact float64; False for ASCII (12 significant
        digits).

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    ValueError
        No FRFs, no excitation, a non-finite value, an id that does not fit an 80-character id
        line, or (ASCII only) an uneven axis that 6 significant digits cannot keep increasing.
    """
    path = Path(path)
    frame = campaign.frame
    if campaign.frf is None or campaign.frf.empty:
        raise ValueError(f"export_frfs: campaign {campaign.name!r} has no FRFs")
    sensors, reference_point = uff_points(frame)
    if reference_point is None:
        raise ValueError(f"export_frfs: {frame.source}: excitation: required to code the reference node")
    ordinate_units = _UNITS[campaign.quantity]
    voltage = campaign.reference == "voltage"
    datasets: list[dict[str, Any]] = []
    for (test_id, sensor), rows in campaign.frf.groupby(["test_id", "sensor"], sort=False):
        if sensor not in sensors:
            raise ValueError(f"export_frfs: sensor {sensor!r} is not a sensor of {frame.source}")
        axis = rows["frequency_hz"].to_numpy(dtype=np.float64)
        values = rows["real"].to_numpy(dtype=np.float64) + 1j * rows["imag"].to_numpy(dtype=np.float64)
        if not (np.all(np.isfinite(axis)) and np.all(np.isfinite(values))):
            raise ValueError(f"export_frfs: test {test_id}, sensor {sensor}: NaN or infinite value "
                             "(pyuff would write it as 0)")
        even = _even_axis(axis)
        if not binary and not even and np.any(np.diff([float(f"{x:.5e}") for x in axis]) <= 0):
            raise ValueError(f"export_frfs: test {test_id}, sensor {sensor}: the uneven frequency axis "
                             "does not stay increasing at the 6 digits of ASCII UFF; use binary=True")
        node, direction = sensors[sensor]
        rotation = direction > 3
        dset = {
            "type": 58, "binary": int(binary),
            "id1": _id_field(f"{_MARK}: {campaign.quantity} over {campaign.reference}", "quantity"),
            "id2": _id_field(f"test_id={test_id}", "test_id"),
            "id3": "NONE",
            "id4": _id_field(f"sensor={sensor}", "sensor"),
            "id5": (campaign.name or "NONE")[:_ID_WIDTH].replace("\n", " ") or "NONE",
            "func_type": FRF_FUNCTION_TYPE, "func_id": len(datasets) + 1, "ver_num": 0, "load_case_id": 0,
            "rsp_ent_name": "NONE", "rsp_node": node, "rsp_dir": direction,
            "ref_ent_name": "NONE", "ref_node": reference_point[0], "ref_dir": reference_point[1],
            "abscissa_spacing": int(even),
            "abscissa_spec_data_type": FREQUENCY_TYPE, "abscissa_axis_lab": "Frequency",
            "abscissa_axis_units_lab": "Hz",
            "ordinate_spec_data_type": ORDINATE_TYPES[campaign.quantity],
            "ordinate_axis_lab": campaign.quantity.capitalize(),
            "ordinate_axis_units_lab": ordinate_units[rotation],
            "orddenom_spec_data_type": 0 if voltage else FORCE_TYPE,
            "orddenom_axis_lab": "Voltage" if voltage else "Force",
            "orddenom_axis_units_lab": "V" if voltage else "N",
            "z_axis_spec_data_type": 0,
            "x": axis, "data": values,
        }
        datasets.append(dset)
    return write_file(path, _uff_bytes(datasets))


def _uff_bytes(datasets: list[dict[str, Any]]) -> bytes:
    """The universal file of ``datasets`` as pyuff writes it (pyuff writes only to a named file)."""
    with tempfile.TemporaryDirectory() as scratch, warnings.catch_warnings():
        # pyuff's binary writer (2.4-2.5) reopens the file and leaves that handle for the
        # garbage collector, which closes it (flushing the closing "-1") with a ResourceWarning
        # as _write58 returns; a warning turned into an error would lose that last line.
        # Its "overwrite" mode reopens the file with "wb" after writing the first header, which
        # erases that header: so start from an empty file and append every dataset.
        warnings.simplefilter("ignore", ResourceWarning)
        scratch_file = Path(scratch) / "frf.uff"
        scratch_file.write_bytes(b"")
        pyuff.UFF(str(scratch_file)).write_sets(datasets, mode="add")
        return scratch_file.read_bytes()


_DATASET_58_START = re.compile(rb"(?:^|\n)[ \t]*-1[ \t]*\r?\n[ \t]*58")


def _check_complete(path: Path, sets: list[dict[str, Any]]) -> None:
    """Refuse a file cut inside a dataset: pyuff drops such a dataset without a word.

    Every dataset, ASCII or binary (58b), opens with a ``-1`` line and closes with ``-1``: a file that
    does not end with one, or in which more datasets 58 open than pyuff could read, was cut short.
    """
    data = path.read_bytes()
    if not data.lstrip().startswith(b"-1"):
        return  # not a universal file at all: said later, when no dataset 58 is found
    opened = len(_DATASET_58_START.findall(data))
    read = sum(1 for d in sets if d.get("type") == 58)
    if not data.rstrip().endswith(b"-1") or opened > read:
        raise ValueError(f"{path}: truncated or damaged: {opened} datasets 58 begin in the file, {read} could be "
                         "read whole; export it again or copy it whole")


def _read_datasets(path: Path, header_only: bool = False) -> list[dict[str, Any]]:
    if not path.is_file():
        raise ValueError(f"{path}: no such UFF file")
    try:
        uff = pyuff.UFF(str(path))
        types = list(uff.get_set_types())
        sets = uff.read_sets(header_only=header_only) if types else []
    # pyuff raises bare Exception for every malformation; keep its text, name the file
    except Exception as exc:  # noqa: BLE001
        raise ValueError(f"{path}: cannot be read as a universal file: {' '.join(str(exc).split())}") from None
    if isinstance(sets, dict):
        sets = [sets]
    _check_complete(path, list(sets))
    return list(sets)


_Fail = Callable[[str], NoReturn]


def _failer(path: Path, index: int, dset: dict[str, Any]) -> _Fail:
    """Raise the one-line error of dataset ``index`` (0-based among datasets 58) of ``path``."""
    def fail(problem: str) -> NoReturn:
        raise ValueError(f"{path}: dataset {index} (id1 {dset.get('id1', '')!r}): {problem}")

    return fail


def _quantity_of(dset: dict[str, Any], fail: _Fail) -> str | None:
    code = int(dset.get("ordinate_spec_data_type", 0))
    for quantity, known in ORDINATE_TYPES.items():
        if code == known:
            return quantity
    if code == 0:
        return None  # unknown: the caller must say
    fail(f"ordinate specific data type {code} is not displacement (8), velocity (11) or acceleration (12)")


def _reference_of(dset: dict[str, Any]) -> str:
    """"force" for denominator type 13 (or 0 without a label: an FRF's default); "voltage" when labelled so."""
    labels = f"{dset.get('orddenom_axis_lab', '')} {dset.get('orddenom_axis_units_lab', '')}".lower().split()
    if int(dset.get("orddenom_spec_data_type", 0)) != FORCE_TYPE and ("voltage" in labels or "v" in labels):
        return "voltage"
    return "force"


@dataclass
class _Agreement:
    """What the datasets read so far share: one quantity, one reference, one excitation, no repeat."""

    asked: str | None  # the quantity the caller asked for
    quantity: str | None = None
    reference: str | None = None
    excitations: set[tuple[int, int]] = field(default_factory=set)
    roving: bool = False  # references checked against the frame's excitation instead (roving hammer allowed)
    seen: set[tuple[Any, str]] = field(default_factory=set)


def _check_frf_kind(dset: dict[str, Any], fail: _Fail, agreed: _Agreement) -> str:
    """Check that ``dset`` is a complex FRF over frequency like the earlier ones; its reference."""
    if int(dset.get("func_type", -1)) != FRF_FUNCTION_TYPE:
        fail(f"function type {dset.get('func_type')} is not an FRF (4)")
    if int(dset.get("ord_data_type", 0)) not in (5, 6):
        fail(f"ordinate data type {dset.get('ord_data_type')} is real; an FRF is complex (5 or 6)")
    if int(dset.get("abscissa_spec_data_type", 0)) not in (0, FREQUENCY_TYPE):
        fail(f"abscissa specific data type {dset['abscissa_spec_data_type']} is not frequency (18)")
    this = _quantity_of(dset, fail) or agreed.asked
    if this is None:
        fail("the ordinate type is unknown (0): pass quantity= (receptance, mobility or accelerance)")
    if agreed.quantity is None:
        agreed.quantity = this
    if this != agreed.quantity:
        fail(f"inconsistent quantity: {this} after {agreed.quantity} in earlier datasets")
    if agreed.asked is not None and this != agreed.asked:
        fail(f"inconsistent quantity: the dataset holds {this}, {agreed.asked} was asked for")
    reference = _reference_of(dset)
    if agreed.reference is None:
        agreed.reference = reference
    if reference != agreed.reference:
        fail(f"inconsistent reference: {reference} after {agreed.reference} in earlier datasets")
    return reference


def _test_and_sensor(dset: dict[str, Any], fail: _Fail, frame: Frame | MatrixModel, lookup: dict[tuple[int, int], str],
                     test_id: Any, excitation: tuple[int, int] | None) -> tuple[Any, str]:
    """The test and the sensor of ``dset``: from its ids in our files, else from its response node."""
    if str(dset.get("id1", "")).startswith(_MARK):
        tid = str(dset.get("id2", "")).removeprefix("test_id=").strip()
        sensor = str(dset.get("id4", "")).removeprefix("sensor=").strip()
        if not str(dset.get("id2", "")).startswith("test_id=") or not tid:
            fail(f"id2 {dset.get('id2')!r} does not hold test_id=...")
        if sensor not in {s.name for s in frame.sensors}:
            fail(f"sensor {sensor!r} (id4) is not a sensor of {frame.source}")
        return tid, sensor
    key = (int(dset["rsp_node"]), abs(int(dset["rsp_dir"])))
    if excitation is not None and (int(dset["ref_node"]), abs(int(dset["ref_dir"]))) != excitation:
        if key != excitation:
            fail(f"reference node {dset['ref_node']} direction {dset['ref_dir']} is not the frame's excitation "
                 f"(node {excitation[0]} direction {excitation[1]}), nor is the response (a roving-hammer FRF)")
        # roving hammer: response fixed at the excitation, force roving; by reciprocity this is the
        # response at the force's point over a force at the excitation
        key = (int(dset["ref_node"]), abs(int(dset["ref_dir"])))
    if key not in lookup:
        fail(f"unknown response node {key[0]} direction {key[1]} "
             f"(known (node, direction): {sorted(lookup)}; pass sensor_map)")
    return test_id, lookup[key]


def _check_directions(dset: dict[str, Any], fail: _Fail, agreed: _Agreement, tid: Any, sensor: str) -> int:
    """Check the response and reference directions, one excitation, a new test/sensor; the reference direction."""
    if int(dset.get("rsp_dir", 0)) == 0 or abs(int(dset.get("rsp_dir", 0))) not in DIRECTION_CODES.values():
        fail(f"unknown response direction {dset.get('rsp_dir')} (a planar frame has 1 +X, 2 +Y, 6 +Z rotation)")
    ref_dir = int(dset.get("ref_dir", 0))
    if abs(ref_dir) not in DIRECTION_CODES.values():
        fail(f"unknown reference direction {ref_dir} (a planar frame has 1 +X, 2 +Y, 6 +Z rotation)")
    agreed.excitations.add((int(dset["ref_node"]), abs(ref_dir)))
    if len(agreed.excitations) > 1 and not agreed.roving:
        fail(f"a second reference (node, direction) {sorted(agreed.excitations)}: a campaign has one excitation")
    if (tid, sensor) in agreed.seen:
        fail(f"test {tid}, sensor {sensor} already read from an earlier dataset")
    agreed.seen.add((tid, sensor))
    return ref_dir


def _dataset_rows(dset: dict[str, Any], fail: _Fail, tid: Any, sensor: str, ref_dir: int, reference: str,
                  quantity: str, from_file: tuple[float, float] | None) -> pd.DataFrame:
    """The long-form rows of one dataset, in the frame's +x, +y, +rz axes and SI units.

    Units come from the record's labels and the file's dataset 164 (`workbench.io.uff_units`).
    """
    axis = np.asarray(dset["x"], dtype=np.float64)
    values = np.asarray(dset["data"], dtype=np.complex128)
    if axis.shape != values.shape or axis.size == 0:
        fail(f"{values.size} ordinates for {axis.size} abscissa values")
    if not (np.all(np.isfinite(axis)) and np.all(np.isfinite(values.real)) and np.all(np.isfinite(values.imag))):
        fail("NaN or infinite value")
    if np.any(np.diff(axis) <= 0) or axis[0] < 0:
        fail("the frequency axis is not strictly increasing from a non-negative value")
    rotation = abs(int(dset["rsp_dir"])) > DIRECTION_CODES["uz"]
    units = record_units(dset, quantity, rotation, from_file, reference == "voltage")
    if isinstance(units, str):
        fail(units)
    sign = math.copysign(1.0, int(dset["rsp_dir"])) * math.copysign(1.0, ref_dir)
    scale = sign * units.response / units.force
    if scale != 1.0:
        values = values * scale
    if units.frequency != 1.0:
        axis = axis * units.frequency
    return pd.DataFrame({"test_id": [tid] * axis.size, "sensor": sensor, "frequency_hz": axis,
                         "real": values.real.copy(), "imag": values.imag.copy()})


def _read(path: str | Path, frame: Frame | MatrixModel, sensor_map: dict[tuple[int, int], str] | None,
          quantity: str | None, test_id: Any) -> tuple[pd.DataFrame, str, str]:
    """The long-form table, the quantity and the reference of a UFF file; see `import_frfs`."""
    path = Path(path)
    if quantity is not None and quantity not in QUANTITIES:
        raise ValueError(f"quantity: {quantity!r} is not one of {', '.join(QUANTITIES)}")
    sets = _read_datasets(path)
    from_file = file_units(sets)
    lookup = sensor_lookup(frame, sensor_map)
    # with the frame's own numbering, the excitation is known: each reference must be it (or, for a
    # roving hammer, the response must); a sensor_map says nothing of the excitation's node
    excitation = uff_points(frame)[1] if sensor_map is None else None
    agreed = _Agreement(quantity, roving=excitation is not None)
    tables = []
    for index, dset in enumerate(d for d in sets if d.get("type") == 58):
        fail = _failer(path, index, dset)
        reference = _check_frf_kind(dset, fail, agreed)
        tid, sensor = _test_and_sensor(dset, fail, frame, lookup, test_id, excitation)
        ref_dir = _check_directions(dset, fail, agreed, tid, sensor)
        tables.append(_dataset_rows(dset, fail, tid, sensor, ref_dir, reference, cast(str, agreed.quantity),
                                    from_file))
    if not tables:
        raise ValueError(f"{path}: holds no dataset 58 (function at nodal DOF)")
    table = pd.concat(tables, ignore_index=True)[list(FRF_COLUMNS)]
    ids = table["test_id"].astype(str)
    if ids.str.fullmatch(r"0|[1-9]\d*").all():  # lossless only: "001" and "1" stay two tests
        table["test_id"] = ids.astype(np.int64)
    else:
        table["test_id"] = ids
    # both set by the first dataset
    return table, cast(str, agreed.quantity), cast(str, agreed.reference)


def import_frfs(path: str | Path, frame: Frame | MatrixModel, sensor_map: dict[tuple[int, int], str] | None = None,
                quantity: str | None = None, test_id: Any = 1) -> pd.DataFrame:
    """Read the FRF datasets (58) of a universal file into the contract's long-form FRF table.

    Parameters
    ----------
    path : a ``.uff`` / ``.unv`` file, ASCII or binary datasets 58.
    frame : the tested article's frame; its sensors name the table's ``sensor`` column.
    sensor_map : ``{(node, direction): sensor}`` for files whose node numbers are not the frame's
        (point index + 1); directions are the positive UFF codes 1 (+X), 2 (+Y), 6 (+Z rotation).
        Not needed for files written by `export_frfs`, which carry test and sensor in their ids.
    quantity : what the file must hold (receptance, mobility or accelerance); required when the
        datasets' ordinate type is unknown (0), else checked against it.
    test_id : the test of datasets not written by `export_frfs` (a foreign file is one test).

    Returns
    -------
    pandas.DataFrame
        Columns ``test_id, sensor, frequency_hz, real, imag`` (Hz; the quantity's SI unit per N,
        or per V for a voltage reference), datasets in file order. ``test_id`` is int64 when all
        ids are integers.

    Raises
    ------
    ValueError
        One line naming the file, the dataset index (0-based among datasets 58) and the problem:
        not an FRF dataset, real ordinates, inconsistent quantity or reference, unknown
        node/direction, a repeated test/sensor, NaN or infinite values, a bad frequency axis.
    """
    return _read(path, frame, sensor_map, quantity, test_id)[0]


def read_uff(path: str | Path, frame: Frame | MatrixModel, quantity: str | None = None,
             test_id: Any = 1) -> tuple[pd.DataFrame, str, str]:
    """`import_frfs` with what the file says of itself: ``(table, quantity, reference)``."""
    return _read(path, frame, None, quantity, test_id)


def uff_quantity(path: str | Path) -> tuple[str | None, str]:
    """The quantity (None when unknown) and reference ("force" or "voltage") of a file's first FRF dataset."""
    path = Path(path)
    for dset in _read_datasets(path, header_only=True):
        if dset.get("type") == 58 and int(dset.get("func_type", -1)) == FRF_FUNCTION_TYPE:
            code = int(dset.get("ordinate_spec_data_type", 0))
            quantity = next((q for q, c in ORDINATE_TYPES.items() if c == code), None)
            return quantity, _reference_of(dset)
    raise ValueError(f"{path}: holds no FRF dataset 58")


def campaign_from_uff(uff_path: str | Path, frame: Frame | MatrixModel, name: str, quantity: str | None = None, *,
                      synthetic: bool = False, factors: tuple[Factor, ...] = (),
                      design: pd.DataFrame | None = None, source: str = "", description: str = "",
                      sensor_map: dict[tuple[int, int], str] | None = None, test_id: Any = 1) -> Campaign:
    """A `Campaign` whose FRFs come from a universal file (see `import_frfs` for the arguments).

    ``design`` defaults to one row per test found, without factors (then ``factors`` must be
    empty). The quantity and the reference (force or voltage) are the file's. The campaign is
    built in memory; `workbench.io.campaign.write_campaign` writes it and `load_campaign` validates it.
    """
    table, found, reference = _read(uff_path, frame, sensor_map, quantity, test_id)
    if design is None:
        if factors:
            raise ValueError("campaign_from_uff: factors need a design (one row per test)")
        design = pd.DataFrame({"test_id": pd.unique(table["test_id"])})
    return Campaign(name=name, frame=frame, synthetic=synthetic, quantity=found, reference=reference,
                    description=description, source=source or f"imported from {Path(uff_path).name}",
                    factors=tuple(factors), design=design, frf=table)
