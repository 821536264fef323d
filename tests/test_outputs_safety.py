"""--out as one run's output set (CONTRACTS.md section 3): all or nothing, locked, stale files gone.

The interrupted and concurrent runs are real processes: `workbench` started with subprocess, killed with
SIGKILL (no handler can run) in the middle of its commit, or raced against a second run on the same DIR.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import REPO

from workbench.cli import main
from workbench.io.outputs import claim_output, write_file

FRAME = REPO / "frames" / "one_bolt_vertical.toml"


def workbench(*args: str, env: dict | None = None) -> subprocess.Popen:
    return subprocess.Popen([sys.executable, "-m", "workbench.cli", *args], cwd=REPO, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            env={**os.environ, **(env or {})})


def listing(folder: Path) -> dict[str, str]:
    return {p.name: p.read_text() for p in sorted(folder.iterdir())}


def test_force_replaces_the_whole_set_and_drops_a_stale_posterior(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "posterior.nc").write_bytes(b"an earlier bayes run")
    (out / "identification.json").write_text("{}")
    with claim_output(out, command="identify", names=("identification.json", "posterior.nc"), force=True) as claimed:
        claimed.commit({"identification.json": '{"method": "moments"}\n'})
    assert listing(out) == {"identification.json": '{"method": "moments"}\n'}


def test_a_refused_claim_writes_nothing_and_the_work_never_starts(tmp_path):
    out = tmp_path / "out"
    assert main(["modes", str(FRAME), "--out", str(out), "--count", "2"]) == 0
    before = listing(out)
    ran = []
    with pytest.raises(FileExistsError, match="pass --force"):
        with claim_output(out, command="modes", names=("modes.csv",), force=False):
            ran.append(True)
    assert not ran and listing(out) == before


def test_orphans_of_a_killed_run_are_cleaned_and_an_interrupted_swap_undone(tmp_path):
    out = tmp_path / "out"
    (tmp_path / ".out.tmp-123-abcd").mkdir()
    (tmp_path / ".out.tmp-123-abcd" / "modes.csv").write_text("half")
    old = tmp_path / ".out.old-123-abcd"  # killed between the two renames of the fallback swap: out is gone
    old.mkdir()
    (old / "modes.csv").write_text("the old set\n")
    with claim_output(out, command="modes", names=("modes.csv",), force=True) as claimed:
        assert listing(out) == {"modes.csv": "the old set\n"}
        claimed.commit({"modes.csv": "the new set\n"})
    assert listing(out) == {"modes.csv": "the new set\n"}
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".lock")) == ["out"]


def test_a_run_killed_during_its_commit_leaves_the_old_set_whole(tmp_path):
    out = tmp_path / "out"
    assert main(["propagate", str(FRAME), "--method", "smr1", "--count", "3", "--out", str(out)]) == 0
    old = listing(out)
    run = workbench("propagate", str(FRAME), "--method", "pert2", "--count", "3", "--out", str(out), "--force",
                    env={"WORKBENCH_TEST_PAUSE_BEFORE_SWAP": "30"})
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob(".out.tmp-*/run.json")) and time.monotonic() < deadline:
        time.sleep(0.05)  # until the new set is fully written beside the old one
    assert list(tmp_path.glob(".out.tmp-*/run.json")), run.communicate()
    run.send_signal(signal.SIGKILL)
    run.communicate()  # reaps the process and closes its pipes
    assert listing(out) == old
    # the next run cleans the orphan and writes its set
    assert main(["propagate", str(FRAME), "--method", "pert2", "--count", "3", "--out", str(out), "--force"]) == 0
    assert '"pert2"' in (out / "run.json").read_text() and set(listing(out)) == {"moments.csv", "run.json"}
    assert not list(tmp_path.glob(".out.tmp-*"))


def test_a_run_killed_at_random_moments_leaves_one_whole_set(tmp_path):
    out = tmp_path / "out"
    assert main(["propagate", str(FRAME), "--method", "smr1", "--count", "3", "--out", str(out)]) == 0
    sets = {"smr1": listing(out)}
    for delay in (0.3, 0.8, 1.5, 2.5):
        run = workbench("propagate", str(FRAME), "--method", "mc", "--samples", "300", "--count", "3",
                        "--out", str(out), "--force")
        time.sleep(delay)
        run.send_signal(signal.SIGKILL)
        run.communicate()
        now = listing(out)
        assert set(now) == {"moments.csv", "run.json"}
        method = '"mc"' if '"mc"' in now["run.json"] else '"smr1"'
        assert method in now["run.json"] and now["moments.csv"].count("\n") == 4  # header + 3 modes, whole
        if method == '"smr1"':
            assert now == sets["smr1"]


def test_two_concurrent_runs_one_refuses_on_the_lock(tmp_path):
    out = tmp_path / "out"
    slow = {"WORKBENCH_TEST_PAUSE_BEFORE_SWAP": "3"}
    first = workbench("modes", str(FRAME), "--count", "3", "--out", str(out), "--force", env=slow)
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob(".out.tmp-*")) and time.monotonic() < deadline:
        time.sleep(0.05)
    second = workbench("modes", str(FRAME), "--count", "5", "--out", str(out), "--force")
    _, err = second.communicate(timeout=60)
    assert second.returncode == 2 and "another workbench run is writing here" in err and err.count("\n") == 1
    first.communicate(timeout=60)
    assert first.returncode == 0
    assert listing(out)["modes.csv"].count("\n") == 4  # the first run's whole set: header + 3 modes


def test_write_file_replaces_one_file_and_leaves_its_folder_alone(tmp_path):
    (tmp_path / "README.md").write_text("keep me")
    write_file(tmp_path / "frame.toml", "name = 'x'\n")
    write_file(tmp_path / "frame.toml", "name = 'y'\n")
    assert listing(tmp_path) == {"README.md": "keep me", "frame.toml": "name = 'y'\n"}
