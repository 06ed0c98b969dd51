//! Bare photos: a project folder whose camera is nominal (written from EXIF: the marked focal length, the
//! principal point at the centre, no distortion) is self-calibrated by `lineflow process` before it is processed.
use std::path::{Path, PathBuf};

use lineflow_e2e::{repo_file, Sandbox};
use lineflow_formats::project::{read_camera, CameraFile};

/// The nominal camera of a synthetic scene's true one, as `lineflow camera import PHOTO` would write it.
fn write_nominal(camera_toml: &Path) {
    let truth = read_camera(camera_toml).unwrap();
    let text = format!(
        "# Nominal camera (test): the marked focal length, the principal point at the centre, no distortion\n\
         width = {}\nheight = {}\npixel_size_mm = {}\nfocal_mm = {}\nprincipal_point_mm = [0.0, 0.0]\n\
         radial = [0.0, 0.0, 0.0]\ndecentering = [0.0, 0.0]\n",
        truth.width,
        truth.height,
        truth.pixel_size_mm,
        truth.focal_mm.round()
    );
    std::fs::write(camera_toml, text).unwrap();
}

/// A synthetic scene of the tuning building @3 at `scale` whose camera is replaced by its nominal one: the folder,
/// the true camera and the nominal file's text.
fn nominal_scene(sb: &Sandbox, scale: &str) -> (PathBuf, CameraFile, String) {
    let scene = sb.path().join("scene");
    let args = [
        "synth",
        "--preset",
        "a55-two-strips@3",
        "--scale",
        scale,
        "--out",
        scene.to_str().unwrap(),
    ];
    assert!(sb.run(&args).status.success(), "synth failed");
    let camera_toml = scene.join("camera.toml");
    let truth = read_camera(&camera_toml).unwrap();
    write_nominal(&camera_toml);
    let text = std::fs::read_to_string(&camera_toml).unwrap();
    (scene, truth, text)
}

fn figure(json: &serde_json::Value, path: &[&str]) -> f64 {
    path.iter()
        .fold(json, |v, k| &v[*k])
        .as_f64()
        .unwrap_or_else(|| panic!("no {path:?} in {json}"))
}

#[test]
fn a_nominal_camera_is_self_calibrated_before_the_folder_is_processed() {
    let sb = Sandbox::new();
    let (scene, truth, nominal_text) = nominal_scene(&sb, "0.3");
    let camera_toml = scene.join("camera.toml");

    // The orientation part of the folder graph stands in for the whole: the calibration is what is tested.
    let graph = repo_file("launch/calibrate.toml");
    let r = sb.run(&["process", scene.to_str().unwrap(), "--graph", graph.to_str().unwrap(), "-q"]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{stderr}");
    assert!(stderr.contains("self-calibration: the camera is nominal"), "{stderr}");

    // The adjusted camera replaced the nominal one, which is kept beside it; the run's copy has the σ.
    let adjusted_text = std::fs::read_to_string(&camera_toml).unwrap();
    assert!(
        adjusted_text.starts_with("# Self-calibrated by `lineflow process`"),
        "{adjusted_text}"
    );
    assert!(adjusted_text.contains("k1 = ") && adjusted_text.contains(" ± "), "{adjusted_text}");
    assert_eq!(std::fs::read_to_string(scene.join("camera_nominal.toml")).unwrap(), nominal_text);
    assert!(scene.join("out/calibration/camera_calibrated.toml").is_file());
    let adjusted = read_camera(&camera_toml).unwrap();
    // The distortion the nominal camera lacked (0.5 mm, 30 px in the corners) is found to within a fifth.
    let k1 = adjusted.radial[0];
    assert!(
        (k1 - truth.radial[0]).abs() < 0.2 * truth.radial[0],
        "k1 {k1} against {}",
        truth.radial[0]
    );
    assert!(
        (adjusted.focal_mm - truth.focal_mm).abs() < 0.03 * truth.focal_mm,
        "f {}",
        adjusted.focal_mm
    );

    // The block oriented with it: every frame, the check points within a few GSD (22 mm here).
    let r = sb.run(&[
        "eval",
        scene.join("out").to_str().unwrap(),
        "--gt",
        scene.to_str().unwrap(),
        "--json",
    ]);
    assert!(r.status.success());
    let json: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(json["orientation"]["missing"].as_array().map(Vec::len), Some(0), "{json}");
    assert!(figure(&json, &["orientation", "rms_center_m"]) < 1.0, "{json}");
    let rmse = &json["orientation"]["checkpoints"]["rmse_m"];
    let worst = (0..3).map(|k| rmse[k].as_f64().unwrap()).fold(0.0, f64::max);
    assert!(worst < 0.1, "check points RMSE {rmse}");

    // A second run takes the adjusted camera as it is.
    let r = sb.run(&[
        "process",
        scene.to_str().unwrap(),
        "--graph",
        graph.to_str().unwrap(),
        "-q",
        "--out",
        sb.path().join("again").to_str().unwrap(),
    ]);
    assert!(r.status.success());
    assert!(!String::from_utf8_lossy(&r.stderr).contains("the camera is nominal"));
}

#[test]
fn a_nominal_camera_is_kept_when_asked_and_a_failed_calibration_is_named() {
    let sb = Sandbox::new();
    let (scene, _, nominal_text) = nominal_scene(&sb, "0.13");
    let camera_toml = scene.join("camera.toml");
    let graph = repo_file("launch/calibrate.toml");
    // At 640 px the A55's two strips give too few tie points to orient five frames: no calibration, named.
    let r = sb.run(&["process", scene.to_str().unwrap(), "--graph", graph.to_str().unwrap(), "-q"]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && stderr.contains("self-calibration failed"), "{stderr}");
    assert_eq!(
        std::fs::read_to_string(&camera_toml).unwrap(),
        nominal_text,
        "the nominal camera is left as it was"
    );
    // Asked to keep it, the run goes on with it.
    let r = sb.run(&[
        "process",
        scene.to_str().unwrap(),
        "--graph",
        graph.to_str().unwrap(),
        "-q",
        "--set",
        "orientation.self_calibrate=[]",
    ]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(stderr.contains("is used as it is"), "{stderr}");
    assert_eq!(std::fs::read_to_string(&camera_toml).unwrap(), nominal_text);
}
