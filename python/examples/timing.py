"""Sombrero 256: the CLI (release) against sfs_studio.solve_file (release),
alternating, N runs each (default 15).

Prints, for each: the wall time (minimum and median: on a busy machine the
minimum is the cost without interference) and the CPU time (user + system;
the CLI's as a child process, Python's of this process around the call),
the solver's own seconds from report.json, and the ratios Python / CLI.

    python python/examples/timing.py target/release/sfs-studio [N]
"""
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import sfs_studio

cli = sys.argv[1]
runs = int(sys.argv[2]) if len(sys.argv) > 2 else 15
img, cam = "assets/sombrero/image16.png", "assets/sombrero/scene.json"


def cpu(who: int) -> float:
    usage = resource.getrusage(who)
    return usage.ru_utime + usage.ru_stime


wall = {"cli": [], "py": []}
cpu_s = {"cli": [], "py": []}
solver = {"cli": [], "py": []}
tmp = tempfile.mkdtemp()
for k in range(runs):
    out = os.path.join(tmp, f"cli{k}")
    c, t = cpu(resource.RUSAGE_CHILDREN), time.perf_counter()
    subprocess.run([cli, "solve", img, "--camera", cam, "--out", out, "--quiet"], check=True)
    wall["cli"].append(time.perf_counter() - t)
    cpu_s["cli"].append(cpu(resource.RUSAGE_CHILDREN) - c)
    solver["cli"].append(json.load(open(os.path.join(out, "report.json")))["seconds"])
    out = os.path.join(tmp, f"py{k}")
    c, t = cpu(resource.RUSAGE_SELF), time.perf_counter()
    sol = sfs_studio.solve_file(img, camera=cam, out=out)
    wall["py"].append(time.perf_counter() - t)
    cpu_s["py"].append(cpu(resource.RUSAGE_SELF) - c)
    solver["py"].append(sol.report["seconds"])
d_cli = np.load(os.path.join(tmp, "cli0", "depth.npy"))
d_py = np.load(os.path.join(tmp, "py0", "depth.npy"))
both = np.isfinite(d_cli)
rel = float(np.max(np.abs(d_py[both] - d_cli[both]) / np.abs(d_cli[both])))
load = os.getloadavg()[0]
print(f"{runs} runs each, alternating; load average {load:.2f}")
for name, label in (("cli", "CLI process"), ("py", "Python solve_file")):
    print(
        f"{label}: wall min {min(wall[name]):.3f} s, median {statistics.median(wall[name]):.3f} s; "
        f"CPU min {min(cpu_s[name]):.3f} s, median {statistics.median(cpu_s[name]):.3f} s; "
        f"solver median {statistics.median(solver[name]):.3f} s"
    )
print(
    f"ratio Python / CLI: wall min {min(wall['py']) / min(wall['cli']):.3f}, "
    f"wall median {statistics.median(wall['py']) / statistics.median(wall['cli']):.3f}, "
    f"CPU min {min(cpu_s['py']) / min(cpu_s['cli']):.3f}; "
    f"max relative depth difference {rel:.2e}"
)
