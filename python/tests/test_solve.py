"""sfs_studio against the command line, arrays in and out, errors, progress
and cancellation."""

from __future__ import annotations

import _thread
import json

import numpy as np
import pytest

import sfs_studio
from conftest import IMAGE, SCENE


def relative_difference(a: np.ndarray, b: np.ndarray) -> float:
    """The largest |a - b| / |b| where both are finite; NaN where one is and
    the other is not counts as a difference of 1."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    assert a.shape == b.shape
    if not np.array_equal(np.isfinite(a), np.isfinite(b)):
        return 1.0
    both = np.isfinite(a)
    return float(np.max(np.abs(a[both] - b[both]) / np.abs(b[both])))


def without_timings(report: dict) -> dict:
    """report.json less what depends on the clock."""
    text = json.dumps(report)
    report = json.loads(text)
    for key in ("seconds", "phases"):
        report.pop(key, None)
    for level in report.get("levels", []):
        level.pop("seconds", None)
    for fit in ("albedo_fit", "material_fit"):
        if isinstance(report.get(fit), dict):
            report[fit].pop("seconds", None)
    return report


def assert_same_report(a, b, path="report", rel=1e-6):
    """Reports equal, numbers to `rel` (sums over threads may differ in the
    last digit)."""
    if isinstance(a, dict) and isinstance(b, dict):
        assert sorted(a) == sorted(b), path
        for key in a:
            assert_same_report(a[key], b[key], f"{path}.{key}", rel)
    elif isinstance(a, list) and isinstance(b, list):
        assert len(a) == len(b), path
        for k, (x, y) in enumerate(zip(a, b)):
            assert_same_report(x, y, f"{path}[{k}]", rel)
    elif isinstance(a, float) or isinstance(b, float):
        assert a == pytest.approx(b, rel=rel, abs=1e-12), path
    else:
        assert a == b, path


def visible(folder) -> list:
    """The files of an output folder, less the hidden lock."""
    return sorted(p.name for p in folder.iterdir() if not p.name.startswith("."))


def test_read_image_is_linear_float32_of_the_photographs_size():
    image = sfs_studio.read_image(IMAGE)
    assert image.dtype == np.float32
    assert image.shape == (256, 256)
    assert 0.0 <= float(image.min()) and float(image.max()) <= 1.0
    assert float(image.max()) > 0.1


def test_solve_file_equals_the_command_line(cli_sombrero, tmp_path):
    out = tmp_path / "py"
    solution = sfs_studio.solve_file(IMAGE, camera=SCENE, out=out)
    cli_depth = np.load(cli_sombrero / "depth.npy")
    assert solution.depth.dtype == np.float32
    assert relative_difference(solution.depth, cli_depth) <= 1e-6
    assert relative_difference(np.load(out / "depth.npy"), cli_depth) <= 1e-6
    # The same files, the same report (less its timings).
    assert visible(out) == visible(cli_sombrero)
    cli_report = json.loads((cli_sombrero / "report.json").read_text())
    assert_same_report(
        without_timings(json.loads((out / "report.json").read_text())), without_timings(cli_report)
    )
    assert_same_report(without_timings(solution.report), without_timings(cli_report))


def test_solve_of_arrays_equals_the_solve_of_the_file(cli_sombrero):
    image = sfs_studio.read_image(IMAGE)
    camera = json.loads(SCENE.read_text())
    solution = sfs_studio.solve(image, camera)
    assert relative_difference(solution.depth, np.load(cli_sombrero / "depth.npy")) <= 1e-6
    h, w = image.shape
    assert solution.normals.shape == (h, w, 3)
    assert solution.reprojection.shape == (h, w)
    lengths = np.linalg.norm(solution.normals, axis=2)
    on = np.isfinite(solution.depth)
    assert np.allclose(lengths[on & np.isfinite(lengths)], 1.0, atol=1e-4)
    assert isinstance(solution.warnings, list)


def test_the_mask_array_leaves_the_background_nan():
    image = sfs_studio.read_image(IMAGE)
    mask = np.zeros(image.shape, dtype=bool)
    mask[64:192, 64:192] = True
    solution = sfs_studio.solve(image, str(SCENE), mask=mask, max_side=0, kappa=1, kappa_max=1)
    assert np.isnan(solution.depth[~mask]).all()
    assert np.isfinite(solution.depth[mask]).mean() > 0.99


def test_bad_input_raises_the_command_lines_errors(tmp_path):
    with pytest.raises(ValueError, match="unknown option no_such_option"):
        sfs_studio.solve_file(IMAGE, camera=SCENE, no_such_option=1)
    with pytest.raises(ValueError, match="eta"):
        sfs_studio.solve_file(IMAGE, camera=SCENE, eta=1.5)
    with pytest.raises(ValueError, match="--albedo 0"):
        sfs_studio.solve_file(IMAGE, camera=SCENE, albedo="0")
    with pytest.raises(ValueError, match="--roughness belongs to --reflectance oren-nayar"):
        sfs_studio.solve_file(IMAGE, camera=SCENE, roughness=0.3)
    # The core's checks of what options mean together, as on the command
    # line (the package once had its own copy without them).
    with pytest.raises(ValueError, match="kappa = 10: exceeds kappa-max's value 5"):
        sfs_studio.solve_file(IMAGE, camera=SCENE, kappa=10)
    with pytest.raises(ValueError, match="--distance and --intensity-scale 2 both set"):
        sfs_studio.solve_file(IMAGE, camera=SCENE, distance=3.0, intensity_scale=2)
    with pytest.raises(ValueError, match="does not apply to photometric stereo"):
        sfs_studio.photometric_stereo([IMAGE, IMAGE], SCENE, method="explicit")
    with pytest.raises(ValueError, match="--known-depth 999,999,"):
        sfs_studio.solve_file(IMAGE, camera=SCENE, known_depth=[(999, 999, 2.0)])
    missing = tmp_path / "missing.png"
    with pytest.raises(OSError, match="missing.png"):
        sfs_studio.solve_file(missing, camera=SCENE)
    with pytest.raises(ValueError, match="H x W"):
        sfs_studio.solve(np.zeros((4, 4, 3), dtype=np.float32), SCENE)


def test_progress_is_reported_and_an_exception_in_it_stops_the_solve():
    steps = []
    sfs_studio.solve_file(IMAGE, camera=SCENE, progress=lambda *step: steps.append(step))
    assert steps, "no progress reported"
    assert all(0 < done <= total for done, total, _ in steps)
    assert steps[-1][0] == steps[-1][1]

    class Stop(Exception):
        pass

    def stop(done, total, message):
        raise Stop(message)

    with pytest.raises(Stop):
        sfs_studio.solve_file(IMAGE, camera=SCENE, progress=stop)


def test_ctrl_c_cancels_the_solve_with_keyboard_interrupt():
    calls = []

    def interrupt(done, total, message):
        calls.append(done)
        # What Ctrl+C does: a SIGINT pending for the main thread.
        _thread.interrupt_main()

    with pytest.raises(KeyboardInterrupt):
        sfs_studio.solve_file(IMAGE, camera=SCENE, progress=interrupt)
    # Cancelled at once: the solve did not run its course after the signal.
    assert len(calls) <= 3, calls


def test_photometric_stereo_recovers_a_synthetic_set():
    scene = sfs_studio.synth(size=96, leds=4, albedo_pattern="patches")
    assert len(scene["images"]) == 4
    solution = sfs_studio.photometric_stereo(scene["images"], scene["camera"], mask=scene["mask"])
    on = scene["mask"] > 0.5
    depth, truth = solution.depth[on], scene["depth_gt"][on]
    both = np.isfinite(depth) & np.isfinite(truth)
    assert both.mean() > 0.95
    # The set's depth unit comes from its lights: about 1 % off here.
    assert np.median(np.abs(depth[both] - truth[both]) / truth[both]) < 0.03
    normals, normals_gt = solution.normals[on][both], scene["normals_gt"][on][both]
    cosine = np.clip(np.sum(normals * normals_gt, axis=1), -1.0, 1.0)
    assert np.degrees(np.median(np.arccos(cosine))) < 3.0
    assert solution.albedo.shape == scene["mask"].shape


def test_evaluate_equals_the_command_lines_eval(cli, tmp_path):
    folder = tmp_path / "scene"
    cli("synth", "sombrero", "--size", "64x64", "--out", folder)
    expected = json.loads(
        cli("eval", "--depth", folder / "depth_gt.npy", "--gt", folder).stdout
    )
    from_folder = sfs_studio.evaluate(folder / "depth_gt.npy", folder)
    assert from_folder["rse"] == pytest.approx(expected["rse"], abs=1e-9)
    assert from_folder["rie"] == pytest.approx(expected["rie"], rel=1e-6)
    # The same scene in memory (its image not quantised to 16 bits).
    scene = sfs_studio.synth(size=64)
    in_memory = sfs_studio.evaluate(scene["depth_gt"], scene)
    assert in_memory["rse"] < 1e-6
    assert in_memory["rie"] == pytest.approx(expected["rie"], rel=1e-3)
    assert sfs_studio.evaluate(scene["depth_gt"] * 1.05, scene)["rse"] > 1e-3


def test_photometric_stereo_of_files_equals_the_command_line(cli, tmp_path):
    scene = tmp_path / "set"
    cli("synth", "sombrero", "--ps-leds", "4", "--size", "96x96", "--out", scene)
    out = tmp_path / "cli"
    images = [scene / f"led{k:02}.png" for k in range(1, 5)]
    cli("solve", *images, "--photometric-stereo", "--camera", scene / "scene.json",
        "--mask", scene / "mask.png", "--out", out, "--quiet")
    py_out = tmp_path / "py"
    solution = sfs_studio.photometric_stereo(
        images, scene / "scene.json", mask=scene / "mask.png", out=py_out
    )
    assert relative_difference(solution.depth, np.load(out / "depth.npy")) <= 1e-6
    # The same files and the command line's report.json (less its timings).
    assert visible(py_out) == visible(out)
    cli_report = json.loads((out / "report.json").read_text())
    assert cli_report["mode"] == "photometric_stereo"
    assert_same_report(
        without_timings(json.loads((py_out / "report.json").read_text())),
        without_timings(cli_report),
    )
    assert_same_report(without_timings(solution.report), without_timings(cli_report))
    assert np.allclose(solution.normals, np.load(out / "normals.npy"), atol=1e-6, equal_nan=True)
