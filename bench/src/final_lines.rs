//! A finished run's final lines with everything linefit's last steps read (its 2-D segments by image with their
//! poses, the camera, the truth), for the benches that apply one of those steps again in this process.
use anyhow::{Context, Result};
use lineflow_eval::Truth;
use lineflow_formats::{read_lines3d, read_poses, Line3Row, PoseRow};
use lineflow_linefit::{line_elements, FitParams, Merged};
use lineflow_linegeom::{FrameSegments, SlaveSegments};
use lineflow_photogrammetry::{Camera, Pose};

use crate::linemap::{frame_segments, run_segments, FinishedRun};

/// What linefit's final steps read, loaded from a finished run of a synthetic building.
pub(crate) struct FinalLines {
    pub truth: Truth,
    pub camera: Camera,
    pub poses: Vec<PoseRow>,
    /// The run's `lines3d.csv`.
    pub lines: Vec<Line3Row>,
    frames: Vec<(Pose, FrameSegments)>,
    /// The image of each of `frames`.
    images: Vec<String>,
}

impl FinalLines {
    /// With `truth_poses`, the scene's true poses stand in for the run's `poses.csv`.
    pub fn load(of: &FinishedRun, truth_poses: bool) -> Result<Self> {
        let run = of.run.as_path();
        let scene = of.scene()?;
        let camera = *scene.camera();
        let truth = Truth::from_scene(scene);
        let poses = if truth_poses {
            truth.poses.clone()
        } else {
            read_poses(&run.join("poses.csv")).with_context(|| format!("{}: the run's poses", run.display()))?
        };
        let lines = read_lines3d(&run.join("lines3d.csv")).with_context(|| format!("{}: the run's lines", run.display()))?;
        let segments = run_segments(run)?;
        let frames = frame_segments(&camera, &poses, &segments);
        let images = poses
            .iter()
            .filter(|p| segments.contains_key(&p.image))
            .map(|p| p.image.clone())
            .collect();
        Ok(FinalLines {
            truth,
            camera,
            poses,
            lines,
            frames,
            images,
        })
    }

    /// Every oriented image's segments with its pose.
    pub fn views(&self) -> Vec<SlaveSegments<'_>> {
        self.frames
            .iter()
            .map(|(pose, segments)| SlaveSegments { pose: *pose, segments })
            .collect()
    }

    /// Every oriented image's segments with the pose `poses` gives it (in the order of [`FinalLines::views`]).
    pub fn views_with<'a>(&'a self, poses: &[Pose]) -> Vec<SlaveSegments<'a>> {
        self.frames
            .iter()
            .zip(poses)
            .map(|((_, segments), &pose)| SlaveSegments { pose, segments })
            .collect()
    }

    /// `poses` (in the order of [`FinalLines::views`]) as rows of `poses.csv`, for scoring them.
    pub fn pose_rows(&self, poses: &[Pose]) -> Vec<PoseRow> {
        self.images
            .iter()
            .zip(poses)
            .map(|(image, &pose)| PoseRow {
                image: image.clone(),
                pose,
                sigma_center_m: None,
                sigma_angles_deg: None,
            })
            .collect()
    }

    /// The run's lines as linefit holds them before its last steps.
    pub fn merged(&self) -> Vec<Merged> {
        self.lines.iter().map(Merged::from_row).collect()
    }

    /// `merged` as rows of `lines3d.csv`, classed as linefit classes them with `fit`.
    pub fn rows(&self, merged: &[Merged], fit: &FitParams) -> Vec<Line3Row> {
        let poses: Vec<Pose> = self.poses.iter().map(|p| p.pose).collect();
        line_elements(merged, fit, Some(&self.camera), &poses)
            .iter()
            .map(Line3Row::from)
            .collect()
    }
}
