//! The renderer: one viewing ray per pixel through the correction model of `conventions.md` (closed form), cast
//! against the faces with correct occlusion; pixels on a surface boundary are supersampled; then the optics and
//! the sensor (vignetting, blur, noise, JPEG). Parallel over rows, each pixel independent, so the bytes never
//! depend on the thread schedule.
use lineflow_photogrammetry::{Camera, Pose, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::bvh::Bvh;
use super::rng::{hash, mix64};
use super::scene::Building;
use super::texture::{albedo, paint_target, target_pattern, Rgb};
use super::tiles::TileIndex;

/// Surface id of rays that hit nothing.
const SKY: u32 = u32::MAX;
/// Marks the id of a ray that hit a target's disc (with [`TARGET_DISC`]) or ring: a target's two edges are edges of
/// the image as much as a face's outline, and are supersampled like them (sampled once at the pixel's centre, their
/// centres lay 0.06–0.1 px off the truth on each axis: `lineflow bench targets`).
const TARGET_RING: u32 = 1 << 31;
const TARGET_DISC: u32 = 1 << 30;
/// Samples per side in a supersampled pixel.
const SUPERSAMPLE: usize = 3;

/// What the optics and the sensor add to the ideal image.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Sensor {
    /// Standard deviation of Gaussian noise, in 8-bit digital numbers.
    pub noise_dn: f64,
    /// Standard deviation of the optical blur, pixels (0 = none).
    pub blur_px: f64,
    /// Light fall-off at the image corners (0 = none, 0.3 = 30 % darker).
    pub vignetting: f64,
    /// JPEG quality 1-100 (0 = lossless).
    pub jpeg_quality: u8,
    /// Display gamma of the encoded values (1 = linear). A gamma other than 1 moves the grey-level midpoint of a
    /// blurred step off the geometric edge by up to a few tenths of a pixel, as in real JPEGs; the default keeps the
    /// yardstick unbiased.
    pub gamma: f64,
}

impl Default for Sensor {
    fn default() -> Self {
        Sensor {
            noise_dn: 1.5,
            blur_px: 0.5,
            vignetting: 0.15,
            jpeg_quality: 0,
            gamma: 1.0,
        }
    }
}

/// The scene prepared for ray casting.
#[derive(Debug, Clone)]
pub struct World {
    bvh: Bvh,
    corners: Vec<Vec<Vec3>>,
    targets: Vec<(u32, Vec3)>,
    target_radius: f64,
    sun: Vec3,
    seed: u64,
    /// Textures at their mean (as if seen from infinitely far): only geometry makes edges.
    pub flat: bool,
}

impl World {
    /// Prepares `building` for rendering; `seed` drives the textures.
    pub fn new(building: &Building, seed: u64) -> World {
        World {
            bvh: Bvh::build(building.faces.iter().map(|f| f.prepare()).collect()),
            corners: building.faces.iter().map(|f| f.corners()).collect(),
            targets: building.targets.iter().map(|t| (t.surface, Vec3::from(t.xyz))).collect(),
            target_radius: building.spec.target_radius_m,
            sun: Vec3::new(-0.35, -0.75, 0.55).normalize(),
            seed,
            flat: false,
        }
    }

    /// The faces and targets each tile of one image can see.
    fn tiles(&self, camera: &Camera, pose: &Pose) -> TileIndex {
        let targets: Vec<(Vec3, f64)> = self.targets.iter().map(|(_, c)| (*c, 2.0 * self.target_radius)).collect();
        TileIndex::new(&self.corners, &targets, camera, pose)
    }

    /// Whether `point` is seen unobstructed from `from` (a hit within `tol` of the point counts as the point).
    pub fn visible(&self, from: &Vec3, point: &Vec3) -> bool {
        let d = point - from;
        let dist = d.norm();
        let tol = 1e-3 + 2e-4 * dist;
        self.bvh.closest(from, &(d / dist), 1e-6, dist - tol).is_none()
    }

    /// Surface id (marked where a target is hit) and linear colour seen along a ray, testing only the `faces` and `targets` of its tile;
    /// `spread` is the footprint per metre of distance.
    fn trace(&self, origin: &Vec3, dir: &Vec3, spread: f64, tiles: &TileIndex, (faces, targets): (&[u32], &[u32])) -> (u32, Rgb) {
        let mut hit: Option<(f64, u32)> = None;
        let mut best = f64::INFINITY;
        for &f in faces {
            if tiles.depth(f) >= best {
                break;
            }
            if let Some(t) = self.bvh.faces[f as usize].intersect(origin, dir, 1e-6, best) {
                hit = Some((t, f));
                best = t;
            }
        }
        let Some((t, face)) = hit else {
            let up = dir.z.clamp(0.0, 1.0) as f32;
            return (SKY, [0.78 - 0.2 * up, 0.84 - 0.14 * up, 0.93 - 0.03 * up]);
        };
        let face = &self.bvh.faces[face as usize];
        let p = origin + dir * t;
        let cos = face.normal.dot(dir);
        let fw = t * spread / cos.abs().max(0.1);
        let texture_fw = if self.flat { f64::INFINITY } else { fw };
        let mut c = albedo(face.material, p.dot(&face.tex_s), p.dot(&face.tex_t), texture_fw, self.seed);
        let mut id = face.surface;
        for &i in targets {
            let (surface, centre) = &self.targets[i as usize];
            if *surface == face.surface {
                let (white, black) = target_pattern((p - centre).norm(), self.target_radius, fw);
                if white + black > 0.0 {
                    c = paint_target(c, white, black);
                    id ^= TARGET_RING | if white > 0.5 { TARGET_DISC } else { 0 };
                }
            }
        }
        // Lambert with the normal turned towards the viewer, plus sky light.
        let n = if cos > 0.0 { -face.normal } else { face.normal };
        let light = (0.35 + 0.65 * n.dot(&self.sun).max(0.0)) as f32;
        (id, [c[0] * light, c[1] * light, c[2] * light])
    }
}

/// Working buffers of the renderer, kept between frames: a 12 MP frame needs 400 MB of them, and the kernel
/// zeroing fresh pages for every frame would cost a third of the render time.
#[derive(Debug, Default)]
pub struct Scratch {
    ids: Vec<u32>,
    rgb: Vec<Rgb>,
    tmp: Vec<Rgb>,
}

/// Renders one frame as packed RGB8 (`width × height × 3`). `frame` seeds the sensor noise.
pub fn render(world: &World, camera: &Camera, pose: &Pose, sensor: &Sensor, frame: u64, scratch: &mut Scratch) -> Vec<u8> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let spread = camera.pixel_size_mm / camera.focal_mm;
    let ray = |col: f64, row: f64| pose.ray_of_pixel(camera, [col, row]);
    let tiles = &world.tiles(camera, pose);

    scratch.ids.resize(w * h, 0);
    scratch.rgb.resize(w * h, [0.0; 3]);
    let Scratch { ids, rgb, tmp } = scratch;
    ids.par_chunks_mut(w)
        .zip(rgb.par_chunks_mut(w))
        .enumerate()
        .for_each(|(row, (ids, rgb))| {
            for col in 0..w {
                let (id, c) = world.trace(&pose.center, &ray(col as f64, row as f64), spread, tiles, tiles.at(col, row));
                ids[col] = id;
                rgb[col] = c;
            }
        });

    // Supersample pixels whose neighbourhood sees more than one surface: their centre sample misplaces the edge.
    let ids = &*ids;
    rgb.par_chunks_mut(w).enumerate().for_each(|(row, out)| {
        for (col, px) in out.iter_mut().enumerate() {
            let id = ids[row * w + col];
            let boundary =
                (row.saturating_sub(1)..(row + 2).min(h)).any(|r| (col.saturating_sub(1)..(col + 2).min(w)).any(|c| ids[r * w + c] != id));
            if !boundary {
                continue;
            }
            let mut sum = [0f32; 3];
            for i in 0..SUPERSAMPLE {
                for j in 0..SUPERSAMPLE {
                    let dc = (j as f64 + 0.5) / SUPERSAMPLE as f64 - 0.5;
                    let dr = (i as f64 + 0.5) / SUPERSAMPLE as f64 - 0.5;
                    let (_, c) = world.trace(
                        &pose.center,
                        &ray(col as f64 + dc, row as f64 + dr),
                        spread / SUPERSAMPLE as f64,
                        tiles,
                        tiles.at(col, row),
                    );
                    for k in 0..3 {
                        sum[k] += c[k];
                    }
                }
            }
            let n = (SUPERSAMPLE * SUPERSAMPLE) as f32;
            *px = [sum[0] / n, sum[1] / n, sum[2] / n];
        }
    });

    if sensor.blur_px > 0.0 {
        blur(rgb, tmp, w, h, sensor.blur_px);
    }
    expose(rgb, w, h, sensor, hash(&[world.seed, 0x5E45, frame]))
}

/// Separable Gaussian blur, in place (`tmp` holds the horizontal pass).
fn blur(rgb: &mut [Rgb], tmp: &mut Vec<Rgb>, w: usize, h: usize, sigma: f64) {
    let radius = (3.0 * sigma).ceil() as isize;
    let mut kernel: Vec<f32> = (-radius..=radius)
        .map(|i| (-(i * i) as f64 / (2.0 * sigma * sigma)).exp() as f32)
        .collect();
    let total: f32 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= total);
    tmp.resize(w * h, [0.0; 3]);
    let src_all = &*rgb;
    tmp.par_chunks_mut(w).enumerate().for_each(|(row, out)| {
        let src = &src_all[row * w..(row + 1) * w];
        for (col, px) in out.iter_mut().enumerate() {
            *px = weighted(&kernel, |o| src[(col as isize + o).clamp(0, w as isize - 1) as usize], radius);
        }
    });
    let horizontal = &*tmp;
    rgb.par_chunks_mut(w).enumerate().for_each(|(row, out)| {
        for (col, px) in out.iter_mut().enumerate() {
            *px = weighted(
                &kernel,
                |o| horizontal[(row as isize + o).clamp(0, h as isize - 1) as usize * w + col],
                radius,
            );
        }
    });
}

#[inline]
fn weighted(kernel: &[f32], sample: impl Fn(isize) -> Rgb, radius: isize) -> Rgb {
    let mut acc = [0f32; 3];
    for (k, weight) in kernel.iter().enumerate() {
        let s = sample(k as isize - radius);
        for ch in 0..3 {
            acc[ch] += weight * s[ch];
        }
    }
    acc
}

/// Vignetting, display encoding (gamma through a table), sensor noise in digital numbers, rounding to 8 bits.
fn expose(rgb: &[Rgb], w: usize, h: usize, sensor: &Sensor, noise_seed: u64) -> Vec<u8> {
    const LEVELS: usize = 4096;
    let table: Vec<f32> = (0..LEVELS)
        .map(|i| (255.0 * (i as f64 / (LEVELS - 1) as f64).powf(1.0 / sensor.gamma.max(0.1))) as f32)
        .collect();
    let (cx, cy) = ((w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0);
    let r2max = cx * cx + cy * cy;
    let mut out = vec![0u8; w * h * 3];
    out.par_chunks_mut(3 * w).enumerate().for_each(|(row, bytes)| {
        let dy = row as f64 - cy;
        for (col, px) in bytes.chunks_mut(3).enumerate() {
            let dx = col as f64 - cx;
            let fall_off = (1.0 - sensor.vignetting * (dx * dx + dy * dy) / r2max) as f32;
            let index = row * w + col;
            let bits = mix64(noise_seed ^ (index as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
            for ch in 0..3 {
                let lin = (rgb[index][ch] * fall_off).clamp(0.0, 1.0);
                let mut dn = table[(lin * (LEVELS - 1) as f32) as usize];
                if sensor.noise_dn > 0.0 {
                    dn += (sensor.noise_dn * normal_from_bits(bits.rotate_left(21 * ch as u32))) as f32;
                }
                px[ch] = (dn.clamp(0.0, 255.0) + 0.5) as u8;
            }
        }
    });
    out
}

/// An approximately standard normal deviate from 64 random bits: the sum of four 16-bit uniforms (Irwin-Hall),
/// centred and scaled; one hash per pixel instead of a logarithm and a cosine per channel.
fn normal_from_bits(bits: u64) -> f64 {
    let sum: u64 = (0..4).map(|k| (bits >> (16 * k)) & 0xFFFF).sum();
    (sum as f64 / 65535.0 - 2.0) * 3f64.sqrt()
}
