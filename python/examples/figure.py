"""The README's figure: the Sombrero asset solved from Python, depth and
normals side by side (matplotlib). Run from the repository:

    python python/examples/figure.py docs/python-sombrero.png
"""

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import sfs_studio  # noqa: E402

out = sys.argv[1] if len(sys.argv) > 1 else "python-sombrero.png"
sol = sfs_studio.solve_file("assets/sombrero/image16.png", camera="assets/sombrero/scene.json")
fig, (left, right) = plt.subplots(1, 2, figsize=(6.4, 3.0), dpi=80)
shown = left.imshow(sol.depth, cmap="viridis")
left.set_title("depth")
fig.colorbar(shown, ax=left, shrink=0.8)
# Normals (camera frame, z towards the camera) as colours: (n + 1) / 2.
right.imshow(np.nan_to_num((sol.normals * np.array([1, -1, -1]) + 1) / 2, nan=1.0).clip(0, 1))
right.set_title("normals")
for axis in (left, right):
    axis.set_axis_off()
fig.tight_layout()
fig.savefig(out)
print(f"wrote {out}")
