//! `lineflow poses import`: the poses of a COLMAP model or a Metashape cameras export as `poses.csv`, brought into
//! the survey's frame by the project's control points where it has them (a COLMAP model's frame is arbitrary in
//! position, rotation and scale; a Metashape chunk's may be geocentric).
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use lineflow_formats::colmap::read_images;
use lineflow_formats::natural::natural_cmp;
use lineflow_formats::project::{file_name, Project};
use lineflow_formats::{write_poses, PoseRow};
use lineflow_photogrammetry::intersect::{intersect_rays, similarity, Similarity};
use lineflow_photogrammetry::{Camera, Pose, Vec3};

/// `lineflow poses …`.
#[derive(Debug, clap::Subcommand)]
pub enum PosesCmd {
    /// Write poses.csv from a COLMAP model (a sparse model folder, or its images.txt or images.bin) or a Metashape
    /// cameras export (.xml); with --project, in the survey's frame of the project's control points
    Import {
        /// The COLMAP model folder (holding images.bin or images.txt), its images file, or a Metashape cameras .xml.
        model: PathBuf,
        /// A project folder whose camera.toml, control_points.csv and observations.csv place the poses in the
        /// survey's frame (a similarity fitted to the control points, the check points reported).
        #[arg(long)]
        project: Option<PathBuf>,
        /// The poses.csv to write (an existing file only with --force).
        #[arg(long, default_value = "poses.csv")]
        out: PathBuf,
        /// Overwrite `--out`.
        #[arg(long)]
        force: bool,
    },
}

/// Runs a `lineflow poses` command.
///
/// # Errors
/// A model or project that cannot be read, too few control points seen in two images, or an existing `--out`
/// without `--force`.
pub fn poses(cmd: PosesCmd) -> Result<ExitCode> {
    let PosesCmd::Import {
        model,
        project,
        out,
        force,
    } = cmd;
    if out.exists() && !force {
        bail!("{} exists: pass --force to overwrite it", out.display());
    }
    let mut images = read_model(&model)?;
    images.sort_by(|a, b| natural_cmp(&a.0, &b.0));
    if let Some(root) = &project {
        let project = Project::open(root, true)?;
        // Metashape's labels drop the extension: the project's images give it back.
        for (name, _) in &mut images {
            if let Some(file) = project.images.iter().map(|p| file_name(p)).find(|f| same_image(f, name)) {
                *name = file;
            }
        }
        let fit = georeference(&images, &project)?;
        let mm = |rms: Option<f64>| rms.map_or("-".into(), |r| format!("{:.1} mm", r * 1e3));
        eprintln!(
            "into the survey's frame by {} control points: scale {:.6}; at the control points {} RMS",
            fit.count(true),
            fit.transform.scale,
            mm(fit.rms_m(true))
        );
        for r in &fit.residuals {
            let role = if r.control { "control" } else { "check" };
            eprintln!("  {role} {}: {:.1} mm", r.id, r.distance_m * 1e3);
        }
        if fit.count(false) > 0 {
            eprintln!("at the {} check points: {} RMS", fit.count(false), mm(fit.rms_m(false)));
        }
        for (_, pose) in &mut images {
            *pose = transformed(pose, &fit.transform);
        }
    } else {
        eprintln!("note: no --project: the poses stay in the model's own frame");
    }
    let rows: Vec<PoseRow> = images
        .iter()
        .map(|(name, pose)| PoseRow {
            image: name.clone(),
            pose: *pose,
            sigma_center_m: None,
            sigma_angles_deg: None,
        })
        .collect();
    write_poses(&out, &rows)?;
    eprintln!("{} poses -> {}", rows.len(), out.display());
    Ok(ExitCode::SUCCESS)
}

/// The (image file name, pose) of every registered camera of a model: a Metashape cameras `.xml`, a COLMAP images
/// file, or a COLMAP model folder (its images.bin, else images.txt).
fn read_model(model: &Path) -> Result<Vec<(String, Pose)>> {
    if model.extension().is_some_and(|e| e.eq_ignore_ascii_case("xml")) {
        let read = lineflow_formats::metashape::read_cameras(model)?;
        eprintln!("{}: {} aligned cameras (Metashape)", model.display(), read.cameras.len());
        for note in &read.notes {
            eprintln!("note: {note}");
        }
        return Ok(read.cameras);
    }
    let file = if model.is_dir() {
        ["images.bin", "images.txt"]
            .iter()
            .map(|f| model.join(f))
            .find(|p| p.is_file())
            .with_context(|| {
                format!(
                    "{}: no images.bin or images.txt in the folder (a COLMAP sparse model)",
                    model.display()
                )
            })?
    } else {
        model.to_owned()
    };
    let images = read_images(&file)?;
    let cameras: std::collections::BTreeSet<u32> = images.iter().map(|i| i.camera_id).collect();
    eprintln!(
        "{}: {} registered images, {} cameras (COLMAP)",
        file.display(),
        images.len(),
        cameras.len()
    );
    Ok(images.into_iter().map(|i| (file_name(Path::new(&i.name)), i.pose)).collect())
}

/// Whether a project's image file and a model's image name are one image: the same file name, or the same name
/// without its extension (Metashape's labels).
fn same_image(file: &str, name: &str) -> bool {
    file == name || Path::new(file).file_stem().is_some_and(|s| s == name)
}

/// The similarity into the survey's frame and how well the points fit it.
pub struct Georeference {
    /// Model frame to survey frame.
    pub transform: Similarity,
    /// Every control and check point seen in two images, after the transformation.
    pub residuals: Vec<PointResidual>,
}

/// One surveyed point against its intersection, moved into the survey's frame.
pub struct PointResidual {
    /// Point id.
    pub id: String,
    /// A control point (fitted to), or a check point (held out).
    pub control: bool,
    /// Distance from its surveyed coordinates, metres.
    pub distance_m: f64,
}

impl Georeference {
    /// How many control (or check) points there are.
    pub fn count(&self, control: bool) -> usize {
        self.residuals.iter().filter(|r| r.control == control).count()
    }

    /// RMS distance at the control (or check) points, metres; `None` without any.
    pub fn rms_m(&self, control: bool) -> Option<f64> {
        let d: Vec<f64> = self
            .residuals
            .iter()
            .filter(|r| r.control == control)
            .map(|r| r.distance_m)
            .collect();
        (!d.is_empty()).then(|| (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt())
    }
}

/// Intersects every control and check point observed in two or more of `images` with the project's camera, and
/// fits the similarity taking the control points onto their surveyed coordinates.
///
/// # Errors
/// Fewer than three control points seen in two images, or all on a line.
pub fn georeference(images: &[(String, Pose)], project: &Project) -> Result<Georeference> {
    let camera = project.camera.camera();
    let pose_of = |frame: u64| -> Option<Pose> {
        let file = file_name(project.images.get(frame as usize)?);
        images.iter().find(|(name, _)| same_image(&file, name)).map(|(_, pose)| *pose)
    };
    let mut points = Vec::new();
    for cp in &project.control_points {
        let rays: Vec<(Vec3, Vec3)> = project
            .observations
            .iter()
            .filter(|o| o.point_id() == cp.id())
            .filter_map(|o| pose_of(o.frame).map(|p| ray(&camera, &p, [o.col, o.row])))
            .collect();
        if let Some((x, _)) = intersect_rays(&rays).filter(|_| rays.len() >= 2) {
            points.push((cp, x));
        }
    }
    let control: Vec<_> = points
        .iter()
        .filter(|(cp, _)| cp.role == lineflow_messages::ControlPoint::CONTROL)
        .collect();
    let from: Vec<Vec3> = control.iter().map(|(_, x)| *x).collect();
    let to: Vec<Vec3> = control.iter().map(|(cp, _)| Vec3::from(cp.xyz)).collect();
    let Some(transform) = similarity(&from, &to) else {
        bail!(
            "{} control points are seen in two or more of the model's images: at least three, not on one line, are needed \
             to place the poses in the survey's frame (control_points.csv, observations.csv)",
            control.len()
        );
    };
    let residuals = points
        .iter()
        .map(|(cp, x)| PointResidual {
            id: cp.id().to_owned(),
            control: cp.role == lineflow_messages::ControlPoint::CONTROL,
            distance_m: (transform.apply(x) - Vec3::from(cp.xyz)).norm(),
        })
        .collect();
    Ok(Georeference { transform, residuals })
}

fn ray(camera: &Camera, pose: &Pose, px: [f64; 2]) -> (Vec3, Vec3) {
    (pose.center, pose.ray_of_pixel(camera, px))
}

/// A pose in the frame `y = s·R·x + t`: the centre moves with the points, and the camera turns by R (scale does not
/// change a direction).
pub fn transformed(pose: &Pose, t: &Similarity) -> Pose {
    Pose {
        center: t.apply(&pose.center),
        rotation: pose.rotation * t.rotation.transpose(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_photogrammetry::{look_at, rotation_from_opk};

    #[test]
    fn a_transformed_pose_projects_the_transformed_point_to_the_same_pixel() {
        let camera = Camera::pinhole(1000, 800, 0.01, 20.0);
        let c = Vec3::new(1.0, -10.0, 2.0);
        let pose = Pose {
            center: c,
            rotation: look_at(&c, &Vec3::new(1.5, 0.0, 2.5), &Vec3::z()),
        };
        let t = Similarity {
            scale: 2.5,
            rotation: rotation_from_opk(0.3, -0.2, 1.1),
            translation: Vec3::new(1000.0, 2000.0, 50.0),
        };
        let x = Vec3::new(1.3, 0.0, 2.9);
        let before = pose.project(&camera, &x).unwrap();
        let after = transformed(&pose, &t).project(&camera, &t.apply(&x)).unwrap();
        assert!((before[0] - after[0]).hypot(before[1] - after[1]) < 1e-9);
    }

    fn fixed(s: &str) -> [u8; 16] {
        let mut b = [0u8; 16];
        b[..s.len()].copy_from_slice(s.as_bytes());
        b
    }

    #[test]
    fn poses_in_a_models_own_frame_come_back_in_the_surveys() {
        let camera = Camera::pinhole(2000, 1500, 0.005, 8.0);
        let truth: Vec<Pose> = [-4.0, -1.0, 2.0, 5.0]
            .iter()
            .map(|&x| {
                let c = Vec3::new(x + 1000.0, 1988.0, 51.6);
                Pose {
                    center: c,
                    rotation: look_at(&c, &Vec3::new(x * 0.6 + 1000.0, 2000.0, 53.0), &Vec3::z()),
                }
            })
            .collect();
        let points = [
            (1000.0, 2000.0, 50.5),
            (1006.0, 2000.0, 51.0),
            (995.0, 2000.3, 55.0),
            (1003.0, 1999.8, 57.0),
            (999.0, 2000.0, 53.0),
        ];
        let control_points: Vec<lineflow_messages::ControlPoint> = points
            .iter()
            .enumerate()
            .map(|(k, &(x, y, z))| lineflow_messages::ControlPoint {
                id: fixed(&format!("P{k}")),
                xyz: [x, y, z],
                sigma_m: [f64::NAN; 3],
                role: if k == 4 {
                    lineflow_messages::ControlPoint::CHECK
                } else {
                    lineflow_messages::ControlPoint::CONTROL
                },
                reserved: 0,
            })
            .collect();
        let observations = control_points
            .iter()
            .flat_map(|cp| {
                truth.iter().enumerate().filter_map(move |(f, pose)| {
                    let px = pose.project(&camera, &Vec3::from(cp.xyz))?;
                    camera.contains(px, 0.0).then_some(lineflow_messages::Observation {
                        frame: f as u64,
                        point_id: cp.id,
                        col: px[0],
                        row: px[1],
                    })
                })
            })
            .collect();
        let project = Project {
            root: PathBuf::from("p"),
            camera: lineflow_formats::project::CameraFile::of(&camera),
            images: (0..truth.len()).map(|f| PathBuf::from(format!("p/images/IMG_{f}.jpg"))).collect(),
            control_points,
            observations,
            walls: Vec::new(),
        };
        // The model's frame: the survey's moved, turned and shrunk, as a COLMAP reconstruction would have it.
        let to_model = Similarity {
            scale: 0.37,
            rotation: rotation_from_opk(0.4, 1.2, -0.7),
            translation: Vec3::new(3.0, -1.0, 0.5),
        };
        // Metashape's labels: no extension.
        let images: Vec<(String, Pose)> = truth
            .iter()
            .enumerate()
            .map(|(f, p)| (format!("IMG_{f}"), transformed(p, &to_model)))
            .collect();
        let fit = georeference(&images, &project).unwrap();
        assert_eq!(fit.count(true), 4);
        assert!(fit.rms_m(true).unwrap() < 1e-6, "{:?}", fit.rms_m(true));
        assert!(fit.residuals.iter().any(|r| !r.control && r.distance_m < 1e-6));
        for ((_, pose), want) in images.iter().zip(&truth) {
            let got = transformed(pose, &fit.transform);
            assert!((got.center - want.center).norm() < 1e-6 && (got.rotation - want.rotation).norm() < 1e-9);
        }
        let few = Project {
            control_points: project.control_points[..2].to_vec(),
            ..project
        };
        let e = georeference(&images, &few).err().unwrap().to_string();
        assert!(e.contains("at least three"), "{e}");
    }
}
