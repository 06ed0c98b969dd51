//! `lineflow targets FOLDER`: the circular survey targets in a project's images, named by the surveyed points of
//! its `control_points.csv` (`lineflow_targets`), written into its `observations.csv` beside the rows measured by
//! hand, which stay as they are and take precedence.
use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use crate::calibrate;
use anyhow::{bail, Context, Result};
use lineflow_formats::project::{file_name, read_camera, Project};
use lineflow_messages::str_from_fixed;
use lineflow_photogrammetry::Vec3;
use lineflow_runtime::run::Verbosity;
use lineflow_targets::{detect, name, DetectSettings, Detection, Face, NameSettings, TargetView};

/// Options of `lineflow targets`.
#[derive(Debug, clap::Args)]
pub struct TargetsArgs {
    /// Project folder.
    pub folder: PathBuf,
    /// The images' poses (poses.csv, any frame) [default: FOLDER/out/poses.csv, from `lineflow process`].
    #[arg(long)]
    pub poses: Option<PathBuf>,
    /// The camera the poses were computed with [default: FOLDER/camera.toml].
    #[arg(long)]
    pub camera: Option<PathBuf>,
    /// Where to write the observations [default: FOLDER/observations.csv].
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// Finds, names and writes the targets of `a.folder`'s images.
///
/// # Errors
/// A project, poses or camera file that cannot be read, an image that cannot be decoded, targets that cannot be
/// named ([`lineflow_targets::NamingError`]), or an observations file that cannot be written.
pub fn targets(a: TargetsArgs) -> Result<ExitCode> {
    let project = Project::open(&a.folder, false).map_err(|e| anyhow::anyhow!("{e}"))?;
    if project.control_points.len() < 4 {
        bail!(
            "{}: {} surveyed points; the targets are named by their layout, which needs at least 4",
            a.folder.join("control_points.csv").display(),
            project.control_points.len()
        );
    }
    let camera = match &a.camera {
        Some(path) => read_camera(path).map_err(|e| anyhow::anyhow!("{e}"))?.camera(),
        None => project.camera.camera(),
    };
    let poses_path = a.poses.clone().unwrap_or_else(|| a.folder.join("out").join("poses.csv"));
    if !poses_path.is_file() {
        bail!(
            "{}: no poses to intersect the targets with; run `lineflow process {}` first (without observations its \
             poses are in an arbitrary frame, which is enough), or pass --poses",
            poses_path.display(),
            a.folder.display()
        );
    }
    let poses: BTreeMap<String, lineflow_photogrammetry::Pose> = lineflow_formats::read_poses(&poses_path)
        .map_err(|e| anyhow::anyhow!("{e}"))?
        .into_iter()
        .map(|r| (r.image, r.pose))
        .collect();

    let sensor = (camera.width, camera.height);
    let mut views = Vec::new();
    let mut without_pose = Vec::new();
    for (frame, path) in project.images.iter().enumerate() {
        let image = file_name(path);
        let detections = detect_in(path, sensor)?;
        eprintln!("{image}: {} targets", detections.len());
        match poses.get(&image) {
            Some(pose) => views.push(TargetView {
                frame,
                pose: *pose,
                detections,
            }),
            None => without_pose.push(image),
        }
    }
    if !without_pose.is_empty() {
        eprintln!(
            "warning: {} images have no pose in {} and are left out: {}",
            without_pose.len(),
            poses_path.display(),
            without_pose.join(", ")
        );
    }
    let points: Vec<(String, Vec3)> = project
        .control_points
        .iter()
        .map(|p| (str_from_fixed(&p.id).to_string(), Vec3::from(p.xyz)))
        .collect();
    let faces: Vec<Face> = project.walls.iter().filter_map(|w| Face::of_wall(w.corners())).collect();
    let naming = name(&views, &camera, &points, &faces, &NameSettings::default()).map_err(|e| anyhow::anyhow!("{e}"))?;

    // The hand-measured rows stay; a detection of a point an image already has a row for is left out.
    let names: Vec<String> = project.images.iter().map(|p| file_name(p)).collect();
    let measured: BTreeSet<(usize, String)> = project
        .observations
        .iter()
        .map(|o| (o.frame as usize, str_from_fixed(&o.point_id).to_string()))
        .collect();
    let out = a.out.clone().unwrap_or_else(|| a.folder.join("observations.csv"));
    let mut text = String::from("image,point_id,col,row\n");
    for o in &project.observations {
        let _ = writeln!(
            text,
            "{},{},{},{}",
            names[o.frame as usize],
            str_from_fixed(&o.point_id),
            o.col,
            o.row
        );
    }
    let added: Vec<_> = naming
        .observations
        .iter()
        .filter(|o| !measured.contains(&(o.frame, o.id.clone())))
        .collect();
    for o in &added {
        let _ = writeln!(text, "{},{},{:.3},{:.3}", names[o.frame], o.id, o.centre[0], o.centre[1]);
    }
    // Written whole, then moved over the old file: an interrupted write leaves the old one.
    let partial = out.with_extension("csv.partial");
    std::fs::write(&partial, text).with_context(|| format!("writing {}", partial.display()))?;
    std::fs::rename(&partial, &out).with_context(|| format!("replacing {}", out.display()))?;
    println!(
        "{} targets intersected, {} of them on surveyed points ({:.1} mm RMS after a similarity of scale {:.4}); \
         {} observations written to {} (the {} rows it held kept, {} detections of points they already held left out)",
        naming.intersected,
        naming.matched,
        1e3 * naming.rms_m,
        naming.similarity.scale,
        added.len(),
        out.display(),
        project.observations.len(),
        naming.observations.len() - added.len(),
    );
    if !naming.unseen.is_empty() {
        println!("not found in any image: {}", naming.unseen.join(", "));
    }
    Ok(ExitCode::SUCCESS)
}

/// The targets in one image file, in grey.
fn detect_in(path: &Path, sensor: (u32, u32)) -> Result<Vec<Detection>> {
    let img = lineflow_capture::decode_file_for(path, sensor).map_err(|e| anyhow::anyhow!("{e}"))?;
    let (w, h) = (img.width as usize, img.height as usize);
    let mut gray = vec![0u8; w * h];
    let step = img.bytes.len() / h.max(1);
    lineflow_imaging::gray_into(img.encoding, w, h, step, &img.bytes, &mut gray).with_context(|| format!("{}", path.display()))?;
    Ok(detect(&gray, w, h, &DetectSettings::default()))
}

/// Whether `lineflow process` should find the targets of `folder` first: it has surveyed points and no
/// observations of them.
pub fn wanted(folder: &Path) -> bool {
    folder.join("control_points.csv").is_file() && !folder.join("observations.csv").exists()
}

/// The first pass over a folder with surveyed points and no observations: its images are oriented on their own
/// (`launch/calibrate.toml` with the camera held, into `OUT/targets/`; or the self-calibration pass's `poses`,
/// when it has just run), and the targets found in them are named by the surveyed points and written to the
/// folder's `observations.csv`, which the main graph then adjusts on.
///
/// # Errors
/// The orientation pass fails, or the targets cannot be named ([`targets`]).
pub fn observe(folder: &Path, out: &Path, poses: Option<PathBuf>, set: &[String], verbosity: Verbosity) -> Result<()> {
    eprintln!(
        "{}: missing; looking for the survey targets of control_points.csv in the images",
        folder.join("observations.csv").display()
    );
    let poses = match poses {
        Some(p) => p,
        None => {
            let pass = out.join("targets");
            let mut set = calibrate::settings_of(set, &["capture.", "features.", "matcher."]);
            set.push("orientation.self_calibrate=[]".into());
            let status = calibrate::run_orientation_pass(&set, &pass, verbosity)?;
            if status != ExitCode::SUCCESS {
                bail!(
                    "orienting the images to find their targets failed (logs in {}); measure the control points in \
                     observations.csv by hand",
                    pass.join("logs").display()
                );
            }
            pass.join("poses.csv")
        }
    };
    targets(TargetsArgs {
        folder: folder.to_owned(),
        poses: Some(poses),
        camera: None,
        out: None,
    })
    .map(drop)
}
