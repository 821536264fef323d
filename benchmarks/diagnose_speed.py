"""Wall time of ``workbench diagnose`` on 12-test campaigns the proving ground made (issue 14: at most 15 s on 2 cores).

For each frame of the proving ground, one 12-test blind campaign (6 low and 6 high amplitude, an effect of the
vocabulary at medium footprint, nuisances on) is written to a temporary directory, then ``workbench diagnose``
runs on it as a user would run it: a new process, the circle fit of every FRF, the diagnosis, the page. The
time printed is the command's whole wall time, with the circle fits on one process and on two
(``--workers 2``, a local Dask cluster, what the command does by default on a 2-core machine), and the
diagnosis's own (``diagnosis.json``'s wall_time_s).

Run: ``python benchmarks/diagnose_speed.py`` (about 3 minutes).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from workbench.io.campaign import write_campaign
from workbench.proving.cases import CaseSpec, case_campaign
from workbench.proving.frames import FRAME_NAMES

EFFECTS = ("support_compliance", "added_mass", "axial_prestress", "joint_stiffness_shift", "amplitude_softening",
           "stinger_stiffness", "joint_damping")


def _run(where: Path, out: Path, workers: int) -> tuple[float, dict | str]:
    """Wall time of one ``workbench diagnose`` and its record (or its error)."""
    start = time.perf_counter()
    done = subprocess.run([sys.executable, "-m", "workbench.cli", "diagnose", str(where), "--out", str(out),
                           "--workers", str(workers)], capture_output=True, text=True)
    wall = time.perf_counter() - start
    if done.returncode != 0:
        return wall, done.stderr.strip()
    return wall, json.loads((out / "diagnosis.json").read_text())


def main() -> None:
    print(f"{'frame':22s} {'effect':22s} {'1 worker (s)':>13s} {'2 workers (s)':>14s} {'diagnosis (s)':>14s}  verdict")
    worst = {1: 0.0, 2: 0.0}
    with tempfile.TemporaryDirectory() as tmp:
        for i, frame in enumerate(FRAME_NAMES):
            effect = EFFECTS[i % len(EFFECTS)]
            spec = CaseSpec(i, 1000 + i, frame, effect, "medium", blind_tests=12)
            campaign, _ = case_campaign(spec)
            where = Path(tmp) / f"campaign_{i}"
            write_campaign(campaign, where)
            walls, record = {}, None
            for workers in (1, 2):  # side by side, the same campaign
                walls[workers], record = _run(where, Path(tmp) / f"out_{i}_{workers}", workers)
                if isinstance(record, str):
                    print(f"{frame}: diagnose failed: {record}")
                    break
                worst[workers] = max(worst[workers], walls[workers])
            if isinstance(record, dict):
                print(f"{frame:22s} {effect:22s} {walls[1]:13.1f} {walls[2]:14.1f} {record['wall_time_s']:14.1f}  "
                      f"{record['verdict']['effect']}")
    print(f"slowest whole command: {worst[1]:.1f} s with 1 worker, {worst[2]:.1f} s with --workers 2 "
          "(target: at most 15 s on 2 cores)")


if __name__ == "__main__":
    main()
