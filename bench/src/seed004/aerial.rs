//! Synthetic aerial photographs of box buildings for seed 004's experiments (its §4.11 set-up): a frame camera
//! with f = 152 mm and 0.025 mm pixels at about 1 : 4000, the building photographed off-nadir from several strip
//! positions, with the distractors the seed blames for failures: a parapet line inside the roof outline, a bright
//! rooftop water tank, cast shadows, ground texture and image noise.
use lineflow_photogrammetry::random::mix64;
use lineflow_photogrammetry::{rotation_from_opk, Camera, Pose, Vec3};

use lineflow_modelfit::parametric::{BoxModel, Parametric};

/// An oriented block: base corner, rotation about the vertical, size.
#[derive(Debug, Clone, Copy)]
pub struct Block {
    /// Base corner.
    pub origin: Vec3,
    /// Rotation about the vertical, rad.
    pub theta: f64,
    /// Length, width, height, m.
    pub size: Vec3,
    /// Albedo of the walls and of the top.
    pub albedo: [f64; 2],
}

impl Block {
    /// The block of box parameters (dX, dY, dZ, θ, L, W, h).
    pub fn from_params(p: &[f64], albedo: [f64; 2]) -> Self {
        Self {
            origin: Vec3::new(p[0], p[1], p[2]),
            theta: p[3],
            size: Vec3::new(p[4], p[5], p[6]),
            albedo,
        }
    }

    fn local_of(&self, x: &Vec3) -> Vec3 {
        let (s, c) = self.theta.sin_cos();
        let d = x - self.origin;
        Vec3::new(c * d.x + s * d.y, -s * d.x + c * d.y, d.z)
    }

    fn world_dir(&self, v: &Vec3) -> Vec3 {
        let (s, c) = self.theta.sin_cos();
        Vec3::new(c * v.x - s * v.y, s * v.x + c * v.y, v.z)
    }

    /// The nearest hit of the ray beyond `t_min`: distance, local hit point, world normal.
    fn hit(&self, origin: &Vec3, dir: &Vec3, t_min: f64) -> Option<(f64, Vec3, Vec3)> {
        let o = self.local_of(origin);
        let (s, c) = self.theta.sin_cos();
        let d = Vec3::new(c * dir.x + s * dir.y, -s * dir.x + c * dir.y, dir.z);
        let (mut t0, mut t1, mut axis) = (t_min, f64::INFINITY, None);
        for k in 0..3 {
            if d[k].abs() < 1e-15 {
                if o[k] < 0.0 || o[k] > self.size[k] {
                    return None;
                }
                continue;
            }
            let (mut a, mut b) = ((0.0 - o[k]) / d[k], (self.size[k] - o[k]) / d[k]);
            let mut sign = -1.0;
            if a > b {
                std::mem::swap(&mut a, &mut b);
                sign = 1.0;
            }
            if a > t0 {
                t0 = a;
                axis = Some((k, sign));
            }
            t1 = t1.min(b);
            if t0 > t1 {
                return None;
            }
        }
        let (k, sign) = axis?;
        let mut n = Vec3::zeros();
        n[k] = sign;
        Some((t0, o + d * t0, self.world_dir(&n)))
    }
}

/// A box building with its distractors.
#[derive(Debug, Clone)]
pub struct BuildingScene {
    /// True box parameters (dX, dY, dZ, θ, L, W, h); the ground lies at dZ.
    pub truth: [f64; 7],
    /// Inset of the parapet's inner line from the roof outline, m (0 = none).
    pub parapet_inset_m: f64,
    /// Rooftop water tank, if any.
    pub tank: Option<Block>,
    /// Unit vector towards the sun.
    pub sun: Vec3,
    /// Image noise, grey levels.
    pub noise: f64,
    /// Seed of the ground texture and the noise.
    pub seed: u64,
}

/// The aerial camera of the seed's set-up (§4.11): f = 152 mm, 0.025 mm pixels, no distortion.
pub fn aerial_camera(width: u32, height: u32, principal_point_mm: [f64; 2]) -> Camera {
    Camera {
        width,
        height,
        pixel_size_mm: 0.025,
        focal_mm: 152.0,
        principal_point_mm,
        radial: [0.0; 3],
        decentering: [0.0; 2],
    }
}

/// Flying height above the building base for a photo scale of 1 : 4000, m.
pub const FLYING_HEIGHT_M: f64 = 608.0;
/// Offset of each photo's nadir from the building, m: four photos of two adjacent strips at 60 % overlap.
const STRIP_OFFSETS: [[f64; 2]; 4] = [[-180.0, -160.0], [180.0, -160.0], [180.0, 160.0], [-180.0, 160.0]];
/// Margin around the projected building in each photo crop, pixels.
const CROP_MARGIN_PX: f64 = 160.0;

impl BuildingScene {
    /// The photos of the building: the first `n` of four strip positions (adjacent photos of one strip first),
    /// each a nadir photo cropped around the building (the crop shifts the principal point).
    pub fn photos(&self, n: usize) -> Vec<(Camera, Pose)> {
        let vertices = BoxModel.vertices(&self.truth);
        let centre = vertices.iter().sum::<Vec3>() / 8.0;
        STRIP_OFFSETS
            .iter()
            .take(n.min(4))
            .map(|o| {
                let pose = Pose {
                    center: Vec3::new(centre.x + o[0], centre.y + o[1], self.truth[2] + FLYING_HEIGHT_M),
                    rotation: rotation_from_opk(0.0, 0.0, 0.0),
                };
                let probe = aerial_camera(2, 2, [0.0; 2]);
                let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
                for v in &vertices {
                    let p = pose.project_ideal(&probe, v).expect("the building is below the camera");
                    for k in 0..2 {
                        lo[k] = lo[k].min(p[k]);
                        hi[k] = hi[k].max(p[k]);
                    }
                }
                let px = probe.pixel_size_mm;
                let width = (((hi[0] - lo[0]) / px + 2.0 * CROP_MARGIN_PX) / 2.0).ceil() as u32 * 2;
                let height = (((hi[1] - lo[1]) / px + 2.0 * CROP_MARGIN_PX) / 2.0).ceil() as u32 * 2;
                let mid = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
                (aerial_camera(width, height, [-mid[0], -mid[1]]), pose)
            })
            .collect()
    }

    fn blocks(&self) -> Vec<Block> {
        let mut b = vec![Block::from_params(&self.truth, [0.62, 0.5])];
        b.extend(self.tank);
        b
    }

    fn ground_albedo(&self, x: f64, y: f64) -> f64 {
        // A few incommensurate waves with seeded phases: texture without straight edges.
        let mut a = 0.3;
        let mut s = self.seed;
        for k in 0..4 {
            s = mix64(s);
            let phase = (s >> 11) as f64 / (1u64 << 53) as f64 * std::f64::consts::TAU;
            let f = 0.07 * (k + 1) as f64;
            a += 0.025 * ((x * f * (1.0 + 0.3 * k as f64) + y * f * 0.7) + phase).sin();
        }
        a
    }

    fn radiance(&self, blocks: &[Block], origin: &Vec3, dir: &Vec3) -> f64 {
        let mut best: Option<(f64, usize, Vec3, Vec3)> = None;
        for (i, b) in blocks.iter().enumerate() {
            if let Some((t, local, n)) = b.hit(origin, dir, 1e-6) {
                if best.is_none_or(|(bt, ..)| t < bt) {
                    best = Some((t, i, local, n));
                }
            }
        }
        let ground_z = self.truth[2];
        let (point, normal, albedo) = match best {
            Some((t, i, local, n)) => {
                let b = &blocks[i];
                let top = n.z > 0.5;
                let mut albedo = b.albedo[usize::from(top)];
                let inset = self.parapet_inset_m;
                if i == 0 && top && inset > 0.0 {
                    let inner = local.x > inset && local.x < b.size.x - inset && local.y > inset && local.y < b.size.y - inset;
                    if inner {
                        albedo *= 0.72;
                    }
                }
                (origin + dir * t, n, albedo)
            }
            None => {
                if dir.z >= 0.0 {
                    return 0.0;
                }
                let t = (ground_z - origin.z) / dir.z;
                let p = origin + dir * t;
                (p, Vec3::z(), self.ground_albedo(p.x, p.y))
            }
        };
        let start = point + normal * 1e-4;
        let lit = !blocks.iter().any(|b| b.hit(&start, &self.sun, 1e-6).is_some());
        let direct = if lit { normal.dot(&self.sun).max(0.0) } else { 0.0 };
        albedo * (0.3 + 0.7 * direct)
    }

    /// The 8-bit grey photo seen by `camera` at `pose`: 3 × 3 rays per pixel, then Gaussian noise.
    pub fn render(&self, camera: &Camera, pose: &Pose) -> Vec<u8> {
        use rayon::prelude::*;
        let (w, h) = (camera.width as usize, camera.height as usize);
        let blocks = self.blocks();
        let mut img = vec![0u8; w * h];
        img.par_chunks_mut(w).enumerate().for_each(|(row, out)| {
            let mut rng = mix64(self.seed ^ (row as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
            for (col, o) in out.iter_mut().enumerate() {
                let mut sum = 0.0;
                for sy in 0..3 {
                    for sx in 0..3 {
                        let px = [col as f64 + (sx as f64 - 1.0) / 3.0, row as f64 + (sy as f64 - 1.0) / 3.0];
                        let ray = pose.ray_of_pixel(camera, px);
                        sum += self.radiance(&blocks, &pose.center, &ray);
                    }
                }
                let (n, next) = gaussian(rng);
                rng = next;
                *o = (sum / 9.0 * 255.0 + self.noise * n).round().clamp(0.0, 255.0) as u8;
            }
        });
        img
    }
}

/// A standard normal deviate (Box-Muller) and the next state.
fn gaussian(state: u64) -> (f64, u64) {
    let a = mix64(state);
    let b = mix64(a);
    let u1 = ((a >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
    let u2 = (b >> 11) as f64 / (1u64 << 53) as f64;
    ((-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos(), b)
}

/// The test buildings: sizes within the seed's 10–40 × 8–25 × 6–30 m, various orientations, each with a
/// parapet line; the second and fourth carry a bright water tank beside a roof edge.
pub fn buildings() -> Vec<BuildingScene> {
    let sun = Vec3::new(-0.45, -0.35, 0.82).normalize();
    let specs: [([f64; 7], f64, bool); 5] = [
        ([500.0, 300.0, 12.0, 15f64.to_radians(), 24.0, 14.0, 18.0], 0.4, false),
        ([1200.0, 800.0, 30.0, -30f64.to_radians(), 36.0, 20.0, 12.0], 0.3, true),
        ([-200.0, 150.0, 5.0, 50f64.to_radians(), 16.0, 12.0, 24.0], 0.5, false),
        ([0.0, 0.0, 20.0, 5f64.to_radians(), 30.0, 18.0, 9.0], 0.4, true),
        ([300.0, -600.0, 8.0, 70f64.to_radians(), 20.0, 20.0, 15.0], 0.35, false),
    ];
    specs
        .iter()
        .enumerate()
        .map(|(i, &(truth, parapet, tank))| {
            let tank = tank.then(|| {
                let (s, c) = truth[3].sin_cos();
                // 3 × 3 × 2.5 m, 0.8 m in from the roof's x = L and y = 0 edges.
                let local = Vec3::new(truth[4] - 3.8, 0.8, truth[6]);
                Block {
                    origin: Vec3::new(truth[0], truth[1], truth[2])
                        + Vec3::new(c * local.x - s * local.y, s * local.x + c * local.y, local.z),
                    theta: truth[3],
                    size: Vec3::new(3.0, 3.0, 2.5),
                    albedo: [0.95, 0.98],
                }
            });
            BuildingScene {
                truth,
                parapet_inset_m: parapet,
                tank,
                sun,
                noise: 2.0,
                seed: 1000 + i as u64,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_building_is_in_every_photo_and_walls_show() {
        let scene = &buildings()[0];
        let photos = scene.photos(4);
        assert_eq!(photos.len(), 4);
        for (camera, pose) in &photos {
            for v in BoxModel.vertices(&scene.truth) {
                let px = pose.project(camera, &v).unwrap();
                assert!(px[0] > 100.0 && px[1] > 100.0, "{px:?}");
                assert!(px[0] < camera.width as f64 - 100.0 && px[1] < camera.height as f64 - 100.0);
            }
        }
        let (camera, pose) = &photos[0];
        let img = scene.render(camera, pose);
        let again = scene.render(camera, pose);
        assert_eq!(img, again, "deterministic");
        let mean = img.iter().map(|&v| v as f64).sum::<f64>() / img.len() as f64;
        assert!(mean > 30.0 && mean < 200.0, "{mean}");
    }
}
