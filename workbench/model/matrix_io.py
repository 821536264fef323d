"""Reading the matrices of a matrix model (CONTRACTS.md section 4) and checking what the contract asks.

Every check raises `MatrixModelError` with one line: ``file: matrix: problem``. The readers look at a
file's header before its data, so that a header that declares a huge matrix is refused instead of
ending in a MemoryError.

Formats: Matrix Market through `scipy.io.mmread`, and Nastran OUTPUT4 (ASCII or binary, dense or
sparse columns) through pyyeti's ``op4`` module. pyNastran is not an option: it pins numpy < 2, and
installing it downgrades numpy under pandas, which then breaks.
"""

from __future__ import annotations

import importlib.util
import io
import re
import sys
import warnings
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import NoReturn

import numpy as np
import scipy.io as sio
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from workbench.model.modal import ldl_pivots

__all__ = ["MatrixModelError", "SYMMETRY_TOLERANCE", "SEMIDEFINITE_TOLERANCE", "load_op4", "read_mtx",
           "op4_directory", "read_op4", "checked_matrix", "check_positive_definite", "check_semidefinite"]

SYMMETRY_TOLERANCE = 1e-9  # largest asymmetric entry over largest entry (the contract's figure)
SEMIDEFINITE_TOLERANCE = 1e-9  # smallest eigenvalue at least -this times the largest (the contract's)
DENSE_EIGEN_LIMIT = 1500  # rows of a joint's support up to which its spectrum is computed densely
_OP4_MODULE = "_workbench_pyyeti_op4"


class MatrixModelError(ValueError):
    """A matrix model breaks the contract; the message is one line: ``file: field: problem``."""


def fail(where: str, problem: str) -> NoReturn:
    """Raise `MatrixModelError` ``"{where}: {problem}"``, squeezed onto one line."""
    raise MatrixModelError(" ".join(f"{where}: {problem}".split()))


def load_op4() -> ModuleType:
    """The ``op4`` module of pyyeti, loaded alone.

    ``from pyyeti.nastran import op4`` runs ``pyyeti/nastran/__init__.py``, which imports pandas,
    matplotlib and numba (2 s), none of which op4 uses and none of which the model layer may import;
    op4.py itself needs only numpy, scipy and ``pyyeti.guitools`` (tkinter, optional). Its module-level
    read functions may open a file dialog when given a directory; this module only calls the `OP4`
    class's methods on paths already checked to be files.
    """
    if _OP4_MODULE in sys.modules:
        return sys.modules[_OP4_MODULE]
    spec = importlib.util.find_spec("pyyeti")
    if spec is None or not spec.submodule_search_locations:
        raise MatrixModelError("format: \"op4\" needs the pyyeti package (pip install 'pyyeti>=1.4')")
    path = Path(list(spec.submodule_search_locations)[0]) / "nastran" / "op4.py"
    op4_spec = importlib.util.spec_from_file_location(_OP4_MODULE, path)
    if op4_spec is None or op4_spec.loader is None:
        raise MatrixModelError(f"format: \"op4\": cannot load pyyeti's op4 reader from {path}")
    module = importlib.util.module_from_spec(op4_spec)
    op4_spec.loader.exec_module(module)
    sys.modules[_OP4_MODULE] = module
    return module


def _reason(exc: BaseException) -> str:
    return f"{type(exc).__name__}: {exc}" if str(exc) else type(exc).__name__


# One Matrix Market data line, strictly: scipy's reader (fast_matrix_market) takes "3.0e" or "0x10"
# followed by a newline for a number and ignores extra fields, and at the very end of a file without a
# newline it reads past its buffer (a segmentation fault, scipy 1.17). The body is screened first.
_NUMBER = rb"[-+]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[iI][nN][fF](?:[iI][nN][iI][tT][yY])?|[nN][aA][nN])"
_ENTRY = {"coordinate": rb"[ \t]*\d+[ \t]+\d+[ \t]+" + _NUMBER + rb"[ \t]*\r?\n",
          "array": rb"[ \t]*" + _NUMBER + rb"[ \t]*\r?\n"}
_BODY = {layout: re.compile(rb"(?:" + line + rb"|[ \t]*\r?\n)*+") for layout, line in _ENTRY.items()}


def read_mtx(path: Path, where: str, size: int) -> sp.csr_matrix:
    """A real square Matrix Market matrix of ``size`` rows (``where`` prefixes every message)."""
    try:
        rows, cols, entries, layout, kind, _ = sio.mminfo(str(path))
    except Exception as exc:  # any failure of the parser means an unreadable header
        fail(where, f"not a Matrix Market file ({_reason(exc)})")
    if kind not in ("real", "integer"):
        fail(where, f"a {kind} matrix; expected real entries")
    _check_shape(where, int(rows), int(cols), size)
    # Each stored entry takes at least two bytes ("1\n"): a header declaring more than the file can
    # hold is corrupt, and believing it would allocate the declared count (a MemoryError).
    stored = int(entries) if layout == "coordinate" else int(rows) * int(cols)
    if stored > path.stat().st_size // 2 + 1:
        fail(where, f"the header declares {stored} entries but the file holds {path.stat().st_size} bytes "
                    "(truncated or corrupt)")
    data = path.read_bytes()
    data += b"" if data.endswith(b"\n") else b"\n"
    _screen_body(data, layout, where)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            matrix = sio.mmread(io.BytesIO(data))
    except Exception as exc:  # as above: a parser failure is a corrupt file, whatever its type
        fail(where, f"unreadable Matrix Market data ({_reason(exc)})")
    return sp.csr_matrix(matrix, dtype=float)


def _screen_body(data: bytes, layout: str, where: str) -> None:
    """Refuse a data line that is not ``row column value`` (coordinate) or ``value`` (array)."""
    start, number = 0, 0
    # the banner, comments and blank lines, then the size line: the body starts after it
    while (end := data.find(b"\n", start) + 1) > 0:
        number += 1
        line = data[start:end].strip()
        start = end
        if number > 1 and line and not line.startswith(b"%"):
            break
    if _BODY[layout].fullmatch(data, start):
        return
    entry, blank = re.compile(_ENTRY[layout]), re.compile(rb"[ \t]*\r?\n")
    for line in io.BytesIO(data[start:]):  # only to name the first bad line
        number += 1
        if not (entry.fullmatch(line) or blank.fullmatch(line)):
            text = line.decode("utf-8", "replace").strip()
            shown = text if len(text) <= 60 else text[:57] + "..."
            expected = "row column value" if layout == "coordinate" else "one value"
            fail(where, f"line {number}: {shown!r} is not a {layout} entry ({expected})")
    fail(where, "unreadable Matrix Market data")


def _check_shape(where: str, rows: int, cols: int, size: int) -> None:
    if rows != cols:
        fail(where, f"not square ({rows} x {cols})")
    if rows != size:
        fail(where, f"{rows} x {cols}, but dofs.csv has {size} rows (one per matrix row)")


def op4_directory(path: Path, where: str) -> dict[str, tuple[int, int, int]]:
    """Lower-case name -> (rows, cols, count) of every matrix of an OUTPUT4 file, data not read.

    ``count`` is how many matrices carry that name (a name used twice is ambiguous).
    """
    op4 = load_op4()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            names, sizes, _, mtypes = op4.OP4().dir(str(path), verbose=False)
    except Exception as exc:  # any failure of the parser means a file it cannot read
        fail(where, f"not a readable OUTPUT4 file ({_reason(exc)})")
    if not names:
        fail(where, "the OUTPUT4 file holds no matrix")
    found: dict[str, tuple[int, int, int]] = {}
    for name, (rows, cols), mtype in zip(names, sizes, mtypes):
        count = found[name][2] + 1 if name in found else 1
        # mtype 1, 2: real single and double precision; 3, 4: complex (or a corrupt header)
        found[name] = (int(rows), int(cols), count if mtype in (1, 2) else -count)
    return found


def read_op4(path: Path, wanted: dict[str, str], size: int) -> dict[str, sp.csr_matrix]:
    """Matrices of an OUTPUT4 file by name (case-insensitive).

    Parameters
    ----------
    path : the op4 file, checked to exist.
    wanted : field (e.g. ``"mass"``, ``"joints[0].stiffness"``) -> matrix name in the file.
    size : rows of the dof table; every matrix must be ``size`` x ``size``.

    Returns
    -------
    dict
        Field -> csr matrix.
    """
    directory = op4_directory(path, f"{path}: file")
    held = ", ".join(list(directory)[:12]) + (", ..." if len(directory) > 12 else "")
    for key, name in wanted.items():
        where = f"{path}: {key} ({name!r})"
        entry = directory.get(name.strip().lower())
        if entry is None:
            fail(where, f"no matrix of that name in the file (it holds: {held})")
        rows, cols, count = entry
        if abs(count) > 1:
            fail(where, f"{abs(count)} matrices of that name in the file: ambiguous")
        if count < 0:
            fail(where, "a complex matrix; expected real entries")
        _check_shape(where, rows, cols, size)
    names = sorted({n.strip().lower() for n in wanted.values()})
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # pyyeti warns on a premature end of file: refuse it
            # sparse=True also for dense columns: no dense n x n array is ever built
            got, matrices, _, _ = load_op4().OP4().listload(str(path), names, sparse=(True, sp.coo_matrix.tocsr))
    except Exception as exc:  # any failure of the parser means a corrupt file
        fail(f"{path}: file", f"unreadable OUTPUT4 data ({_reason(exc)})")
    by_name = dict(zip(got, matrices))
    return {key: sp.csr_matrix(by_name[name.strip().lower()], dtype=float) for key, name in wanted.items()}


def checked_matrix(a: sp.csr_matrix, where: str) -> sp.csr_matrix:
    """``a`` after the checks every matrix needs: finite entries, symmetric to `SYMMETRY_TOLERANCE`.

    Returns the symmetric part ``(a + a^T) / 2``, which is ``a`` itself, bit for bit, when ``a`` is
    exactly symmetric: the solvers read one triangle, and must not depend on which.
    """
    a = sp.csr_matrix(a, dtype=float, copy=True)  # sum_duplicates below works in place
    a.sum_duplicates()
    bad = ~np.isfinite(a.data)
    if bad.any():
        coo = a.tocoo()
        first = np.flatnonzero(~np.isfinite(coo.data))[0]
        fail(where, f"{int(bad.sum())} non-finite entries (NaN or inf), the first at row {coo.row[first]}, "
                    f"column {coo.col[first]} (rows from 0)")
    largest = float(np.abs(a.data).max()) if a.nnz else 0.0
    if largest == 0.0:
        return a
    skew = (a - a.T).tocoo()
    if skew.nnz:
        k = int(np.abs(skew.data).argmax())
        ratio = abs(skew.data[k]) / largest
        if ratio > SYMMETRY_TOLERANCE:
            fail(where, f"not symmetric: entry ({skew.row[k]}, {skew.col[k]}) differs from its transpose by "
                        f"{ratio:.3g} of the largest entry (tolerance {SYMMETRY_TOLERANCE:g})")
        a = sp.csr_matrix((a + a.T) * 0.5)
        a.sum_duplicates()
        a.prune()  # a sum may leave spare storage past nnz
    return a


def check_positive_definite(a: sp.csr_matrix, where: str, label: Callable[[int], str] | None = None) -> None:
    """Refuse a mass matrix that is not positive definite.

    A pivot counts as positive only above ``n eps max|a|``, the rounding error of the factorisation:
    a smaller one cannot be told from zero, and the modal solve would divide by it. ``label(row)``
    names a row in the message (e.g. ``"node 4 rz"``).
    """
    def name(row: int) -> str:
        return f"row {row}" + (f" ({label(row)})" if label is not None else "")

    n = a.shape[0]
    diagonal = a.diagonal()
    if (diagonal <= 0).any():
        row = int(np.flatnonzero(diagonal <= 0)[0])
        fail(where, f"not positive definite: diagonal entry of {name(row)} is {diagonal[row]:g} "
                    "(every dof needs mass)")
    largest = float(np.abs(a.data).max())
    factors = ldl_pivots(a)
    if factors is None:
        fail(where, "not positive definite (singular, or indefinite: the symmetric factorisation fails)")
    pivots, rows = factors
    small = pivots <= n * np.finfo(float).eps * largest
    if small.any():
        k = int(np.flatnonzero(small)[0])
        fail(where, f"not positive definite: pivot {pivots[k]:.3g} at {name(int(rows[k]))} in a symmetric "
                    f"factorisation (largest entry {largest:.3g})")


def check_semidefinite(a: sp.csr_matrix, where: str) -> None:
    """Refuse a joint matrix that is zero, or not positive semi-definite to `SEMIDEFINITE_TOLERANCE`.

    Only the rows where the joint acts count (the others are zero and add zero eigenvalues). Up to
    `DENSE_EIGEN_LIMIT` of them, the extreme eigenvalues are computed densely; above, the largest comes
    from Lanczos and the test is that ``A + tol lambda_max I`` has a positive-definite factorisation,
    which holds exactly when the smallest eigenvalue is above ``-tol lambda_max``.
    """
    a = sp.csr_matrix(a, copy=True)  # eliminate_zeros works in place: leave the caller's matrix alone
    a.eliminate_zeros()
    support = np.flatnonzero(np.diff(a.indptr))
    if support.size == 0:
        fail(where, "the matrix is all zeros: the joint would have no effect")
    sub = a[support][:, support]
    if support.size <= DENSE_EIGEN_LIMIT:
        values = sla.eigvalsh(sub.toarray())
        low, high = float(values[0]), float(values[-1])
    else:
        try:
            high = float(spla.eigsh(sub, k=1, which="LA", tol=1e-6, return_eigenvectors=False,
                                    v0=np.ones(support.size))[0])
        except spla.ArpackError:
            high = float(abs(sub).sum(axis=1).max())  # Gershgorin: an upper bound, so a looser test
        low = high
        if high > 0:
            shifted = sub + SEMIDEFINITE_TOLERANCE * high * sp.identity(support.size, format="csr")
            factors = ldl_pivots(shifted)
            low = high if factors is not None and (factors[0] > 0).all() else -np.inf
    if high <= 0 or low < -SEMIDEFINITE_TOLERANCE * high:
        smallest = "below that" if np.isinf(low) else f"{low:.3g}"
        fail(where, f"not positive semi-definite: largest eigenvalue {high:.3g}, smallest {smallest} "
                    f"(at least -{SEMIDEFINITE_TOLERANCE:g} times the largest required)")
