"""A daskrad cluster on SLURM through dask-jobqueue (``pip install dask-jobqueue``).

Run it on a login node; it starts the scheduler here, submits worker jobs, prints the address
and waits (Ctrl-C stops the jobs). The solution store must be on a file system every compute
node mounts (``/shared`` below): daskrad checks that each worker can open it.

    python cluster/slurm.py --jobs 4 --cores 32 --account myproj --queue compute
    daskrad run /shared/scenes/cornell_box.obj --scheduler tcp://LOGIN:8786 \
        -o /shared/runs/cb.exr

Edit VENV to the shared virtual environment where daskrad is installed.
"""

from __future__ import annotations

import argparse
import time

import dask

VENV = "/shared/daskrad/.venv"
ROUTES = "daskrad.distributed.dashboard"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--jobs", type=int, default=2, help="SLURM jobs (nodes) to start")
    p.add_argument("--cores", type=int, default=32, help="cores per job = worker processes")
    p.add_argument("--memory", default="64GB", help="memory per job")
    p.add_argument("--walltime", default="02:00:00")
    p.add_argument("--account", default=None)
    p.add_argument("--queue", default=None)
    p.add_argument("--port", type=int, default=8786)
    args = p.parse_args()

    from dask_jobqueue import SLURMCluster

    # the /daskrad page: the scheduler runs in this process and reads its routes at start
    routes = list(dask.config.get("distributed.scheduler.http.routes"))
    with dask.config.set({"distributed.scheduler.http.routes": routes + [ROUTES]}):
        cluster = SLURMCluster(
            cores=args.cores, processes=args.cores,       # one thread per worker process
            memory=args.memory, walltime=args.walltime,
            account=args.account, queue=args.queue,
            job_script_prologue=[f"source {VENV}/bin/activate",
                                 "export NUMBA_NUM_THREADS=1"],  # numba threads = 1 per process
            # dashboard on the login node's loopback: reach it with ssh -L 8787:127.0.0.1:8787
            scheduler_options={"port": args.port, "dashboard_address": "127.0.0.1:8787"},
        )
    cluster.scale(jobs=args.jobs)
    print(cluster.job_script())
    print(f"scheduler {cluster.scheduler_address}; dashboard {cluster.dashboard_link} "
          "(progress at /daskrad); Ctrl-C to stop")
    try:
        while True:
            time.sleep(3600)
    except KeyboardInterrupt:
        cluster.close()


if __name__ == "__main__":
    main()
