"""Speedup of the Dask execution layer on 2 workers against 1, and a worker killed at half time.

Run from the repository root: ``python benchmarks/dask_speedup.py [--cases 20] [--samples 2000]``
(about 6 minutes on 2 cores). For a 2 000-sample Monte Carlo of the four-bolt frame and for 20
validation cases of the diagnosis, it times a local Dask cluster of 1 single-threaded worker and of
2, side by side in one run, prints the ratio, and checks that the results are identical to the bit.
Then it runs the Monte Carlo again on 2 workers, kills one of them when half the tasks are done,
and checks that the result is still complete and identical (the scheduler reruns the lost tasks).
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

import numpy as np
from distributed import Client, LocalCluster

from workbench.model.assembly import assemble
from workbench.model.frame_file import read_frame
from workbench.uq.stochastic import joint_model, monte_carlo
from workbench.workflow.diagnosis import validate
from workbench.workflow.execution import _dask_mapper

REPO = Path(__file__).resolve().parents[1]


def _cluster(workers: int) -> LocalCluster:
    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                        silence_logs=logging.ERROR)


def timed(workers: int, job, progress=None):
    with _cluster(workers) as cluster, Client(cluster, set_as_default=False) as client:
        client.run(lambda: None)  # workers up before the clock starts
        start = time.perf_counter()
        result = job(_dask_mapper(client, progress), cluster)
        return time.perf_counter() - start, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=2000)
    parser.add_argument("--cases", type=int, default=20)
    args = parser.parse_args()
    model = assemble(read_frame(REPO / "frames" / "four_bolt.toml"))
    joints = joint_model(model.frame)

    def mc(mapper, cluster):
        return monte_carlo(model, joints, 10, args.samples, seed=3, mapper=mapper, chunk=50).frequency_hz

    def cases(mapper, cluster):
        summary = validate(args.cases, 5, mapper=mapper)
        return [(r.case, r.verdict, r.where, r.shrinkage, r.confidence) for r in summary["results"]]

    print(f"{'job':36s} {'1 worker':>10s} {'2 workers':>10s} {'speedup':>8s}  identical")
    for name, job in ((f"Monte Carlo, four-bolt, {args.samples} samples", mc),
                      (f"validate-diagnosis, {args.cases} cases", cases)):
        t1, r1 = timed(1, job)
        t2, r2 = timed(2, job)
        same = np.array_equal(r1, r2) if isinstance(r1, np.ndarray) else r1 == r2
        print(f"{name:36s} {t1:9.1f}s {t2:9.1f}s {t1 / t2:7.2f}x  {same}", flush=True)

    killed = []

    def kill_at_half(cluster):
        def progress(label, done, total):
            if done == total // 2 and not killed:
                victim = next(iter(cluster.workers.values()))
                victim.process.process.kill()
                killed.append(done)
        return progress

    reference = monte_carlo(model, joints, 10, args.samples, seed=3, chunk=50).frequency_hz
    with _cluster(2) as cluster, Client(cluster, set_as_default=False) as client:
        again = monte_carlo(model, joints, 10, args.samples, seed=3, chunk=50,
                            mapper=_dask_mapper(client, kill_at_half(cluster))).frequency_hz
    print(f"a worker killed after {killed[0] if killed else '?'} tasks: result complete "
          f"({again.shape[0]} samples) and identical to the serial run: {np.array_equal(again, reference)}")


if __name__ == "__main__":
    main()
