//! The linefit stage: a 3-D segment per matched point group ([`fit`]), and the fragments of one edge merged across
//! masters ([`merge`]).
#![warn(missing_docs)]

pub mod bridge;
pub mod fit;
pub mod merge;

use lineflow_linegeom::{
    classify_elements, refine_line, uncovered_stretches, ClassRule, Cover, LayerParams, LayerStats, MultiviewLine, MultiviewParams,
    SideRule, Sight, SlaveSegments,
};
use lineflow_messages::Line3;
use lineflow_photogrammetry::{Camera, Pose, Vec3};
use serde::Deserialize;

pub use bridge::bridges;
pub use fit::{fit_thesis, fit_tls, Fitted, Method};
pub use merge::{merge, Fragment, MergeRule, Merged};

/// Parameters of the `linefit` node.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FitParams {
    /// Inlier distance from the line, metres (also the thesis method's smallest outlier limit).
    pub inlier_m: f64,
    /// Two-point hypotheses of the robust fit.
    pub iterations: usize,
    /// Fewest inliers of a line.
    pub min_points: usize,
    /// Smallest share of a group's points that must be inliers.
    pub min_inlier_share: f64,
    /// Shortest line kept, metres.
    pub min_length_m: f64,
    /// Fragments within this angle, degrees…
    pub merge_angle_deg: f64,
    /// …whose endpoints lie this close to each other's line, metres…
    pub merge_distance_m: f64,
    /// …and that overlap or leave at most this gap, metres, are one edge.
    pub merge_gap_m: f64,
    /// …and, with the camera and poses, that no image holding both shows more than this many pixels apart across
    /// the line (1.5 by default: a sill and the mortar joint 14 mm below it are 2 px apart at full size, while at
    /// the demo's scale 0.3 a pixel is 23 mm and `merge_distance_m` decides alone); 0 leaves it to `merge_distance_m`
    /// (docs/lines3d.md, "Merged across features").
    pub merge_max_px: f64,
    /// Re-estimate the final lines from every image's 2-D segments (needs `lines2d`, `poses` and `camera`).
    pub multiview: bool,
    /// Largest distance, pixels, of an image's 2-D segment from a line's projection to count as its view.
    pub multiview_max_distance_px: f64,
    /// Images a line needs to be re-estimated.
    pub multiview_min_views: usize,
    /// In the re-estimate, only directions across a line that its images' planes fix to this standard deviation,
    /// metres, move (at 0.3 px per segment); the others keep the matched position.
    pub multiview_max_sigma_m: f64,
    /// Lines within this angle of plumb, or of level along the façade's plan direction or square to it, are turned
    /// onto it about their midpoint, degrees ([`lineflow_linegeom::plumb_level`]); 0 turns none.
    pub snap_deg: f64,
    /// Class each line as structure or texture ([`lineflow_linegeom::class`]; the `class` column of
    /// `lines3d.csv`); off, every line is left unclassed.
    pub classify: bool,
    /// The classing's settings.
    pub class: ClassRule,
    /// The half-plane test of the final lines against the images ([`lineflow_linegeom::sides`]; needs `images`,
    /// `poses` and `camera` wired; `sides = { enabled = true }`): a structure line with one surface on both sides
    /// becomes texture.
    pub sides: SideRule,
    /// A line covers a stretch of another within this distance of it, metres (and `merge_angle_deg`).
    pub join_distance_m: f64,
    /// With the `joined` input wired (another line stage's lines, linemap's): the stretches of its final lines
    /// that the final lines leave uncovered join them, each of at least this length, metres.
    pub join_stretch_m: f64,
    /// With the camera and poses known: a joined line whose RMS residual, in pixels at the distance of the nearest
    /// image, exceeds this does not join (on brick most such lines are courses at a wrong depth).
    pub join_max_rms_px: f64,
    /// With the 2-D lines, poses and camera: level lines between the upper (and the lower) ends of two plumb lines
    /// at most this far apart along the façade join the final set where the images show them (an opening's head and
    /// sill between its jambs, [`bridge`]), metres; 0 (the default) turns this off: the lines gain, the model
    /// loses openings (docs/lines3d.md, "Bridges").
    pub bridge_max_span_m: f64,
    /// The ends of the two plumb lines lie within this height of each other, metres.
    pub bridge_height_m: f64,
    /// A bridge's first search for its 2-D segments reaches this far across its projection, pixels (the jambs'
    /// ends may stop short of the corner).
    pub bridge_search_px: f64,
    /// The smallest share of the images whose frame holds a bridge that must show it.
    pub bridge_min_share: f64,
    /// With the 2-D lines, poses and camera: a final line moves onto the nearest depth layer (a plane of the
    /// façade that the well-placed lines share, [`lineflow_linegeom::layers`]) within this many of its standard
    /// deviations, where its images still show it there; 0 turns this off.
    pub layer_k_sigma: f64,
    /// Lines within this distance of each other's coordinate are one layer, metres.
    pub layer_bandwidth_m: f64,
    /// Lines a layer needs.
    pub layer_min_lines: usize,
    /// Lines placed to this standard deviation or better define the layers, metres.
    pub layer_define_sigma_m: f64,
    /// Farthest a line moves onto a layer, metres.
    pub layer_max_move_m: f64,
    /// The layers near a line come from the lines within this distance of it across the layer's axis, metres (an
    /// opening's recess has a depth of its own); 0: the whole building.
    pub layer_radius_m: f64,
}

impl Default for FitParams {
    fn default() -> Self {
        FitParams {
            inlier_m: 0.03,
            iterations: 200,
            min_points: 5,
            min_inlier_share: 0.5,
            min_length_m: 0.1,
            merge_angle_deg: 2.0,
            merge_distance_m: 0.03,
            merge_gap_m: 0.05,
            merge_max_px: 1.5,
            multiview: true,
            multiview_max_distance_px: 2.5,
            multiview_min_views: 3,
            multiview_max_sigma_m: 0.005,
            snap_deg: 8.0,
            classify: true,
            class: ClassRule::default(),
            sides: SideRule::default(),
            join_distance_m: 0.03,
            join_stretch_m: 0.2,
            join_max_rms_px: 0.35,
            bridge_max_span_m: 0.0,
            bridge_height_m: 0.1,
            bridge_search_px: 5.0,
            bridge_min_share: 0.67,
            layer_k_sigma: 0.0,
            layer_bandwidth_m: 0.01,
            layer_min_lines: 4,
            layer_define_sigma_m: 0.03,
            layer_max_move_m: 0.15,
            layer_radius_m: 1.5,
        }
    }
}

impl FitParams {
    /// The multi-view re-estimate's settings these parameters describe.
    pub fn multiview(&self) -> MultiviewParams {
        MultiviewParams {
            max_distance_px: self.multiview_max_distance_px,
            min_views: self.multiview_min_views,
            max_sigma_m: self.multiview_max_sigma_m,
            ..MultiviewParams::default()
        }
    }

    /// When a line covers a stretch of another (the join, the bridges): within `merge_angle_deg` and
    /// `join_distance_m`.
    pub fn cover(&self) -> Cover {
        Cover {
            angle_deg: self.merge_angle_deg,
            distance_m: self.join_distance_m,
        }
    }

    /// The merge rule these parameters describe.
    pub fn rule(&self) -> MergeRule {
        MergeRule {
            angle_deg: self.merge_angle_deg,
            distance_m: self.merge_distance_m,
            gap_m: self.merge_gap_m,
            max_apart_px: self.merge_max_px,
        }
    }
}

impl lineflow_runtime::StageParams for FitParams {
    fn validate(&self) -> Result<(), lineflow_runtime::ParamError> {
        use lineflow_runtime::params::{at_least, in_closed, in_half_open, non_negative, positive};
        positive("inlier_m", self.inlier_m)?;
        non_negative("merge_distance_m", self.merge_distance_m)?;
        non_negative("merge_gap_m", self.merge_gap_m)?;
        non_negative("merge_max_px", self.merge_max_px)?;
        non_negative("min_length_m", self.min_length_m)?;
        in_closed("min_inlier_share", self.min_inlier_share, 0.0, 1.0)?;
        non_negative("join_distance_m", self.join_distance_m)?;
        positive("join_stretch_m", self.join_stretch_m)?;
        positive("join_max_rms_px", self.join_max_rms_px)?;
        non_negative("bridge_max_span_m", self.bridge_max_span_m)?;
        positive("bridge_height_m", self.bridge_height_m)?;
        positive("bridge_search_px", self.bridge_search_px)?;
        in_closed("bridge_min_share", self.bridge_min_share, 0.0, 1.0)?;
        non_negative("layer_k_sigma", self.layer_k_sigma)?;
        positive("layer_bandwidth_m", self.layer_bandwidth_m)?;
        at_least("layer_min_lines", self.layer_min_lines, 2)?;
        positive("layer_define_sigma_m", self.layer_define_sigma_m)?;
        positive("layer_max_move_m", self.layer_max_move_m)?;
        non_negative("layer_radius_m", self.layer_radius_m)?;
        in_half_open("merge_angle_deg", self.merge_angle_deg, 0.0, 90.0)?;
        in_half_open("snap_deg", self.snap_deg, 0.0, 45.0)?;
        positive("multiview_max_distance_px", self.multiview_max_distance_px)?;
        at_least("multiview_min_views", self.multiview_min_views, 2)?;
        positive("multiview_max_sigma_m", self.multiview_max_sigma_m)?;
        at_least("min_points", self.min_points, 2)?;
        at_least("iterations", self.iterations, 1)?;
        let named = |e: lineflow_linegeom::RuleError| lineflow_runtime::ParamError::new(e.name, e.requirement, e.value);
        self.class.validate().map_err(named)?;
        self.sides.validate().map_err(named)
    }
}

/// Shortest 2-D segment, pixels, that counts as an image's view of a line in [`refine_multiview`].
pub const MULTIVIEW_MIN_SEGMENT_PX: f64 = 20.0;

/// Re-estimates each merged line from the 2-D segments of every image in `views` (multi-view line intersection,
/// [`lineflow_linegeom::multiview`]); lines that too few images show keep their place. Returns how many moved
/// and the RMS of their image residuals, pixels.
pub fn refine_multiview(
    camera: &lineflow_photogrammetry::Camera,
    lines: &mut [Merged],
    views: &[SlaveSegments],
    p: &FitParams,
) -> (usize, f64) {
    use rayon::prelude::*;
    let params = p.multiview();
    let refined: Vec<Option<MultiviewLine>> = lines
        .par_iter()
        .map(|l| refine_line(camera, l.start, l.end, views, &params))
        .collect();
    let (mut moved, mut sum_sq) = (0, 0.0);
    for (l, r) in lines.iter_mut().zip(refined) {
        if let Some(r) = r {
            l.start = r.start;
            l.end = r.end;
            l.n_images = l.n_images.max(r.views as u32);
            moved += 1;
            sum_sq += r.rms_px * r.rms_px;
        }
    }
    (moved, (sum_sq / moved.max(1) as f64).sqrt())
}

/// Moves the lines onto the depth layers the well-placed lines share ([`lineflow_linegeom::snap_to_layers`]) with
/// `p.layer_*`; nothing when `layer_k_sigma` is 0.
pub fn snap_layers(camera: &Camera, lines: &mut [Merged], views: &[SlaveSegments], p: &FitParams) -> LayerStats {
    if p.layer_k_sigma <= 0.0 {
        return LayerStats::default();
    }
    let layer = LayerParams {
        bandwidth_m: p.layer_bandwidth_m,
        min_lines: p.layer_min_lines,
        define_sigma_m: p.layer_define_sigma_m,
        k_sigma: p.layer_k_sigma,
        max_move_m: p.layer_max_move_m,
        radius_m: p.layer_radius_m,
        ..LayerParams::default()
    };
    move_ends(lines, |ends| {
        lineflow_linegeom::snap_to_layers(camera, ends, views, &p.multiview(), &layer)
    })
}

/// Runs `f` on the lines' endpoints and moves the lines to where it left them.
fn move_ends<R>(lines: &mut [Merged], f: impl FnOnce(&mut [[Vec3; 2]]) -> R) -> R {
    let mut ends: Vec<[Vec3; 2]> = lines.iter().map(|l| [l.start, l.end]).collect();
    let result = f(&mut ends);
    for (l, [a, b]) in lines.iter_mut().zip(ends) {
        l.start = a;
        l.end = b;
    }
    result
}

/// Turns the lines nearly plumb or level onto those directions ([`lineflow_linegeom::snap_plumb_and_level`]) with
/// `p.snap_deg`; returns how many turned.
pub fn snap(lines: &mut [Merged], p: &FitParams) -> usize {
    move_ends(lines, |ends| lineflow_linegeom::snap_plumb_and_level(ends, p.snap_deg))
}

/// Joins to `lines` the stretches of another line stage's lines (`others`) that they leave uncovered
/// (`lineflow_linegeom::fuse`), each of at least `p.join_stretch_m`; returns how many joined. With `sight`, a line
/// whose RMS residual exceeds `p.join_max_rms_px` at the distance of the nearest image joins not. A joined stretch
/// keeps its line's counts and RMS and has no fragments.
pub fn join_lines(lines: &mut Vec<Merged>, others: &[Line3], p: &FitParams, sight: Option<Sight>) -> usize {
    let others: Vec<&Line3> = others
        .iter()
        .filter(|l| {
            sight.is_none_or(|s| l.rms_m <= p.join_max_rms_px * s.metres_per_px(&Vec3::from(l.start_m).lerp(&Vec3::from(l.end_m), 0.5)))
        })
        .collect();
    let own: Vec<[Vec3; 2]> = lines.iter().map(|l| [l.start, l.end]).collect();
    let theirs: Vec<[Vec3; 2]> = others.iter().map(|l| [Vec3::from(l.start_m), Vec3::from(l.end_m)]).collect();
    let rule = p.cover();
    let before = lines.len();
    for ((l, x), free) in others.iter().zip(&theirs).zip(uncovered_stretches(&own, &theirs, &rule)) {
        let length = (x[1] - x[0]).norm();
        for (s, t) in free.into_iter().filter(|(s, t)| (t - s) * length >= p.join_stretch_m) {
            lines.push(Merged {
                start: x[0] + (x[1] - x[0]) * s,
                end: x[0] + (x[1] - x[0]) * t,
                n_points: l.n_points,
                n_images: l.n_images,
                rms_m: l.rms_m,
                fragments: Vec::new(),
            });
        }
    }
    lines.len() - before
}

/// The message elements of the merged lines, numbered from 1, classed when `params.classify` (by their support
/// too when the camera is given, against the images of `poses`).
pub fn line_elements(lines: &[Merged], params: &FitParams, camera: Option<&Camera>, poses: &[Pose]) -> Vec<Line3> {
    let mut out: Vec<Line3> = lines
        .iter()
        .enumerate()
        .map(|(k, l)| Line3 {
            id: k as u64 + 1,
            start_m: l.start.into(),
            end_m: l.end.into(),
            n_points: l.n_points,
            n_images: l.n_images,
            rms_m: l.rms_m,
            ..Line3::default()
        })
        .collect();
    if params.classify {
        let sight = camera.map(|camera| Sight { camera, poses });
        classify_elements(&mut out, &params.class, sight);
    }
    out
}

/// The fragment of one point group, when its fit passes the support tests.
pub fn fit_group(method: Method, points: &[Vec3], master: u64, segment: u32, n_views: u32, p: &FitParams) -> Option<Fragment> {
    if points.len() < p.min_points {
        return None;
    }
    let f = match method {
        Method::Tls => fit_tls(points, p.inlier_m, p.iterations)?,
        Method::Thesis => fit_thesis(points, p.inlier_m)?,
    };
    let enough = f.inliers.len() >= p.min_points && f.inliers.len() as f64 >= p.min_inlier_share * points.len() as f64;
    (enough && f.length() >= p.min_length_m).then(|| Fragment {
        master,
        segment,
        start: f.start,
        end: f.end,
        points: f.inliers.iter().map(|&i| points[i]).collect(),
        n_views,
        rms_m: f.rms_m,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn merged(a: [f64; 3], b: [f64; 3]) -> Merged {
        Merged {
            start: Vec3::from(a),
            end: Vec3::from(b),
            n_points: 10,
            n_images: 5,
            rms_m: 0.004,
            fragments: vec![(1, 2)],
        }
    }

    fn line3(a: [f64; 3], b: [f64; 3]) -> Line3 {
        Line3 {
            start_m: a,
            end_m: b,
            n_points: 7,
            n_images: 9,
            rms_m: 0.002,
            ..Line3::default()
        }
    }

    #[test]
    fn only_the_stretches_the_own_lines_leave_uncovered_join() {
        let p = FitParams::default();
        let mut lines = vec![merged([1.0, 0.0, 0.0], [3.0, 0.0, 0.0])];
        let others = [
            // Covered on [1, 3] by the own line 1 cm away: [0.7, 1] is too short, [3, 6] joins.
            line3([0.7, 0.01, 0.0], [6.0, 0.01, 0.0]),
            // Wholly covered: the same edge twice.
            line3([1.2, 0.0, 0.0], [2.8, 0.0, 0.0]),
            // A plumb line: joins whole, with its counts.
            line3([5.0, 0.0, 0.0], [5.0, 0.0, 2.0]),
            // 10 cm in front of the own line: another edge.
            line3([1.0, -0.1, 0.0], [3.0, -0.1, 0.0]),
        ];
        let p = FitParams { join_stretch_m: 0.5, ..p };
        assert_eq!(join_lines(&mut lines, &others, &p, None), 3);
        let ends: Vec<(Vec3, Vec3)> = lines[1..].iter().map(|l| (l.start, l.end)).collect();
        assert!((ends[0].0 - Vec3::new(3.0, 0.01, 0.0)).norm() < 1e-9 && (ends[0].1 - Vec3::new(6.0, 0.01, 0.0)).norm() < 1e-9);
        assert_eq!(ends[1], (Vec3::new(5.0, 0.0, 0.0), Vec3::new(5.0, 0.0, 2.0)));
        assert_eq!(ends[2], (Vec3::new(1.0, -0.1, 0.0), Vec3::new(3.0, -0.1, 0.0)));
        assert_eq!((lines[2].n_points, lines[2].n_images, lines[2].rms_m), (7, 9, 0.002));
        assert!(lines[1..].iter().all(|l| l.fragments.is_empty()));
        assert_eq!(
            lines[0],
            merged([1.0, 0.0, 0.0], [3.0, 0.0, 0.0]),
            "the own lines stay as they were"
        );
        // Seen from 10 m by a camera of 10 µm pixels and 10 mm focal length: 1 cm per pixel. A line with an RMS
        // of 5 mm (0.5 px) joins without the cameras, not with them.
        let camera = Camera::pinhole(1000, 800, 0.01, 10.0);
        let poses = [Pose {
            center: Vec3::new(5.0, -10.0, 1.0),
            rotation: lineflow_photogrammetry::Mat3::identity(),
        }];
        let sight = Sight {
            camera: &camera,
            poses: &poses,
        };
        let rough = line3([5.0, 0.0, 3.0], [5.0, 0.0, 5.0]);
        let rough = Line3 { rms_m: 0.005, ..rough };
        let mut with = lines.clone();
        assert_eq!(join_lines(&mut with, &[rough], &p, Some(sight)), 0);
        assert_eq!(join_lines(&mut with, &[Line3 { rms_m: 0.003, ..rough }], &p, Some(sight)), 1);
        assert_eq!(join_lines(&mut lines.clone(), &[rough], &p, None), 1);
        // Nothing to join: nothing changes.
        assert_eq!(join_lines(&mut lines, &[], &p, None), 0);
        assert_eq!(lines.len(), 4);
    }
}
