"""The house's plan holds (ARCHITECTURE.md): numerical sub-packages import neither pandas, matplotlib
nor tqdm (STYLE.md), importing prints nothing, and imports point one way between the layers."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "workbench"
NUMERICAL_PACKAGES = ("model", "uq", "extraction", "identify", "diagnose", "plan")
# each layer and the layers it may import (ARCHITECTURE.md); a sub-package may import itself
ALLOWED = {
    "model": set(),
    "uq": {"model"},
    "extraction": {"model"},
    "identify": {"model", "uq", "extraction"},
    "plan": {"model", "uq", "identify"},
    "rig": {"model", "io", "plan"},
    "diagnose": {"model", "uq", "extraction", "rig"},
    "io": {"model"},
    "proving": {"model", "io"},  # its own physics: nothing of what it judges (tests/test_proving.py, finer)
    "workflow": {"model", "uq", "extraction", "identify", "rig", "diagnose", "io", "plan", "proving"},
    "report": {"model", "uq", "extraction", "identify", "rig", "diagnose", "io", "workflow", "plan"},
}


def _module(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


NUMERICAL = ["workbench"] + sorted(_module(p) for sub in NUMERICAL_PACKAGES for p in (PACKAGE / sub).glob("*.py"))


HEAVY = ("pandas", "matplotlib", "tqdm", "dask", "distributed")
# One interpreter imports what every module shares (numpy, scipy, the package's __init__), checks that it pulled
# in none of HEAVY, then forks a child per module: the child imports the module on top and reports every HEAVY
# module then loaded, inherited ones included, and what it printed. Eighty fresh interpreters took 90 s of the
# default suite; the forks a few. Where there is no fork, each module gets its own interpreter.
PROBE = r"""
import importlib, json, os, sys, tempfile
heavy = json.loads(sys.argv[1])
results = {}
def report():
    return {"heavy": [m for m in heavy if m in sys.modules]}
for name in ("numpy", "scipy", "scipy.sparse", "scipy.sparse.linalg", "scipy.linalg", "scipy.optimize",
             "scipy.special", "scipy.stats", "scipy.interpolate", "workbench"):
    importlib.import_module(name)
results["(shared imports)"] = report() | {"printed": ""}
for module in sys.argv[2:]:
    with tempfile.TemporaryFile() as printed, tempfile.TemporaryFile() as answer:
        sys.stdout.flush(); sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            os.dup2(printed.fileno(), 1)
            os.dup2(printed.fileno(), 2)
            try:
                importlib.import_module(module)
                found = report()
            except BaseException as error:
                found = {"error": repr(error)}
            sys.stdout.flush(); sys.stderr.flush()
            os.write(answer.fileno(), json.dumps(found).encode())
            os._exit(0)
        os.waitpid(pid, 0)
        printed.seek(0); answer.seek(0)
        results[module] = json.loads(answer.read() or b'{"error": "the child died"}')
        results[module]["printed"] = printed.read().decode(errors="replace")
print(json.dumps(results))
"""


@pytest.fixture(scope="module")
def imported() -> dict:
    """module -> {"heavy": [...], "printed": text} or {"error": ...}, from `PROBE` (or fresh interpreters)."""
    import json
    import os

    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")  # no BLAS threads across the forks
    if hasattr(os, "fork"):
        done = subprocess.run([sys.executable, "-c", PROBE, json.dumps(HEAVY), *NUMERICAL], capture_output=True,
                              text=True, check=True, env=env)
        assert done.stderr == "", done.stderr
        return json.loads(done.stdout)
    results = {}
    for module in NUMERICAL:
        code = f"import sys, {module}; print(','.join(m for m in {HEAVY!r} if m in sys.modules))"
        done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=env)
        heavy = done.stdout.strip().splitlines()[-1] if done.stdout.strip() else ""
        results[module] = {"heavy": [m for m in heavy.split(",") if m], "printed": done.stderr}
    return results


def test_the_shared_imports_of_the_probe_pull_in_nothing_heavy(imported):
    assert imported.get("(shared imports)", {"heavy": []})["heavy"] == []


@pytest.mark.parametrize("module", NUMERICAL)
def test_numerical_module_stays_free_of_pandas_matplotlib_tqdm_and_dask(imported, module):
    found = imported[module]
    assert "error" not in found, f"{module} failed to import: {found.get('error')}"
    assert found["heavy"] == [], f"{module} pulls in {','.join(found['heavy'])}"
    assert found["printed"] == "", f"importing {module} printed {found['printed'][:200]!r}"


def test_every_layer_imports_only_the_layers_below_it():
    breaches = []
    for path in PACKAGE.rglob("*.py"):
        layer = path.relative_to(PACKAGE).parts[0]
        if layer not in ALLOWED:  # cli.py, progress.py and the package's __init__
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("workbench."):
                target = node.module.split(".")[1]
                if target != layer and target in ALLOWED and target not in ALLOWED[layer]:
                    breaches.append(f"{_module(path)} imports {node.module}")
    assert breaches == []


def test_the_house_plan_measures_clean():
    """`../shared/tools/house.py` (sub-packages, circles, sizes, edge libraries, lint in CI) exits 0."""
    from conftest import REPO, shared_path

    done = subprocess.run([sys.executable, str(shared_path("tools", "house.py"))], cwd=REPO, capture_output=True,
                          text=True, timeout=120)
    assert done.returncode == 0, done.stdout[-2000:]
    assert "0 module circles, 0 sub-package circles, 0 over 500 lines, 0 functions over 100 lines" in done.stdout
