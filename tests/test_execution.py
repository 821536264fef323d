"""Dask as the one execution layer (issue 18): same seed, same bytes, whatever ran the work.

`propagate --method mc` runs serially, on a local two-worker cluster (``--workers 2``) and on a running
scheduler (``--scheduler ADDRESS``, a `distributed.LocalCluster` started here as a user would start
``dask scheduler`` and two ``dask worker``); the three moments.csv must be identical. A scheduler that
does not answer is one line naming the address, well within the 10 s the contract allows and the
test's alarm. A worker killed while its tasks run is replaced, and the result is still identical.
"""

from __future__ import annotations

import logging
import time

import numpy as np
import pytest
from conftest import REPO, error_lines, run_cli, shared_path

distributed = pytest.importorskip("distributed")

FRAME = REPO / "frames" / "four_bolt.toml"
# distributed's comms leave sockets to the garbage collector when a client or cluster closes (a
# ResourceWarning raised at an arbitrary later moment): not ours to fix, and not a result
pytestmark = pytest.mark.filterwarnings("ignore::ResourceWarning",
                                        "ignore::pytest.PytestUnraisableExceptionWarning")


@pytest.fixture(scope="module")
def cluster():
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                                  silence_logs=logging.ERROR) as running:
        yield running


def _mc(tmp_path, name: str, *extra: str) -> bytes:
    out = tmp_path / name
    code, err = run_cli(["propagate", str(FRAME), "--method", "mc", "--samples", "400", "--seed", "3",
                         "--count", "6", "--out", str(out), *extra])
    assert code == 0, err
    return (out / "moments.csv").read_bytes()


def test_monte_carlo_gives_the_same_bytes_serially_locally_and_on_a_scheduler(tmp_path, cluster):
    serial = _mc(tmp_path, "serial")
    assert _mc(tmp_path, "local", "--workers", "2") == serial
    assert _mc(tmp_path, "remote", "--scheduler", cluster.scheduler_address) == serial


def test_circle_fits_give_the_same_modes_serially_and_on_a_scheduler(tmp_path, cluster):
    from conftest import cut_example_campaign

    campaign = cut_example_campaign(tmp_path / "campaign")
    found = []
    for name, extra in (("serial", ()), ("remote", ("--scheduler", cluster.scheduler_address))):
        code, err = run_cli(["extract", str(campaign), "--out", str(tmp_path / name), *extra])
        assert code == 0, err
        found.append((tmp_path / name / "modes.csv").read_bytes())
    assert found[0] == found[1] and len(found[0].splitlines()) > 2


def test_a_local_cluster_started_on_demand_leaves_dask_configured():
    """In a fresh process (distributed not yet imported), two tasks start the local cluster inside the mapper;
    after it closes, distributed's configuration is still there. A "distributed.*" setting made before its
    import once took the whole of it away as the setting ended, and the cluster failed as it closed (a
    200-case validation lost at its end)."""
    import subprocess
    import sys

    code = ("import dask, sys\n"
            "from workbench.workflow.execution import mapper\n"
            "assert 'distributed' not in sys.modules\n"
            "with mapper(2) as run:\n"
            "    assert run(lambda shared, task: task * 2, [1, 2], 'x', None) == [2, 4]\n"
            "print(dask.config.get('distributed.scheduler.events-cleanup-delay'))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=REPO)
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr[-2000:]


def test_an_unreachable_scheduler_is_one_line_naming_it(tmp_path, monkeypatch):
    import workbench.workflow.execution as execution

    monkeypatch.setattr(execution, "SCHEDULER_TIMEOUT_S", 2)  # the wait is the timeout's, not 10 s of the suite
    start = time.perf_counter()
    code, err = run_cli(["propagate", str(FRAME), "--method", "mc", "--samples", "10", "--scheduler",
                         "tcp://127.0.0.1:9", "--out", str(tmp_path / "o")])
    assert code == 2 and time.perf_counter() - start < 2 + 5
    [line] = error_lines(err)
    assert "tcp://127.0.0.1:9" in line and "--scheduler" in line and "within 2 s" in line
    assert not (tmp_path / "o").exists()


@pytest.mark.slow  # 16 s on 2 cores: moved to the slow step to keep the default suite under 5 minutes
def test_a_worker_killed_mid_run_changes_nothing(cluster):
    from workbench.model.assembly import assemble
    from workbench.model.frame_file import read_frame
    from workbench.uq.stochastic import joint_model, monte_carlo
    from workbench.workflow.execution import _dask_mapper

    model = assemble(read_frame(FRAME))
    joints = joint_model(model.frame)
    reference = monte_carlo(model, joints, 6, 600, seed=8, chunk=20)
    with distributed.Client(cluster, set_as_default=False) as client:
        killed = []

        def kill_once(label, done, total):  # at a third of the tasks, kill the worker of the next ones
            if done == total // 3 and not killed:
                victim = next(iter(cluster.workers.values()))
                victim.process.process.kill()
                killed.append(victim)

        result = monte_carlo(model, joints, 6, 600, seed=8, chunk=20, mapper=_dask_mapper(client, kill_once))
    assert killed
    assert np.array_equal(result.frequency_hz, reference.frequency_hz)


@pytest.mark.slow
def test_validation_cases_are_the_same_with_and_without_a_scheduler(tmp_path, cluster):
    outputs = []
    for name, extra in (("serial", ("--workers", "1")), ("remote", ("--scheduler", cluster.scheduler_address))):
        from workbench.cli import main  # not run_cli: two cases take longer than its hang alarm

        assert main(["validate-diagnosis", "--cases", "2", "--seed", "5", "--out", str(tmp_path / name), *extra]) == 0
        rows = (tmp_path / name / "cases.csv").read_text().splitlines()
        outputs.append([row.rsplit(",", 1)[0] for row in rows])  # all but the wall time
    assert outputs[0] == outputs[1]


@pytest.mark.slow
def test_diagnose_gives_the_same_record_serially_and_on_a_scheduler(tmp_path, cluster):
    """`workbench diagnose` with its circle fits handed to a running scheduler (spawned workers): the same
    diagnosis.json (but its wall time) as in this process, on the campaign another program wrote
    (../shared/examples), also with the local cluster it starts by default (one worker per core, forked on
    Linux), and on a 12-test two-bay campaign of the proving ground, whose lowest mode is narrower than the line
    spacing (a fit whose damping collapsed onto a line once stopped where rounding stopped it, so the spawned
    workers' numbers differed from this process's).
    """
    import json

    from workbench.cli import main  # not run_cli: twelve tests' circle fits take longer than its hang alarm
    from workbench.io.campaign import write_campaign
    from workbench.proving.cases import CaseSpec, case_campaign

    two_bay = tmp_path / "two_bay"
    write_campaign(case_campaign(CaseSpec(4, 1004, "two_bay", "amplitude_softening", "medium", blind_tests=12))[0],
                   two_bay)
    remote = ("remote", ("--scheduler", cluster.scheduler_address))
    # the two-bay campaign on the scheduler's spawned workers only (their heap differs the most from this
    # process's; each run is 15 s), the example on the default local cluster too
    for campaign, runs in ((shared_path("examples", "independent-two-test-campaign"), (remote, ("every_core", ()))),
                           (two_bay, (remote,))):
        records = []
        for name, extra in (("serial", ("--workers", "1")), *runs):
            out = tmp_path / f"{campaign.name}_{name}"
            assert main(["diagnose", str(campaign), "--out", str(out), *extra]) == 0
            record = json.loads((out / "diagnosis.json").read_text())
            record.pop("wall_time_s")
            records.append(record)
        assert all(record == records[0] for record in records[1:]) and records[0]["ranking"]


@pytest.mark.slow
def test_design_gives_the_same_plan_and_check_serially_and_on_a_scheduler(tmp_path, cluster):
    """`workbench design`'s candidates and its simulation check (``--verify``) handed to a running scheduler:
    the same designs.csv, design.csv and check table as in this process."""
    outs = []
    for name, extra in (("serial", ()), ("remote", ("--scheduler", cluster.scheduler_address))):
        out = tmp_path / name
        code, err = run_cli(["design", str(REPO / "frames" / "two_bolt.toml"), "--out", str(out), "--budget", "12",
                             "--target", "5", "--verify", "2", *extra])
        assert code == 0, err
        outs.append(out)
    for name in ("designs.csv", "design.csv"):
        assert (outs[0] / name).read_bytes() == (outs[1] / name).read_bytes()
    checks = [(o / "index.html").read_text().split("Simulation check")[1].split("Every candidate")[0] for o in outs]
    assert checks[0] == checks[1] and "simulated width" in checks[0]
