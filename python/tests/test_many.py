"""Many photographs: solve_many on this machine, and the documented Dask
example (sfs_studio.dask.solve_folder) on a LocalCluster of two processes."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import sfs_studio
from conftest import REPO, SCENE
from test_solve import relative_difference


def test_solve_many_writes_a_folder_per_photograph_and_one_table(four_photographs, tmp_path):
    out = tmp_path / "solved"
    seen = []
    rows = sfs_studio.solve_many(
        four_photographs, camera=SCENE, out_dir=out, workers=2,
        progress=lambda done, total, name: seen.append((done, total)),
    )
    assert [r["file"].rsplit("/", 1)[-1] for r in rows] == [
        f"frame{k:02}.png" for k in range(4)
    ]
    assert all(r["error"] is None for r in rows), rows
    assert all((out / f"frame{k:02}" / "depth.npy").is_file() for k in range(4))
    assert seen[-1] == (4, 4)
    table = sfs_studio.format_table(rows)
    assert "frame03.png" in table


def test_a_bad_photograph_is_a_row_with_its_error(four_photographs, tmp_path):
    (four_photographs / "broken.png").write_bytes(b"not a png")
    rows = sfs_studio.solve_many(four_photographs / "b*.png", camera=SCENE)
    assert len(rows) == 1
    assert rows[0]["error"] and "broken.png" in rows[0]["error"]


def test_dask_example_on_two_processes_equals_the_command_line(
    four_photographs, tmp_path, cli_sombrero
):
    """The documented example, python/examples/dask_folder.py, as a user runs
    it: a LocalCluster of two worker processes, solve_file mapped over the
    folder, one summary table printed."""
    pytest.importorskip("dask.distributed")
    out = tmp_path / "solved"
    example = REPO / "python" / "examples" / "dask_folder.py"
    run = subprocess.run(
        [sys.executable, str(example), str(four_photographs), str(SCENE), str(out)],
        capture_output=True, text=True, timeout=600, cwd=tmp_path,
    )
    assert run.returncode == 0, run.stderr
    table = run.stdout.splitlines()
    assert table[0].split()[:3] == ["file", "seconds", "fit"]
    assert [line.split()[0] for line in table[1:]] == [f"frame{k:02}.png" for k in range(4)]
    expected = np.load(cli_sombrero / "depth.npy")
    for k in range(4):
        depth = np.load(out / f"frame{k:02}" / "depth.npy")
        assert relative_difference(depth, expected) <= 1e-6


def test_dask_rows_carry_seconds_fit_and_warnings(four_photographs):
    distributed = pytest.importorskip("dask.distributed")
    import sfs_studio.dask

    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as client:
        rows = sfs_studio.dask.solve_folder(client, sorted(four_photographs.iterdir())[:2],
                                            camera=str(SCENE), max_side=128)
    assert len(rows) == 2
    assert all(r["error"] is None for r in rows), rows
    assert all(r["seconds"] > 0 and r["fit"] is not None for r in rows)
    assert all(isinstance(r["warnings"], list) for r in rows)
