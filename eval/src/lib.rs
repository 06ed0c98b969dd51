//! `lineflow eval`: the results of a run against the ground truth of a synthetic scene, as numbers
//! ([`Evaluation`]) and as a Markdown report with plots. Metrics are defined in `docs/eval.md`.
pub mod geometry;
pub mod lines2d;
pub mod lines3d;
pub mod model;
pub mod orientation;
mod plot;
pub mod report;
pub mod resolvable;
pub mod summary;

use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};
use lineflow_formats::{read_checkpoints, read_lines2d, read_lines3d, read_poses, CheckRow, Line2Row, Line3Row, PoseRow};
use lineflow_synthetic::Synthetic;

/// The ground truth of a scene folder written by `lineflow synth`.
pub struct Truth {
    /// The folder.
    pub dir: PathBuf,
    /// True poses, by image.
    pub poses: Vec<PoseRow>,
    /// Structural edges seen in at least two images.
    pub lines: Vec<Line3Row>,
    /// The regenerated scene (deterministic from preset, scale and seed in `gt/scene.json`).
    pub scene: Synthetic,
}

/// A wire-frame read from `model.obj`: vertices and edges.
pub type Wireframe = (Vec<lineflow_photogrammetry::Vec3>, Vec<[usize; 2]>);

impl Truth {
    /// Every structural edge of the building, seen or not (the truth's `lines` hold those two images see).
    pub fn every_edge(&self) -> Vec<Line3Row> {
        self.scene
            .building
            .edges
            .iter()
            .map(|e| Line3Row {
                id: String::new(),
                start: e.a.into(),
                end: e.b.into(),
                n_points: None,
                n_images: None,
                rms_m: None,
                class: Default::default(),
            })
            .collect()
    }

    /// Loads `DIR/gt/` and regenerates the scene it describes.
    pub fn load(dir: &Path) -> Result<Truth> {
        let gt = dir.join("gt");
        let scene_path = gt.join("scene.json");
        let text = std::fs::read_to_string(&scene_path)
            .with_context(|| format!("{}: cannot read (is this a `lineflow synth` folder?)", scene_path.display()))?;
        let v: serde_json::Value = serde_json::from_str(&text).with_context(|| format!("{}: malformed", scene_path.display()))?;
        let (Some(preset), Some(scale), Some(seed)) = (v["preset"].as_str(), v["scale"].as_f64(), v["seed"].as_u64()) else {
            bail!("{}: needs preset, scale and seed", scene_path.display());
        };
        let scene = Synthetic::new(preset, scale, seed).with_context(|| format!("{}", scene_path.display()))?;
        Ok(Truth {
            dir: dir.to_owned(),
            poses: read_poses(&gt.join("poses.csv"))?,
            lines: read_lines3d(&gt.join("lines3d.csv"))?,
            scene,
        })
    }

    /// The truth of a scene generated in memory (no folder): its poses and seen edges.
    pub fn from_scene(scene: Synthetic) -> Truth {
        Truth {
            dir: PathBuf::new(),
            poses: lineflow_synthetic::truth_poses(&scene),
            lines: lineflow_synthetic::truth_lines(&scene),
            scene,
        }
    }

    /// The ground sample distance at the typical object distance (median over the edges of the distance to the
    /// nearest camera), metres.
    pub fn gsd_m(&self) -> f64 {
        let mut d: Vec<f64> = self
            .lines
            .iter()
            .map(|l| {
                let mid = (l.start + l.end) * 0.5;
                self.poses
                    .iter()
                    .map(|p| (p.pose.center - mid).norm())
                    .fold(f64::INFINITY, f64::min)
            })
            .collect();
        if d.is_empty() {
            return f64::NAN;
        }
        d.sort_by(f64::total_cmp);
        self.scene.camera().gsd_m(d[d.len() / 2])
    }
}

/// What a run wrote (each file optional).
#[derive(Default)]
pub struct Results {
    pub poses: Option<Vec<PoseRow>>,
    pub checkpoints: Option<Vec<CheckRow>>,
    pub lines2d: Option<Lines2d>,
    pub lines3d: Option<Vec<Line3Row>>,
    pub model: Option<Wireframe>,
    /// The wire-frame fitted to the images (`model_fitted.obj`).
    pub model_fitted: Option<Wireframe>,
    /// The window and door faces of `model.obj`.
    pub model_openings: Option<Vec<model::ModelOpening>>,
    /// Edges of `model.obj` completed behind an occluder (not scored: the truth holds the edges seen in images).
    pub model_hidden_edges: Option<usize>,
    /// Lines of `model.obj` set aside as lying inside a surface (vertex pairs into the model's vertices).
    pub model_surface_lines: Option<Vec<[usize; 2]>>,
}

/// A run's 2-D lines: as read from `lines2d.csv`, or scored frame by frame as a live sink received them (it keeps
/// the scores, not the segments, so its memory does not grow with the stream).
pub enum Lines2d {
    Rows(Vec<Line2Row>),
    /// Scores by frame of the truth.
    Scored(std::collections::BTreeMap<usize, lines2d::ImageScores>),
}

/// The window and door faces (groups `Window` and `Door`) of an OBJ model.
pub fn openings_of_obj(obj: &lineflow_formats::ObjModel) -> Vec<model::ModelOpening> {
    obj.faces
        .iter()
        .filter(|(group, _)| group == "Window" || group == "Door")
        .map(|(group, ring)| model::ModelOpening {
            door: group == "Door",
            ring: ring.iter().map(|&v| obj.vertices[v]).collect(),
        })
        .collect()
}

fn optional<T>(path: PathBuf, read: impl Fn(&Path) -> Result<T, lineflow_formats::FormatError>) -> Result<Option<T>> {
    if path.exists() {
        Ok(Some(read(&path)?))
    } else {
        Ok(None)
    }
}

impl Results {
    /// Reads `poses.csv`, `checkpoints.csv`, `lines2d.csv`, `lines3d.csv`, `model.obj` and `model_fitted.obj`
    /// from `dir`, where present.
    pub fn load(dir: &Path) -> Result<Results> {
        if !dir.is_dir() {
            bail!("{}: not a folder", dir.display());
        }
        let obj = optional(dir.join("model.obj"), lineflow_formats::read_obj)?;
        Ok(Results {
            poses: optional(dir.join("poses.csv"), read_poses)?,
            checkpoints: optional(dir.join("checkpoints.csv"), read_checkpoints)?,
            lines2d: optional(dir.join("lines2d.csv"), read_lines2d)?.map(Lines2d::Rows),
            lines3d: optional(dir.join("lines3d.csv"), read_lines3d)?,
            model_openings: obj.as_ref().map(openings_of_obj),
            model_hidden_edges: obj.as_ref().map(|o| o.hidden_edges.len()),
            model_surface_lines: obj.as_ref().map(|o| o.surface_lines.clone()),
            model: obj.map(|o| (o.vertices, o.edges)),
            model_fitted: optional(dir.join("model_fitted.obj"), lineflow_formats::read_obj_wireframe)?,
        })
    }
}

/// Every metric that the results allow.
pub struct Evaluation {
    pub orientation: Option<orientation::OrientationReport>,
    pub lines2d: Option<lines2d::Lines2dReport>,
    pub lines3d: Option<lines3d::Lines3dReport>,
    pub model: Option<model::ModelReport>,
    pub model_fitted: Option<model::ModelReport>,
    pub openings: Option<model::OpeningReport>,
    /// Edges of the model completed behind an occluder, left out of the scores.
    pub hidden_edges: Option<usize>,
    /// The model's lines inside a surface, set aside from its edges.
    pub surface_lines: Option<model::SurfaceLinesReport>,
}

/// Evaluates whatever `results` holds.
pub fn evaluate(truth: &Truth, results: &Results) -> Evaluation {
    let every = truth.every_edge();
    Evaluation {
        orientation: results
            .poses
            .as_ref()
            .map(|p| orientation::evaluate(truth, p, results.checkpoints.as_deref())),
        lines2d: results.lines2d.as_ref().map(|l| match l {
            Lines2d::Rows(rows) => lines2d::evaluate(truth, rows),
            Lines2d::Scored(scored) => lines2d::evaluate_scored(truth, scored),
        }),
        lines3d: results.lines3d.as_ref().map(|l| lines3d::evaluate(truth, l)),
        model: results
            .model
            .as_ref()
            .map(|(v, e)| model::evaluate(&truth.lines, &every, v, e, truth.gsd_m())),
        model_fitted: results
            .model_fitted
            .as_ref()
            .map(|(v, e)| model::evaluate(&truth.lines, &every, v, e, truth.gsd_m())),
        openings: results
            .model_openings
            .as_ref()
            .map(|o| model::evaluate_openings(&truth.scene.building.openings, o, truth.gsd_m())),
        hidden_edges: results.model_hidden_edges,
        surface_lines: results
            .model
            .as_ref()
            .zip(results.model_surface_lines.as_ref())
            .map(|((v, _), lines)| model::evaluate_surface_lines(&truth.lines, v, lines, truth.gsd_m())),
    }
}

/// `lineflow eval RESULTS --gt SCENE`: evaluates a run's results, writes the report (into `out`, by default
/// `RESULTS/eval`) and prints the headline figures, or the summary as one JSON object with `json`.
///
/// # Errors
/// When the truth or the results cannot be read, or the report cannot be written.
pub fn command(
    results: &std::path::Path,
    gt: &std::path::Path,
    out: Option<std::path::PathBuf>,
    json: bool,
) -> anyhow::Result<std::process::ExitCode> {
    let truth = crate::Truth::load(gt)?;
    let found = crate::Results::load(results)?;
    let evaluation = crate::evaluate(&truth, &found);
    let out = out.unwrap_or_else(|| results.join("eval"));
    let report = crate::report::write(&truth, results, &evaluation, &out)?;
    if json {
        println!("{}", serde_json::to_string(&crate::summary::summary(&evaluation))?);
        return Ok(std::process::ExitCode::SUCCESS);
    }
    if let Some(o) = &evaluation.orientation {
        println!(
            "orientation: {} images, centre RMS {:.1} mm, rotation RMS {:.4} deg",
            o.images.len(),
            o.rms_center_m * 1000.0,
            o.rms_rotation_deg
        );
    }
    if let Some(l) = &evaluation.lines2d {
        println!(
            "2-D lines: recall {:.1} %, precision {:.1} %",
            100.0 * l.recall,
            100.0 * l.precision
        );
    }
    if let Some(l) = &evaluation.lines3d {
        let all = &l.classes[0];
        println!(
            "3-D lines: {} estimated, success rate {:.1} % (the images allow at most {:.1} %; {:.1} % of the {} edges they resolve)",
            all.n_estimated,
            100.0 * all.success_rate,
            100.0 * all.success_ceiling,
            100.0 * all.success_resolvable,
            all.n_resolvable
        );
    }
    println!("report: {}", report.display());
    Ok(std::process::ExitCode::SUCCESS)
}
