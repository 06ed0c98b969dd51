//! Ground truth derived from the scene: which structural edges the images see, and the target measurements.
use lineflow_photogrammetry::{Camera, Pose, Vec3};
use rayon::prelude::*;

use super::geometry::Edge;
use super::render::World;
use super::rng::{gaussian, hash};
use super::scene::Target;

/// Samples along an edge for the visibility test.
const EDGE_SAMPLES: usize = 32;

/// A structural edge that the images see, with the images that see it.
#[derive(Debug, Clone)]
pub struct SeenEdge {
    /// The edge.
    pub edge: Edge,
    /// Frames that see at least half of it.
    pub frames: Vec<usize>,
}

/// Whether `point` projects into the image and is not hidden from the camera.
pub fn sees(world: &World, camera: &Camera, pose: &Pose, point: &Vec3) -> Option<[f64; 2]> {
    let px = pose.project(camera, point)?;
    (camera.contains(px, 0.0) && world.visible(&pose.center, point)).then_some(px)
}

/// The edges that are unoccluded over at least half their length in at least two images (`conventions.md`).
pub fn seen_edges(world: &World, camera: &Camera, poses: &[Pose], edges: &[Edge]) -> Vec<SeenEdge> {
    edges
        .par_iter()
        .filter_map(|edge| {
            let (a, b) = (Vec3::from(edge.a), Vec3::from(edge.b));
            let frames: Vec<usize> = poses
                .iter()
                .enumerate()
                .filter(|(_, pose)| {
                    let seen = (0..EDGE_SAMPLES)
                        .filter(|&k| {
                            let p = a + (b - a) * ((k as f64 + 0.5) / EDGE_SAMPLES as f64);
                            sees(world, camera, pose, &p).is_some()
                        })
                        .count();
                    2 * seen >= EDGE_SAMPLES
                })
                .map(|(i, _)| i)
                .collect();
            (frames.len() >= 2).then(|| SeenEdge {
                edge: edge.clone(),
                frames,
            })
        })
        .collect()
}

/// A measured target: frame, point id, pixel position.
#[derive(Debug, Clone, PartialEq)]
pub struct TargetObservation {
    /// Frame number.
    pub frame: usize,
    /// Point id.
    pub id: String,
    /// Measured pixel (true projection plus noise).
    pub px: [f64; 2],
}

/// The true projection of every visible target, plus Gaussian noise of `sigma_px` drawn from `seed`.
pub fn observe_targets(
    world: &World,
    camera: &Camera,
    poses: &[Pose],
    targets: &[Target],
    sigma_px: f64,
    seed: u64,
) -> Vec<TargetObservation> {
    let mut out = Vec::new();
    for (frame, pose) in poses.iter().enumerate() {
        for (k, t) in targets.iter().enumerate() {
            // The whole target must be in the frame for a person (or a detector) to measure its centre.
            let Some(px) = sees(world, camera, pose, &Vec3::from(t.xyz)) else {
                continue;
            };
            if !camera.contains(px, 10.0) {
                continue;
            }
            let h = hash(&[seed, 0x0B5, frame as u64, k as u64]);
            let noise = [gaussian(h, hash(&[h, 1])), gaussian(hash(&[h, 2]), hash(&[h, 3]))];
            out.push(TargetObservation {
                frame,
                id: t.id.clone(),
                px: [px[0] + sigma_px * noise[0], px[1] + sigma_px * noise[1]],
            });
        }
    }
    out
}
