//! Which faces can appear in which 16×16-pixel tile of one image. Rays of one tile are coherent, so testing the
//! few faces whose projection overlaps the tile beats walking the hierarchy for every ray (6× on a 12 MP frame).
use lineflow_photogrammetry::{Camera, Pose, Vec3};

/// Tile side in pixels.
pub const TILE: usize = 16;
/// Pixels of slack around every projected box: distortion bends box sides between the samples taken.
const MARGIN_PX: f64 = 3.0;
/// Samples per side when a box is carried from ideal to measured coordinates.
const SIDE_SAMPLES: usize = 16;

/// Candidate faces and targets per tile.
#[derive(Debug, Clone)]
pub struct TileIndex {
    cols: usize,
    /// Nearest camera depth of each face (a lower bound of any ray's distance to it).
    depth: Vec<f64>,
    faces: Vec<Vec<u32>>,
    targets: Vec<Vec<u32>>,
}

/// Axis-aligned box in ideal photo coordinates: [xmin, ymin, xmax, ymax].
type Box2 = [f64; 4];

fn grow(b: &mut Box2, p: [f64; 2]) {
    b[0] = b[0].min(p[0]);
    b[1] = b[1].min(p[1]);
    b[2] = b[2].max(p[0]);
    b[3] = b[3].max(p[1]);
}

const EMPTY: Box2 = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];

impl TileIndex {
    /// Bins `faces` and the targets (centre, radius) of one image into tiles.
    pub fn new(corners: &[Vec<Vec3>], targets: &[(Vec3, f64)], camera: &Camera, pose: &Pose) -> TileIndex {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let cols = w.div_ceil(TILE);
        let rows = h.div_ceil(TILE);
        let mut index = TileIndex {
            cols,
            depth: Vec::with_capacity(corners.len()),
            faces: vec![Vec::new(); cols * rows],
            targets: vec![Vec::new(); cols * rows],
        };
        // The image's extent in ideal coordinates: its border, corrected.
        let mut frame = EMPTY;
        let border = (0..=64).flat_map(|i| {
            let (x, y) = (i as f64 / 64.0 * (w as f64 - 1.0), i as f64 / 64.0 * (h as f64 - 1.0));
            [[x, 0.0], [x, h as f64 - 1.0], [0.0, y], [w as f64 - 1.0, y]]
        });
        for px in border {
            grow(&mut frame, camera.pixel_to_ideal(px));
        }
        let slack = (frame[2] - frame[0]) * 0.02;
        let frame = [frame[0] - slack, frame[1] - slack, frame[2] + slack, frame[3] + slack];

        for (i, corners) in corners.iter().enumerate() {
            let visible = clip_to_front(&corners.iter().map(|c| pose.to_camera(c)).collect::<Vec<_>>());
            index.depth.push(visible.iter().map(|c| -c.z).fold(f64::INFINITY, f64::min));
            if visible.is_empty() {
                continue;
            }
            let mut b = EMPTY;
            for c in &visible {
                grow(&mut b, [-camera.focal_mm * c.x / c.z, -camera.focal_mm * c.y / c.z]);
            }
            for tile in index.tiles_under(b, &frame, camera) {
                index.faces[tile].push(i as u32);
            }
        }
        // Nearest first, so that a ray can stop as soon as the next face cannot be nearer than its best hit.
        let depth = std::mem::take(&mut index.depth);
        for list in &mut index.faces {
            list.sort_by(|&a, &b| depth[a as usize].total_cmp(&depth[b as usize]).then(a.cmp(&b)));
        }
        index.depth = depth;
        for (i, (centre, radius)) in targets.iter().enumerate() {
            let Some(p) = pose.project_ideal(camera, centre) else { continue };
            let r = radius * camera.focal_mm / -pose.to_camera(centre).z;
            for tile in index.tiles_under([p[0] - r, p[1] - r, p[0] + r, p[1] + r], &frame, camera) {
                index.targets[tile].push(i as u32);
            }
        }
        index
    }

    /// The tiles an ideal box (clipped to the image) may touch.
    fn tiles_under(&self, b: Box2, frame: &Box2, camera: &Camera) -> Vec<usize> {
        let b = [b[0].max(frame[0]), b[1].max(frame[1]), b[2].min(frame[2]), b[3].min(frame[3])];
        if b[0] > b[2] || b[1] > b[3] {
            return Vec::new();
        }
        let mut px = EMPTY;
        for k in 0..=SIDE_SAMPLES {
            let s = k as f64 / SIDE_SAMPLES as f64;
            let (x, y) = (b[0] + s * (b[2] - b[0]), b[1] + s * (b[3] - b[1]));
            for ideal in [[x, b[1]], [x, b[3]], [b[0], y], [b[2], y]] {
                match camera.ideal_to_pixel(ideal) {
                    Some(p) => grow(&mut px, p),
                    None => px = [f64::NEG_INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::INFINITY],
                }
            }
        }
        let rows = self.faces.len() / self.cols;
        let tile_of = |v: f64, n: usize| ((v / TILE as f64).floor().max(0.0) as usize).min(n - 1);
        let (c0, c1) = (tile_of(px[0] - MARGIN_PX, self.cols), tile_of(px[2] + MARGIN_PX, self.cols));
        let (r0, r1) = (tile_of(px[1] - MARGIN_PX, rows), tile_of(px[3] + MARGIN_PX, rows));
        if px[0] - MARGIN_PX > (self.cols * TILE) as f64
            || px[1] - MARGIN_PX > (rows * TILE) as f64
            || px[2] + MARGIN_PX < 0.0
            || px[3] + MARGIN_PX < 0.0
        {
            return Vec::new();
        }
        (r0..=r1).flat_map(|r| (c0..=c1).map(move |c| r * self.cols + c)).collect()
    }

    /// Candidate faces (nearest first) and targets of the tile holding pixel (col, row).
    pub fn at(&self, col: usize, row: usize) -> (&[u32], &[u32]) {
        let t = (row / TILE) * self.cols + col / TILE;
        (&self.faces[t], &self.targets[t])
    }

    /// Lower bound of the distance from the camera to `face`.
    #[inline]
    pub fn depth(&self, face: u32) -> f64 {
        self.depth[face as usize]
    }
}

/// The part of a convex polygon (camera coordinates) in front of the camera, z ≤ −1 mm (Sutherland-Hodgman).
fn clip_to_front(poly: &[Vec3]) -> Vec<Vec3> {
    const NEAR: f64 = -1e-3;
    let mut out = Vec::with_capacity(poly.len() + 1);
    for (i, a) in poly.iter().enumerate() {
        let b = &poly[(i + 1) % poly.len()];
        let (ina, inb) = (a.z <= NEAR, b.z <= NEAR);
        if ina {
            out.push(*a);
        }
        if ina != inb {
            out.push(a + (b - a) * ((NEAR - a.z) / (b.z - a.z)));
        }
    }
    out
}
