"""Wall time of ``workbench diagnose`` on 12-test campaigns the proving ground made (issue 14: at most 15 s on 2 cores).

For each frame of the proving ground, one 12-test blind campaign (6 low and 6 high amplitude, an effect of the
vocabulary at medium footprint, nuisances on) is written to a temporary directory, then ``workbench diagnose``
runs on it as a user would run it: a new process, the circle fit of every FRF, the diagnosis, the page. The
time printed is the command's whole wall time, and the diagnosis's own (``diagnosis.json``'s wall_time_s).

Run: ``python benchmarks/diagnose_speed.py`` (about 2 minutes).
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


def main() -> None:
    print(f"{'frame':22s} {'effect':22s} {'command (s)':>12s} {'diagnosis (s)':>14s}  verdict")
    worst = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for i, frame in enumerate(FRAME_NAMES):
            effect = EFFECTS[i % len(EFFECTS)]
            spec = CaseSpec(i, 1000 + i, frame, effect, "medium", blind_tests=12)
            campaign, _ = case_campaign(spec)
            where = Path(tmp) / f"campaign_{i}"
            write_campaign(campaign, where)
            out = Path(tmp) / f"out_{i}"
            start = time.perf_counter()
            done = subprocess.run([sys.executable, "-m", "workbench.cli", "diagnose", str(where), "--out", str(out)],
                                  capture_output=True, text=True)
            wall = time.perf_counter() - start
            if done.returncode != 0:
                print(f"{frame}: diagnose failed: {done.stderr.strip()}")
                continue
            record = json.loads((out / "diagnosis.json").read_text())
            worst = max(worst, wall)
            print(f"{frame:22s} {effect:22s} {wall:12.1f} {record['wall_time_s']:14.1f}  {record['verdict']['effect']}")
    print(f"slowest whole command: {worst:.1f} s (target: at most 15 s on 2 cores)")


if __name__ == "__main__":
    main()
