//! Structure or texture: which 3-D lines are edges of the building and which lie inside a surface.
//!
//! A brick, tiled or panelled wall gives the line stages ten lines of its joints for every edge of the building,
//! and all of them are real lines of the images. What sets a joint apart is its company: it lies in a field of
//! parallel lines like it, spread in one surface on both sides of it (the courses above and below), and it meets no
//! line across it at a corner. An edge of the building has one side that is no such field (a window head has the
//! wall's courses above it and the opening below; an eaves line the wall below and the roof above, not in the
//! wall's surface), or it turns a corner with another edge (an opening's outline, a reveal, a frame).
//!
//! A joint also shows less steadily: its contrast is weak and it looks like its neighbours, so the 2-D segments
//! of most images that see it miss it or break it, and where the line stages matched it one course off, no other
//! image agrees with its wrong depth. An edge of the building shows in nearly every image that sees it. With the
//! cameras at hand ([`Sight`]), a line that fewer than `min_support` of the images seeing it show is texture too,
//! unless it turns a corner with a line that passes.
//!
//! Where the line stages placed a joint at a wrong depth behind its wall (a horizontal line's depth from two strips
//! a few metres apart is open to decimetres), it has no field of its own, yet the wall's courses still lie on both
//! sides of it, between it and the cameras: no image could see a line there through a solid wall. With the cameras
//! at hand and `behind_m` set, such a line is texture (off by default: it costs the model openings). A recessed
//! edge inside an opening has the courses on one side at most (a head below them, a sill above them) or none (a
//! transom).
//!
//! Measured at scale 0.3 (docs/lines3d.md, "Structure and texture"): 48–65 % of the lines of brick façades are
//! classed texture by their field, of which 0.1–0.5 % are true edges; plaster façades have next to none.
use lineflow_messages::LineClass;
use lineflow_photogrammetry::{Camera, Pose, Vec3};

use crate::grid::Grid;

/// The settings of the classing: the `class` parameter of the line stages, a table
/// (`class = { neighbours = 6, reach_m = 0.3 }`; what it leaves out keeps its default).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClassRule {
    /// A field: at least this many parallel lines around a line, half of them on each side of it.
    pub neighbours: usize,
    /// How far across the line (in the field's surface) its neighbours lie at most, metres.
    pub reach_m: f64,
    /// How far out of the field's surface they lie at most, metres: a window's frame 15 cm behind the courses
    /// above its head is no part of their field.
    pub band_m: f64,
    /// An end within this distance of an end of a line across it (more than 60° apart) is a corner, metres.
    pub corner_m: f64,
    /// Lines within this angle are parallel, degrees.
    pub parallel_deg: f64,
    /// With the cameras known: the smallest share of the images that see a line (both ends in the frame) which
    /// must show it (`n_images`) for it to be structure, unless it turns a corner with a line that passes;
    /// 0 turns the test off.
    pub min_support: f64,
    /// With the cameras known: a line lying behind a field (between it and the cameras, more than half of
    /// `band_m` and at most this far behind it) is texture, metres; 0, the default, turns the test off (it costs
    /// the model openings, docs/lines3d.md "Behind a field"; 0.6 is the measured setting).
    pub behind_m: f64,
    /// A line across reaching past another's line by more than this meets it at its side, not at a corner,
    /// metres: less than half a brick course (7.5 cm), more than the placing error of a level edge's height.
    pub overshoot_m: f64,
}

impl Default for ClassRule {
    fn default() -> Self {
        ClassRule {
            neighbours: 6,
            reach_m: 0.3,
            band_m: 0.1,
            corner_m: 0.15,
            parallel_deg: 8.0,
            min_support: 0.67,
            behind_m: 0.0,
            overshoot_m: 0.03,
        }
    }
}

/// A setting of a [`ClassRule`] out of its range: its name (as in the launch file), what it must be, and the
/// value given.
#[derive(Debug, Clone, PartialEq)]
pub struct RuleError {
    /// The setting, `class.NAME`.
    pub name: String,
    /// What it must be.
    pub requirement: &'static str,
    /// What was given.
    pub value: String,
}

impl RuleError {
    /// The error of setting `TABLE.NAME` of a line stage's parameters.
    pub fn of(table: &str, name: &str, requirement: &'static str, value: String) -> Self {
        RuleError {
            name: format!("{table}.{name}"),
            requirement,
            value,
        }
    }
}

impl ClassRule {
    /// `Ok` for a rule whose numbers make sense, else the first setting that does not.
    pub fn validate(&self) -> Result<(), RuleError> {
        let bad = |name: &str, requirement: &'static str, value: String| Err(RuleError::of("class", name, requirement, value));
        if !(self.behind_m.is_finite() && self.behind_m >= 0.0) {
            return bad("behind_m", ">= 0", self.behind_m.to_string());
        }
        for (name, v) in [
            ("reach_m", self.reach_m),
            ("band_m", self.band_m),
            ("corner_m", self.corner_m),
            ("overshoot_m", self.overshoot_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(name, "> 0", v.to_string());
            }
        }
        if !(self.parallel_deg > 0.0 && self.parallel_deg < 45.0) {
            return bad("parallel_deg", "in (0, 45)", self.parallel_deg.to_string());
        }
        if !(0.0..=1.0).contains(&self.min_support) {
            return bad("min_support", "in [0, 1]", self.min_support.to_string());
        }
        if self.neighbours < 2 {
            return bad("neighbours", ">= 2", self.neighbours.to_string());
        }
        Ok(())
    }
}

/// Two lines closer than this across are one edge seen twice, not two lines of a field, metres.
const SAME_LINE_M: f64 = 0.01;

/// Lines more than 60° apart meet at a corner.
const CORNER_COS: f64 = 0.5;

/// The cameras of a set of lines: each line's support is measured against the images whose frame holds it.
#[derive(Debug, Clone, Copy)]
pub struct Sight<'a> {
    /// The camera of every image.
    pub camera: &'a Camera,
    /// The images' poses.
    pub poses: &'a [Pose],
}

impl Sight<'_> {
    /// How many of the images see the segment: both ends in front of the camera and inside the frame.
    pub fn images_seeing(&self, line: &[Vec3; 2]) -> u32 {
        let inside = |pose: &Pose, p: &Vec3| pose.project(self.camera, p).is_some_and(|px| self.camera.contains(px, 0.0));
        self.poses.iter().filter(|pose| line.iter().all(|p| inside(pose, p))).count() as u32
    }

    /// The mean of the cameras' centres, if there are any.
    pub fn mean_center(&self) -> Option<Vec3> {
        (!self.poses.is_empty()).then(|| self.poses.iter().map(|p| p.center).sum::<Vec3>() / self.poses.len() as f64)
    }

    /// Metres per pixel at `point` in the nearest of the images (infinite with none).
    pub fn metres_per_px(&self, point: &Vec3) -> f64 {
        let nearest = self
            .poses
            .iter()
            .map(|pose| (point - pose.center).norm())
            .fold(f64::INFINITY, f64::min);
        nearest * self.camera.pixel_size_mm / self.camera.focal_mm
    }
}

/// The class of each segment `[start, end]` (object coordinates, metres) by its neighbours alone. Independent of
/// the order of the lines.
pub fn classify(lines: &[[Vec3; 2]], rule: &ClassRule) -> Vec<LineClass> {
    by_field(lines, rule).0
}

/// [`classify`], and the grid of the lines it searched (cells of `reach_m` or `corner_m`, whichever is larger).
fn by_field(lines: &[[Vec3; 2]], rule: &ClassRule) -> (Vec<LineClass>, Grid) {
    let grid = Grid::of(lines, rule.reach_m.max(rule.corner_m));
    let mut seen = vec![usize::MAX; lines.len()];
    let mut near = Vec::new();
    let class = (0..lines.len())
        .map(|k| {
            let Some(u) = direction(&lines[k]) else {
                return LineClass::Structure;
            };
            near.clear();
            grid.near(&lines[k], k, &mut seen, &mut near);
            let texture = in_a_field(lines, k, &u, &near, rule) && !turns_a_corner(lines, k, &u, &near, rule);
            if texture {
                LineClass::Texture
            } else {
                LineClass::Structure
            }
        })
        .collect();
    (class, grid)
}

/// The class of each segment by its neighbours and, with `sight`, by its support: `shown[k]` images show line
/// `k` (its `n_images`); a structure line shown by fewer than `min_support` of the images that see it becomes
/// texture, unless an end of it lies within `corner_m` of an end of a line across it that keeps its class.
pub fn classify_supported(lines: &[[Vec3; 2]], shown: &[u32], sight: Option<Sight>, rule: &ClassRule) -> Vec<LineClass> {
    let (mut class, grid) = by_field(lines, rule);
    if let Some(cameras) = sight.filter(|_| rule.behind_m > 0.0).and_then(|s| s.mean_center()) {
        hidden_behind_fields(lines, &mut class, &cameras, rule);
    }
    let Some(sight) = sight.filter(|_| rule.min_support > 0.0) else {
        return class;
    };
    let weak: Vec<bool> = lines
        .iter()
        .zip(&class)
        .zip(shown)
        .map(|((l, c), &n)| *c == LineClass::Structure && (n as f64) < rule.min_support * sight.images_seeing(l) as f64)
        .collect();
    // The field's grid serves: its cells are at least `corner_m`.
    let mut seen = vec![usize::MAX; lines.len()];
    let mut near = Vec::new();
    for k in (0..lines.len()).filter(|&k| weak[k]) {
        let Some(u) = direction(&lines[k]) else { continue };
        near.clear();
        grid.near(&lines[k], k, &mut seen, &mut near);
        near.retain(|&j| class[j] == LineClass::Structure && !weak[j]);
        // Any meeting will do here: a line deep in a reveal, hidden from the oblique images, takes its class from
        // the frame or head it meets, a T as much as an L.
        if !meets_an_end_across(lines, k, &u, &near, rule, |_, _, _| true) {
            class[k] = LineClass::Texture;
        }
    }
    class
}

/// Classes a stage's `Line3` elements in place, by their support too when `sight` is given.
pub fn classify_elements(lines: &mut [lineflow_messages::Line3], rule: &ClassRule, sight: Option<Sight>) {
    let segments: Vec<[Vec3; 2]> = lines.iter().map(|l| [Vec3::from(l.start_m), Vec3::from(l.end_m)]).collect();
    let shown: Vec<u32> = lines.iter().map(|l| l.n_images).collect();
    for (l, c) in lines.iter_mut().zip(classify_supported(&segments, &shown, sight, rule)) {
        l.class = c.code();
    }
}

fn direction(l: &[Vec3; 2]) -> Option<Vec3> {
    let d = l[1] - l[0];
    let n = d.norm();
    (n > 1e-9).then(|| d / n)
}

/// The offsets across line `k` (in [`across_basis`] of its direction `u`, from its start) of the midpoints of its
/// parallel neighbours among `near` that overlap it along its length, within `reach` of it.
fn parallel_offsets(lines: &[[Vec3; 2]], k: usize, u: &Vec3, near: &[usize], rule: &ClassRule, reach: f64) -> Vec<[f64; 2]> {
    let [a, b] = lines[k];
    let length = (b - a).norm();
    let cos = rule.parallel_deg.to_radians().cos();
    let (e1, e2) = across_basis(u);
    near.iter()
        .filter_map(|&j| {
            let [p, q] = lines[j];
            let v = direction(&lines[j])?;
            let (tp, tq) = ((p - a).dot(u), (q - a).dot(u));
            let overlaps = tp.min(tq).max(0.0) < tp.max(tq).min(length);
            let w = (p + q) / 2.0 - a;
            let off = [w.dot(&e1), w.dot(&e2)];
            (v.dot(u).abs() >= cos && overlaps && off[0].hypot(off[1]) <= reach).then_some(off)
        })
        .collect()
}

/// Whether line `k` lies in a field: its parallel neighbours that overlap it along its length lie in one surface
/// through it (the principal direction of their offsets across it), within `reach_m` on both sides and `band_m`
/// out of that surface, at least half of `neighbours` on each side.
fn in_a_field(lines: &[[Vec3; 2]], k: usize, u: &Vec3, near: &[usize], rule: &ClassRule) -> bool {
    let mut offsets = parallel_offsets(lines, k, u, near, rule, rule.reach_m.hypot(rule.band_m));
    offsets.retain(|o| o[0].hypot(o[1]) > SAME_LINE_M);
    let half = rule.neighbours.div_ceil(2);
    if offsets.len() < 2 * half {
        return false;
    }
    // The field's surface: the principal axis of the offsets' second moments (about the line itself).
    let (sxx, sxy, syy) = offsets.iter().fold((0.0, 0.0, 0.0), |(xx, xy, yy), o| {
        (xx + o[0] * o[0], xy + o[0] * o[1], yy + o[1] * o[1])
    });
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let (along, out) = ([angle.cos(), angle.sin()], [-angle.sin(), angle.cos()]);
    let (mut one_side, mut other_side) = (0, 0);
    for o in &offsets {
        let (x, y) = (o[0] * along[0] + o[1] * along[1], o[0] * out[0] + o[1] * out[1]);
        if y.abs() <= rule.band_m && x.abs() <= rule.reach_m && x.abs() > SAME_LINE_M {
            if x > 0.0 {
                one_side += 1;
            } else {
                other_side += 1;
            }
        }
    }
    one_side.min(other_side) >= half
}

/// The structure lines that lie behind a field, seen from `cameras`, become texture ([`behind_a_field`]).
fn hidden_behind_fields(lines: &[[Vec3; 2]], class: &mut [LineClass], cameras: &Vec3, rule: &ClassRule) {
    use rayon::prelude::*;
    let grid = Grid::of(lines, rule.reach_m.max(rule.behind_m));
    let structure: Vec<usize> = (0..lines.len()).filter(|&k| class[k] == LineClass::Structure).collect();
    let hidden: Vec<usize> = structure
        .par_iter()
        .map_init(
            || (vec![usize::MAX; lines.len()], Vec::new()),
            |(seen, near), &k| {
                let u = direction(&lines[k])?;
                near.clear();
                grid.near(&lines[k], k, seen, near);
                behind_a_field(lines, k, &u, near, cameras, rule).then_some(k)
            },
        )
        .flatten()
        .collect();
    for k in hidden {
        class[k] = LineClass::Texture;
    }
}

/// Whether line `k` lies behind a field seen from `cameras`: parallel lines overlapping it along its length, at
/// least half of `neighbours` on each side of it within `reach_m` along one surface through its
/// direction (within a quarter of `band_m` of it), with the line more than half of `band_m` and at most `behind_m`
/// behind that surface, on the side away from the cameras. The surface is the one through two of the neighbours
/// that holds the most of them (the lines around a window hold a wall's courses and the recess's lines at once).
fn behind_a_field(lines: &[[Vec3; 2]], k: usize, u: &Vec3, near: &[usize], cameras: &Vec3, rule: &ClassRule) -> bool {
    let a = lines[k][0];
    let (e1, e2) = across_basis(u);
    let offsets = parallel_offsets(lines, k, u, near, rule, rule.reach_m.hypot(rule.behind_m));
    let half = rule.neighbours.div_ceil(2);
    if offsets.len() < 2 * half {
        return false;
    }
    let tight = rule.band_m / 4.0;
    // An offset's position along the surface through `o` with direction `along`, and its distance from it.
    let on = |r: &[f64; 2], o: &[f64; 2], along: &[f64; 2]| {
        let d = [r[0] - o[0], r[1] - o[1]];
        (d[0] * along[0] + d[1] * along[1], d[1] * along[0] - d[0] * along[1])
    };
    let mut best: Option<(usize, [f64; 2], [f64; 2])> = None;
    for (i, o) in offsets.iter().enumerate() {
        for q in &offsets[i + 1..] {
            let d = [q[0] - o[0], q[1] - o[1]];
            let n = d[0].hypot(d[1]);
            if n < 2.0 * SAME_LINE_M {
                continue;
            }
            let along = [d[0] / n, d[1] / n];
            let held = offsets.iter().filter(|r| on(r, o, &along).1.abs() <= tight).count();
            if best.is_none_or(|(h, _, _)| held > h) {
                best = Some((held, *o, along));
            }
        }
    }
    let Some((_, o, along)) = best.filter(|(held, _, _)| *held >= 2 * half) else {
        return false;
    };
    // The line itself is at offset (0, 0): its foot on the surface and its distance from it.
    let (foot, apart) = on(&[0.0, 0.0], &o, &along);
    if apart.abs() <= rule.band_m / 2.0 || apart.abs() > rule.behind_m {
        return false;
    }
    let (mut one_side, mut other_side) = (0, 0);
    for r in &offsets {
        let (x, y) = on(r, &o, &along);
        if y.abs() <= tight && (x - foot).abs() <= rule.reach_m {
            if x > foot {
                one_side += 1;
            } else if x < foot {
                other_side += 1;
            }
        }
    }
    if one_side.min(other_side) < half {
        return false;
    }
    // The surface's normal in space (`on`'s second coordinate); the line and the cameras on opposite sides of it.
    let normal = e2 * along[0] - e1 * along[1];
    let on_surface = a + e1 * o[0] + e2 * o[1];
    apart * (cameras - on_surface).dot(&normal) < 0.0
}

/// Two unit vectors completing `u` to an orthonormal frame.
fn across_basis(u: &Vec3) -> (Vec3, Vec3) {
    let helper = if u.z.abs() < 0.9 { Vec3::z() } else { Vec3::x() };
    let e1 = u.cross(&helper).normalize();
    (e1, u.cross(&e1))
}

/// Whether an end of line `k` is a corner: an end of a line across it (among `near`) lies within `corner_m`,
/// that line reaches no more than `overshoot_m` past `k`'s own line (a course meeting a jamb a course below its
/// top ends on the jamb's side, not at its corner), passes within `band_m` of it ([`apart`]), and its end is
/// where its edge ends, not a break in it (no other line among `near` continues it past the corner).
fn turns_a_corner(lines: &[[Vec3; 2]], k: usize, u: &Vec3, near: &[usize], rule: &ClassRule) -> bool {
    meets_an_end_across(lines, k, u, near, rule, |e, j, end| {
        overshoot(&lines[k], u, &lines[j], end) <= rule.overshoot_m
            && apart(&lines[k], u, &lines[j]) <= rule.band_m
            && !continued(lines, j, end, e, near, rule)
    })
}

/// How far apart two lines across each other pass (the distance of their infinite lines): a pier's course and
/// the frame's corner 12 cm behind it in the reveal end near each other, but do not meet; a sill's nose 6 cm
/// proud of the wall meets its jamb within the field's `band_m`.
fn apart(line: &[Vec3; 2], u: &Vec3, across: &[Vec3; 2]) -> f64 {
    let Some(v) = direction(across) else { return f64::INFINITY };
    let normal = u.cross(&v);
    let n = normal.norm();
    if n < 1e-9 {
        return f64::INFINITY;
    }
    ((across[0] - line[0]).dot(&normal) / n).abs()
}

/// Whether an end `e` of line `k` lies within `corner_m` of an end `end` of a line `j` across it (among
/// `across`) for which `also(e, j, end)` holds.
fn meets_an_end_across(
    lines: &[[Vec3; 2]],
    k: usize,
    u: &Vec3,
    across: &[usize],
    rule: &ClassRule,
    also: impl Fn(&Vec3, usize, usize) -> bool,
) -> bool {
    across.iter().any(|&j| {
        direction(&lines[j]).is_some_and(|v| v.dot(u).abs() < CORNER_COS)
            && lines[k]
                .iter()
                .any(|e| (0..2).any(|end| (e - lines[j][end]).norm() <= rule.corner_m && also(e, j, end)))
    })
}

/// How far end `end` of `across` lies past the line through `line` (direction `u`), measured outward along
/// `across`: negative where it stops short of it.
fn overshoot(line: &[Vec3; 2], u: &Vec3, across: &[Vec3; 2], end: usize) -> f64 {
    let Some(out) = outward(across, end) else { return 0.0 };
    // The across line's end relative to `line`, in the plane of `out` and `u`.
    off_line(&(across[end] - line[0]), u).dot(&out)
}

/// The direction of `line` out of its end `end` (from its other end towards it).
fn outward(line: &[Vec3; 2], end: usize) -> Option<Vec3> {
    direction(&[line[1 - end], line[end]])
}

/// The part of `w` across the direction `u`.
fn off_line(w: &Vec3, u: &Vec3) -> Vec3 {
    w - u * w.dot(u)
}

/// A break in an edge, not its end, is within this distance across of a line continuing it, metres. The line
/// stages break a long edge where images lose it (at full size a jamb comes in pieces of a few brick courses);
/// the next edge parallel to it, a reveal's other corner, lies 10 cm or more away.
const CONTINUES_M: f64 = 0.05;

/// Whether end `end` of line `j` is continued, for the line ending at `e`, by another line of `near`: parallel to
/// it, within [`CONTINUES_M`] of that end across, and either starting within `overshoot_m` of it and reaching
/// more than `corner_m` beyond it, or passing `e` by more than `overshoot_m` on both sides (a gap in the edge
/// beside which the line ends on the next piece's side). The next pane's edge across a glazing bar, 6 cm on,
/// passes no pane edge ending at the bar: it is another edge with corners of its own. A course of a pier between
/// windows ends on the window's jamb, whose pieces end anywhere along it: without this, every course ending near
/// the end of a piece would turn a corner.
fn continued(lines: &[[Vec3; 2]], j: usize, end: usize, e: &Vec3, near: &[usize], rule: &ClassRule) -> bool {
    let f = lines[j][end];
    let Some(out) = outward(&lines[j], end) else { return false };
    let cos = rule.parallel_deg.to_radians().cos();
    let at = (e - f).dot(&out);
    near.iter().any(|&m| {
        if m == j || !direction(&lines[m]).is_some_and(|v| v.dot(&out).abs() >= cos) {
            return false;
        }
        let (p, q) = (lines[m][0] - f, lines[m][1] - f);
        let (tp, tq) = (p.dot(&out), q.dot(&out));
        let (from, to) = (tp.min(tq), tp.max(tq));
        let runs_on = from <= rule.overshoot_m && to > rule.corner_m;
        let passes_e = from <= at - rule.overshoot_m && to >= at + rule.overshoot_m;
        (runs_on || passes_e) && off_line(&p, &out).norm().max(off_line(&q, &out).norm()) <= CONTINUES_M
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn level(x0: f64, x1: f64, y: f64, z: f64) -> [Vec3; 2] {
        [Vec3::new(x0, y, z), Vec3::new(x1, y, z)]
    }

    fn plumb(x: f64, y: f64, z0: f64, z1: f64) -> [Vec3; 2] {
        [Vec3::new(x, y, z0), Vec3::new(x, y, z1)]
    }

    /// Brick courses every 7.5 cm from z = 0 to 3 m on a wall at y = 0, x from 0 to 10 m.
    fn courses() -> Vec<[Vec3; 2]> {
        (0..=40).map(|i| level(0.0, 10.0, 0.0, 0.075 * i as f64)).collect()
    }

    #[test]
    fn courses_inside_a_wall_are_texture_and_the_outermost_are_not() {
        let lines = courses();
        let class = classify(&lines, &ClassRule::default());
        // Three courses on each side are needed: the three at the top and the bottom have fewer on one side.
        for (i, c) in class.iter().enumerate() {
            let want = if (3..=37).contains(&i) {
                LineClass::Texture
            } else {
                LineClass::Structure
            };
            assert_eq!(*c, want, "course {i}");
        }
    }

    #[test]
    fn a_window_outline_in_a_brick_wall_is_structure() {
        // Courses cut by a window from x = 4 to 5.4 m, z = 0.9 to 2.4 m; the window's outline and its reveals.
        let mut lines: Vec<[Vec3; 2]> = Vec::new();
        for i in 0..=40 {
            let z = 0.075 * i as f64;
            if (0.9..=2.4).contains(&z) {
                lines.push(level(0.0, 4.0, 0.0, z));
                lines.push(level(5.4, 10.0, 0.0, z));
            } else {
                lines.push(level(0.0, 10.0, 0.0, z));
            }
        }
        let outline = lines.len();
        lines.extend([
            level(4.0, 5.4, 0.0, 0.9),
            level(4.0, 5.4, 0.0, 2.4),
            plumb(4.0, 0.0, 0.9, 2.4),
            plumb(5.4, 0.0, 0.9, 2.4),
        ]);
        let reveals = lines.len();
        for [x, z] in [[4.0, 0.9], [5.4, 0.9], [4.0, 2.4], [5.4, 2.4]] {
            lines.push([Vec3::new(x, 0.0, z), Vec3::new(x, 0.2, z)]);
        }
        let class = classify(&lines, &ClassRule::default());
        for (k, c) in class.iter().enumerate().skip(outline) {
            assert_eq!(*c, LineClass::Structure, "line {k} of the window (reveals from {reveals})");
        }
        // The courses well away from the window stay texture.
        assert_eq!(class[5], LineClass::Texture);
    }

    #[test]
    fn lines_behind_or_before_the_courses_are_not_their_field() {
        // A frame's three parallel edges 15 cm behind a course wall: the course beside them still has its field,
        // the frame's middle edge has neighbours on both sides but only three, and none in the courses' surface.
        let mut lines = courses();
        let frame = lines.len();
        lines.extend([level(2.0, 3.0, 0.15, 1.45), level(2.0, 3.0, 0.15, 1.5), level(2.0, 3.0, 0.15, 1.55)]);
        let class = classify(&lines, &ClassRule::default());
        assert_eq!(class[frame + 1], LineClass::Structure);
        assert_eq!(class[20], LineClass::Texture);
    }

    #[test]
    fn a_field_in_any_plane_counts_and_the_order_of_the_lines_does_not_matter() {
        // A roof's tile rows on a 35° slope, along a façade 30° off the axes, 4,000 m from the origin.
        let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let along = Vec3::new(c, s, 0.0);
        let up_slope = Vec3::new(-s, c, 0.0) * 35f64.to_radians().cos() + Vec3::z() * 35f64.to_radians().sin();
        let origin = Vec3::new(4000.0, -2500.0, 12.0);
        let rows: Vec<[Vec3; 2]> = (0..20)
            .map(|i| {
                let p = origin + up_slope * (0.08 * i as f64);
                [p, p + along * 6.0]
            })
            .collect();
        let class = classify(&rows, &ClassRule::default());
        assert_eq!(class[10], LineClass::Texture);
        assert_eq!(class[0], LineClass::Structure);
        let mut reversed = rows.clone();
        reversed.reverse();
        let mut back = classify(&reversed, &ClassRule::default());
        back.reverse();
        assert_eq!(back, class);
    }

    #[test]
    fn a_line_behind_the_courses_is_texture_seen_from_the_cameras_and_a_recessed_head_or_sill_is_not() {
        let strip = Strip::new();
        let sight = strip.sight();
        // Courses cut by a window from x = 4 to 5.4 m, z = 0.9 to 2.4 m.
        let mut lines: Vec<[Vec3; 2]> = Vec::new();
        for l in courses() {
            if (0.9..=2.4).contains(&l[0].z) {
                lines.extend([level(0.0, 4.0, 0.0, l[0].z), level(5.4, 10.0, 0.0, l[0].z)]);
            } else {
                lines.push(l);
            }
        }
        // A joint matched at a wrong depth, 20 cm behind the wall; the same 20 cm in front of it (a line there
        // could be seen); the recess's head and sill 25 cm behind the wall, the courses above the head only and
        // below the sill only.
        let first = lines.len();
        lines.extend([level(2.0, 3.0, 0.2, 1.5), level(2.0, 3.0, -0.2, 1.5)]);
        let recess = lines.len();
        lines.extend([level(4.0, 5.4, 0.25, 2.4), level(4.0, 5.4, 0.25, 0.9)]);
        let shown = vec![9; lines.len()];
        let rule = ClassRule {
            behind_m: 0.6,
            ..ClassRule::default()
        };
        let class = classify_supported(&lines, &shown, Some(sight), &rule);
        assert_eq!(class[first], LineClass::Texture, "behind the wall");
        assert_eq!(class[first + 1], LineClass::Structure, "in front of the wall");
        assert_eq!(class[recess], LineClass::Structure, "the recess's head");
        assert_eq!(class[recess + 1], LineClass::Structure, "the recess's sill");
        // Without the cameras there is no behind; with the test off (the default), none either.
        assert_eq!(classify(&lines, &rule)[first], LineClass::Structure);
        assert_eq!(
            classify_supported(&lines, &shown, Some(sight), &ClassRule::default())[first],
            LineClass::Structure
        );
        // Farther behind than `behind_m`: another surface (a courtyard's wall seen over a low one), not hidden.
        let far = ClassRule {
            behind_m: 0.15,
            ..ClassRule::default()
        };
        assert_eq!(classify_supported(&lines, &shown, Some(sight), &far)[first], LineClass::Structure);
    }

    #[test]
    fn a_course_that_ends_at_a_corner_is_structure_and_one_that_runs_past_a_line_is_not() {
        let mut lines = courses();
        // A plumb line whose end meets the 20th course's end: a corner. One crossing the 10th in its middle: no
        // corner (a course runs past a pilaster's edge).
        lines.push(plumb(10.0, 0.0, 1.5, 3.5));
        lines.push(plumb(5.0, 0.0, 0.5, 1.0));
        let class = classify(&lines, &ClassRule::default());
        assert_eq!(class[20], LineClass::Structure);
        assert_eq!(class[10], LineClass::Texture);
    }

    #[test]
    fn courses_ending_on_a_jamb_in_pieces_below_its_top_or_beside_a_frame_turn_no_corner() {
        // A pier's courses (x 0 to 2 m, up to the head at 2.46 m) end on the window's jamb at x = 2, which the
        // line stages found in pieces of 0.41 m; the courses above the head run on over the opening.
        let head_z = 2.46;
        let mut lines: Vec<[Vec3; 2]> = (0..=40)
            .map(|i| 0.075 * i as f64)
            .map(|z| {
                if z < head_z {
                    level(0.0, 2.0, 0.0, z)
                } else {
                    level(0.0, 3.4, 0.0, z)
                }
            })
            .collect();
        let pieces: Vec<[Vec3; 2]> = (0..6).map(|i| plumb(2.0, 0.0, 0.41 * i as f64, 0.41 * (i + 1) as f64)).collect();
        lines.extend(pieces);
        let head = lines.len();
        lines.push(level(2.0, 3.4, 0.0, head_z));
        let class = classify(&lines, &ClassRule::default());
        // 0.375 m ends 3.5 cm from a piece's end; 2.4 m is the last course below the jamb's top.
        for (course, z) in [(5, 0.375), (11, 0.825), (32, 2.4)] {
            assert!((lines[course][0].z - z).abs() < 1e-9);
            assert_eq!(class[course], LineClass::Texture, "course at {z} m");
        }
        assert_eq!(class[head], LineClass::Structure);
        // The same pier with the jamb in one piece: the courses' ends along it are no corners either.
        let mut whole = lines[..=40].to_vec();
        whole.push(plumb(2.0, 0.0, 0.0, head_z));
        let class = classify(&whole, &ClassRule::default());
        assert_eq!(class[5], LineClass::Texture);
        assert_eq!(class[32], LineClass::Texture);
        // The jamb in pieces with gaps of 6 cm between them: the course at 0.525 m ends on the second piece's side,
        // 14.5 cm above the first piece's top.
        let mut gapped = lines[..=40].to_vec();
        gapped.extend((0..6).map(|i| plumb(2.0, 0.0, 0.44 * i as f64, 0.44 * i as f64 + 0.38)));
        assert_eq!(classify(&gapped, &ClassRule::default())[7], LineClass::Texture);
        // A frame's corner 12 cm back in the reveal, starting at the 16th course's end: near, but they never meet;
        // a jamb at the wall's face starting there is the course's corner.
        let mut framed = lines[..=40].to_vec();
        framed.push(plumb(2.0, 0.12, 1.2, 2.0));
        assert_eq!(classify(&framed, &ClassRule::default())[16], LineClass::Texture);
        framed.push(plumb(2.0, 0.0, 1.2, 2.0));
        assert_eq!(classify(&framed, &ClassRule::default())[16], LineClass::Structure);
    }

    /// Nine cameras 20 m in front of the wall y = 0, one every metre along it, looking at it.
    struct Strip {
        camera: Camera,
        poses: Vec<Pose>,
    }

    impl Strip {
        fn new() -> Strip {
            let poses = (0..9)
                .map(|k| Pose {
                    center: Vec3::new(1.0 + k as f64, -20.0, 1.5),
                    rotation: lineflow_photogrammetry::rotation_from_opk(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
                })
                .collect();
            Strip {
                camera: Camera::pinhole(4000, 3000, 0.005, 20.0),
                poses,
            }
        }

        fn sight(&self) -> Sight<'_> {
            Sight {
                camera: &self.camera,
                poses: &self.poses,
            }
        }
    }

    #[test]
    fn lines_few_of_the_images_seeing_them_show_are_texture_unless_they_turn_a_corner_with_one_that_passes() {
        let strip = Strip::new();
        let sight = strip.sight();
        // Two courses alone (no field around them), a window head and its jamb meeting at a corner, and a short
        // piece of a sill meeting the jamb's other end.
        let lines = vec![
            level(1.0, 3.0, 0.0, 0.3),
            level(6.0, 8.0, 0.0, 0.375),
            level(4.0, 5.4, 0.0, 2.4),
            plumb(5.4, 0.0, 0.9, 2.4),
            level(5.0, 5.4, 0.0, 0.9),
        ];
        assert!(lines.iter().all(|l| sight.images_seeing(l) == 9));
        let shown = [2, 9, 9, 8, 3];
        let by_field = classify(&lines, &ClassRule::default());
        assert!(by_field.iter().all(|c| *c == LineClass::Structure));
        let class = classify_supported(&lines, &shown, Some(sight), &ClassRule::default());
        use LineClass::{Structure, Texture};
        assert_eq!(class, vec![Texture, Structure, Structure, Structure, Structure]);
        // The sill piece owes its class to the jamb: a weak jamb keeps its own by the head, but lends none.
        let class = classify_supported(&lines, &[2, 9, 9, 3, 3], Some(sight), &ClassRule::default());
        assert_eq!(class, vec![Texture, Structure, Structure, Structure, Texture]);
        // Off: no cameras, or no share asked for.
        assert_eq!(classify_supported(&lines, &shown, None, &ClassRule::default()), by_field);
        let off = ClassRule {
            min_support: 0.0,
            ..ClassRule::default()
        };
        assert_eq!(classify_supported(&lines, &shown, Some(sight), &off), by_field);
    }

    #[test]
    fn a_line_no_image_sees_is_never_weak() {
        let strip = Strip::new();
        let sight = strip.sight();
        // 40 m up the wall, out of every frame; and behind the cameras.
        let lines = vec![level(1.0, 3.0, 0.0, 40.0), level(1.0, 3.0, -30.0, 1.0)];
        assert!(lines.iter().all(|l| sight.images_seeing(l) == 0));
        let class = classify_supported(&lines, &[0, 0], Some(sight), &ClassRule::default());
        assert!(class.iter().all(|c| *c == LineClass::Structure));
    }

    #[test]
    fn degenerate_lines_and_bad_rules_are_handled() {
        let lines = vec![[Vec3::zeros(), Vec3::zeros()]];
        assert_eq!(classify(&lines, &ClassRule::default()), vec![LineClass::Structure]);
        assert!(classify(&[], &ClassRule::default()).is_empty());
        let bad = ClassRule {
            reach_m: f64::NAN,
            ..ClassRule::default()
        };
        assert_eq!(bad.validate().unwrap_err().name, "class.reach_m");
        let bad = ClassRule {
            neighbours: 1,
            ..ClassRule::default()
        };
        assert!(bad.validate().is_err());
        let bad = ClassRule {
            min_support: 1.5,
            ..ClassRule::default()
        };
        assert_eq!(bad.validate().unwrap_err().name, "class.min_support");
        let bad = ClassRule {
            behind_m: -0.1,
            ..ClassRule::default()
        };
        assert_eq!(bad.validate().unwrap_err().name, "class.behind_m");
        assert!(ClassRule::default().validate().is_ok());
    }
}
