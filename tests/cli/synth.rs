//! `synth` and what follows it: the synth, solve and eval round trip, a mesh
//! rendered, and a scene with cast shadows solved with the shadow taken out.

use std::collections::BTreeSet;
use std::path::Path;

use serde_json::Value;
use sfs_core::params::SolverParams;
use tempfile::tempdir;

use crate::common::{
    Fixture, SOLVE_FILES, SYNTH_FILES, assert_said, assert_success, entries, read_json, s, sfs,
    solve_scene, stdout, synth_in_temp, synth_into,
};

#[test]
fn synth_solve_eval_round_trip() {
    let fx = Fixture::new();
    let names = entries(&fx.scene);
    let expected: Vec<String> = {
        let mut v: Vec<String> = SYNTH_FILES.iter().map(|f| f.to_string()).collect();
        v.sort();
        v
    };
    assert_eq!(names, expected, "synth wrote the wrong files");

    let camera = read_json(&fx.scene.join("scene.json"));
    let keys: BTreeSet<&str> = camera
        .as_object()
        .expect("scene.json is an object")
        .keys()
        .map(String::as_str)
        .collect();
    let expected_keys: BTreeSet<&str> = [
        "name",
        "width",
        "height",
        "focal",
        "cx",
        "cy",
        "intensity_scale",
        "intensity_scale_measured",
    ]
    .into();
    assert_eq!(keys, expected_keys);
    assert_eq!(camera["intensity_scale_measured"], true);
    assert_eq!(camera["width"], 40);
    assert_eq!(camera["height"], 40);
    assert!(camera["focal"].as_f64().unwrap() > 0.0);

    // Solve against the ground truth, through the paper's whole pyramid.
    let r = fx.path("result");
    let mut args = fx.solve_args(&r, &["--init-depth", "from-image"]);
    args.extend(["--gt".into(), s(&fx.scene)]);
    assert_success(&sfs(&args), "solve");
    let mut expected: Vec<String> = SOLVE_FILES.iter().map(|f| f.to_string()).collect();
    expected.sort();
    assert_eq!(entries(&r), expected, "solve wrote the wrong files");
    // `--albedo auto` (the default) on a uniform render: the estimate is
    // reported and not used; albedo.npy holds 1 on the surface.
    let albedo_report = read_json(&r.join("report.json"));
    assert_eq!(
        albedo_report["albedo_fit"]["used"], false,
        "{albedo_report}"
    );
    let used = sfs_core::io::read_npy(&r.join("albedo.npy")).expect("albedo.npy");
    assert!(used.as_slice().iter().all(|a| a.is_nan() || *a == 1.0));
    // `--albedo 1`: no estimate, no albedo files, the same depth.
    let plain = fx.path("albedo_one");
    let mut args_one = fx.solve_args(&plain, &["--init-depth", "from-image", "--albedo", "1"]);
    args_one.extend(["--gt".into(), s(&fx.scene)]);
    assert_success(&sfs(&args_one), "solve --albedo 1");
    assert!(!plain.join("albedo.npy").exists() && !plain.join("albedo.png").exists());
    assert!(read_json(&plain.join("report.json"))["albedo_fit"].is_null());
    assert_eq!(
        std::fs::read(plain.join("depth.npy")).expect("depth.npy"),
        std::fs::read(r.join("depth.npy")).expect("depth.npy"),
        "albedo auto unused must solve exactly as albedo 1"
    );

    let report = read_json(&r.join("report.json"));
    let rse = report["rse"].as_f64().expect("report.rse is a number");
    assert!(rse.is_finite() && (0.0..0.1).contains(&rse), "rse {rse}");
    assert!(
        report["rie"]
            .as_f64()
            .expect("report.rie is a number")
            .is_finite()
    );
    assert!(
        report["seconds"]
            .as_f64()
            .expect("report.seconds is a number")
            >= 0.0
    );
    let levels = report["levels"]
        .as_array()
        .expect("report.levels is an array");
    assert!(!levels.is_empty());
    let widths: Vec<u64> = levels
        .iter()
        .map(|l| l["width"].as_u64().expect("level width"))
        .collect();
    assert!(
        widths.windows(2).all(|w| w[0] < w[1]),
        "level widths do not grow: {widths:?}"
    );
    assert_eq!(*widths.last().unwrap(), 40);
    assert_eq!(report["parameters"]["alpha"], "auto");
    assert_eq!(report["parameters"]["units"], "relative");
    let chosen = report["alpha_used"].as_f64().expect("alpha_used");
    assert!(chosen > 0.0 && chosen < 1e-3, "auto alpha {chosen}");
    assert_eq!(
        report["parameters"]["lambda"].as_f64(),
        Some(SolverParams::default().lambda)
    );

    // The depth map has the image's size and positive depth on the object.
    let depth = sfs_core::io::read_npy(&r.join("depth.npy")).unwrap();
    assert_eq!(depth.size(), (40, 40));
    assert!(depth.as_slice().iter().any(|z| z.is_finite() && *z > 0.0));

    // eval agrees with the report.
    let out = sfs([
        "eval",
        "--depth",
        &s(&r.join("depth.npy")),
        "--gt",
        &s(&fx.scene),
    ]);
    assert_success(&out, "eval");
    let printed: Value = serde_json::from_str(stdout(&out).trim())
        .unwrap_or_else(|e| panic!("eval printed no JSON ({e}): {}", stdout(&out)));
    let eval_rse = printed["rse"].as_f64().expect("eval rse");
    assert!(
        (eval_rse - rse).abs() <= 1e-6,
        "eval rse {eval_rse} != report rse {rse}"
    );
    assert!(printed["rie"].as_f64().is_some());

    // Warm start from the result: one level at full resolution.
    let warm = fx.path("warm");
    let depth_path = s(&r.join("depth.npy"));
    let args = fx.solve_args(&warm, &["--init-depth", &depth_path, "--kappa", "2"]);
    assert_success(&sfs(&args), "solve --init-depth depth.npy");
    let report = read_json(&warm.join("report.json"));
    let levels = report["levels"].as_array().unwrap();
    assert_eq!(levels.len(), 1, "a warm start skips the coarse levels");
    assert_eq!(levels[0]["width"], 40);
    assert_eq!(report["parameters"]["init_depth"], depth_path.as_str());
    assert!(report["rse"].is_null(), "no --gt, no rse");
}

#[test]
fn synth_renders_a_mesh() {
    let mesh = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/meshes/suzanne.obj");
    if !mesh.is_file() {
        eprintln!("skipped: {} does not exist", mesh.display());
        return;
    }
    let tmp = tempdir().unwrap();
    let d = synth_into(&tmp.path().join("suzanne"), &[&s(&mesh), "--size", "64x32"]);
    let mask = image::open(d.join("mask.png")).unwrap().to_luma8();
    assert_eq!(mask.dimensions(), (64, 32));
    let values: BTreeSet<u8> = mask.pixels().map(|p| p.0[0]).collect();
    assert!(
        values.contains(&0) && values.len() >= 2,
        "the mask should show object and background: {values:?}"
    );
    let camera = read_json(&d.join("scene.json"));
    assert_eq!(camera["name"], "suzanne");
    assert_eq!(
        (camera["width"].clone(), camera["height"].clone()),
        (64.into(), 32.into())
    );
}

#[test]
fn synth_shadows_has_ground_truth_and_solve_takes_the_shadow_out() {
    let (dir, scene) = synth_in_temp(
        "scene",
        "sombrero --size 96x96 --light 1.29,0,0.47 --shadows",
    );
    let truth = image::open(scene.join("shadow.png"))
        .expect("shadow.png")
        .to_luma8();
    let in_shadow = truth.pixels().filter(|p| p.0[0] > 127).count();
    assert!(
        in_shadow > 100,
        "the light 40 degrees off casts a shadow: {in_shadow}"
    );
    let out = dir.path().join("solved");
    let run = solve_scene(&scene, "image16.png", &out, &[]);
    assert_success(&run, "solve of the shadowed render");
    assert_said(&run, "taken out of the data term");
    let found = image::open(out.join("shadow.png"))
        .expect("solve writes shadow.png")
        .to_luma8();
    let agree = found
        .pixels()
        .zip(truth.pixels())
        .filter(|(a, b)| (a.0[0] > 127) == (b.0[0] > 127))
        .count();
    assert!(
        agree as f64 >= 0.99 * (96.0 * 96.0),
        "the solve's shadow is the render's: {agree} of 9216 agree"
    );
    let report = read_json(&out.join("report.json"));
    let share = report["shadow_share"].as_f64().expect("shadow_share");
    assert!((share - in_shadow as f64 / 9216.0).abs() < 0.01, "{share}");
}

/// Issue 48, item 7: `synth` 64x64 with noise, then 96x96 without, into one
/// folder left the old `noisy8.png`; a set (`--ps-leds`) then one image left
/// the set's photographs and truth. One run's files per folder, whatever
/// ran there before; files the tool does not write are never removed.
#[test]
fn a_reused_synth_folder_holds_one_runs_files() {
    let dir = tempdir().unwrap();
    let out = dir.path().join("d");
    let synth = |extra: &[&str]| {
        let mut args = vec!["sombrero"];
        args.extend(extra);
        synth_into(&out, &args);
    };
    synth(&["--size", "64x64", "--noise", "5"]);
    std::fs::write(out.join("notes.txt"), "mine").unwrap();
    synth(&["--size", "96x96"]);
    let names = entries(&out);
    assert!(!names.contains(&"noisy8.png".to_owned()), "{names:?}");
    assert!(names.contains(&"notes.txt".to_owned()), "{names:?}");
    synth(&["--size", "32x32", "--ps-leds", "3"]);
    synth(&["--size", "32x32"]);
    let names = entries(&out);
    for gone in ["led01.png", "led03.png", "normals_gt.npy", "albedo_gt.npy"] {
        assert!(!names.contains(&gone.to_owned()), "{gone} left: {names:?}");
    }
    assert!(names.contains(&"notes.txt".to_owned()), "{names:?}");
    assert!(names.contains(&"image16.png".to_owned()), "{names:?}");
}

/// Issue 51: `synth --shading depth-map` renders the true depth through the
/// core's model (the same image `scene::shading` computes), with the light
/// beside the lens, a material and noise; the depth and the scale are the
/// mesh shading's, the image is not; a set refuses it by name.
#[test]
fn h13_synth_shades_from_the_depth_map_through_the_cores_model() {
    let options = "sombrero --size 48x40 --light 0.3,0,0 --reflectance blinn-phong --specular 0.3 \
                   --shininess 30 --noise 5";
    let (_mesh_dir, mesh) = synth_in_temp("mesh", options);
    let (_dir, depth_map) = synth_in_temp("depth_map", &format!("{options} --shading depth-map"));
    let read = |dir: &Path, name: &str| {
        sfs_core::io::read_image(&dir.join(name), false).expect("a written image")
    };
    assert_eq!(
        std::fs::read(mesh.join("depth_gt.npy")).expect("depth_gt.npy"),
        std::fs::read(depth_map.join("depth_gt.npy")).expect("depth_gt.npy"),
    );
    // The same camera, light and material; the gloss's highlight would pass
    // 1 at the mesh's scale, so the depth-map image and its scale come down
    // together.
    let without_scale = |dir: &Path| {
        let mut camera = read_json(&dir.join("scene.json"));
        camera.as_object_mut().map(|o| o.remove("intensity_scale"));
        camera
    };
    assert_eq!(without_scale(&mesh), without_scale(&depth_map));
    assert!(depth_map.join("noisy8.png").is_file());
    // The core's depth-map shading of the same scene, to 16-bit rounding.
    let light = sfs_core::light::PointLight {
        position: [0.3, 0.0, 0.0],
        ..sfs_core::light::PointLight::CENTRED
    };
    let material = sfs_core::material::Material::BlinnPhong {
        specular: 0.3,
        shininess: 30.0,
    };
    let core = sfs_core::scene::shading::shade_from_depth(
        &sfs_core::scene::sombrero::sombrero_shaded(48, 40, &[light], material),
    );
    let written = read(&depth_map, "image16.png");
    let largest = written
        .as_slice()
        .iter()
        .zip(core.image.as_slice())
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(largest <= 1.0 / 65535.0, "{largest}");
    let mesh_image = read(&mesh, "image16.png");
    let differs = mesh_image
        .as_slice()
        .iter()
        .zip(written.as_slice())
        .filter(|(a, b)| (*a - *b).abs() > 1e-3)
        .count();
    assert!(differs > 100, "the shadings differ: {differs} pixels");

    let dir = tempdir().unwrap();
    let out = s(&dir.path().join("set"));
    for (line, says) in [
        (
            vec![
                "synth",
                "sombrero",
                "--ps-leds",
                "3",
                "--shading",
                "depth-map",
            ],
            &["--shading depth-map", "--ps-leds"][..],
        ),
        (
            vec!["synth", "sombrero", "--shading", "normals"],
            &["--shading", "normals", "mesh or depth-map"][..],
        ),
    ] {
        let mut args: Vec<String> = line.iter().map(|w| w.to_string()).collect();
        args.extend(["--out".into(), out.clone()]);
        crate::common::assert_refused(&args, says);
    }
}
