//! The synthetic camera: a procedural building with known geometry, rendered through the camera model of
//! `conventions.md`, with ground truth (poses, structural edges, targets) for every accuracy figure.
#![warn(missing_docs)]
mod bvh;
pub mod geometry;
mod presets;
pub mod render;
/// The workspace's seeded generator, where the scenes have always drawn from.
pub use lineflow_photogrammetry::random as rng;
pub mod scene;
mod texture;
mod tiles;
pub mod truth;
mod write;

use lineflow_photogrammetry::{Camera, Pose, Vec3};

pub use presets::{preset, Preset, PRESETS};
pub use render::{Sensor, World};
pub use truth::{SeenEdge, TargetObservation};
pub use write::{jpeg_bytes, make_bare, truth_lines, truth_poses, write_project, write_project_files, PROJECT_FILES};

use rng::Rng;

/// Preset of the `synthetic` capture node when the launch file names none.
pub const DEFAULT_PRESET: &str = "a55-two-strips";
/// Scale of the `synthetic` capture node when the launch file names none (≈ 740 px wide).
pub const DEFAULT_SCALE: f64 = 0.15;
/// Seed of the `synthetic` capture node when the launch file names none.
pub const DEFAULT_SEED: u64 = 1;
use scene::Building;

/// A synthetic data set: camera, stations, building, sensor, and the prepared scene.
#[derive(Debug)]
pub struct Synthetic {
    /// The preset it came from (poses and camera already scaled).
    pub preset: Preset,
    /// The seed of everything random.
    pub seed: u64,
    /// Image scale relative to the preset.
    pub scale: f64,
    /// The generated building.
    pub building: Building,
    world: World,
    scratch: std::sync::Mutex<render::Scratch>,
}

/// What is wrong with a request for a synthetic scene.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// The preset name is not known.
    #[error("unknown preset '{0}' (available: {list})", list = PRESETS.join(", "))]
    UnknownPreset(String),
    /// The scale is out of range.
    #[error("scale must be in (0, 2], got {0}")]
    BadScale(f64),
    /// Writing failed.
    #[error("{0}")]
    Io(String),
}

impl Synthetic {
    /// The scene of preset `name` at `scale`, all randomness drawn from `seed`.
    pub fn new(name: &str, scale: f64, seed: u64) -> Result<Synthetic, SynthError> {
        let mut preset = preset(name, seed).ok_or_else(|| SynthError::UnknownPreset(name.to_string()))?;
        if !(scale > 0.0 && scale <= 2.0) {
            return Err(SynthError::BadScale(scale));
        }
        preset.camera = preset.camera.scaled(scale);
        let building = scene::build(&preset.building, seed);
        let world = World::new(&building, seed);
        Ok(Synthetic {
            preset,
            seed,
            scale,
            building,
            world,
            scratch: Default::default(),
        })
    }

    /// The camera (scaled).
    pub fn camera(&self) -> &Camera {
        &self.preset.camera
    }

    /// True exterior orientations in capture order.
    pub fn poses(&self) -> &[Pose] {
        &self.preset.poses
    }

    /// Renders frame `frame` as packed RGB8. Past the last pose the strip starts over (a second pass along the
    /// façade, with its own sensor noise): a stream of any length (`repeat` of the synthetic capture).
    pub fn render(&self, frame: usize) -> Vec<u8> {
        let mut scratch = self.scratch.lock().unwrap_or_else(|p| p.into_inner());
        render::render(
            &self.world,
            self.camera(),
            &self.preset.poses[frame % self.preset.poses.len()],
            &self.preset.sensor,
            frame as u64,
            &mut scratch,
        )
    }

    /// The file name of frame `frame` in a project folder.
    pub fn image_name(&self, frame: usize) -> String {
        let ext = if self.preset.sensor.jpeg_quality > 0 { "jpg" } else { "png" };
        format!("IMG_{:04}.{ext}", frame + 1)
    }

    /// Structural edges seen (half their length or more) in at least two images.
    pub fn seen_edges(&self) -> Vec<SeenEdge> {
        truth::seen_edges(&self.world, self.camera(), self.poses(), &self.building.edges)
    }

    /// Measurements of the targets in every image that sees them.
    pub fn target_observations(&self) -> Vec<TargetObservation> {
        truth::observe_targets(
            &self.world,
            self.camera(),
            self.poses(),
            &self.building.targets,
            self.preset.obs_sigma_px,
            self.seed,
        )
    }

    /// Textures at their mean colour, so that only geometry makes edges (for measuring edge positions).
    pub fn set_flat_textures(&mut self, flat: bool) {
        self.world.flat = flat;
    }

    /// The ray-casting scene (for visibility tests).
    pub fn world(&self) -> &World {
        &self.world
    }

    /// An approximate site model, as a real LOD-1/2 model would be: every wall moved 2-5 cm along its normal
    /// and its corners by up to 3 cm.
    pub fn approximate_walls(&self) -> Vec<(String, Vec<[f64; 3]>)> {
        let mut rng = Rng::new(self.seed, 3);
        self.building
            .walls
            .iter()
            .map(|(name, corners)| {
                let c: Vec<Vec3> = corners.iter().map(|&p| Vec3::from(p)).collect();
                let normal = (c[1] - c[0]).cross(&(c[2] - c[1])).normalize();
                let shift = normal * rng.uniform(0.02, 0.05) * if rng.uniform(0.0, 1.0) < 0.5 { -1.0 } else { 1.0 };
                let moved = c
                    .iter()
                    .map(|p| {
                        let jitter = Vec3::new(rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03), rng.uniform(-0.03, 0.03));
                        // Jitter within the plane only, so the wall stays planar.
                        let in_plane = jitter - normal * normal.dot(&jitter);
                        (p + shift + in_plane).into()
                    })
                    .collect();
                (name.clone(), moved)
            })
            .collect()
    }
}
