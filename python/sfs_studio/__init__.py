"""Perspective shape from shading and near-light photometric stereo.

One photograph of an object lit by a point light near the camera (the light
falls off as 1/r^2) gives its depth; a set of photographs, each lit by its
own LED, gives depth, normals and albedo. The work is done by sfs-studio's
Rust core (the same code as the ``sfs-studio`` command line), with the GIL
released; Ctrl+C cancels a solve and raises ``KeyboardInterrupt``.

Options are the command line's, in snake case: ``max_side=324`` is
``--max-side 324``, ``albedo="auto"``, ``known_depth=[(x, y, z)]``,
``alpha=3e-7``, ``reflectance="oren-nayar"``. Bad input raises ``ValueError``
(``OSError`` for files) with the command line's message.

>>> import sfs_studio
>>> sol = sfs_studio.solve_file("assets/sombrero/image16.png",
...                             camera="assets/sombrero/scene.json")
>>> sol.depth.shape, sol.report["model_fit"]["rie_trusted"]  # doctest: +SKIP
"""

from __future__ import annotations

import json
import os
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Optional, Sequence, Union

import numpy as np

from . import _native
from ._native import DEFAULT_MAX_SIDE

__all__ = [
    "DEFAULT_MAX_SIDE",
    "Solution",
    "format_table",
    "photographs",
    "evaluate",
    "photometric_stereo",
    "read_image",
    "solve",
    "solve_file",
    "solve_many",
    "solve_row",
    "summary_row",
    "synth",
]

PathLike = Union[str, "os.PathLike[str]"]
#: What ``progress=`` takes: a callable ``progress(done, total, message)``,
#: ``True`` for a tqdm bar, or ``None``/``False`` for nothing.
Progress = Union[None, bool, Callable[[int, int, str], Any]]


@dataclass
class Solution:
    """A solve's result.

    ``depth``: float32 H x W, the camera's depth unit, NaN off the object;
    ``reprojection``: the image the solved surface renders (None for a
    photometric-stereo set); ``normals``: float32 H x W x 3, unit normals in
    the camera frame; ``albedo``: float32 H x W or None (no albedo
    estimated); ``report``: dict, the content of ``report.json``;
    ``warnings``: list of str; ``seconds``: the solver's time.
    """

    depth: np.ndarray
    reprojection: Optional[np.ndarray]
    normals: np.ndarray
    albedo: Optional[np.ndarray]
    report: dict
    warnings: list = field(default_factory=list)
    seconds: float = 0.0

    @classmethod
    def _of(cls, native: dict) -> "Solution":
        return cls(
            depth=native["depth"],
            reprojection=native["reprojection"],
            normals=native["normals"],
            albedo=native["albedo"],
            report=json.loads(native["report"]),
            warnings=list(native["warnings"]),
            seconds=float(native["seconds"]),
        )


def read_image(path: PathLike, srgb: str = "auto") -> np.ndarray:
    """A photograph as linear values, float32 H x W, read as the command line
    reads it: sRGB decoded for JPEG and 8-bit images (``srgb="auto"``; or
    ``"on"``/``"off"``), EXIF orientation applied, 16-bit and float TIFF
    kept, colour converted to luminance."""
    return _native.read_image(os.fspath(path), srgb)


# --- options ---------------------------------------------------------------


def _plain(value: Any) -> Any:
    """A keyword option's value as JSON: paths as text, numpy scalars and
    arrays as numbers and lists, tuples as lists."""
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    return value


def _options_json(options: Mapping[str, Any]) -> str:
    return json.dumps({k: _plain(v) for k, v in options.items()})


class _Bar:
    """``progress=True``: a tqdm bar (tqdm is imported only then)."""

    def __init__(self, description: str):
        try:
            from tqdm.auto import tqdm
        except ImportError as e:  # pragma: no cover - depends on the machine
            raise ImportError(
                "progress=True draws a tqdm bar: pip install tqdm "
                "(or pass a callable progress(done, total, message))"
            ) from e
        self._tqdm = tqdm
        self._bar = None
        self._description = description

    def __call__(self, done: int, total: int, message: str) -> None:
        if self._bar is None:
            self._bar = self._tqdm(total=total, desc=self._description, leave=False)
        if self._bar.total != total:
            self._bar.total = total
        self._bar.n = done
        self._bar.set_postfix_str(message, refresh=False)
        self._bar.refresh()

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def _progress(progress: Progress, description: str):
    if progress is None or progress is False:
        return None
    if progress is True:
        return _Bar(description)
    if callable(progress):
        return progress
    raise ValueError("progress: expected a callable progress(done, total, message), True or None")


def _run(call: Callable[[Any], dict], progress: Progress, description: str) -> dict:
    relay = _progress(progress, description)
    try:
        return call(relay)
    finally:
        if isinstance(relay, _Bar):
            relay.close()


class _Files:
    """Arrays and dicts as the files the photo pipeline reads, in a
    temporary folder removed afterwards."""

    def __init__(self) -> None:
        self._dir: Optional[tempfile.TemporaryDirectory] = None

    def __enter__(self) -> "_Files":
        return self

    def __exit__(self, *exc: Any) -> None:
        if self._dir is not None:
            self._dir.cleanup()

    def _path(self, name: str) -> str:
        if self._dir is None:
            self._dir = tempfile.TemporaryDirectory(prefix="sfs_studio-")
        return os.path.join(self._dir.name, name)

    def image(self, value: Any, name: str, what: str) -> Optional[str]:
        """A path as given, or an H x W array written as a float32 TIFF
        (read back bit for bit, as linear values)."""
        if value is None:
            return None
        if isinstance(value, (str, os.PathLike)):
            return os.fspath(value)
        array = np.asarray(value)
        if array.dtype == bool:
            array = array.astype(np.float32)
        if array.ndim != 2:
            raise ValueError(f"{what}: expected a path or an H x W array, not shape {array.shape}")
        path = self._path(name)
        _native.write_float_tiff(path, np.ascontiguousarray(array, dtype=np.float32))
        return path

    def camera(self, camera: Any, images: Optional[Sequence[str]] = None) -> Optional[str]:
        """A camera file's path as given, or a dict of its keys written as
        one (with ``images``, the lights' ``image`` names are those files',
        in order)."""
        if camera is None:
            return None
        if isinstance(camera, (str, os.PathLike)):
            return os.fspath(camera)
        if not isinstance(camera, Mapping):
            raise ValueError("camera: expected a camera file's path or a dict of its keys")
        keys = dict(camera)
        if images is not None and keys.get("lights"):
            lights = [dict(light) for light in keys["lights"]]
            named = [light for light in lights if light.get("image")]
            if len(named) == len(images):
                for light, image in zip(named, images):
                    light["image"] = os.path.basename(image)
            keys["lights"] = lights
        path = self._path("camera.json")
        with open(path, "w", encoding="utf-8") as f:
            json.dump(_plain(keys), f)
        return path


# --- one photograph --------------------------------------------------------


def _solve(native: Callable[..., dict], paths: list, camera_path: Optional[str],
           options: dict, out: Optional[PathLike], progress: Progress, name: str) -> dict:
    """A native solve of ``paths`` (one photograph's or a set's) with the
    command line's ``options``, written to ``out`` when given."""
    return _run(
        lambda relay: native(
            paths,
            camera_path,
            _options_json(options),
            None if out is None else os.fspath(out),
            relay,
        ),
        progress,
        name,
    )


def solve(
    image: Any,
    camera: Any,
    mask: Any = None,
    confidence: Any = None,
    *,
    progress: Progress = None,
    **options: Any,
) -> Solution:
    """Depth from one photograph: ``image`` is a path or a float32 H x W array
    of linear values (``read_image``); ``camera`` a camera file's path
    (scene.json or a near_ps calibration.json) or a dict of its keys (``focal``
    and ``cx``/``cy`` options instead work too: ``camera=None``); ``mask``
    and ``confidence`` paths or H x W arrays (mask: nonzero = object).
    ``options``: the command line's, snake case. ``progress``: a callable
    ``progress(done, total, message)`` or ``True`` for a tqdm bar."""
    with _Files() as files:
        images = image if isinstance(image, (list, tuple)) else [image]
        paths = [files.image(one, f"image_{k:02}.tiff", "image") for k, one in enumerate(images)]
        options = dict(options)
        options["mask"] = files.image(mask, "mask.tiff", "mask")
        options["confidence"] = files.image(confidence, "confidence.tiff", "confidence")
        camera_path = files.camera(camera)
        native = _solve(
            _native.solve_photograph, paths, camera_path, options, None, progress, "solve"
        )
    return Solution._of(native)


def solve_file(
    path: PathLike,
    camera: Any = None,
    out: Optional[PathLike] = None,
    *,
    progress: Progress = None,
    **options: Any,
) -> Solution:
    """What ``sfs-studio solve PATH --camera CAMERA --out OUT`` does: the same
    solve, and with ``out`` the same files in that folder (depth.npy,
    depth16.png, reprojection.png, mesh.ply, report.json, ...), written as one
    unit under a lock on the folder. ``path`` may be a list of photographs
    (summed, lights on together)."""
    paths = path if isinstance(path, (list, tuple)) else [path]
    paths = [os.fspath(p) for p in paths]
    with _Files() as files:
        camera_path = files.camera(camera)
        native = _solve(
            _native.solve_photograph, paths, camera_path, options, out, progress,
            os.path.basename(paths[0]),
        )
    return Solution._of(native)


# --- a set -----------------------------------------------------------------


def photometric_stereo(
    images: Sequence[Any],
    camera: Any,
    mask: Any = None,
    out: Optional[PathLike] = None,
    *,
    progress: Progress = None,
    **options: Any,
) -> Solution:
    """Near-light photometric stereo: ``images`` (paths or H x W arrays), each
    lit by a light of its own: the camera file's lights name each image (a
    dict's lights are taken in the images' order), or ``light=[(x, y, z),
    ...]`` one per image. Depth, normals and albedo. Options: ``max_side``,
    ``ambient``, ``confidence``, ``ps_smoothness``, ``ps_robust_scale``,
    ``ps_no_cast_shadows``, the light options. With ``out``, the files of
    ``sfs-studio solve --photometric-stereo --out OUT`` are written there
    (depth, normals, albedo, mesh, residuals, report.json); ``report`` is
    that report.json either way."""
    with _Files() as files:
        paths = [
            files.image(one, f"photo_{k + 1:02}.tiff", f"images[{k}]")
            for k, one in enumerate(images)
        ]
        options = dict(options)
        options["mask"] = files.image(mask, "mask.tiff", "mask")
        camera_path = files.camera(camera, paths)
        native = _solve(
            _native.solve_set, paths, camera_path, options, out, progress, "photometric stereo"
        )
    return Solution._of(native)


# --- synthetic scenes and errors --------------------------------------------


def synth(size: Union[int, Sequence[int]] = 256, leds: Optional[int] = None,
          albedo_pattern: str = "patches") -> dict:
    """A synthetic scene with its ground truth: the Sombrero (as ``sfs-studio
    synth``). Without ``leds``: one image lit from the camera centre, a dict
    of ``image``, ``depth_gt``, ``mask``, ``camera`` (a camera file's keys).
    With ``leds=N``: a photometric-stereo set of N LEDs around the camera
    (``sfs-studio synth --ps-leds N``), a dict of ``images`` (list),
    ``mask``, ``depth_gt``, ``normals_gt``, ``albedo_gt``, ``camera``."""
    width, height = (size, size) if isinstance(size, int) else tuple(size)
    if leds is None:
        native = _native.synth_sombrero(int(width), int(height))
    else:
        native = _native.synth_set(int(width), int(height), int(leds), albedo_pattern)
    native = dict(native)
    native["camera"] = json.loads(native["camera"])
    return native


def evaluate(depth: Any, truth: Any) -> dict:
    """The relative surface error ``rse`` and the reprojection error ``rie``
    of ``depth`` (an H x W array, or a .npy path) against a ground truth: a
    folder written by ``sfs-studio synth`` (as ``sfs-studio eval``) or a dict
    from ``synth()`` (one image)."""
    if isinstance(depth, (str, os.PathLike)):
        depth = np.load(os.fspath(depth))
    depth = np.ascontiguousarray(depth, dtype=np.float32)
    with _Files() as files:
        if isinstance(truth, (str, os.PathLike)):
            folder = Path(truth)
            for name in ("depth_gt.npy", "image16.png", "scene.json"):
                if not (folder / name).is_file():
                    raise ValueError(
                        f"{folder}: the folder has no {name}; evaluate takes a folder "
                        "written by `synth`"
                    )
            depth_gt = np.load(folder / "depth_gt.npy").astype(np.float32)
            image = read_image(folder / "image16.png", srgb="off")
            camera = str(folder / "scene.json")
        else:
            depth_gt = np.asarray(truth["depth_gt"], dtype=np.float32)
            image = np.asarray(truth["image"], dtype=np.float32)
            camera = files.camera(truth["camera"])
        return dict(_native.evaluate(depth, depth_gt, image, camera))


# --- many photographs --------------------------------------------------------


def photographs(paths: Union[PathLike, Iterable[PathLike]]) -> list:
    """The photographs ``paths`` names, as ``sfs-studio solve --out-dir``
    takes them: a folder (its PNG, JPEG and TIFF files, sorted), a pattern
    (``"photos/*.png"``, sorted), or a list of these and files."""
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    return [str(p) for p in _native.photographs([os.fspath(p) for p in paths])]


def summary_row(path: PathLike, solution: Optional[Solution], seconds: float,
                out: Optional[str] = None, error: Optional[str] = None) -> dict:
    """One photograph's line of a summary table: file, seconds (wall clock of
    the whole solve), fit (the model fit's RIE over trusted pixels),
    warnings, out, error."""
    fit = None
    if solution is not None:
        fit = solution.report.get("model_fit", {}).get("rie_trusted")
    return {
        "file": os.fspath(path),
        "seconds": seconds,
        "fit": fit,
        "warnings": [] if solution is None else list(solution.warnings),
        "out": out,
        "error": error,
    }


def _outs(out_dir: Optional[PathLike], files: Sequence[str]) -> list:
    """``out_dir/NAME`` for each photograph (its stem, or its file name where
    two share a stem), as ``sfs-studio solve --out-dir``."""
    if out_dir is None:
        return [None] * len(files)
    return [os.path.join(os.fspath(out_dir), name) for name in _native.folder_names(list(files))]


def solve_row(path: PathLike, camera: Any = None, out: Optional[PathLike] = None,
              **options: Any) -> dict:
    """``solve_file`` as a summary row (for maps over many photographs: an
    error becomes the row's ``error`` instead of stopping the others)."""
    start = time.perf_counter()
    try:
        solution = solve_file(path, camera=camera, out=out, **options)
    except (ValueError, OSError) as e:
        return summary_row(path, None, time.perf_counter() - start,
                           None if out is None else os.fspath(out), str(e))
    return summary_row(path, solution, time.perf_counter() - start,
                       None if out is None else os.fspath(out))


def solve_many(
    paths: Union[PathLike, Iterable[PathLike]],
    camera: Any = None,
    out_dir: Optional[PathLike] = None,
    workers: Optional[int] = None,
    *,
    progress: Progress = None,
    **options: Any,
) -> list:
    """``solve_file`` over many photographs on this machine: ``paths`` is a
    folder, a glob pattern or a list; each photograph's files go to
    ``out_dir/STEM``. ``workers`` solves at once (threads: the GIL is released
    during a solve; default 1, as each solve already uses every core).
    Returns the summary table: one dict per photograph, in order (file,
    seconds, fit, warnings, out, error). ``progress=True``: a tqdm bar over
    the photographs; a callable gets ``(done, total, file)``."""
    files = photographs(paths)
    outs = _outs(out_dir, files)
    relay = _progress(progress, "photographs")
    rows: list = [None] * len(files)
    done = 0
    try:
        with ThreadPoolExecutor(max_workers=max(1, workers or 1)) as pool:
            futures = {
                pool.submit(solve_row, p, camera, o, **options): k
                for k, (p, o) in enumerate(zip(files, outs))
            }
            from concurrent.futures import as_completed

            for future in as_completed(futures):
                k = futures[future]
                rows[k] = future.result()
                done += 1
                if relay is not None:
                    relay(done, len(files), os.path.basename(files[k]))
    finally:
        if isinstance(relay, _Bar):
            relay.close()
    return rows


def format_table(rows: Sequence[Mapping[str, Any]]) -> str:
    """A summary table as text, as ``sfs-studio solve --out-dir`` prints it:
    file, seconds, fit, and the warnings or the error."""
    return _native.format_table([
        (os.fspath(r["file"]), float(r["seconds"]), r.get("fit"),
         list(r.get("warnings") or []), r.get("error"))
        for r in rows
    ])
