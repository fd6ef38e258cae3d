"""Shared fixtures: the repository's Sombrero asset and the command line's
own results on it (the binary from SFS_STUDIO_BIN, which scripts/test sets,
else target/{release,debug}/sfs-studio)."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SOMBRERO = REPO / "assets" / "sombrero"
IMAGE = SOMBRERO / "image16.png"
SCENE = SOMBRERO / "scene.json"


def cli_binary() -> Path | None:
    given = os.environ.get("SFS_STUDIO_BIN")
    if given:
        path = Path(given)
        if not path.is_file():
            raise FileNotFoundError(f"SFS_STUDIO_BIN={given}: no such file")
        return path
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    for profile in ("release", "debug"):
        path = target / profile / "sfs-studio"
        if path.is_file():
            return path
    return None


@pytest.fixture(scope="session")
def cli():
    """A function running `sfs-studio ARGS` (the command line)."""
    binary = cli_binary()
    if binary is None:
        pytest.skip("no sfs-studio binary: set SFS_STUDIO_BIN (scripts/test does)")

    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run(
            [str(binary), *map(str, args)], check=True, capture_output=True, text=True
        )

    return run


@pytest.fixture(scope="session")
def cli_sombrero(cli, tmp_path_factory) -> Path:
    """The command line's output folder for the Sombrero asset."""
    out = tmp_path_factory.mktemp("cli-sombrero")
    cli("solve", IMAGE, "--camera", SCENE, "--out", out, "--quiet")
    return out


@pytest.fixture()
def four_photographs(tmp_path) -> Path:
    """A folder of four photographs (copies of the Sombrero asset)."""
    folder = tmp_path / "photos"
    folder.mkdir()
    for k in range(4):
        shutil.copy(IMAGE, folder / f"frame{k:02}.png")
    return folder
