#!/usr/bin/python3
"""A worked study with volume_haptics (docs/python.md): a coupling-stiffness sweep over one scene
and push-and-slide trajectory, each run recorded, then the recordings as a cohort table.

    stiffness_study.py [SCENE.json] [OUT_DIR]

SCENE defaults to resources/scenes/sphere-probe.json; the trajectory comes from
`volume-haptics make-trajectory` (on PATH, or VH_CLI). Writes OUT_DIR/k*.vhrec,
OUT_DIR/sweep.csv and OUT_DIR/cohort.csv, and OUT_DIR/sweep.png when matplotlib is installed.
"""
import csv
import json
import os
import pathlib
import subprocess
import sys

import numpy as np

import volume_haptics as vh

here = pathlib.Path(__file__).resolve()
scene_file = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else here.parents[3] / "resources/scenes/sphere-probe.json")
out = pathlib.Path(sys.argv[2] if len(sys.argv) > 2 else "stiffness-study")
out.mkdir(parents=True, exist_ok=True)

# The device path: cast the tool down onto the surface, push 5 mm past the contact, slide 20 mm.
cli = os.environ.get("VH_CLI", "volume-haptics")
subprocess.run([cli, "make-trajectory", "--scene", str(scene_file), "--out", str(out / "push.csv")], check=True,
               stdout=subprocess.DEVNULL)
trajectory = vh.read_trajectory(out / "push.csv")  # (N, 8): t_s, x_m, y_m, z_m, qw, qx, qy, qz

# The sweep: the same scene with five coupling stiffnesses, the volume loaded for each (a dict).
base = json.loads(scene_file.read_text())
sweep = []
for k_N_per_m in (250, 500, 1000, 2000, 4000):
    spec = dict(base, coupling=dict(base.get("coupling", {}), linear_N_per_m=k_N_per_m))
    scene = vh.load_scene(spec, base_dir=scene_file.parent)
    r = vh.run(scene, trajectory, record=out / ("k%04d.vhrec" % k_N_per_m))
    force = np.linalg.norm(r.force_N, axis=1)                                # |F| per tick [N]
    gap = np.linalg.norm(r.device_pose[:, :3] - r.proxy_pose[:, :3], axis=1)  # coupling stretch [m]
    sweep.append({"k_N_per_m": k_N_per_m, "peak_force_N": force.max(), "mean_contact_force_N": force[r.contacts > 0].mean(),
                  "max_stretch_mm": 1e3 * gap.max(), "max_penetration_um": 1e6 * r.report["max_penetration_m"],
                  "crossings": r.report["crossings"], "p99_tick_us": r.report["p99_us"]})

with open(out / "sweep.csv", "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(sweep[0]))
    w.writeheader()
    w.writerows(sweep)
print("%10s %13s %16s %15s %19s %10s" % ("k [N/m]", "peak |F| [N]", "mean |F| cont.", "stretch [mm]", "penetration [um]",
                                        "crossings"))
for s in sweep:
    print("%10d %13.3f %16.3f %15.3f %19.2f %10d" % (s["k_N_per_m"], s["peak_force_N"], s["mean_contact_force_N"],
                                                     s["max_stretch_mm"], s["max_penetration_um"], s["crossings"]))

# The cohort: every recording of the folder through the session metrics of `volume-haptics report`.
cohort = [vh.session_metrics(p) for p in sorted(out.glob("*.vhrec"))]
columns = ["file", "time_in_contact_s", "mean_contact_force_N", "max_force_N", "path_length_m",
           "proxy_path_length_m", "log_dimensionless_jerk"]
with open(out / "cohort.csv", "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=columns, extrasaction="ignore")
    w.writeheader()
    w.writerows(cohort)
print()
print("%12s %10s %12s %10s %10s %10s" % ("recording", "contact s", "mean |F| N", "max |F| N", "path mm", "LDLJ"))
for m in cohort:
    print("%12s %10.3f %12.3f %10.3f %10.2f %10.2f" % (pathlib.Path(m["file"]).name, m["time_in_contact_s"],
                                                      m["mean_contact_force_N"], m["max_force_N"],
                                                      1e3 * m["path_length_m"], m["log_dimensionless_jerk"]))

try:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    print("\nmatplotlib not installed: no plot (apt-get install python3-matplotlib)")
else:
    k = [s["k_N_per_m"] for s in sweep]
    fig, ax = plt.subplots(figsize=(5, 3.5))
    ax.plot(k, [s["peak_force_N"] for s in sweep], "o-", label="peak |F|")
    ax.plot(k, [s["mean_contact_force_N"] for s in sweep], "s-", label="mean |F| in contact")
    ax.set_xscale("log")
    ax.set_xlabel("coupling stiffness [N/m]")
    ax.set_ylabel("force on the hand [N]")
    ax.legend()
    fig.tight_layout()
    fig.savefig(out / "sweep.png", dpi=120)
    print("\nplot:", out / "sweep.png")
