"""Writing results: a command's ``--out DIR`` as one output set, and files whole or not at all.

Two writers, one per need:

- `claim_output` (the command line, CONTRACTS.md section 3): ``--out DIR`` is one run's output set.
  The claim comes first, before any work: it takes a lock beside DIR (a second run refuses), refuses
  a DIR that is empty, an input or inside one, a campaign or model folder, or one holding files the
  command does not write, and an earlier set without ``force``. `OutputSet.commit` writes the set
  into a temporary sibling directory, fsyncs it and swaps it into place, so that a run killed at any
  moment leaves the old set or the new one, never a mix, and a set replaced with ``force`` loses
  the stale files of another method (a ``posterior.nc`` beside a moments-only result).
- `write_outputs` / `write_file` (the library: campaigns, UFF files, frame files, figures): files
  written under temporary names, fsynced and renamed into place, in a directory that may hold
  other files (a campaign's README).
"""

from __future__ import annotations

import contextlib
import csv
import ctypes
import io
import json
import os
import secrets
import shutil
import time
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path

import filelock

from workbench.model.frame import Frame
from workbench.model.frame_file import frame_to_toml

__all__ = ["OutputExistsError", "OutputSet", "claim_output", "write_outputs", "write_file", "write_frame", "csv_text",
           "json_text"]


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
            _write_synced(tmp, content)
        for tmp, target in zip(temporary, targets):
            tmp.replace(target)
        for folder in folders:
            _sync_directory(folder)
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


def _write_synced(path: Path, content: str | bytes) -> None:
    """Write ``content`` to ``path`` and flush it to the disk (a rename after a crash keeps whole data)."""
    data = content.encode("utf-8") if isinstance(content, str) else content
    with open(path, "wb") as handle:
        handle.write(data)
        handle.flush()
        os.fsync(handle.fileno())


def _sync_directory(folder: Path) -> None:
    """Flush a directory to the disk (fsync), so that the renames in it survive a power cut."""
    with contextlib.suppress(OSError):  # some file systems refuse to open a directory: nothing to do there
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


_RENAME_EXCHANGE = 2  # linux/fs.h
_AT_FDCWD = -100


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths atomically with Linux ``renameat2(RENAME_EXCHANGE)``; False where unavailable.

    Python's ``os`` has no call that swaps two directories in one step, hence ctypes: a reader (or a
    crash) sees the old set or the new one, never no set.
    """
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    done = renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    return done == 0


_MARKERS = ("campaign.toml", "model.toml", "frame.toml")  # a campaign or a model folder
# The source line that opens a campaign written by `workbench import` (or `design`): the campaign folders
# a command may replace (with --force), since they are that command's own earlier output
IMPORT_STAMP = "workbench import:"
DESIGN_STAMP = "workbench design:"
_STAMPS = {"import": IMPORT_STAMP, "design": DESIGN_STAMP}


def _own_campaign(out: Path, command: str) -> bool:
    if command not in _STAMPS:
        return False
    try:
        text = (out / "campaign.toml").read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return False
    return f'source = "{_STAMPS[command]}' in text


class OutputSet:
    """``--out DIR`` claimed by one run (see `claim_output`); `commit` writes the whole set."""

    def __init__(self, out: Path, command: str, names: frozenset[str], force: bool) -> None:
        self.out, self.command, self.names, self.force = out, command, names, force
        self.committed = False

    def _sibling(self, kind: str) -> Path:
        return self.out.parent / f".{self.out.name}.{kind}-{os.getpid()}-{secrets.token_hex(4)}"

    def recover(self) -> None:
        """Undo what a killed run left (called under the lock, so no other run is writing here)."""
        olds = sorted(self.out.parent.glob(f".{self.out.name}.old-*"))
        if not self.out.exists() and olds:
            olds[-1].rename(self.out)  # killed between the two renames of the fallback swap
            olds = olds[:-1]
        for orphan in [*self.out.parent.glob(f".{self.out.name}.tmp-*"), *olds]:
            shutil.rmtree(orphan, ignore_errors=True)

    def check(self) -> None:
        """Refuse a DIR the command may not replace (CONTRACTS.md section 3)."""
        out, where = self.out, f"--out {self.out}"
        if not out.exists():
            return
        if not out.is_dir():
            raise OutputExistsError(f"{where}: exists and is not a directory")
        entries = sorted(p.name for p in out.iterdir())
        marker = next((m for m in _MARKERS if m in entries), None)
        if marker and not (marker == "campaign.toml" and _own_campaign(out, self.command)):
            raise OutputExistsError(f"{where}: holds {marker}, a campaign or model folder; the workbench never "
                                    "writes into one: choose a new or empty directory")
        foreign = [n for n in entries if n not in self.names or not (out / n).is_file()]
        if foreign:
            raise OutputExistsError(f"{where}: holds {foreign[0]}, which workbench {self.command} does not write; "
                                    "choose a new or empty directory")
        if entries and not self.force:
            raise OutputExistsError(f"{where}: holds {entries[0]} from an earlier run; pass --force to replace "
                                    "the output set")

    def commit(self, files: dict[str, str | bytes]) -> list[Path]:
        """Write ``files`` (name -> text or bytes) as DIR's whole content, all or nothing."""
        unknown = sorted(set(files) - self.names)
        if unknown:  # a programming error: every command lists what it writes
            raise ValueError(f"workbench {self.command}: {unknown[0]} is not among the files it declares")
        tmp = self._sibling("tmp")
        tmp.mkdir(parents=True)
        try:
            for name, content in files.items():
                (tmp / name).parent.mkdir(parents=True, exist_ok=True)  # a model's matrices may sit in a folder
                _write_synced(tmp / name, content)
            _sync_directory(tmp)
            pause = os.environ.get("WORKBENCH_TEST_PAUSE_BEFORE_SWAP")
            if pause:  # test hook: lets tests/test_outputs_safety.py kill a run in the middle of its commit
                time.sleep(float(pause))
            if not self.out.exists():
                tmp.rename(self.out)
            elif _exchange(tmp, self.out):
                shutil.rmtree(tmp)  # tmp now holds the old set
            else:
                old = self._sibling("old")
                self.out.rename(old)
                tmp.rename(self.out)
                shutil.rmtree(old)
            _sync_directory(self.out.parent)
        finally:
            if tmp.exists():
                shutil.rmtree(tmp, ignore_errors=True)
        self.committed = True
        return [self.out / name for name in files]


def _inside(path: Path, folder: Path) -> bool:
    return path == folder or folder in path.parents


@contextlib.contextmanager
def claim_output(out: str | Path, *, command: str, names: Iterable[str], force: bool,
                 inputs: Sequence[str | Path] = ()) -> Iterator[OutputSet]:
    """Claim ``--out`` for one run, before any work (CONTRACTS.md section 3).

    Parameters
    ----------
    out : the ``--out`` argument.
    command : the command's name, for messages.
    names : every file the command may write, other methods' included (so ``force`` drops stale ones).
    force : an earlier output set may be replaced.
    inputs : the command's input paths. DIR may not hold any of them; it may be neither an input
        directory (a campaign, a model's folder) nor inside one, nor the folder of an input file.

    Raises
    ------
    OutputExistsError
        DIR is empty text, an input, a campaign or model folder, holds other files, holds an earlier
        set without ``force``, or another run holds its lock.
    """
    if not str(out).strip():
        raise OutputExistsError("--out: the empty string is not a directory; name the output directory")
    target = Path(out).expanduser().resolve()
    for given in inputs:
        path = Path(given).expanduser().resolve()
        if _inside(path, target) or (_inside(target, path) if path.is_dir() else target == path.parent):
            raise OutputExistsError(f"--out {out}: is, holds or lies inside the input {given}; the workbench never "
                                    "writes into an input: choose another directory")
    if not target.parent.is_dir():
        target.parent.mkdir(parents=True, exist_ok=True)
    # the empty lock file stays after the run: unlinking a released flock lets a process that opened the old
    # file and one that creates a new one both hold "the" lock (filelock keeps it for that reason too)
    lock = filelock.FileLock(target.parent / f".{target.name}.lock", timeout=0)
    try:
        lock.acquire()
    except filelock.Timeout:
        raise OutputExistsError(f"--out {out}: another workbench run is writing here; wait for it or choose another "
                                "directory") from None
    try:
        claimed = OutputSet(target, command, frozenset(names), force)
        claimed.recover()
        claimed.check()
        yield claimed
    finally:
        lock.release()
