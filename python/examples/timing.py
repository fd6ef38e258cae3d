"""Sombrero 256: the CLI (release) against sfs_studio.solve_file (release), 7 runs each, alternating."""
import json, statistics, subprocess, sys, time, tempfile, os
import numpy as np
import sfs_studio
cli = sys.argv[1]
img, cam = "assets/sombrero/image16.png", "assets/sombrero/scene.json"
cli_t, py_t, cli_s, py_s = [], [], [], []
tmp = tempfile.mkdtemp()
for k in range(7):
    out = os.path.join(tmp, f"cli{k}")
    t = time.perf_counter()
    subprocess.run([cli, "solve", img, "--camera", cam, "--out", out, "--quiet"], check=True)
    cli_t.append(time.perf_counter() - t)
    cli_s.append(json.load(open(os.path.join(out, "report.json")))["seconds"])
    out = os.path.join(tmp, f"py{k}")
    t = time.perf_counter()
    sol = sfs_studio.solve_file(img, camera=cam, out=out)
    py_t.append(time.perf_counter() - t)
    py_s.append(sol.report["seconds"])
d_cli = np.load(os.path.join(tmp, "cli0", "depth.npy")); d_py = np.load(os.path.join(tmp, "py0", "depth.npy"))
both = np.isfinite(d_cli)
rel = float(np.max(np.abs(d_py[both] - d_cli[both]) / np.abs(d_cli[both])))
print(f"CLI process wall s: median {statistics.median(cli_t):.3f} (runs {', '.join(f'{x:.3f}' for x in cli_t)})")
print(f"Python solve_file wall s: median {statistics.median(py_t):.3f} (runs {', '.join(f'{x:.3f}' for x in py_t)})")
print(f"solver seconds (report.json): CLI median {statistics.median(cli_s):.3f}, Python median {statistics.median(py_s):.3f}")
print(f"ratio Python/CLI wall: {statistics.median(py_t)/statistics.median(cli_t):.3f}; max relative depth difference {rel:.2e}")
