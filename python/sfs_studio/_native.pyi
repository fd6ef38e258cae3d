"""Type stubs of the native module (crate sfs-python); use the functions of
``sfs_studio`` itself, which take arrays, dicts and keyword options."""

from typing import Any, Callable, Optional, Sequence

import numpy as np
import numpy.typing as npt

DEFAULT_MAX_SIDE: int

_Progress = Optional[Callable[[int, int, str], Any]]

def read_image(path: str, srgb: str = "auto") -> npt.NDArray[np.float32]: ...
def write_float_tiff(path: str, image: npt.NDArray[np.float32]) -> None: ...
def solve_photograph(
    images: Sequence[str],
    camera: Optional[str],
    options: str,
    out: Optional[str] = None,
    progress: _Progress = None,
) -> dict[str, Any]: ...
def solve_set(
    images: Sequence[str],
    camera: Optional[str],
    options: str,
    out: Optional[str] = None,
    progress: _Progress = None,
) -> dict[str, Any]: ...
def synth_sombrero(width: int, height: int) -> dict[str, Any]: ...
def synth_set(
    width: int, height: int, count: int, albedo_pattern: str = "patches"
) -> dict[str, Any]: ...
def evaluate(
    depth: npt.NDArray[np.float32],
    depth_gt: npt.NDArray[np.float32],
    image: npt.NDArray[np.float32],
    camera: str,
) -> dict[str, float]: ...
def photographs(paths: Sequence[str]) -> list[str]: ...
def folder_names(paths: Sequence[str]) -> list[str]: ...
def format_table(
    rows: Sequence[tuple[str, float, Optional[float], Sequence[str], Optional[str]]],
) -> str: ...
