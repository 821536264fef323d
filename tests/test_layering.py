"""Numerical modules import neither pandas nor matplotlib (STYLE.md), and importing prints nothing."""

from __future__ import annotations

import subprocess
import sys

import pytest

NUMERICAL = ["workbench", "workbench.frame", "workbench.elements", "workbench.assembly", "workbench.modal",
             "workbench.generate", "workbench.outputs", "workbench.stochastic", "workbench.smr", "workbench.designs",
             "workbench.circlefit", "workbench.extraction", "workbench.identify", "workbench.bayes", "workbench.surrogate", "workbench.prediction", "workbench.effects", "workbench.diagnosis",
             "workbench.workflow", "workbench.measured"]


@pytest.mark.parametrize("module", NUMERICAL)
def test_numerical_module_stays_free_of_pandas_and_matplotlib(module):
    code = (f"import sys, {module}; heavy = [m for m in ('pandas', 'matplotlib') if m in sys.modules]; "
            "print(','.join(heavy))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout.strip() == "", f"{module} pulls in {done.stdout.strip()}"
    assert done.stderr == ""
