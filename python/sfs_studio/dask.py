"""Many photographs on a dask.distributed cluster: ``solve_file`` mapped over a
folder through a ``Client``, the results gathered into one summary table.

On one machine (the example the tests run)::

    from dask.distributed import Client, LocalCluster
    import sfs_studio.dask

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster, \\
            Client(cluster) as client:
        rows = sfs_studio.dask.solve_folder(
            client, "photos/", camera="photos/calibration.json",
            out_dir="solved/", max_side=324)
    print(sfs_studio.format_table(rows))

On a real cluster, start ``dask scheduler`` on one machine and ``dask worker
tcp://SCHEDULER:8786`` on each of the others (each with ``pip install
./python`` done, and the photographs and ``out_dir`` on a file system they all
see), then ``Client("tcp://SCHEDULER:8786")`` instead of the LocalCluster.

Each task runs ``sfs_studio.solve_row`` in a worker process: the solve's
files go to ``out_dir/STEM`` on the worker's file system and only the summary
row (file, seconds, fit, warnings, out, error) travels back.
"""

from __future__ import annotations

from typing import Any, Iterable, Optional, Union

import sfs_studio

__all__ = ["solve_folder"]


def solve_folder(
    client: Any,
    paths: Union[str, "sfs_studio.os.PathLike[str]", Iterable[Any]],
    camera: Any = None,
    out_dir: Optional[str] = None,
    **options: Any,
) -> list:
    """``sfs_studio.solve_file`` over ``paths`` (a folder, a glob pattern or a
    list) as one dask task per photograph on ``client``'s cluster; returns the
    summary table (one dict per photograph, in the photographs' order).
    ``camera`` is a path the workers can read, or a dict of its keys;
    ``options`` are ``solve_file``'s."""
    files = sfs_studio.photographs(paths)
    outs = sfs_studio._outs(out_dir, files)
    futures = client.map(
        _row,
        files,
        outs,
        camera=camera,
        options=options,
        # The same file twice is two tasks, not one cached result.
        pure=False,
    )
    return client.gather(futures)


def _row(path: str, out: Optional[str], camera: Any, options: dict) -> dict:
    """One task: a photograph's solve as a summary row."""
    return sfs_studio.solve_row(path, camera=camera, out=out, **options)
