//! Writes a synthetic scene as a project folder plus `gt/`, exactly as `conventions.md` defines them.
use std::fmt::Write as _;
use std::path::Path;

use lineflow_formats::{write_lines3d, write_poses, Line3Row, PoseRow};
use lineflow_photogrammetry::Vec3;

use super::{SynthError, Synthetic};

fn io(path: &Path) -> impl Fn(std::io::Error) -> SynthError + '_ {
    move |e| SynthError::Io(format!("{}: {e}", path.display()))
}

fn write(path: &Path, text: &str) -> Result<(), SynthError> {
    std::fs::write(path, text).map_err(io(path))
}

/// Encodes packed RGB8 as JPEG at `quality`.
pub fn jpeg_bytes(rgb: &[u8], width: u32, height: u32, quality: u8) -> Result<Vec<u8>, SynthError> {
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, quality)
        .encode(rgb, width, height, image::ExtendedColorType::Rgb8)
        .map_err(|e| SynthError::Io(format!("JPEG encoding: {e}")))?;
    Ok(out)
}

/// Makes a project folder written by [`write_project`] with JPEG images look like a camera's photos: each image
/// gains an EXIF block (the lens's marked focal length, whole millimetres as most lenses report it, the sensor's
/// pitch as its focal-plane resolution, the image size), and `camera.toml` and `observations.csv` move into `gt/`,
/// so that the folder holds only what a photographer brings: photos, the surveyed points and the site model.
///
/// # Errors
/// The images are not JPEG, or a file cannot be read, written or moved.
pub fn make_bare(syn: &Synthetic, dir: &Path) -> Result<(), SynthError> {
    let cam = syn.camera();
    let tags = lineflow_formats::exif_camera::ExifTags {
        make: "lineflow".into(),
        model: "synthetic camera".into(),
        focal_mm: cam.focal_mm.round(),
        pixel_size_mm: cam.pixel_size_mm,
        width: cam.width,
        height: cam.height,
    };
    for frame in 0..syn.poses().len() {
        let path = dir.join("images").join(syn.image_name(frame));
        let jpeg = std::fs::read(&path).map_err(io(&path))?;
        let tagged = lineflow_formats::exif_camera::with_exif(&jpeg, &tags)
            .ok_or_else(|| SynthError::Io(format!("{}: not a JPEG, so no EXIF", path.display())))?;
        std::fs::write(&path, tagged).map_err(io(&path))?;
    }
    for name in ["camera.toml", "observations.csv"] {
        let (from, to) = (dir.join(name), dir.join("gt").join(name));
        std::fs::rename(&from, &to).map_err(io(&from))?;
    }
    Ok(())
}

/// The true poses as `poses.csv` rows (standard deviations empty).
pub fn truth_poses(syn: &Synthetic) -> Vec<PoseRow> {
    syn.poses()
        .iter()
        .enumerate()
        .map(|(i, p)| PoseRow {
            image: syn.image_name(i),
            pose: *p,
            sigma_center_m: None,
            sigma_angles_deg: None,
        })
        .collect()
}

/// The structural edges seen in at least two images as `lines3d.csv` rows (statistics empty), ids `G1`...
pub fn truth_lines(syn: &Synthetic) -> Vec<Line3Row> {
    syn.seen_edges()
        .iter()
        .enumerate()
        .map(|(i, e)| Line3Row {
            id: format!("G{}", i + 1),
            start: Vec3::from(e.edge.a),
            end: Vec3::from(e.edge.b),
            n_points: None,
            n_images: None,
            rms_m: None,
            class: lineflow_formats::LineClass::Structure,
        })
        .collect()
}

/// Writes `images/`, `camera.toml`, `control_points.csv`, `observations.csv`, `site.toml` and `gt/` into `dir`.
/// `progress(done, total)` is called after each image.
pub fn write_project(syn: &Synthetic, dir: &Path, progress: &mut dyn FnMut(usize, usize)) -> Result<(), SynthError> {
    let images = dir.join("images");
    std::fs::create_dir_all(&images).map_err(io(&images))?;
    let cam = syn.camera();
    let n = syn.poses().len();
    for frame in 0..n {
        let rgb = syn.render(frame);
        let path = images.join(syn.image_name(frame));
        let q = syn.preset.sensor.jpeg_quality;
        if q > 0 {
            std::fs::write(&path, jpeg_bytes(&rgb, cam.width, cam.height, q)?).map_err(io(&path))?;
        } else {
            image::save_buffer(&path, &rgb, cam.width, cam.height, image::ExtendedColorType::Rgb8)
                .map_err(|e| SynthError::Io(format!("{}: {e}", path.display())))?;
        }
        progress(frame + 1, n);
    }
    write_project_files(syn, dir)
}

/// The files [`write_project_files`] writes, relative to the project folder.
pub const PROJECT_FILES: [&str; 7] = [
    "camera.toml",
    "control_points.csv",
    "observations.csv",
    "site.toml",
    "gt/poses.csv",
    "gt/lines3d.csv",
    "gt/scene.json",
];

/// The project folder's files without its images, and `gt/`: what scores a run of the synthetic camera node (which
/// renders its own images) with `lineflow eval`, in seconds rather than a render of every frame.
pub fn write_project_files(syn: &Synthetic, dir: &Path) -> Result<(), SynthError> {
    let gt = dir.join("gt");
    std::fs::create_dir_all(&gt).map_err(io(&gt))?;
    let cam = syn.camera();
    let camera_toml =
        toml::to_string(&lineflow_formats::project::CameraFile::of(cam)).map_err(|e| SynthError::Io(format!("camera.toml: {e}")))?;
    write(
        &dir.join("camera.toml"),
        &format!(
            "# {} at scale {}: {}\n{camera_toml}",
            syn.preset.name, syn.scale, syn.preset.description
        ),
    )?;

    let s = syn.preset.survey_sigma_m;
    let mut cp = String::from("id,X,Y,Z,sx,sy,sz,role\n");
    for t in &syn.building.targets {
        let role = if t.control { "control" } else { "check" };
        let _ = writeln!(cp, "{},{:.4},{:.4},{:.4},{s},{s},{s},{role}", t.id, t.xyz[0], t.xyz[1], t.xyz[2]);
    }
    write(&dir.join("control_points.csv"), &cp)?;

    let mut obs = String::from("image,point_id,col,row\n");
    for o in syn.target_observations() {
        let _ = writeln!(obs, "{},{},{:.3},{:.3}", syn.image_name(o.frame), o.id, o.px[0], o.px[1]);
    }
    write(&dir.join("observations.csv"), &obs)?;

    let mut site = String::from("# Approximate walls (a few centimetres off, like a real LOD-1/2 model).\n");
    for (name, corners) in syn.approximate_walls() {
        let list: Vec<String> = corners.iter().map(|c| format!("[{:.3}, {:.3}, {:.3}]", c[0], c[1], c[2])).collect();
        let _ = write!(site, "\n[[wall]]\nname = \"{name}\"\ncorners = [{}]\n", list.join(", "));
    }
    write(&dir.join("site.toml"), &site)?;

    let poses = truth_poses(syn);
    write_poses(&gt.join("poses.csv"), &poses).map_err(|e| SynthError::Io(e.to_string()))?;
    let lines = truth_lines(syn);
    write_lines3d(&gt.join("lines3d.csv"), &lines).map_err(|e| SynthError::Io(e.to_string()))?;
    write(&gt.join("scene.json"), &scene_json(syn))
}

/// The generator's full description: preset, seed, camera, sensor, building (faces, edges, targets), poses.
pub fn scene_json(syn: &Synthetic) -> String {
    let c = syn.camera();
    let poses: Vec<serde_json::Value> = syn
        .poses()
        .iter()
        .map(|p| serde_json::json!({"center": [p.center.x, p.center.y, p.center.z], "rotation": p.rotation.transpose().as_slice()}))
        .collect();
    let v = serde_json::json!({
        "generator": "lineflow synth",
        "preset": syn.preset.name,
        "description": syn.preset.description,
        "seed": syn.seed,
        "scale": syn.scale,
        "camera": {
            "width": c.width, "height": c.height, "pixel_size_mm": c.pixel_size_mm, "focal_mm": c.focal_mm,
            "principal_point_mm": c.principal_point_mm, "radial": c.radial, "decentering": c.decentering
        },
        "sensor": syn.preset.sensor,
        "observation_sigma_px": syn.preset.obs_sigma_px,
        "survey_sigma_m": syn.preset.survey_sigma_m,
        "poses_note": "rotation is M (object to image), row-major",
        "poses": poses,
        "building": syn.building,
    });
    serde_json::to_string_pretty(&v).unwrap_or_default()
}
