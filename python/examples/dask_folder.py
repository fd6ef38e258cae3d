"""Solve every photograph of a folder on a dask.distributed cluster and print
one summary table (file, seconds, fit, warnings).

    python python/examples/dask_folder.py FOLDER CAMERA OUT_DIR [SCHEDULER]

Without SCHEDULER a LocalCluster of two worker processes runs here; with
one (``tcp://host:8786``, from ``dask scheduler``) the workers of that
cluster do the work: each needs ``pip install ./python`` and must see FOLDER
and OUT_DIR at the same paths (a shared file system).
"""

import sys

from dask.distributed import Client, LocalCluster

import sfs_studio
import sfs_studio.dask


def main() -> None:
    folder, camera, out_dir = sys.argv[1:4]
    scheduler = sys.argv[4] if len(sys.argv) > 4 else None
    if scheduler is None:
        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster, \
                Client(cluster) as client:
            rows = sfs_studio.dask.solve_folder(client, folder, camera=camera, out_dir=out_dir)
    else:
        with Client(scheduler) as client:
            rows = sfs_studio.dask.solve_folder(client, folder, camera=camera, out_dir=out_dir)
    print(sfs_studio.format_table(rows), end="")


if __name__ == "__main__":
    main()
