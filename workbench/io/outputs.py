"""Writing a command's results into ``--out DIR``: every file whole or not at all (CONTRACTS.md s. 3).

Files are first written under temporary names in the output directory, then renamed into place
only once all of them are written; existing files are replaced only with ``force``. `write_outputs`
is the workbench's one way of writing files: campaigns, UFF files, frame files and figures go
through it too.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

from workbench.model.frame import Frame
from workbench.model.frame_file import frame_to_toml

__all__ = ["OutputExistsError", "write_outputs", "write_file", "write_frame", "csv_text", "json_text"]


class OutputExistsError(FileExistsError):
    """An output file exists and ``--force`` was not given."""


def csv_text(header: Sequence[str], rows: Iterable[Sequence[object]]) -> str:
    """CSV text with a header; floats keep their full precision (``repr``)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    for row in rows:
        writer.writerow([repr(float(v)) if isinstance(v, float) else v for v in row])
    return buffer.getvalue()


def json_text(data: object) -> str:
    """Indented JSON text ending with a newline; NaN and infinity are refused (``ValueError``)."""
    return json.dumps(data, indent=2, allow_nan=False) + "\n"


def write_outputs(out_dir: str | Path, files: dict[str, str | bytes], force: bool = False) -> list[Path]:
    """Write ``files`` (name -> text or bytes) into ``out_dir``, all or none.

    Parameters
    ----------
    out_dir : the directory, created when missing.
    files : file name -> content (text is written as UTF-8). A name may hold a sub-directory of
        ``out_dir`` (``"campaign/frame.toml"``), created when missing.
    force : replace existing files.

    Returns
    -------
    list of Path
        The files written, in the order of ``files``.

    Raises
    ------
    OutputExistsError
        A target exists and ``force`` is false, or a directory to write into is a file; nothing
        is written.
    """
    out = Path(out_dir)
    targets = [out / name for name in files]
    folders = list(dict.fromkeys([out, *(t.parent for t in targets)]))
    for folder in folders:
        if folder.exists() and not folder.is_dir():
            raise OutputExistsError(f"{folder}: --out exists and is not a directory")
    existing = [p for p in targets if p.exists()]
    if existing and not force:
        raise OutputExistsError(f"{existing[0]}: exists; pass --force to replace it")
    for folder in folders:
        folder.mkdir(parents=True, exist_ok=True)
    temporary: list[Path] = []
    try:
        for target, content in zip(targets, files.values()):
            tmp = target.with_name(f".{target.name}.{os.getpid()}.tmp")
            temporary.append(tmp)
            if isinstance(content, bytes):
                tmp.write_bytes(content)
            else:
                tmp.write_text(content, encoding="utf-8")
        for tmp, target in zip(temporary, targets):
            tmp.replace(target)
    finally:
        for tmp in temporary:
            tmp.unlink(missing_ok=True)
    return targets


def write_file(path: str | Path, content: str | bytes) -> Path:
    """Write one file whole or not at all (through `write_outputs`), replacing an existing one."""
    path = Path(path)
    write_outputs(path.parent, {path.name: content}, force=True)
    return path


def write_frame(frame: Frame, path: str | Path) -> None:
    """Write ``frame`` as a frame file (`frame_to_toml`), whole or not at all; an existing file is replaced."""
    write_file(path, frame_to_toml(frame))
