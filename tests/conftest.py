"""Shared test helpers: small frames built from text, in the contract's own format."""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import math
import os
import re
import shutil
import signal
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from workbench.model.frame import Frame
from workbench.model.frame_file import parse_frame

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"

if os.environ.get("PYTEST_XDIST_WORKER"):
    # `-n auto` runs a worker per core: a BLAS pool per worker as well oversubscribes the cores (the default suite
    # took 251 s so and 200 s with one BLAS thread per worker on 2 cores, 2026-12-03); the processes a test starts
    # (the command line, Dask's workers) inherit the environment
    threadpool_limits(1)
    for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(_name, "1")

ALUMINIUM = {"youngs_modulus": 70e9, "density": 2700.0, "poisson_ratio": 0.33}


def bar_section(width: float = 0.03, thickness: float = 0.008) -> dict:
    """A flat bar bending about its thin direction; kappa = 5/6 (rectangle)."""
    return {"area": width * thickness, "second_moment": width * thickness**3 / 12, "shear_coefficient": 5 / 6}


def straight_beam(length: float, supports: list[dict], *, element_length: float = 0.01,
                  theory: str = "euler-bernoulli", section: dict | None = None,
                  axial_force: float = 0.0) -> Frame:
    """A beam along x from point 'a' to point 'b'."""
    member = {"name": "beam", "start": "a", "end": "b", "material": "al", "section": "s"}
    if axial_force:
        member["axial_force"] = axial_force
    return parse_frame({
        "name": "straight beam", "beam_theory": theory, "element_length": element_length,
        "materials": {"al": dict(ALUMINIUM)}, "sections": {"s": section or bar_section()},
        "points": {"a": [0.0, 0.0], "b": [length, 0.0]},
        "members": [member], "supports": supports,
    })


CLAMP = {"ux": "fixed", "uy": "fixed", "rz": "fixed"}


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20201206)


def shared_path(*parts: str) -> Path:
    """``../shared/<parts>``; a test that needs it fails when it is missing (CI always has ../shared),
    or skips when ``WORKBENCH_ALLOW_NO_SHARED=1`` says a checkout without it is meant."""
    path = SHARED.joinpath(*parts)
    if not path.exists():
        if os.environ.get("WORKBENCH_ALLOW_NO_SHARED") == "1":
            pytest.skip(f"{path} is absent (WORKBENCH_ALLOW_NO_SHARED=1)")
        pytest.fail(f"{path} is missing: this test needs ../shared beside the repository; set "
                    "WORKBENCH_ALLOW_NO_SHARED=1 to skip such tests", pytrace=False)
    return path


def pytest_runtest_setup(item: pytest.Item) -> None:
    """``@pytest.mark.shared("data/real/...")``: the test needs that path under ../shared (`shared_path`)."""
    for marker in item.iter_markers(name="shared"):
        shared_path(*marker.args)


# ---------------------------------------------------------------- inputs for the bad-input and fuzz suites

def _key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else '"' + key.replace('"', '\\"') + '"'


def _value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return "nan" if math.isnan(value) else ("inf" if value > 0 else "-inf") if math.isinf(value) else repr(value)
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, list):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{_key(k)} = {_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(value)


def dump_toml(data: dict) -> str:
    """TOML text of ``data``: scalars first, then tables, then arrays of tables (inline below them)."""
    lines = [f"{_key(k)} = {_value(v)}" for k, v in data.items()
             if not isinstance(v, dict) and not (isinstance(v, list) and v and all(isinstance(e, dict) for e in v))]
    for k, v in data.items():
        if isinstance(v, dict):
            lines.append(f"\n[{_key(k)}]")
            lines += [f"{_key(kk)} = {_value(vv)}" for kk, vv in v.items()]
    for k, v in data.items():
        if isinstance(v, list) and v and all(isinstance(e, dict) for e in v):
            for entry in v:
                lines.append(f"\n[[{_key(k)}]]")
                lines += [f"{_key(kk)} = {_value(vv)}" for kk, vv in entry.items()]
    return "\n".join(lines) + "\n"


EXAMPLE = "examples/independent-two-test-campaign"


def cut_example_campaign(target: Path) -> Path:
    """The independent example campaign (../shared/examples) cut to one sensor and 0-130 Hz (two
    modes), copied to ``target``: a campaign written by another program that extracts in a blink."""
    source = shared_path(EXAMPLE)
    target.mkdir(parents=True)
    for name in ("campaign.toml", "design.csv", "frame.toml"):
        shutil.copy(source / name, target / name)
    with (source / "frf.csv").open() as src, (target / "frf.csv").open("w", newline="") as dst:
        rows = csv.reader(src)
        writer = csv.writer(dst, lineterminator="\n")
        writer.writerow(next(rows))
        writer.writerows(r for r in rows if r[1] == "s1" and float(r[2]) <= 130.0)
    return target


HANG_S = 30  # the commands of these suites take well under a second on small inputs; 30 s means a hang


class Hang(Exception):
    """The command ran longer than HANG_S."""


def run_cli(args: list[str]) -> tuple[int, str]:
    """``workbench ARGS`` in this process: exit status and standard error (exceptions propagate)."""
    from workbench.cli import main  # the CLI loads on first use, as a user would start it

    err, out = io.StringIO(), io.StringIO()

    def on_alarm(signum, frame):
        raise Hang(f"workbench {' '.join(args)} ran over {HANG_S} s")

    previous = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(HANG_S)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(out):
            status = main(args)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    return status, err.getvalue()


def error_lines(stderr: str) -> list[str]:
    """Standard error without the one-line warnings the CLI may print before its result."""
    return [line for line in stderr.splitlines() if line.strip() and "warning" not in line.lower()]


def digest(paths: list[Path]) -> dict[str, str]:
    return {str(p): hashlib.sha256(p.read_bytes()).hexdigest() for p in paths if p.is_file()}


def tree(directory: Path) -> list[Path]:
    return sorted(p for p in directory.rglob("*") if p.is_file())
