//! One multi-view estimate per 3-D edge: the line through the interpretation planes of every image's 2-D segment
//! of it.
//!
//! Object-space matching places a line from one master and the slaves around it, a few frames of baseline at most;
//! along a strip the depth error per pixel of 2-D error shrinks with the baseline. Once the whole stream is in,
//! every image that sees the edge can take part: the merged 3-D line is projected into each image, the 2-D segment
//! lying along its projection (within a few pixels and degrees, overlapping it) is taken as that image's view of
//! the edge, and the line is moved to where its endpoints best lie on all those segments' interpretation planes
//! (the planes through each camera centre and its segment), in pixels of each image; directions the planes do not
//! determine (the depth of a horizontal edge seen along a horizontal strip) keep the current position. Views whose
//! plane disagrees by more than a pixel are dropped and the line solved again.
use lineflow_photogrammetry::{Camera, Mat3, Vec3};
use nalgebra::{Matrix2, Vector2};

use crate::line2::Line2;
use crate::segments::SlaveSegments;

/// Settings of the multi-view line estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultiviewParams {
    /// Largest distance, pixels, of a 2-D segment's endpoints from the line's projection.
    pub max_distance_px: f64,
    /// Largest angle between a 2-D segment and the line's projection, degrees.
    pub max_angle_deg: f64,
    /// A-priori standard deviation of a 2-D line across itself, pixels.
    pub sigma_px: f64,
    /// Directions across the line that the planes determine worse than this (standard deviation, metres) keep
    /// the current position.
    pub max_sigma_m: f64,
    /// Views whose residual exceeds this many pixels are dropped.
    pub max_residual_px: f64,
    /// Views needed to move a line.
    pub min_views: usize,
}

impl Default for MultiviewParams {
    fn default() -> Self {
        Self {
            max_distance_px: 2.5,
            max_angle_deg: 2.0,
            sigma_px: 0.3,
            max_sigma_m: 0.005,
            max_residual_px: 1.0,
            min_views: 3,
        }
    }
}

/// A re-estimated line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultiviewLine {
    /// First endpoint.
    pub start: Vec3,
    /// Second endpoint.
    pub end: Vec3,
    /// Images whose segments it rests on.
    pub views: usize,
    /// RMS of their residuals, pixels.
    pub rms_px: f64,
    /// Covariance of the line's position across itself, m², from its segments' planes at the a-priori σ
    /// (`sigma_px`); a direction the planes barely determine has a huge variance.
    pub across_cov: Mat3,
}

impl MultiviewLine {
    /// Standard deviation of the line's position along the unit direction `w` (across the line), metres.
    pub fn sigma_along(&self, w: &Vec3) -> f64 {
        w.dot(&(self.across_cov * w)).max(0.0).sqrt()
    }
}

/// One image's view of the edge: its camera centre, the unit normal of its segment's interpretation plane, and
/// the size of a pixel at each endpoint's distance (metres per pixel across the line).
struct PlaneView {
    center: Vec3,
    normal: Vec3,
    metres_per_px: [f64; 2],
}

/// The line `start`–`end` re-estimated from the 2-D segments of `views` (every image with a pose), or none when
/// fewer than `min_views` images show it. The views are collected again around the moved line once: images far
/// along the strip see the first estimate's depth error as a larger shift and join only when it is smaller.
pub fn refine_line(camera: &Camera, start: Vec3, end: Vec3, views: &[SlaveSegments], p: &MultiviewParams) -> Option<MultiviewLine> {
    let first = solve_line(camera, [start, end], views, p, false)?;
    Some(solve_line(camera, [first.start, first.end], views, p, false).unwrap_or(first))
}

/// [`refine_line`] with the line's direction fixed to `direction` (a vanishing direction, the vertical or a wall's
/// horizontal): the line is first turned about its midpoint onto it, then moved across itself as a whole. Where
/// the planes fix the depth of each endpoint poorly (a horizontal edge seen from strips a few metres apart), the
/// free estimate tilts the line by their independent errors; with the direction known only the common offset is
/// estimated, from all the planes at both ends.
pub fn refine_line_along(
    camera: &Camera,
    start: Vec3,
    end: Vec3,
    direction: Vec3,
    views: &[SlaveSegments],
    p: &MultiviewParams,
) -> Option<MultiviewLine> {
    let d = direction.try_normalize(1e-12)?;
    let d = if d.dot(&(end - start)) < 0.0 { -d } else { d };
    let (mid, half) = ((start + end) * 0.5, (end - start).norm() * 0.5);
    let ends = [mid - d * half, mid + d * half];
    let first = solve_line(camera, ends, views, p, true)?;
    Some(solve_line(camera, [first.start, first.end], views, p, true).unwrap_or(first))
}

/// The line `start`–`end` where it is, as its images see it: the views whose segment along its projection lies
/// within `max_residual_px` of it at both ends, the RMS of their residuals and the covariance across the line; none
/// when fewer than `min_views` images show it there. For testing a position proposed from elsewhere (a prior).
pub fn line_support(camera: &Camera, start: Vec3, end: Vec3, views: &[SlaveSegments], p: &MultiviewParams) -> Option<MultiviewLine> {
    let ends = [start, end];
    let (u, v) = across_axes(&ends)?;
    let planes: Vec<PlaneView> = views
        .iter()
        .filter_map(|v| plane_view(camera, &start, &end, v, p))
        .filter(|pv| pv.worst_residual_px(&ends) <= p.max_residual_px)
        .collect();
    (planes.len() >= p.min_views).then(|| line_on(ends, &u, &v, &planes, p))
}

/// Two unit directions across the line through `ends`, square to each other; each endpoint moves in their plane.
pub(crate) fn across_axes(ends: &[Vec3; 2]) -> Option<(Vec3, Vec3)> {
    let dir = (ends[1] - ends[0]).try_normalize(1e-12)?;
    let u = dir.cross(&if dir.z.abs() < 0.9 { Vec3::z() } else { Vec3::x() }).normalize();
    Some((u, dir.cross(&u)))
}

impl PlaneView {
    /// The distance of endpoint `i` of `ends` from the plane, pixels of this image.
    fn residual_px(&self, ends: &[Vec3; 2], i: usize) -> f64 {
        self.normal.dot(&(ends[i] - self.center)) / self.metres_per_px[i]
    }

    /// The larger of the two endpoints' residuals, pixels.
    fn worst_residual_px(&self, ends: &[Vec3; 2]) -> f64 {
        self.residual_px(ends, 0).abs().max(self.residual_px(ends, 1).abs())
    }
}

/// The line through `ends` with the views `planes`: their RMS residual and the covariance across the line.
fn line_on(ends: [Vec3; 2], u: &Vec3, v: &Vec3, planes: &[PlaneView], p: &MultiviewParams) -> MultiviewLine {
    let sum: f64 = planes
        .iter()
        .map(|pv| pv.residual_px(&ends, 0).powi(2) + pv.residual_px(&ends, 1).powi(2))
        .sum();
    MultiviewLine {
        start: ends[0],
        end: ends[1],
        views: planes.len(),
        rms_px: (sum / (2 * planes.len()) as f64).sqrt(),
        across_cov: across_covariance(&ends, u, v, planes, p),
    }
}

/// One estimate from the views whose segments lie along the projection of `ends`; with `rigid` both endpoints move
/// by one offset, keeping the direction.
fn solve_line(camera: &Camera, ends: [Vec3; 2], views: &[SlaveSegments], p: &MultiviewParams, rigid: bool) -> Option<MultiviewLine> {
    let (u, v) = across_axes(&ends)?;
    let mut planes: Vec<PlaneView> = views.iter().filter_map(|v| plane_view(camera, &ends[0], &ends[1], v, p)).collect();
    if planes.len() < p.min_views {
        return None;
    }
    for _ in 0..3 {
        let moved = if rigid {
            let offset = solve_offset(&ends, &[0, 1], &u, &v, &planes, p);
            [ends[0] + offset, ends[1] + offset]
        } else {
            [0, 1].map(|i| ends[i] + solve_offset(&ends, &[i], &u, &v, &planes, p))
        };
        let before = planes.len();
        planes.retain(|pv| pv.worst_residual_px(&moved) <= p.max_residual_px);
        if planes.len() < p.min_views {
            return None;
        }
        if planes.len() == before {
            return Some(line_on(moved, &u, &v, &planes, p));
        }
    }
    None
}

/// The normal matrix of an offset across the line (along `u` and `v`) of the endpoints `which`, and its right-hand
/// side, from the views' planes weighted in pixels.
fn normal_equations(
    ends: &[Vec3; 2],
    which: &[usize],
    u: &Vec3,
    v: &Vec3,
    planes: &[PlaneView],
    p: &MultiviewParams,
) -> (Matrix2<f64>, Vector2<f64>) {
    let mut n = Matrix2::zeros();
    let mut b = Vector2::zeros();
    for pv in planes {
        for &i in which {
            // Residual in pixels: (normal · (x + a u + b v − C)) / metres_per_px, linear in (a, b).
            let w = 1.0 / (pv.metres_per_px[i] * p.sigma_px).powi(2);
            let row = Vector2::new(pv.normal.dot(u), pv.normal.dot(v));
            let r0 = pv.normal.dot(&(ends[i] - pv.center));
            n += row * row.transpose() * w;
            b -= row * (r0 * w);
        }
    }
    (n, b)
}

/// The covariance of the line's position across itself (both endpoints moved together), in object space.
fn across_covariance(ends: &[Vec3; 2], u: &Vec3, v: &Vec3, planes: &[PlaneView], p: &MultiviewParams) -> Mat3 {
    // Variance given to a direction no plane determines: far beyond any façade's relief.
    const UNDETERMINED_M2: f64 = 1e6;
    let (n, _) = normal_equations(ends, &[0, 1], u, v, planes, p);
    let eigen = n.symmetric_eigen();
    let mut cov = Mat3::zeros();
    for k in 0..2 {
        let e = eigen.eigenvectors.column(k);
        let axis = u * e[0] + v * e[1];
        let variance = if eigen.eigenvalues[k] > 1.0 / UNDETERMINED_M2 {
            1.0 / eigen.eigenvalues[k]
        } else {
            UNDETERMINED_M2
        };
        cov += axis * axis.transpose() * variance;
    }
    cov
}

/// The offset across the line (along `u` and `v`) that moves the endpoints `which` of `ends` to lie best on the
/// views' planes, weighted in pixels. Only directions the planes determine to `max_sigma_m` move: a horizontal
/// edge seen along a horizontal strip has planes that all contain the cameras' line, its depth is barely observed,
/// and letting the noise move each endpoint's depth on its own would tilt the line.
fn solve_offset(ends: &[Vec3; 2], which: &[usize], u: &Vec3, v: &Vec3, planes: &[PlaneView], p: &MultiviewParams) -> Vec3 {
    let (n, b) = normal_equations(ends, which, u, v, planes, p);
    let eigen = n.symmetric_eigen();
    let min_information = 1.0 / (p.max_sigma_m * p.max_sigma_m);
    let mut d = Vector2::zeros();
    for k in 0..2 {
        let (lambda, e) = (eigen.eigenvalues[k], eigen.eigenvectors.column(k));
        if lambda >= min_information {
            d += e * (e.dot(&b) / lambda);
        }
    }
    u * d[0] + v * d[1]
}

/// The one 2-D segment of `view` that lies best along the projection of `start`–`end` (within `max_distance_px`
/// at both its ends, within `max_angle_deg`, overlapping the projection by half), as its index, if any.
pub(crate) fn segment_along(camera: &Camera, start: &Vec3, end: &Vec3, view: &SlaveSegments, p: &MultiviewParams) -> Option<usize> {
    let pose = &view.pose;
    let (a, b) = (pose.project_ideal(camera, start)?, pose.project_ideal(camera, end)?);
    let segments = view.segments;
    let pixel = segments.pixel_mm;
    let line = Line2::new(a, b).filter(|l| l.len >= 10.0 * pixel)?;
    let tolerance = p.max_distance_px * pixel;
    segments
        .near(a, b, tolerance, p.max_angle_deg.to_radians())
        .into_iter()
        .filter_map(|k| {
            let [s, e] = segments.ends[k];
            let distance = line.across(s).abs().max(line.across(e).abs());
            (distance <= tolerance && line.overlap_share(segments.ends[k]) >= 0.5).then_some((distance, k))
        })
        .min_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)))
        .map(|(_, k)| k)
}

/// The interpretation plane of the 2-D segment of view `view` that lies along the projection of `start`–`end`,
/// if there is exactly one best such segment.
fn plane_view(camera: &Camera, start: &Vec3, end: &Vec3, view: &SlaveSegments, p: &MultiviewParams) -> Option<PlaneView> {
    let pose = &view.pose;
    let [s, e] = view.segments.ends[segment_along(camera, start, end, view, p)?];
    let normal = pose
        .ray_of_ideal(camera, s)
        .cross(&pose.ray_of_ideal(camera, e))
        .try_normalize(1e-12)?;
    let angle = view.segments.pixel_mm / camera.focal_mm;
    Some(PlaneView {
        center: pose.center,
        normal,
        metres_per_px: [(start - pose.center).norm() * angle, (end - pose.center).norm() * angle],
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::segments::FrameSegments;
    use lineflow_messages::Segment2;
    use lineflow_photogrammetry::{rotation_from_opk, Pose};

    fn camera() -> Camera {
        Camera::pinhole(4000, 3000, 0.005, 20.0)
    }

    /// A strip of cameras 12 m in front of the wall y = 0, looking at it, every metre along x.
    fn strip(n: usize) -> Vec<Pose> {
        (0..n)
            .map(|k| Pose {
                center: Vec3::new(k as f64 - (n as f64 - 1.0) / 2.0, -12.0, 1.5),
                rotation: rotation_from_opk(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
            })
            .collect()
    }

    /// Each pose's 2-D segment of the true line a–b, moved across itself by `noise(k)` pixels.
    fn frames(cam: &Camera, poses: &[Pose], a: Vec3, b: Vec3, noise: impl Fn(usize) -> f64) -> Vec<FrameSegments> {
        poses
            .iter()
            .enumerate()
            .map(|(k, pose)| {
                let (pa, pb) = (pose.project(cam, &a).unwrap(), pose.project(cam, &b).unwrap());
                let len = (pb[0] - pa[0]).hypot(pb[1] - pa[1]);
                let off = [-(pb[1] - pa[1]) / len * noise(k), (pb[0] - pa[0]) / len * noise(k)];
                let seg = Segment2 {
                    id: 1,
                    start_px: [pa[0] + off[0], pa[1] + off[1]],
                    end_px: [pb[0] + off[0], pb[1] + off[1]],
                    ..Default::default()
                };
                FrameSegments::new(cam, &[seg], 10.0)
            })
            .collect()
    }

    fn views<'a>(poses: &[Pose], frames: &'a [FrameSegments]) -> Vec<SlaveSegments<'a>> {
        poses
            .iter()
            .zip(frames)
            .map(|(&pose, segments)| SlaveSegments { pose, segments })
            .collect()
    }

    fn distance(p: &Vec3, a: &Vec3, b: &Vec3) -> f64 {
        let d = (b - a).normalize();
        let v = p - a;
        (v - d * v.dot(&d)).norm()
    }

    #[test]
    fn a_vertical_edge_placed_2_cm_off_comes_back_to_within_a_millimetre() {
        let cam = camera();
        let poses = strip(9);
        let (a, b) = (Vec3::new(0.3, 0.0, 0.5), Vec3::new(0.3, 0.0, 2.5));
        // Sub-pixel noise of ±0.2 px across the segments.
        let frames = frames(&cam, &poses, a, b, |k| if k % 2 == 0 { 0.2 } else { -0.2 });
        let off = Vec3::new(0.004, -0.02, 0.0);
        let r = refine_line(&cam, a + off, b + off, &views(&poses, &frames), &MultiviewParams::default()).expect("refined");
        assert_eq!(r.views, 9);
        assert!(distance(&r.start, &a, &b) < 1e-3 && distance(&r.end, &a, &b) < 1e-3, "{r:?}");
        assert!(r.rms_px < 0.3, "{r:?}");
    }

    #[test]
    fn the_covariance_knows_a_vertical_edges_depth_and_not_a_horizontal_ones_from_one_strip() {
        let cam = camera();
        let poses = strip(9);
        let p = MultiviewParams::default();
        let (a, b) = (Vec3::new(0.3, 0.0, 0.5), Vec3::new(0.3, 0.0, 2.5));
        let frames_v = frames(&cam, &poses, a, b, |_| 0.0);
        let v = refine_line(&cam, a, b, &views(&poses, &frames_v), &p).expect("vertical");
        // Nine views over 8 m at 12 m, 0.3 px of 3 mm: the depth to a few millimetres, across to a fraction.
        let depth = v.sigma_along(&Vec3::y());
        assert!(depth > 1e-4 && depth < 0.01, "{depth}");
        assert!(v.sigma_along(&Vec3::x()) < depth, "{v:?}");
        let (a, b) = (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(1.0, 0.0, 2.0));
        let frames_h = frames(&cam, &poses, a, b, |_| 0.0);
        let h = refine_line(&cam, a, b, &views(&poses, &frames_h), &p).expect("horizontal");
        // One horizontal strip: every plane holds the cameras' line, so the position along the line of sight from
        // the strip (12 m across, 0.5 m up) is not determined at all; square to it, it is.
        let sight = Vec3::new(0.0, 12.0, 0.5).normalize();
        let square = Vec3::new(0.0, -0.5, 12.0).normalize();
        assert!(h.sigma_along(&sight) > 100.0, "{h:?}");
        assert!(h.sigma_along(&square) < 0.01, "{h:?}");
    }

    #[test]
    fn a_horizontal_edge_along_the_strip_keeps_its_depth_but_is_lifted_onto_the_planes() {
        let cam = camera();
        let poses = strip(9);
        let (a, b) = (Vec3::new(-1.0, 0.0, 2.0), Vec3::new(1.0, 0.0, 2.0));
        let frames = frames(&cam, &poses, a, b, |_| 0.0);
        // 5 mm too low and 3 cm too deep: the planes fix the height; the depth along the cameras' line of sight is
        // what they cannot see, and it stays (on both endpoints alike, so the line does not tilt).
        let off = Vec3::new(0.0, -0.03, -0.005);
        let r = refine_line(&cam, a + off, b + off, &views(&poses, &frames), &MultiviewParams::default()).expect("refined");
        let dz = (r.start.z - 2.0).abs().max((r.end.z - 2.0).abs());
        assert!(dz < 0.003, "height not restored: {r:?}");
        assert!(
            (r.start.y - (a.y + off.y)).abs() < 0.002 && (r.end.y - (a.y + off.y)).abs() < 0.002,
            "the depth cannot be observed and must not move: {r:?}"
        );
    }

    #[test]
    fn a_line_seen_in_too_few_images_or_with_a_wrong_segment_is_left_alone() {
        let cam = camera();
        let poses = strip(2);
        let (a, b) = (Vec3::new(0.3, 0.0, 0.5), Vec3::new(0.3, 0.0, 2.5));
        let frames = frames(&cam, &poses, a, b, |_| 0.0);
        assert!(refine_line(&cam, a, b, &views(&poses, &frames), &MultiviewParams::default()).is_none());
        // A segment 5 px away in every image is not the edge.
        let poses = strip(9);
        let frames = self::frames(&cam, &poses, a, b, |_| 5.0);
        assert!(refine_line(&cam, a, b, &views(&poses, &frames), &MultiviewParams::default()).is_none());
    }
}
