"""Writing a command's results into ``--out DIR``: every file whole or not at all (CONTRACTS.md s. 3).

Files are first written under temporary names in the output directory, then renamed into place
only once all of them are written; existing files are replaced only with ``force``.
"""

from __future__ import annotations

import csv
import io
import json
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

__all__ = ["OutputExistsError", "write_outputs", "csv_text", "json_text"]


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
    return json.dumps(data, indent=2, allow_nan=False) + "\n"


def write_outputs(out_dir: str | Path, files: dict[str, str | bytes], force: bool = False) -> list[Path]:
    """Write ``files`` (name -> text or bytes) into ``out_dir``, all or none.

    Raises
    ------
    OutputExistsError
        A target exists and ``force`` is false; nothing is written.
    """
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise OutputExistsError(f"{out}: --out exists and is not a directory")
    targets = [out / name for name in files]
    existing = [p for p in targets if p.exists()]
    if existing and not force:
        raise OutputExistsError(f"{existing[0]}: exists; pass --force to replace it")
    out.mkdir(parents=True, exist_ok=True)
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
