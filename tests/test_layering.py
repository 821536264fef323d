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


@pytest.mark.parametrize("module", NUMERICAL)
def test_numerical_module_stays_free_of_pandas_matplotlib_tqdm_and_dask(module):
    code = (f"import sys, {module}; heavy = [m for m in ('pandas', 'matplotlib', 'tqdm', 'dask', 'distributed') "
            "if m in sys.modules]; "
            "print(','.join(heavy))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "", f"{module} pulls in {done.stdout.strip()}"
    assert done.stderr == ""


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
