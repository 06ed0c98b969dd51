//! Refine (seed 003 §3.5): the model's edges measured again in the images. Each edge is projected into every
//! image that sees it; the image's 2-D lines near the projection pass three tests with error-propagated
//! thresholds (distance, angle, and the side of the neighbouring edges: the seed's thresholds 1–3), and the
//! nearest one gives the image's interpretation plane; pairs of planes are intersected, each common line tested
//! against the edge (thresholds 4 and 5), and the one most planes agree with selects the images whose planes the
//! edge is then fitted to by least squares. The Shape adjustment takes that line as a second observation of the
//! edge (the spec's fusion option (i)).
//!
//! Where the seed fused aerial image lines with LiDAR lines, a façade model fuses its image lines with the
//! object-space matches of `linematch`: the image lines are sharper across the edge, the matches carry the depth
//! where the interpretation planes meet at a grazing angle (horizontal edges seen from one strip).
use lineflow_photogrammetry::{Camera, Pose, Vec3};

use crate::ModelLine;

/// The farthest an image line may lie from an edge's projection, pixels, however uncertain the edge.
const MAX_REACH_PX: f64 = 200.0;

/// Refine's parameters.
#[derive(Debug, Clone, Copy)]
pub struct RefineParams {
    /// Thresholds are this many standard deviations (the seed: "two or three times").
    pub k: f64,
    /// Standard deviation of an image line's endpoint across the line, pixels.
    pub image_sigma_px: f64,
    /// Image lines shorter than this are not used, pixels.
    pub min_image_line_px: f64,
    /// Two interpretation planes closer than this angle are not intersected, degrees (the image line runs along
    /// the epipolar direction).
    pub min_plane_angle_deg: f64,
    /// Smallest standard deviation credited to a refined line, metres.
    pub min_sigma_m: f64,
}

impl Default for RefineParams {
    fn default() -> Self {
        RefineParams {
            k: 3.0,
            image_sigma_px: 0.5,
            min_image_line_px: 20.0,
            min_plane_angle_deg: 5.0,
            min_sigma_m: 0.001,
        }
    }
}

/// A 2-D line's endpoints in measured pixels.
pub type Endpoints = ([f64; 2], [f64; 2]);

/// One image's pose and its 2-D lines, endpoints in ideal photo coordinates (mm; straight where the image lines
/// are straight after the correction model), with a coarse grid over them.
#[derive(Debug, Clone)]
pub struct ImageLines {
    /// `None` while the image is not oriented: Refine passes it by.
    pose: Option<Pose>,
    segments: Vec<[[f64; 2]; 2]>,
    grid: SegmentIndex,
}

impl ImageLines {
    /// The image lines of one image from their measured pixel endpoints; lines shorter than `min_px` are left out.
    pub fn new(camera: &Camera, pose: Option<Pose>, measured: &[Endpoints], min_px: f64) -> Self {
        let segments: Vec<[[f64; 2]; 2]> = measured
            .iter()
            .filter(|(a, b)| (b[0] - a[0]).hypot(b[1] - a[1]) >= min_px)
            .map(|&(a, b)| [camera.pixel_to_ideal(a), camera.pixel_to_ideal(b)])
            .collect();
        let grid = SegmentIndex::new(&segments, 64.0 * camera.pixel_size_mm);
        ImageLines { pose, segments, grid }
    }
    /// The image's newest pose (the lines stay where they were measured).
    pub fn set_pose(&mut self, pose: Option<Pose>) {
        self.pose = pose;
    }

    /// The image's pose, if oriented.
    pub(crate) fn pose(&self) -> Option<&Pose> {
        self.pose.as_ref()
    }

    /// Where the oriented image sees `x` (ideal coordinates), if inside its frame.
    pub(crate) fn visible(&self, camera: &Camera, x: &Vec3) -> Option<[f64; 2]> {
        let i = self.pose.as_ref()?.project_ideal(camera, x)?;
        camera.ideal_to_pixel(i).filter(|px| camera.contains(*px, 0.0)).map(|_| i)
    }

    /// The image lines whose midpoints may lie within `reach` of the segment a–b (ideal coordinates) or 5 %
    /// beyond its ends.
    pub(crate) fn near(&self, a: [f64; 2], b: [f64; 2], reach: f64) -> impl Iterator<Item = &[[f64; 2]; 2]> {
        self.grid.near(a, b, reach).into_iter().map(|i| &self.segments[i as usize])
    }
}

/// Image lines bucketed by the cells their midpoints fall in.
#[derive(Debug, Clone)]
struct SegmentIndex {
    cell: f64,
    cells: std::collections::HashMap<(i64, i64), Vec<u32>>,
}

impl SegmentIndex {
    fn new(segments: &[[[f64; 2]; 2]], cell: f64) -> Self {
        let mut cells: std::collections::HashMap<(i64, i64), Vec<u32>> = Default::default();
        for (i, s) in segments.iter().enumerate() {
            let m = [(s[0][0] + s[1][0]) / 2.0, (s[0][1] + s[1][1]) / 2.0];
            cells.entry(Self::key(cell, m)).or_default().push(i as u32);
        }
        SegmentIndex { cell, cells }
    }
    fn key(cell: f64, p: [f64; 2]) -> (i64, i64) {
        ((p[0] / cell).floor() as i64, (p[1] / cell).floor() as i64)
    }
    /// Segments whose midpoints may lie within `reach` of the segment a–b or 5 % beyond its ends (where the
    /// tests look), in ascending order.
    fn near(&self, a: [f64; 2], b: [f64; 2], reach: f64) -> Vec<u32> {
        let beyond = [(b[0] - a[0]) * 0.05, (b[1] - a[1]) * 0.05];
        let (a, b) = ([a[0] - beyond[0], a[1] - beyond[1]], [b[0] + beyond[0], b[1] + beyond[1]]);
        // The cells within reach of points every cell along the segment.
        let len = (b[0] - a[0]).hypot(b[1] - a[1]);
        let n = (len / self.cell).ceil() as usize + 1;
        let r = (reach / self.cell).ceil() as i64 + 1;
        let mut keys = Vec::new();
        for s in 0..=n {
            let t = s as f64 / n as f64;
            let (kx, ky) = Self::key(self.cell, [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            keys.extend((-r..=r).flat_map(|dx| (-r..=r).map(move |dy| (kx + dx, ky + dy))));
        }
        keys.sort_unstable();
        keys.dedup();
        let mut found: Vec<u32> = keys.iter().flat_map(|k| self.cells.get(k).into_iter().flatten().copied()).collect();
        found.sort_unstable();
        found
    }
}

/// An edge of the model as Refine sees it: its span between its corners, each end's standard deviations, and
/// the neighbouring edge met at each end (a point on it and its direction), for the topology test.
#[derive(Debug, Clone)]
pub struct StructureLine {
    pub start: Vec3,
    pub end: Vec3,
    pub sigma: [Vec3; 2],
    pub neighbours: [Option<(Vec3, Vec3)>; 2],
}

/// What Refine measured for one edge.
#[derive(Debug, Clone)]
pub struct Refined {
    /// The edge fitted to the agreeing interpretation planes, spanning the structure line's extent, with its σ per
    /// object axis.
    pub line: ModelLine,
    /// Images whose interpretation planes agree on the edge (those in the fit).
    pub images: usize,
}

/// One image's view of a structure line: where it projects (ideal coordinates) and how uncertain that is.
struct Projection {
    a: [f64; 2],
    u: [f64; 2],
    n: [f64; 2],
    len: f64,
    /// σ across the projected line at each end, mm (structure line and image measurement).
    sigma: [f64; 2],
    /// The neighbouring edges, projected: a point and a unit direction.
    neighbours: [Option<([f64; 2], [f64; 2])>; 2],
}

pub(crate) fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}
pub(crate) fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}
pub(crate) fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// The Jacobian of the ideal projection at `x` by central differences (rows: photo x, y).
fn projection_jacobian(camera: &Camera, pose: &Pose, x: &Vec3) -> Option<[[f64; 3]; 2]> {
    let h = 1e-4 * (x - pose.center).norm().max(1.0);
    let mut j = [[0.0; 3]; 2];
    for k in 0..3 {
        let mut e = Vec3::zeros();
        e[k] = h;
        let (p, m) = (pose.project_ideal(camera, &(x + e))?, pose.project_ideal(camera, &(x - e))?);
        j[0][k] = (p[0] - m[0]) / (2.0 * h);
        j[1][k] = (p[1] - m[1]) / (2.0 * h);
    }
    Some(j)
}

fn project(camera: &Camera, image: &ImageLines, s: &StructureLine, p: &RefineParams) -> Option<Projection> {
    let pose = image.pose.as_ref()?;
    let (a, b) = (image.visible(camera, &s.start)?, image.visible(camera, &s.end)?);
    let d = sub(b, a);
    let len = d[0].hypot(d[1]);
    if len < p.min_image_line_px * camera.pixel_size_mm {
        return None;
    }
    let u = [d[0] / len, d[1] / len];
    let n = [-u[1], u[0]];
    let image_sigma = p.image_sigma_px * camera.pixel_size_mm;
    let mut sigma = [0.0; 2];
    for (e, x) in [s.start, s.end].iter().enumerate() {
        let j = projection_jacobian(camera, pose, x)?;
        // σ² across the line: nᵀ J diag(σ²) Jᵀ n.
        let across: f64 = (0..3)
            .map(|k| (n[0] * j[0][k] + n[1] * j[1][k]).powi(2) * s.sigma[e][k].powi(2))
            .sum();
        sigma[e] = (across + image_sigma * image_sigma).sqrt();
    }
    let neighbours = s.neighbours.map(|nb| {
        let (q, dir) = nb?;
        let (q0, q1) = (pose.project_ideal(camera, &q)?, pose.project_ideal(camera, &(q + dir))?);
        let dd = sub(q1, q0);
        let l = dd[0].hypot(dd[1]);
        (l > 0.0).then(|| (q0, [dd[0] / l, dd[1] / l]))
    });
    Some(Projection {
        a,
        u,
        n,
        len,
        sigma,
        neighbours,
    })
}

/// Thresholds 1–3 for one image line against a projected structure line: its distance in standard deviations
/// when it passes.
fn image_tests(proj: &Projection, seg: &[[f64; 2]; 2], p: &RefineParams, image_sigma: f64) -> Option<f64> {
    let m = [(seg[0][0] + seg[1][0]) / 2.0, (seg[0][1] + seg[1][1]) / 2.0];
    let t = dot(sub(m, proj.a), proj.u) / proj.len;
    if !(-0.05..=1.05).contains(&t) {
        return None;
    }
    let tc = t.clamp(0.0, 1.0);
    // Threshold 1: distance of the image line's midpoint from the projected line (Hessian normal form).
    let d = dot(sub(m, proj.a), proj.n).abs();
    let sigma_line = (1.0 - tc) * proj.sigma[0] + tc * proj.sigma[1];
    let sigma_d = (sigma_line * sigma_line + image_sigma * image_sigma / 2.0).sqrt();
    if d > p.k * sigma_d {
        return None;
    }
    // Threshold 2: angle, lines undirected.
    let v = sub(seg[1], seg[0]);
    let lv = v[0].hypot(v[1]);
    if lv <= 0.0 {
        return None;
    }
    let theta = (cross(v, proj.u).abs() / lv).clamp(0.0, 1.0).asin();
    let sigma_theta =
        ((proj.sigma[0].powi(2) + proj.sigma[1].powi(2)) / (proj.len * proj.len) + 2.0 * image_sigma * image_sigma / (lv * lv)).sqrt();
    if theta > p.k * sigma_theta {
        return None;
    }
    // Threshold 3: the image line must lie on the same side of each neighbouring edge as the structure line's
    // midpoint, unless it lies within the distance band of that edge (then the test cannot tell).
    let mid = [proj.a[0] + proj.u[0] * proj.len / 2.0, proj.a[1] + proj.u[1] * proj.len / 2.0];
    for nb in proj.neighbours.iter().flatten() {
        let side = |q: [f64; 2]| cross(nb.1, sub(q, nb.0));
        let (template, candidate) = (side(mid), side(m));
        if template.signum() != candidate.signum() && candidate.abs() > p.k * sigma_d {
            return None;
        }
    }
    Some(d / sigma_d)
}

/// One image's observation of an edge: its interpretation plane (unit normal through the perspective centre,
/// spanned by the rays of the chosen image line) and the plane's positional σ at the structure line's two ends.
#[derive(Debug, Clone, Copy)]
struct PlaneObservation {
    normal: Vec3,
    center: Vec3,
    sigma: [f64; 2],
}

impl PlaneObservation {
    /// `seg` is the image line, `proj` the structure line's projection; `image_sigma` the σ of the image line's
    /// endpoints across it (mm), which grows where the plane is extrapolated beyond a short image line.
    fn new(camera: &Camera, pose: &Pose, seg: &[[f64; 2]; 2], s: &StructureLine, proj: &Projection, image_sigma: f64) -> Option<Self> {
        let normal = pose
            .ray_of_ideal(camera, seg[0])
            .cross(&pose.ray_of_ideal(camera, seg[1]))
            .try_normalize(1e-12)?;
        let v = sub(seg[1], seg[0]);
        let l2 = dot(v, v);
        if l2 <= 0.0 {
            return None;
        }
        let ends = [proj.a, [proj.a[0] + proj.u[0] * proj.len, proj.a[1] + proj.u[1] * proj.len]];
        let mut sigma = [0.0; 2];
        for (e, (q, x)) in ends.iter().zip([s.start, s.end]).enumerate() {
            let t = dot(sub(*q, seg[0]), v) / l2;
            let across = image_sigma * ((1.0 - t) * (1.0 - t) + t * t).sqrt();
            sigma[e] = ((x - pose.center).norm() * across / camera.focal_mm).max(1e-6);
        }
        Some(PlaneObservation {
            normal,
            center: pose.center,
            sigma,
        })
    }
    fn distance(&self, x: &Vec3) -> f64 {
        self.normal.dot(&(x - self.center))
    }
}

/// The common line of two interpretation planes through the structure line's span: the points of the line
/// nearest to the span's ends, if the planes cut at a usable angle.
fn pair_line(a: &PlaneObservation, b: &PlaneObservation, s: &StructureLine, p: &RefineParams) -> Option<[Vec3; 2]> {
    let dir = a.normal.cross(&b.normal);
    let sin_angle = dir.norm();
    if sin_angle < p.min_plane_angle_deg.to_radians().sin() {
        return None;
    }
    let dir = dir / sin_angle;
    // A point on both planes: the least-norm offset from a's centre within both.
    let (da, db) = (0.0, b.distance(&a.center));
    let n = [a.normal, b.normal];
    let g = nalgebra::Matrix2::new(n[0].dot(&n[0]), n[0].dot(&n[1]), n[1].dot(&n[0]), n[1].dot(&n[1]));
    let c = g.try_inverse()? * nalgebra::Vector2::new(da, -db);
    let origin = a.center + n[0] * c[0] + n[1] * c[1];
    let on = |x: &Vec3| origin + dir * (x - origin).dot(&dir);
    Some([on(&s.start), on(&s.end)])
}

/// Thresholds 4 and 5: the hypothesis's midpoint near the structure line, and its direction along it.
fn passes_space_tests(s: &StructureLine, line: &[Vec3; 2], p: &RefineParams) -> bool {
    let axis = s.end - s.start;
    let len = axis.norm();
    let v = line[1] - line[0];
    if len <= 0.0 || v.norm() <= 0.0 {
        return false;
    }
    let u = axis / len;
    let m = (line[0] + line[1]) / 2.0;
    let foot = s.start + u * (m - s.start).dot(&u);
    let sigma_d = ((s.sigma[0].norm() + s.sigma[1].norm()) / 2.0).max(p.min_sigma_m);
    if (m - foot).norm() > p.k * sigma_d {
        return false;
    }
    let theta = (v.cross(&u).norm() / v.norm()).clamp(0.0, 1.0).asin();
    let sigma_theta = (s.sigma[0].norm_squared() + s.sigma[1].norm_squared()).sqrt() / len;
    theta <= (p.k * sigma_theta).max(0.5f64.to_radians())
}

/// Two unit vectors across the unit direction `u`, orthogonal to it and to each other.
fn across(u: &Vec3) -> [Vec3; 2] {
    let e1 = u.cross(&if u.x.abs() < 0.9 { Vec3::x() } else { Vec3::y() }).normalize();
    [e1, u.cross(&e1)]
}

/// The point nearest to `prior` in the plane through it across `u` that best fits the interpretation planes
/// (weights 1/σ²), with its covariance there (m²); `None` when the planes leave it undetermined.
fn fit_point(planes: &[(PlaneObservation, f64)], prior: &Vec3, u: &Vec3) -> Option<(Vec3, nalgebra::Matrix2<f64>)> {
    let [e1, e2] = across(u);
    let (mut n, mut b) = (nalgebra::Matrix2::zeros(), nalgebra::Vector2::zeros());
    for (pl, sigma) in planes {
        let w = 1.0 / (sigma * sigma);
        let a = nalgebra::Vector2::new(pl.normal.dot(&e1), pl.normal.dot(&e2));
        n += a * a.transpose() * w;
        b -= a * pl.distance(prior) * w;
    }
    let cov = n.try_inverse()?;
    let x = cov * b;
    Some((prior + e1 * x[0] + e2 * x[1], cov))
}

/// Refine one edge: in every image that sees it, the image line the tests pick gives an interpretation plane;
/// the pair of planes whose common line the most other planes agree with (RANSAC over the pairs, thresholds 4
/// and 5 on each hypothesis) selects the consistent images, and the line is fitted to their planes by least
/// squares (the spec's rigorous fusion form, conditions n · (X − O) = 0), with its precision. `None` when
/// fewer than two images agree.
pub fn refine_line(camera: &Camera, images: &[ImageLines], s: &StructureLine, p: &RefineParams) -> Option<Refined> {
    let image_sigma = p.image_sigma_px * camera.pixel_size_mm;
    let mut planes: Vec<PlaneObservation> = Vec::new();
    for image in images {
        let Some(proj) = project(camera, image, s, p) else { continue };
        // Capped: an edge known to a metre has no business picking lines from half the image.
        let reach = (p.k * proj.sigma[0].max(proj.sigma[1]) + image_sigma).min(MAX_REACH_PX * camera.pixel_size_mm);
        let b = [proj.a[0] + proj.u[0] * proj.len, proj.a[1] + proj.u[1] * proj.len];
        // Façade edges come in close parallel families (an opening's outline, its frame a few centimetres
        // behind, the reveal) and several can pass the tests; the image line nearest to the projection, in
        // standard deviations, is this image's observation.
        let best = image
            .grid
            .near(proj.a, b, reach)
            .into_iter()
            .map(|k| image.segments[k as usize])
            .filter_map(|seg| image_tests(&proj, &seg, p, image_sigma).map(|z| (z, seg)))
            .min_by(|x, y| x.0.total_cmp(&y.0));
        let pose = image.pose.as_ref()?;
        if let Some(plane) = best.and_then(|(_, seg)| PlaneObservation::new(camera, pose, &seg, s, &proj, image_sigma)) {
            planes.push(plane);
        }
    }
    let agrees = |pl: &PlaneObservation, line: &[Vec3; 2]| {
        pl.distance(&line[0]).abs() <= p.k * pl.sigma[0] && pl.distance(&line[1]).abs() <= p.k * pl.sigma[1]
    };
    // Hypotheses from pairs; the most agreeing planes win, then the smaller normalised residual.
    let mut best: Option<(usize, f64, Vec<usize>)> = None;
    for (x, a) in planes.iter().enumerate() {
        for b in &planes[x + 1..] {
            let Some(line) = pair_line(a, b, s, p).filter(|l| passes_space_tests(s, l, p)) else {
                continue;
            };
            let inliers: Vec<usize> = (0..planes.len()).filter(|&k| agrees(&planes[k], &line)).collect();
            let residual: f64 = inliers
                .iter()
                .map(|&k| {
                    (planes[k].distance(&line[0]) / planes[k].sigma[0]).powi(2)
                        + (planes[k].distance(&line[1]) / planes[k].sigma[1]).powi(2)
                })
                .sum();
            let better = match &best {
                None => true,
                Some((n, r, _)) => inliers.len() > *n || (inliers.len() == *n && residual < *r),
            };
            if better {
                best = Some((inliers.len(), residual, inliers));
            }
        }
    }
    let (_, _, inliers) = best?;
    if inliers.len() < 2 {
        return None;
    }
    let at = |e: usize| -> Vec<(PlaneObservation, f64)> { inliers.iter().map(|&k| (planes[k], planes[k].sigma[e])).collect() };
    let u = (s.end - s.start).normalize();
    let (a, cov_a) = fit_point(&at(0), &s.start, &u)?;
    let (b, cov_b) = fit_point(&at(1), &s.end, &u)?;
    if !passes_space_tests(s, &[a, b], p) {
        return None;
    }
    // The endpoints' error ellipses as σ per object axis: façade edges run along the axes, so the ellipse's
    // long axis (along the viewing rays) and short axis (across them) fall on different coordinates.
    let basis = nalgebra::Matrix3x2::from_columns(&across(&u));
    let per_axis = |c: &nalgebra::Matrix2<f64>| (basis * c * basis.transpose()).diagonal();
    let (va, vb) = (per_axis(&cov_a), per_axis(&cov_b));
    let sigma_axes = Vec3::from_fn(|k, _| va[k].max(vb[k]).max(0.0).sqrt().max(p.min_sigma_m));
    let largest = sigma_axes.max();
    let mut line = ModelLine::new(a, b, largest);
    line.sigma_axes_m = Some(sigma_axes);
    Some(Refined {
        line,
        images: inliers.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_views::{cameras, image_lines};

    #[test]
    fn a_vertical_edge_is_placed_by_its_image_lines_and_a_wrong_image_is_outvoted() {
        let (camera, poses) = cameras(&[-1.5, -0.5, 0.5, 1.5]);
        let edge = (Vec3::new(0.2, 0.0, 0.0), Vec3::new(0.2, 0.0, 1.0));
        // The 3-D line is 8 mm off along the wall and 5 mm in depth, with σ 6 mm.
        let off = Vec3::new(0.008, 0.005, 0.0);
        let s = StructureLine {
            start: edge.0 + off,
            end: edge.1 + off,
            sigma: [Vec3::repeat(0.006); 2],
            neighbours: [None, None],
        };
        let p = RefineParams::default();
        let images: Vec<ImageLines> = poses.iter().map(|q| image_lines(&camera, q, &[edge], 0.0)).collect();
        let r = refine_line(&camera, &images, &s, &p).expect("refined");
        assert_eq!(r.images, 4);
        let error = |l: &ModelLine| (l.start - edge.0).x.abs().max((l.end - edge.1).x.abs());
        assert!(error(&r.line) < 1e-4, "{:?}", r.line);
        // Along the wall (X) the images are sharp, in depth (Y) far weaker: the σ per axis says so.
        let sigma = r.line.sigma_axes_m.unwrap();
        assert!(sigma.y > 2.0 * sigma.x, "{sigma:?}");

        // One image's line 3 px off (another edge of the family, within the tests' band): the other three agree
        // and leave it out.
        let mut wrong = images.clone();
        wrong[1] = image_lines(&camera, &poses[1], &[edge], 3.0);
        let r = refine_line(&camera, &wrong, &s, &p).expect("refined");
        assert_eq!(r.images, 3);
        assert!(error(&r.line) < 1e-4, "{:?}", r.line);
    }

    #[test]
    fn no_lines_one_image_or_unoriented_images_give_nothing() {
        let (camera, poses) = cameras(&[-0.5, 0.5]);
        let edge = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.0, 0.0, 1.0));
        let s = StructureLine {
            start: edge.0,
            end: edge.1,
            sigma: [Vec3::repeat(0.005); 2],
            neighbours: [None, None],
        };
        let p = RefineParams::default();
        let empty: Vec<ImageLines> = poses.iter().map(|q| ImageLines::new(&camera, Some(*q), &[], 20.0)).collect();
        assert!(refine_line(&camera, &empty, &s, &p).is_none());
        let one = vec![image_lines(&camera, &poses[0], &[edge], 0.0)];
        assert!(refine_line(&camera, &one, &s, &p).is_none());
        let mut unoriented: Vec<ImageLines> = poses.iter().map(|q| image_lines(&camera, q, &[edge], 0.0)).collect();
        unoriented[1].set_pose(None);
        assert!(refine_line(&camera, &unoriented, &s, &p).is_none());
    }
}
