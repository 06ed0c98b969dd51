//! The linematch stage: object-space multi-image matching of 2-D line chains (seed 000 §2.8–2.15).
//!
//! Every frame is a master for its own 2-D lines. Each line's sampled chain pixels are searched along their master
//! rays through planes parallel to the line's wall ([`wall`]), with the master and slave images resampled on an
//! object-space lattice ([`view`]) and compared by SNCC over several window modes ([`ncc`], [`search`]).
#![warn(missing_docs)]

pub mod ncc;
pub mod search;
pub mod slave_lines;
pub mod view;
pub mod wall;

use lineflow_photogrammetry::{Camera, Pose, Vec3};
use lineflow_runtime::params::{self, ParamError};
use rayon::prelude::*;
use serde::Deserialize;

pub use lineflow_linegeom::{FrameSegments, SlaveSegments};
pub use search::{match_segment, SegmentInput, SegmentMatch, Unmatched};
pub use view::{DistortionLut, View};
pub use wall::{fit_wall, fit_walls, wall_of_ray, NoWall, WallPlane, WALL_MIN_POINTS};

/// A correlation window (seed 000 §2.12), in the line's own lattice: "along" follows the line, "across" is its
/// normal in the wall plane. For the horizontal and vertical lines of a façade these are the thesis's windows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize)]
pub enum Mode {
    /// Single point, centred.
    C,
    /// Single point at the window's left edge (window extends along the line).
    L,
    /// Single point at the right edge.
    R,
    /// Single point at the upper edge (window extends across the line, negative side).
    U,
    /// Single point at the bottom edge.
    B,
    /// The whole segment, centred across.
    #[serde(rename = "linear-C")]
    LinearC,
    /// The whole segment along one side.
    #[serde(rename = "linear-L")]
    LinearL,
    /// The whole segment along the other side.
    #[serde(rename = "linear-R")]
    LinearR,
    /// A thin strip along the whole segment, just off it on the linear-L side: the surface that meets the edge
    /// there and nothing beyond (a 6 cm sill's front face, not the wall around it).
    #[serde(rename = "strip-L")]
    StripL,
    /// The same on the linear-R side.
    #[serde(rename = "strip-R")]
    StripR,
}

impl Mode {
    /// Every mode.
    pub const ALL: [Mode; 10] = [
        Mode::C,
        Mode::L,
        Mode::R,
        Mode::U,
        Mode::B,
        Mode::LinearC,
        Mode::LinearL,
        Mode::LinearR,
        Mode::StripL,
        Mode::StripR,
    ];

    /// Whether the window spans the whole segment.
    pub fn is_linear(self) -> bool {
        matches!(self, Mode::LinearC | Mode::LinearL | Mode::LinearR | Mode::StripL | Mode::StripR)
    }

    /// Whether the window is one of the thin strips beside the segment.
    pub fn is_strip(self) -> bool {
        matches!(self, Mode::StripL | Mode::StripR)
    }

    /// The window's inclusive lattice ranges (cols, rows) around the target (c, r) for half-size `h`; for linear
    /// modes only the rows are meaningful.
    pub fn window(self, c: i32, r: i32, h: i32) -> ((i32, i32), (i32, i32)) {
        // Off-centre windows reach a third of a half-window past the target, so that the edge itself, not only the
        // surface beside it, is inside the window: otherwise a textured surface beside an edge pulls the edge to its
        // own depth.
        let o = (h / 3).max(1);
        match self {
            Mode::C | Mode::LinearC => ((c - h, c + h), (r - h, r + h)),
            Mode::L => ((c - o, c + 2 * h), (r - h, r + h)),
            Mode::R => ((c - 2 * h, c + o), (r - h, r + h)),
            Mode::U | Mode::LinearR => ((c - h, c + h), (r - 2 * h, r + o)),
            Mode::B | Mode::LinearL => ((c - h, c + h), (r - o, r + 2 * h)),
            // One cell off the edge, whose blur belongs to both sides.
            Mode::StripL => ((c - h, c + h), (r + 1, r + o)),
            Mode::StripR => ((c - h, c + h), (r - o, r - 1)),
        }
    }

    /// The columns of a linear window along a segment spanning lattice columns `first..=last`: the segment and a
    /// half-window past each end, except for a strip, which keeps to the segment (past its ends lie the corners,
    /// whose structure would anchor any depth).
    pub fn linear_cols(self, first: i32, last: i32, h: i32) -> (i32, i32) {
        if self.is_strip() {
            (first, last)
        } else {
            (first - h, last + h)
        }
    }

    /// The smallest master variance per sample (grey levels²) at which the window carries information.
    pub fn min_variance(self) -> f64 {
        if self.is_strip() {
            ncc::STRIP_MIN_VARIANCE
        } else {
            ncc::MIN_VARIANCE
        }
    }
}

/// Parameters of the matching (launch-file `params` of the `linematch` node).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MatchParams {
    /// Distance between matched chain pixels, pixels.
    pub spacing_px: f64,
    /// Shorter segments are not matched, pixels.
    pub min_length_px: f64,
    /// Segments shorter than this on the wall are not matched, metres (the thesis's 100 px at the D2X's 5.9 mm
    /// GSD is 0.59 m): resolution-independent, and at full size it keeps the short joints of a brick wall out.
    pub min_length_m: f64,
    /// Depth search range on each side of the wall, metres (thesis: 1 m).
    pub depth_range_m: f64,
    /// Depth step, metres (the thesis leaves it open; 1 cm, equal to the grid).
    pub depth_step_m: f64,
    /// Grid cell, metres (thesis: 1 cm).
    pub cell_m: f64,
    /// Cells are at least this many ground sample distances (cell and depth step grow together).
    pub min_cell_gsd: f64,
    /// Half the window size in cells (thesis: 21×21 → 10).
    pub half_window: usize,
    /// Window modes; the match is the best over all of them.
    pub modes: Vec<Mode>,
    /// The coarse pass tests every `coarse_factor`-th depth on a lattice of triple cells.
    pub coarse_factor: usize,
    /// Coarse peaks refined at every depth step.
    pub max_candidates: usize,
    /// Smallest accepted SNCC (the thesis accepts everything; 0 reproduces that).
    pub min_sncc: f64,
    /// A peak is rejected when another one, two coarse steps away or more, reaches this share of it (flat curves of
    /// lines along the epipolar direction). 1 or more disables the test.
    pub max_ambiguity: f64,
    /// Each point takes the front-most window peak within this much SNCC of the best (edges at depth steps belong
    /// to the nearer surface), within the steps below; a negative value takes the best SNCC over all modes, as the
    /// thesis does, and computes no strips.
    pub front_margin: f64,
    /// How far in front of the best peak, metres, the front-most window may lie.
    pub front_reach_m: f64,
    /// How far in front of the best peak, in pixels of parallax at the longest baseline, a window must lie to count
    /// as another surface: nearer peaks are the same surface seen through a broad correlation curve (a short
    /// baseline), and taking the front-most of them would only bias the depth forward.
    pub front_min_px: f64,
    /// The same as a distance, metres: the larger of the two applies.
    pub front_min_m: f64,
    /// Where that step is larger than this, metres (short baselines), the best SNCC over the windows applies.
    pub front_max_step_m: f64,
    /// A line whose depth changes by less than this from end to end is taken as parallel to its wall and its
    /// points share one depth, metres (0 keeps every point's own depth, as the thesis does).
    pub parallel_snap_m: f64,
    /// Slaves per master (nearest by overlap).
    pub max_slaves: usize,
    /// Slaves (and the frames whose 2-D lines place depths) come from the frames less than this many frame numbers
    /// from the master; older frames' images and lines are let go once no pending master can use them, and at most
    /// twice this many images are held (the rest wait in the edge): the stage's memory stays bounded on a stream of
    /// any length (`lineflow bench soak`). 0 keeps every frame. The default holds both strips of every preset (36
    /// frames), so their results do not change.
    pub window: u64,
    /// Every `master_every`-th frame (by frame number) is a master; the others serve as slaves only. With six
    /// slaves, masters two frames apart still see every part of a strip from several masters.
    pub master_every: u64,
    /// A slave must see at least this share of the master's wall area.
    pub min_overlap: f64,
    /// Fewest slaves that must see a window.
    pub min_slaves: usize,
    /// Lines are assigned to walls whose polygon, grown by this margin, their ray hits, metres.
    pub wall_margin_m: f64,
    /// Refine SNCC depths with the slaves' own 2-D lines ([`slave_lines`]).
    pub line_depth: bool,
    /// A slave segment is a candidate when its direction is within this angle of the master line's projection,
    /// degrees.
    pub line_max_angle_deg: f64,
    /// Largest change of a point's SNCC depth by the slaves' lines, metres.
    pub line_max_shift_m: f64,
    /// A slave's line is used only where one pixel across it moves the depth by less than this, metres (the line
    /// runs nearly along the baseline otherwise).
    pub line_max_depth_per_px_m: f64,
    /// Slaves whose lines agree on a depth needed to move a point.
    pub line_min_slaves: usize,
    /// Slave segments shorter than this are not used, pixels.
    pub line_min_length_px: f64,
    /// Frames whose 2-D lines place the depths: the slaves and up to this many frames in all, by overlap (lines
    /// cost no resampling; more frames give wider baselines than the SNCC slaves' few).
    pub line_views: usize,
    /// Points SNCC gives no accepted depth take the depth on which this many slaves' 2-D lines agree anywhere in
    /// the depth range (0: such points are dropped, as in the thesis).
    pub line_only_min_slaves: usize,
    /// ... and where this share of the slaves with a line near the point agree on it (a chance agreement of a few
    /// among many parallel lines, the jambs and frames of a row of windows, is not an edge).
    pub line_only_min_share: f64,
    /// ... and where no other depth, a pixel or more away, has this share of as many slaves agreeing (a brick
    /// course one course off, seen from the other strip).
    pub line_only_max_rival: f64,
}

impl Default for MatchParams {
    fn default() -> Self {
        MatchParams {
            spacing_px: 3.0,
            min_length_px: 10.0,
            min_length_m: 0.3,
            depth_range_m: 1.0,
            depth_step_m: 0.01,
            cell_m: 0.01,
            min_cell_gsd: 1.0,
            half_window: 10,
            modes: Mode::ALL.to_vec(),
            coarse_factor: 4,
            max_candidates: 2,
            min_sncc: 0.6,
            max_ambiguity: 0.95,
            front_margin: 0.05,
            front_reach_m: 0.4,
            front_min_px: 1.5,
            front_min_m: 0.03,
            front_max_step_m: 0.05,
            parallel_snap_m: 0.03,
            max_slaves: 6,
            window: 48,
            master_every: 1,
            min_overlap: 0.2,
            min_slaves: 1,
            wall_margin_m: 0.5,
            line_depth: true,
            line_max_angle_deg: 3.0,
            line_max_shift_m: 0.3,
            line_max_depth_per_px_m: 0.25,
            line_min_slaves: 2,
            line_min_length_px: 20.0,
            line_only_min_slaves: 6,
            line_only_min_share: 0.6,
            line_only_max_rival: 0.5,
            line_views: 12,
        }
    }
}

impl lineflow_runtime::StageParams for MatchParams {
    fn validate(&self) -> Result<(), ParamError> {
        for (name, v) in [
            ("spacing_px", self.spacing_px),
            ("depth_range_m", self.depth_range_m),
            ("depth_step_m", self.depth_step_m),
            ("cell_m", self.cell_m),
            ("line_max_angle_deg", self.line_max_angle_deg),
            ("line_max_shift_m", self.line_max_shift_m),
            ("line_max_depth_per_px_m", self.line_max_depth_per_px_m),
        ] {
            params::positive(name, v)?;
        }
        for (name, v) in [
            ("min_length_px", self.min_length_px),
            ("min_length_m", self.min_length_m),
            ("min_cell_gsd", self.min_cell_gsd),
            ("wall_margin_m", self.wall_margin_m),
            ("line_min_length_px", self.line_min_length_px),
            ("front_min_px", self.front_min_px),
            ("front_min_m", self.front_min_m),
            ("front_max_step_m", self.front_max_step_m),
            ("front_reach_m", self.front_reach_m),
            ("line_only_min_share", self.line_only_min_share),
            ("line_only_max_rival", self.line_only_max_rival),
        ] {
            params::non_negative(name, v)?;
        }
        params::at_least("line_min_slaves", self.line_min_slaves, 1)?;
        params::check((1..=50).contains(&self.half_window), "half_window", "in 1..=50", self.half_window)?;
        params::check(!self.modes.is_empty(), "modes", "at least one window mode", "none")?;
        params::at_least("max_slaves", self.max_slaves, self.min_slaves.max(1))?;
        params::check(self.master_every >= 1, "master_every", ">= 1", self.master_every)?;
        let (step, range) = (self.depth_step_m, self.depth_range_m);
        params::check(step <= range, "depth_step_m", &format!("<= depth_range_m ({range})"), step)?;
        params::check(!self.front_margin.is_nan(), "front_margin", "a number", self.front_margin)?;
        let (min, reach) = (self.front_min_m, self.front_reach_m);
        params::check(min <= reach, "front_min_m", &format!("<= front_reach_m ({reach})"), min)
    }
}

/// The matches of one master and how many segments gave none, by reason.
#[derive(Debug, Clone, Default)]
pub struct MasterMatch {
    /// Segments with points, in segment order.
    pub matches: Vec<SegmentMatch>,
    /// Segments without, by reason.
    pub unmatched: UnmatchedCounts,
}

/// How many of a master's segments gave no points, by [`Unmatched`] reason.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct UnmatchedCounts {
    /// [`Unmatched::TooShort`].
    pub too_short: usize,
    /// [`Unmatched::OutsideWalls`].
    pub outside_walls: usize,
    /// [`Unmatched::NoSlave`].
    pub no_slave: usize,
    /// [`Unmatched::NoDepth`].
    pub no_depth: usize,
}

/// Masters with fewer long segments than this on their walls are not worth a warning when none of them matches.
const MIN_SEGMENTS_TO_WARN: usize = 10;

impl UnmatchedCounts {
    fn add(&mut self, why: Unmatched) {
        match why {
            Unmatched::TooShort => self.too_short += 1,
            Unmatched::OutsideWalls => self.outside_walls += 1,
            Unmatched::NoSlave => self.no_slave += 1,
            Unmatched::NoDepth => self.no_depth += 1,
        }
    }

    /// What is wrong with a master whose segments mostly lie outside the walls, whose walls no slave sees, or
    /// whose searched segments found no depth at all (`matched` of them did); `None` for an ordinary master.
    pub fn warning(&self, matched: usize) -> Option<String> {
        let long = matched + self.outside_walls + self.no_slave + self.no_depth;
        let on_walls = long - self.outside_walls;
        if long >= MIN_SEGMENTS_TO_WARN && 2 * self.outside_walls > long {
            return Some(format!(
                "{} of its {long} long segments lie outside every wall: the site model (or the walls fitted to the \
                 tie points) does not cover this view",
                self.outside_walls
            ));
        }
        if on_walls >= MIN_SEGMENTS_TO_WARN && self.no_slave == on_walls {
            return Some(format!("no slave sees the walls of its {on_walls} segments on walls"));
        }
        let searched = on_walls - self.no_slave;
        if searched >= MIN_SEGMENTS_TO_WARN && matched == 0 {
            return Some(format!(
                "none of its {searched} searched segments found a depth: nothing to correlate (glass, a uniform \
                 wall) or the poses are off"
            ));
        }
        None
    }
}

impl std::fmt::Display for UnmatchedCounts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "unmatched: {} too short, {} outside every wall, {} seen by too few slaves, {} without an accepted depth",
            self.too_short, self.outside_walls, self.no_slave, self.no_depth
        )
    }
}

/// Matches every segment of one master (in parallel, results in segment order).
pub fn match_master(master: &View, slaves: &[View], walls: &[WallPlane], segments: &[SegmentInput], p: &MatchParams) -> MasterMatch {
    let line_frames: Vec<SlaveSegments> = slaves
        .iter()
        .filter_map(|v| v.segments.map(|segments| SlaveSegments { pose: v.pose, segments }))
        .collect();
    match_master_with_lines(master, slaves, &line_frames, walls, segments, p)
}

/// [`match_master`] with the frames whose 2-D lines place the depths (`line_frames`, [`slave_lines`]) given apart
/// from the slaves SNCC correlates with: lines cost no resampling, so many more frames, and wider baselines, can
/// serve.
pub fn match_master_with_lines(
    master: &View,
    slaves: &[View],
    line_frames: &[SlaveSegments],
    walls: &[WallPlane],
    segments: &[SegmentInput],
    p: &MatchParams,
) -> MasterMatch {
    let results: Vec<Result<SegmentMatch, Unmatched>> = segments
        .par_iter()
        .map(|s| match_segment(master, slaves, line_frames, walls, s, p))
        .collect();
    let mut out = MasterMatch::default();
    for r in results {
        match r {
            Ok(m) => out.matches.push(m),
            Err(why) => out.unmatched.add(why),
        }
    }
    out
}

/// The share of a master's image whose wall points (a 7×5 grid of pixels, cut with the wall their ray meets)
/// another camera sees inside its image.
pub fn overlap(camera: &Camera, master: &Pose, other: &Pose, walls: &[WallPlane]) -> f64 {
    let (w, h) = (camera.width as f64, camera.height as f64);
    let (mut seen, mut total) = (0usize, 0usize);
    for i in 0..7 {
        for j in 0..5 {
            let px = [(i as f64 + 0.5) / 7.0 * w, (j as f64 + 0.5) / 5.0 * h];
            let ray = master.ray_of_pixel(camera, px);
            let Some(k) = wall_of_ray(walls, &master.center, &ray, 0.0) else {
                continue;
            };
            let Some(s) = walls[k].ray_parameter(&master.center, &ray, 0.0) else {
                continue;
            };
            let x: Vec3 = master.center + s * ray;
            total += 1;
            if walls[k].normal.dot(&(x - other.center)) < 0.0 && other.project(camera, &x).is_some_and(|q| camera.contains(q, 0.0)) {
                seen += 1;
            }
        }
    }
    if total == 0 {
        0.0
    } else {
        seen as f64 / total as f64
    }
}

/// The first frame a pending master can still take a slave or a line from under `window` (`MatchParams::window`):
/// the earliest arrived master not yet `finished` (matched or skipped) less the window, or with none pending the
/// frame after the last arrived less the window. Frames before it can be let go; with `window` 0, none.
pub fn first_needed_frame(arrived: impl IntoIterator<Item = u64>, finished: impl Fn(u64) -> bool, master_every: u64, window: u64) -> u64 {
    if window == 0 {
        return 0;
    }
    let mut last = None;
    let mut pending = None;
    for f in arrived {
        last = last.max(Some(f));
        if f % master_every.max(1) == 0 && !finished(f) {
            pending = pending.min(Some(f)).or(Some(f));
        }
    }
    let Some(last) = last else { return 0 };
    (pending.unwrap_or(last + 1) + 1).saturating_sub(window)
}

/// The slaves of a master: the candidates (frame, pose) overlapping it by at least `min_overlap`, the
/// `max_slaves` with the largest overlap (ties to the nearer frame number, then the earlier).
pub fn choose_slaves(
    camera: &Camera,
    master: (u64, &Pose),
    candidates: &[(u64, Pose)],
    walls: &[WallPlane],
    max_slaves: usize,
    min_overlap: f64,
) -> Vec<u64> {
    let mut scored: Vec<(u64, f64)> = candidates
        .iter()
        .filter(|(f, _)| *f != master.0)
        .map(|(f, pose)| (*f, overlap(camera, master.1, pose, walls)))
        .filter(|(_, o)| *o >= min_overlap)
        .collect();
    scored.sort_by(|a, b| {
        b.1.total_cmp(&a.1)
            .then(a.0.abs_diff(master.0).cmp(&b.0.abs_diff(master.0)))
            .then(a.0.cmp(&b.0))
    });
    scored.into_iter().take(max_slaves).map(|(f, _)| f).collect()
}

/// A matched chain pixel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MatchedPoint {
    /// The master chain pixel (col, row).
    pub pixel: [f64; 2],
    /// Its foot on the segment's straight line, in ideal photo coordinates (mm): the point lies on this ray.
    pub ideal: [f64; 2],
    /// Depth in front of the wall, metres.
    pub depth_m: f64,
    /// The master-ray point at that depth (eq. 15).
    pub xyz: Vec3,
    /// SNCC of the winning window.
    pub sncc: f64,
    /// The winning window.
    pub mode: Mode,
    /// The depth comes from the slaves' 2-D lines, not from SNCC.
    pub from_lines: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_a_pending_master_can_no_longer_use_are_let_go() {
        let done = |f: u64| f < 50;
        // Master 50 pending: slaves from 3 on (less than 48 frame numbers away).
        assert_eq!(first_needed_frame(0..60, done, 1, 48), 3);
        // Nothing pending: the next master is 60 at the earliest.
        assert_eq!(first_needed_frame(0..60, |_| true, 1, 48), 13);
        // Only every other frame is a master: 51 pending does not count.
        assert_eq!(first_needed_frame([49, 51], |f| f <= 50, 2, 10), 43);
        assert_eq!(first_needed_frame(0..60, done, 1, 0), 0, "window 0 keeps every frame");
        assert_eq!(first_needed_frame([], done, 1, 48), 0);
        assert_eq!(first_needed_frame(0..10, |_| false, 1, 48), 0, "early frames: nothing to let go");
    }
    use lineflow_runtime::StageParams;

    #[test]
    fn parameters_out_of_range_are_refused_by_name() {
        assert!(MatchParams::default().validate().is_ok());
        let no_masters = MatchParams {
            master_every: 0,
            ..MatchParams::default()
        };
        let no_slaves = MatchParams {
            max_slaves: 0,
            ..MatchParams::default()
        };
        let front_behind = MatchParams {
            front_reach_m: -0.1,
            ..MatchParams::default()
        };
        for (params, name) in [
            (no_masters, "master_every"),
            (no_slaves, "max_slaves"),
            (front_behind, "front_reach_m"),
        ] {
            let e = params.validate().unwrap_err();
            assert_eq!(e.name, name, "{e}");
        }
    }
}
