#!/usr/bin/python3
"""A parameter study and a cohort on a Dask cluster with volume_haptics.study (docs/python.md):
scenes x trajectories x coupling stiffnesses, each run recorded, then the recordings' metrics;
the same study in a plain loop and on 1 and 2 worker processes, timed side by side.

    dask_study.py [OUT_DIR] [--scheduler tcp://HOST:8786] [--repeat N]

Without --scheduler it starts a LocalCluster on this machine (1, then 2 worker processes, one
thread each); with it, the same code runs on that cluster (its workers need volume_haptics and
the scene files at the same paths, and OUT_DIR on a shared file system). The trajectories come
from `volume-haptics make-trajectory` (on PATH, or VH_CLI). Writes OUT_DIR/study.csv,
OUT_DIR/cohort.csv and OUT_DIR/throughput.csv, and prints the throughput table: runs per second
for each way, the speed-up over the plain loop, and the per-run overhead of a cluster task
(measured with runs of one tick).
"""
import argparse
import os
import pathlib
import subprocess
import time


import volume_haptics as vh
import volume_haptics.study as st



def main():
    """Run from the script only: Dask's worker processes import this file (spawn), and must not
    start the study again."""
    here = pathlib.Path(__file__).resolve()
    scenes_dir = here.parents[3] / "resources/scenes"
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", nargs="?", default="dask-study")
    parser.add_argument("--scheduler", help="a dask.distributed scheduler's address (default: a LocalCluster here)")
    parser.add_argument("--repeat", type=int, default=2, help="trajectories per scene (default 2)")
    args = parser.parse_args()
    out = pathlib.Path(args.out).resolve()
    out.mkdir(parents=True, exist_ok=True)

    # Scenes that need no shared datasets: the sphere with a probe, the block with a peg.
    scenes = {"sphere-probe": scenes_dir / "sphere-probe.json", "block-peg": scenes_dir / "block-peg.json"}
    # Where make-trajectory casts each tool down from (the block's hole is at its centre).
    ray_starts = {"sphere-probe": [], "block-peg": ["--ray-start", "0.015", "0", "0.04", "--slide-dir", "0", "1", "0"]}
    cli = os.environ.get("VH_CLI", "volume-haptics")
    trajectories = {}
    for name, scene in scenes.items():
        path = out / (name + ".csv")
        subprocess.run([cli, "make-trajectory", "--scene", str(scene), "--out", str(path)] + ray_starts[name], check=True,
                       stdout=subprocess.DEVNULL)
        base = vh.read_trajectory(path)
        base[:, 0] *= 0.25  # four times faster: about 1,100 ticks a run
        for r in range(args.repeat):  # the same push, each repeat 1 mm farther along x
            t = base.copy()
            t[:, 1] += 0.001 * r
            trajectories[(name, r)] = t
    stiffnesses = (300, 1000, 3000)
    runs = []
    for name, scene in scenes.items():
        mine = {"%s-%d" % (name, r): t for (n, r), t in trajectories.items() if n == name}
        runs += st.parameter_study({name: scene}, mine, [{"coupling": {"linear_N_per_m": k}} for k in stiffnesses])
    # Runs of one tick: what a task costs beyond the run itself.
    tiny = [dict(r, trajectory=r["trajectory"][:2] * [1e-3, 1, 1, 1, 1, 1, 1, 1]) for r in runs] * 10


    def timed(fn):
        t0 = time.perf_counter()
        value = fn()
        return value, time.perf_counter() - t0


    rows = []
    plain, plain_s = timed(lambda: st.run_study(runs))
    _, plain_tiny_s = timed(lambda: st.run_study(tiny))
    rows.append(("plain loop", 0, plain_s, plain_tiny_s))
    plain.to_csv(out / "study.csv", index=False)

    from distributed import Client, LocalCluster  # noqa: E402  (Debian python3-distributed)

    ways = [(None, 1), (None, 2)] if args.scheduler is None else [(args.scheduler, None)]
    for address, workers in ways:
        cluster = None
        if address is None:
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                                   local_directory=str(out / "dask"))
            client = Client(cluster)
        else:
            client = Client(address)
            workers = len(client.scheduler_info()["workers"])
        client.run(lambda: __import__("volume_haptics"))  # import once on every worker, not in the timing
        table, s = timed(lambda: st.run_study(runs, client=client))
        _, tiny_s = timed(lambda: st.run_study(tiny, client=client))
        assert table.equals(plain), "the cluster's table differs from the plain loop's"
        rows.append(("cluster" if address else "LocalCluster", workers, s, tiny_s))
        if address is not None or workers == ways[-1][1]:
            # Untimed: the study again, recorded, and its recordings' cohort table.
            recorded = st.run_study(runs, client=client, record_dir=str(out / "recordings"))
            cohort = st.cohort(list(recorded["recording"]), client=client)
            cohort.to_csv(out / "cohort.csv", index=False)
        client.close()
        if cluster is not None:
            cluster.close()

    n = len(runs)
    print("%d runs (%d scenes x %d trajectories x %d stiffnesses), %d ticks in all"
          % (n, len(scenes), args.repeat, len(stiffnesses), int(plain["ticks"].sum())))
    print("%-14s %8s %10s %10s %10s %16s" % ("way", "workers", "wall s", "runs/s", "speed-up", "overhead ms/run"))
    lines = ["way,workers,wall_s,runs_per_s,speed_up,overhead_ms_per_run"]
    for way, workers, s, tiny_s in rows:
        # A task's cost beyond its run, on a worker's clock: the workers' time on one-tick runs
        # (wall time x workers) per run, less the plain loop's time per one-tick run.
        overhead_ms = 1e3 * (tiny_s * max(workers, 1) - plain_tiny_s) / len(tiny)
        print("%-14s %8s %10.2f %10.2f %10.2f %16.1f" % (way, workers or "-", s, n / s, plain_s / s,
                                                           overhead_ms if workers else 0.0))
        lines.append("%s,%d,%.3f,%.3f,%.3f,%.2f" % (way, workers, s, n / s, plain_s / s, overhead_ms if workers else 0.0))
    (out / "throughput.csv").write_text("\n".join(lines) + "\n")
    print("tables: %s, %s, %s" % (out / "study.csv", out / "cohort.csv", out / "throughput.csv"))


if __name__ == "__main__":
    main()
