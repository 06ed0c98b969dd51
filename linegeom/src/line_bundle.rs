//! Poses and 3-D lines adjusted together on the lines' 2-D segments: a bundle adjustment whose observations are
//! the interpretation planes of each image's segment of each line, and whose datum is the given poses'.
//!
//! Why: keypoint tie points form short tracks (about three images each), which leave the block's shape across a
//! façade (its depth) to several millimetres at 25 m, and at full size that is half of the 2 GSD a line's ends may
//! be off. A façade's long edges are seen, each, in every image that covers them, and their segments are placed to
//! a tenth of a pixel: the long, precise tracks the orientation lacks. Priors on every pose (about where the
//! orientation put it, with its control points) fix the datum; the lines only make the poses agree with each
//! other.
//!
//! Each line moves its two endpoints across itself (four unknowns); each pose turns its rays about its centre and
//! moves the centre (six). The lines are eliminated per line (Schur complement), leaving a dense system in the
//! poses only.
use lineflow_photogrammetry::{Camera, Pose, Vec3};
use nalgebra::{DMatrix, DVector, Matrix4, Rotation3, SMatrix, Vector4};
use rayon::prelude::*;

use crate::multiview::{across_axes, segment_along, MultiviewParams};
use crate::segments::SlaveSegments;

type Matrix4x6 = SMatrix<f64, 4, 6>;
type Matrix6 = SMatrix<f64, 6, 6>;
type Vector6 = SMatrix<f64, 6, 1>;

/// Settings of the joint adjustment of poses and lines.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineBundleParams {
    /// A-priori standard deviation of a segment's interpretation plane at a line's endpoint, pixels.
    pub sigma_px: f64,
    /// Prior standard deviation of each camera centre about its given position, metres.
    pub center_sigma_m: f64,
    /// Prior standard deviation of each camera's rotation about its given one, radians.
    pub rotation_sigma_rad: f64,
    /// Prior standard deviation of each line endpoint's move across the line, metres: it holds the directions
    /// the images barely see (the depth of a level edge seen along a level strip) where they are.
    pub line_sigma_m: f64,
    /// An observation whose plane lies further than this from its line's endpoint (pixels) is dropped.
    pub max_residual_px: f64,
    /// Images a line must be seen in to take part.
    pub min_views: usize,
    /// Gauss-Newton iterations at most.
    pub iterations: usize,
    /// Which segment of an image is a line's view of it (distance and angle to the line's projection).
    pub association: MultiviewParams,
}

impl Default for LineBundleParams {
    fn default() -> Self {
        Self {
            sigma_px: 0.3,
            center_sigma_m: 0.02,
            rotation_sigma_rad: 0.002,
            line_sigma_m: 0.05,
            max_residual_px: 1.0,
            min_views: 4,
            iterations: 6,
            association: MultiviewParams::default(),
        }
    }
}

/// What the adjustment did.
#[derive(Debug, Clone, PartialEq)]
pub struct LineBundle {
    /// The adjusted poses, in the order of the views given.
    pub poses: Vec<Pose>,
    /// Each given line as adjusted, where it took part (seen in `min_views` images to the end).
    pub lines: Vec<Option<[Vec3; 2]>>,
    /// Observations (one per line and image) at the end.
    pub observations: usize,
    /// RMS of the observations' residuals with the given poses and lines, and at the end, pixels.
    pub rms_px: [f64; 2],
    /// Iterations run.
    pub iterations: usize,
}

/// One image's segment of a line: the image, and the unit normal of the segment's interpretation plane in the
/// camera's frame (fixed: only the pose moves it in object space).
struct Observation {
    view: usize,
    normal_camera: Vec3,
}

/// A line taking part: its endpoints now and as given, and its observations.
struct Track {
    line: usize,
    ends: [Vec3; 2],
    given: [Vec3; 2],
    /// Two unit directions across the given line; the endpoints move along them.
    axes: (Vec3, Vec3),
    observations: Vec<Observation>,
}

/// Where one observation stands with pose `pose`: the plane's object-space normal, and for each endpoint the
/// vector from the camera centre and metres per pixel there.
struct Sight {
    normal: Vec3,
    from_center: [Vec3; 2],
    metres_per_px: [f64; 2],
}

impl Sight {
    fn new(o: &Observation, pose: &Pose, ends: &[Vec3; 2], angle_per_px: f64) -> Self {
        let from_center = ends.map(|e| e - pose.center);
        Sight {
            normal: pose.rotation.transpose() * o.normal_camera,
            from_center,
            metres_per_px: from_center.map(|q| q.norm() * angle_per_px),
        }
    }

    /// The endpoints' distances from the plane, pixels.
    fn residuals_px(&self) -> [f64; 2] {
        [0, 1].map(|i| self.normal.dot(&self.from_center[i]) / self.metres_per_px[i])
    }
}

/// One line's share of the normal equations: its own block and right-hand side, and per observation the pose's
/// index, the pose-line block, the pose's own block and right-hand side.
struct TrackSystem {
    /// The inverse of the line's own block (regular: the line's prior is in it).
    inverse: Matrix4<f64>,
    rhs: Vector4<f64>,
    poses: Vec<(usize, Matrix4x6, Matrix6, Vector6)>,
}

/// Poses and lines adjusted together (see the module's comment). `views` are the oriented images with their
/// segments; `lines` the lines' endpoints. Lines seen in fewer than `min_views` images, or whose direction is
/// undefined, stay out.
pub fn adjust_with_lines(camera: &Camera, views: &[SlaveSegments], lines: &[[Vec3; 2]], p: &LineBundleParams) -> LineBundle {
    let angle_per_px = views.first().map_or(0.0, |v| v.segments.pixel_mm) / camera.focal_mm;
    let mut poses: Vec<Pose> = views.iter().map(|v| v.pose).collect();
    let given_poses = poses.clone();
    let mut turned = vec![Vec3::zeros(); poses.len()];
    let mut tracks: Vec<Track> = lines
        .par_iter()
        .enumerate()
        .filter_map(|(line, ends)| track_of(camera, views, line, ends, angle_per_px, p))
        .collect();
    let rms_before = rms_px(&tracks, &poses, angle_per_px);
    let mut iterations = 0;
    for _ in 0..p.iterations {
        iterations += 1;
        let systems: Vec<TrackSystem> = tracks.par_iter().map(|t| track_system(t, &poses, angle_per_px, p)).collect();
        let Some(steps) = pose_steps(&systems, &poses, &given_poses, &turned, p) else {
            break;
        };
        for (t, s) in tracks.iter_mut().zip(&systems) {
            let d = line_step(s, &steps);
            let (u, v) = t.axes;
            t.ends[0] += u * d[0] + v * d[1];
            t.ends[1] += u * d[2] + v * d[3];
        }
        let mut largest = 0.0f64;
        for ((pose, turn), step) in poses.iter_mut().zip(turned.iter_mut()).zip(&steps) {
            let rotation = Vec3::new(step[0], step[1], step[2]);
            let shift = Vec3::new(step[3], step[4], step[5]);
            pose.rotation *= Rotation3::new(rotation).matrix().transpose();
            pose.center += shift;
            *turn += rotation;
            largest = largest.max(shift.norm()).max(rotation.norm() * 25.0);
        }
        screen(&mut tracks, &poses, angle_per_px, p);
        // Below a tenth of a millimetre at a façade's distance nothing any figure reads moves.
        if largest < 1e-4 {
            break;
        }
    }
    let mut adjusted = vec![None; lines.len()];
    for t in &tracks {
        adjusted[t.line] = Some(t.ends);
    }
    LineBundle {
        rms_px: [rms_before, rms_px(&tracks, &poses, angle_per_px)],
        observations: tracks.iter().map(|t| t.observations.len()).sum(),
        poses,
        lines: adjusted,
        iterations,
    }
}

/// The line `ends` with its views in `views` that lie within `max_residual_px` of it, if enough.
fn track_of(
    camera: &Camera,
    views: &[SlaveSegments],
    line: usize,
    ends: &[Vec3; 2],
    angle_per_px: f64,
    p: &LineBundleParams,
) -> Option<Track> {
    let axes = across_axes(ends)?;
    let observations: Vec<Observation> = views
        .iter()
        .enumerate()
        .filter_map(|(view, v)| {
            let [s, e] = v.segments.ends[segment_along(camera, &ends[0], &ends[1], v, &p.association)?];
            let ray = |x: [f64; 2]| Vec3::new(x[0], x[1], -camera.focal_mm);
            let o = Observation {
                view,
                normal_camera: ray(s).cross(&ray(e)).try_normalize(1e-12)?,
            };
            let worst = Sight::new(&o, &v.pose, ends, angle_per_px)
                .residuals_px()
                .map(f64::abs)
                .into_iter()
                .fold(0.0, f64::max);
            (worst <= p.max_residual_px).then_some(o)
        })
        .collect();
    (observations.len() >= p.min_views).then_some(Track {
        line,
        ends: *ends,
        given: *ends,
        axes,
        observations,
    })
}

/// RMS of every observation's residuals, pixels.
fn rms_px(tracks: &[Track], poses: &[Pose], angle_per_px: f64) -> f64 {
    let (mut sum, mut n) = (0.0, 0usize);
    for t in tracks {
        for o in &t.observations {
            let r = Sight::new(o, &poses[o.view], &t.ends, angle_per_px).residuals_px();
            sum += r[0] * r[0] + r[1] * r[1];
            n += 2;
        }
    }
    (sum / n.max(1) as f64).sqrt()
}

/// Drops the observations now beyond `max_residual_px`, and the tracks left with too few.
fn screen(tracks: &mut Vec<Track>, poses: &[Pose], angle_per_px: f64, p: &LineBundleParams) {
    for t in tracks.iter_mut() {
        let ends = t.ends;
        t.observations.retain(|o| {
            Sight::new(o, &poses[o.view], &ends, angle_per_px)
                .residuals_px()
                .iter()
                .all(|r| r.abs() <= p.max_residual_px)
        });
    }
    tracks.retain(|t| t.observations.len() >= p.min_views);
}

/// One line's share of the Gauss-Newton normal equations at the current poses and endpoints.
fn track_system(t: &Track, poses: &[Pose], angle_per_px: f64, p: &LineBundleParams) -> TrackSystem {
    let (u, v) = t.axes;
    let weight = 1.0 / (p.sigma_px * p.sigma_px);
    let prior = 1.0 / (p.line_sigma_m * p.line_sigma_m);
    let mut lines = Matrix4::identity() * prior;
    let mut rhs = Vector4::zeros();
    for i in 0..2 {
        let moved = t.ends[i] - t.given[i];
        rhs[2 * i] += moved.dot(&u) * prior;
        rhs[2 * i + 1] += moved.dot(&v) * prior;
    }
    let mut pose_blocks = Vec::with_capacity(t.observations.len());
    for o in &t.observations {
        let s = Sight::new(o, &poses[o.view], &t.ends, angle_per_px);
        let r = s.residuals_px();
        let (mut cross, mut own, mut own_rhs) = (Matrix4x6::zeros(), Matrix6::zeros(), Vector6::zeros());
        for i in 0..2 {
            let m = s.metres_per_px[i];
            let mut line_row = Vector4::zeros();
            line_row[2 * i] = s.normal.dot(&u) / m;
            line_row[2 * i + 1] = s.normal.dot(&v) / m;
            // Turning the rays by δ turns the plane's normal by δ × n: the residual changes by δ · (n × q) / m.
            let turn = s.normal.cross(&s.from_center[i]) / m;
            let shift = -s.normal / m;
            let pose_row = Vector6::new(turn.x, turn.y, turn.z, shift.x, shift.y, shift.z);
            lines += line_row * line_row.transpose() * weight;
            rhs += line_row * (r[i] * weight);
            cross += line_row * pose_row.transpose() * weight;
            own += pose_row * pose_row.transpose() * weight;
            own_rhs += pose_row * (r[i] * weight);
        }
        pose_blocks.push((o.view, cross, own, own_rhs));
    }
    TrackSystem {
        inverse: lines.try_inverse().unwrap_or_else(Matrix4::zeros),
        rhs,
        poses: pose_blocks,
    }
}

/// The poses' Gauss-Newton steps (turn δ, then centre shift, per pose) from the reduced system, or none when it
/// is singular.
fn pose_steps(systems: &[TrackSystem], poses: &[Pose], given: &[Pose], turned: &[Vec3], p: &LineBundleParams) -> Option<Vec<Vector6>> {
    let n = poses.len();
    let mut reduced = DMatrix::<f64>::zeros(6 * n, 6 * n);
    let mut rhs = DVector::<f64>::zeros(6 * n);
    let (rotation_prior, center_prior) = (p.rotation_sigma_rad.powi(-2), p.center_sigma_m.powi(-2));
    for j in 0..n {
        let shift = poses[j].center - given[j].center;
        for k in 0..3 {
            reduced[(6 * j + k, 6 * j + k)] += rotation_prior;
            reduced[(6 * j + 3 + k, 6 * j + 3 + k)] += center_prior;
            rhs[6 * j + k] += turned[j][k] * rotation_prior;
            rhs[6 * j + 3 + k] += shift[k] * center_prior;
        }
    }
    for s in systems {
        let inverse = s.inverse;
        for (a, cross_a, own, own_rhs) in &s.poses {
            let mut diagonal = reduced.fixed_view_mut::<6, 6>(6 * a, 6 * a);
            diagonal += own;
            let reduce_rhs = cross_a.transpose() * (inverse * s.rhs);
            let mut rows = rhs.fixed_view_mut::<6, 1>(6 * a, 0);
            rows += own_rhs - reduce_rhs;
            let left = cross_a.transpose() * inverse;
            for (b, cross_b, _, _) in &s.poses {
                let mut block = reduced.fixed_view_mut::<6, 6>(6 * a, 6 * b);
                block -= left * cross_b;
            }
        }
    }
    let step = reduced.cholesky()?.solve(&(-rhs));
    Some((0..n).map(|j| step.fixed_rows::<6>(6 * j).into_owned()).collect())
}

/// One line's step (u and v of each endpoint) given the poses' steps: back-substitution into its own block.
fn line_step(s: &TrackSystem, steps: &[Vector6]) -> Vector4<f64> {
    let mut rhs = -s.rhs;
    for (a, cross, _, _) in &s.poses {
        rhs -= cross * steps[*a];
    }
    s.inverse * rhs
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::segments::FrameSegments;
    use lineflow_messages::Segment2;
    use lineflow_photogrammetry::random::Rng;
    use lineflow_photogrammetry::{rotation_from_opk, Mat3};

    fn camera() -> Camera {
        Camera::pinhole(4000, 3000, 0.005, 20.0)
    }

    /// Two strips of cameras 12 m in front of the wall y = 0, every metre along x, 1 m apart in height.
    fn strips() -> Vec<Pose> {
        (0..14)
            .map(|k| Pose {
                center: Vec3::new((k % 7) as f64 - 3.0, -12.0, 1.0 + (k / 7) as f64),
                rotation: rotation_from_opk(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
            })
            .collect()
    }

    /// A wall's worth of plumb and level edges at depths 0–0.3 m.
    fn edges(rng: &mut Rng) -> Vec<[Vec3; 2]> {
        (0..120)
            .map(|k| {
                let (x, z, y) = (rng.uniform(-4.0, 4.0), rng.uniform(-1.0, 3.0), rng.uniform(0.0, 0.3));
                if k % 2 == 0 {
                    [Vec3::new(x, y, z), Vec3::new(x, y, z + 1.5)]
                } else {
                    [Vec3::new(x, y, z), Vec3::new(x + 1.5, y, z)]
                }
            })
            .collect()
    }

    /// Each pose's segments of the edges, with `noise_px` of noise at each end.
    fn frames(cam: &Camera, poses: &[Pose], edges: &[[Vec3; 2]], rng: &mut Rng, noise_px: f64) -> Vec<FrameSegments> {
        poses
            .iter()
            .map(|pose| {
                let segments: Vec<Segment2> = edges
                    .iter()
                    .enumerate()
                    .filter_map(|(id, [a, b])| {
                        let (pa, pb) = (pose.project(cam, a)?, pose.project(cam, b)?);
                        let mut jitter = || rng.normal() * noise_px;
                        Some(Segment2 {
                            id: id as u32,
                            start_px: [pa[0] + jitter(), pa[1] + jitter()],
                            end_px: [pb[0] + jitter(), pb[1] + jitter()],
                            ..Default::default()
                        })
                    })
                    .collect();
                FrameSegments::new(cam, &segments, 10.0)
            })
            .collect()
    }

    /// Poses disturbed as an orientation leaves them: centres a few millimetres off, rays turned to compensate.
    fn disturbed(poses: &[Pose], rng: &mut Rng) -> Vec<Pose> {
        poses
            .iter()
            .map(|p| {
                let shift = Vec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.006;
                let turn = Vec3::new(rng.normal(), rng.normal(), rng.normal()) * 0.0003;
                Pose {
                    center: p.center + shift,
                    rotation: p.rotation * Rotation3::new(turn).matrix().transpose(),
                }
            })
            .collect()
    }

    /// The rotation `pose` has relative to `given`, as an axis-angle vector (radians), in object space.
    fn turn_between(given: &Pose, pose: &Pose) -> Vec3 {
        let relative: Mat3 = given.rotation.transpose() * pose.rotation;
        Rotation3::from_matrix_unchecked(relative.transpose()).scaled_axis()
    }

    fn center_rms(a: &[Pose], b: &[Pose]) -> f64 {
        (a.iter().zip(b).map(|(p, q)| (p.center - q.center).norm_squared()).sum::<f64>() / a.len() as f64).sqrt()
    }

    /// The true poses' relative geometry is recovered from the lines' segments: the residuals fall to the
    /// segments' noise, and the centres move towards the truth.
    #[test]
    fn the_lines_segments_pull_disturbed_poses_towards_the_truth() {
        let cam = camera();
        let mut rng = Rng::new(7, 0);
        let truth = strips();
        let edges = edges(&mut rng);
        let frames = frames(&cam, &truth, &edges, &mut rng, 0.05);
        let start = disturbed(&truth, &mut rng);
        let views: Vec<SlaveSegments> = start
            .iter()
            .zip(&frames)
            .map(|(&pose, segments)| SlaveSegments { pose, segments })
            .collect();
        let p = LineBundleParams {
            max_residual_px: 3.0,
            ..LineBundleParams::default()
        };
        let got = adjust_with_lines(&cam, &views, &edges, &p);
        assert!(got.lines.iter().filter(|l| l.is_some()).count() > 100, "{:?}", got.rms_px);
        assert!(got.rms_px[1] < 0.5 * got.rms_px[0], "{:?}", got.rms_px);
        // The lines each placed with the disturbed poses held, against the lines adjusted with the poses.
        let free = MultiviewParams {
            max_sigma_m: 1.0,
            max_residual_px: 3.0,
            ..MultiviewParams::default()
        };
        let (mut held, mut adjusted, mut n) = (0.0, 0.0, 0);
        for (edge, line) in edges.iter().zip(&got.lines) {
            let (Some(fixed), Some(line)) = (crate::multiview::refine_line(&cam, edge[0], edge[1], &views, &free), line) else {
                continue;
            };
            held += off_edge(&[fixed.start, fixed.end], edge);
            adjusted += off_edge(line, edge);
            n += 1;
        }
        let (before, after) = (center_rms(&start, &truth), center_rms(&got.poses, &truth));
        let (held, adjusted) = (held / n as f64, adjusted / n as f64);
        assert!(
            adjusted < 0.6 * held,
            "lines {held} → {adjusted} m off, centres {before} → {after} m"
        );
    }

    /// The mean distance of a line's endpoints from the infinite line of `edge`, metres.
    fn off_edge(line: &[Vec3; 2], edge: &[Vec3; 2]) -> f64 {
        let d = (edge[1] - edge[0]).normalize();
        line.iter()
            .map(|p| {
                let q = p - edge[0];
                (q - d * q.dot(&d)).norm()
            })
            .sum::<f64>()
            / 2.0
    }

    /// With the true poses nothing needs to move: the adjustment leaves them within a tenth of a millimetre.
    #[test]
    fn true_poses_stay() {
        let cam = camera();
        let mut rng = Rng::new(3, 0);
        let truth = strips();
        let edges = edges(&mut rng);
        let frames = frames(&cam, &truth, &edges, &mut rng, 0.0);
        let views: Vec<SlaveSegments> = truth
            .iter()
            .zip(&frames)
            .map(|(&pose, segments)| SlaveSegments { pose, segments })
            .collect();
        let got = adjust_with_lines(&cam, &views, &edges, &LineBundleParams::default());
        assert!(center_rms(&got.poses, &truth) < 1e-4);
        assert!(got.poses.iter().zip(&truth).all(|(a, b)| turn_between(b, a).norm() < 1e-6));
    }
}
