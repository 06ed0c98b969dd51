//! Line tracing (seed 000 §2.7): from a seed edge pixel, follow 8-neighbours that stay within a
//! perpendicular distance of the current line (through the first two pixels, then the total-least-squares line
//! of all once more than three are stacked), in both directions, and keep chains of a minimum length. Lines are
//! fitted in **corrected** coordinates, so a straight edge bent by distortion stays one segment. Beyond the thesis,
//! collinear fragments (broken at junctions, where a pixel can belong to one chain only) are joined across small gaps.
#![warn(missing_docs)]

pub mod lsd;
pub mod stage;

use lineflow_runtime::params::{self, ParamError};
use rayon::prelude::*;

/// Tracing parameters (the `trace` implementation's launch-file parameters).
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TraceParams {
    /// Largest perpendicular distance of a new pixel from the current line, pixels.
    pub max_distance_px: f64,
    /// Shortest segment kept, pixels (the thesis: 100 for the D2X, 50 for the A55, at full size).
    pub min_length_px: f64,
    /// Collinear fragments closer than this along their line are joined (0 = the thesis's tracing alone).
    pub max_gap_px: f64,
    /// Largest angle between fragments that are joined, degrees.
    pub max_merge_angle_deg: f64,
    /// A chain that finds no next pixel beside its end looks this far ahead along its line for one (0 or 1 = no
    /// jumps): edges cut by junctions or weak for a few pixels stay whole.
    pub max_jump_px: f64,
}

impl Default for TraceParams {
    fn default() -> Self {
        TraceParams {
            max_distance_px: 1.0,
            min_length_px: 20.0,
            // Off by default: on the full-size d2x-strip joining at 4 px raised recall from 48.9 % to 50.9 % but
            // cost 2.6x the time (brick texture leaves hundreds of thousands of short fragments to consider).
            max_gap_px: 0.0,
            max_merge_angle_deg: 2.0,
            // Off by default: on the full-size d2x-strip 3 px raised recall from 84.5 % to 85.6 %, but brick
            // courses, cut every few pixels by the vertical joints, then become wall-long lines (30,000 segments
            // became 4,300) and the 3-D line stage's first master took 20 s instead of 5 (docs/lines2d.md).
            max_jump_px: 0.0,
        }
    }
}

/// Longer jumps would join unrelated edges that happen to line up.
pub const MAX_JUMP_PX: f64 = 32.0;

impl lineflow_runtime::StageParams for TraceParams {
    fn validate(&self) -> Result<(), ParamError> {
        params::positive("max_distance_px", self.max_distance_px)?;
        params::non_negative("min_length_px", self.min_length_px)?;
        params::non_negative("max_gap_px", self.max_gap_px)?;
        params::in_half_open("max_merge_angle_deg", self.max_merge_angle_deg, 0.0, 90.0)?;
        params::in_closed("max_jump_px", self.max_jump_px, 0.0, MAX_JUMP_PX)
    }
}

/// The `lsd` implementation's launch-file parameters.
#[derive(Debug, Clone, Copy, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LsdParams {
    /// Shortest segment kept, pixels.
    pub min_length_px: f64,
}

impl Default for LsdParams {
    fn default() -> Self {
        LsdParams {
            min_length_px: TraceParams::default().min_length_px,
        }
    }
}

impl lineflow_runtime::StageParams for LsdParams {
    fn validate(&self) -> Result<(), ParamError> {
        params::non_negative("min_length_px", self.min_length_px)
    }
}

/// A traced segment: its chain of pixels from one end to the other and its endpoints in corrected coordinates.
#[derive(Debug, Clone, PartialEq)]
pub struct Traced {
    /// (col, row) of every pixel, ordered along the segment.
    pub chain: Vec<[u16; 2]>,
    /// First endpoint, corrected pixel coordinates (the chain's first pixel projected on the fitted line).
    pub start: [f64; 2],
    /// Second endpoint, corrected pixel coordinates.
    pub end: [f64; 2],
}

/// Running sums of a total-least-squares line.
#[derive(Debug, Clone, Copy, Default)]
struct Fit {
    n: f64,
    sx: f64,
    sy: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
}

impl Fit {
    fn add(&mut self, p: [f64; 2]) {
        self.n += 1.0;
        self.sx += p[0];
        self.sy += p[1];
        self.sxx += p[0] * p[0];
        self.sxy += p[0] * p[1];
        self.syy += p[1] * p[1];
    }
    /// Centroid and unit direction of the principal axis.
    fn line(&self) -> ([f64; 2], [f64; 2]) {
        let c = [self.sx / self.n, self.sy / self.n];
        let a = self.sxx / self.n - c[0] * c[0];
        let b = self.sxy / self.n - c[0] * c[1];
        let d = self.syy / self.n - c[1] * c[1];
        // The major eigenvector of [[a, b], [b, d]] without trigonometry (this runs once per traced pixel):
        // (b, λ − a) or (λ − d, b), whichever is better conditioned.
        let lambda = 0.5 * (a + d) + (0.25 * (a - d) * (a - d) + b * b).sqrt();
        let (u, v) = if a >= d { (lambda - d, b) } else { (b, lambda - a) };
        let n = (u * u + v * v).sqrt();
        if n > 0.0 {
            (c, [u / n, v / n])
        } else {
            (c, [1.0, 0.0])
        }
    }
}

/// The current constraint line: through the first two stacked pixels until more than three are stacked, then
/// the fit.
fn constraint(first_two: &[[f64; 2]; 2], fit: &Fit) -> Option<([f64; 2], [f64; 2])> {
    match fit.n as usize {
        0 | 1 => None,
        2..=3 => {
            let (a, b) = (first_two[0], first_two[1]);
            let d = [b[0] - a[0], b[1] - a[1]];
            let n = (d[0] * d[0] + d[1] * d[1]).sqrt();
            (n > 0.0).then(|| (a, [d[0] / n, d[1] / n]))
        }
        _ => Some(fit.line()),
    }
}

/// Distance of `q` from the line through `o` with unit direction `d`.
fn off_line(q: [f64; 2], o: [f64; 2], d: [f64; 2]) -> f64 {
    ((q[0] - o[0]) * d[1] - (q[1] - o[1]) * d[0]).abs()
}

const NEIGHBOURS: [(i32, i32); 8] = [(1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1)];

/// Horizontal bands of rows traced in parallel; fixed, so that the result does not depend on the thread count.
const BANDS: usize = 8;

/// Traces the edge pixels (`pixels`, in raster order) of a `width × height` image. `corrected[i]` holds the
/// corrected coordinates of `pixels[i]`.
///
/// The image is traced in [`BANDS`] bands of rows in parallel; a chain that crosses from one band into the next is
/// traced as two fragments, joined again where they continue each other across the boundary.
pub fn trace(width: usize, height: usize, pixels: &[[u16; 2]], corrected: &[[f64; 2]], p: &TraceParams) -> Vec<Traced> {
    let sorted = pixels.windows(2).all(|w| (w[0][1], w[0][0]) <= (w[1][1], w[1][0]));
    let bands = if sorted { BANDS.min(height.max(1)) } else { 1 };
    let edges: Vec<usize> = (0..=bands).map(|b| b * height / bands).collect();
    // Pixels are in raster order, so each band's pixels are one range of them.
    let ranges: Vec<std::ops::Range<usize>> = edges
        .windows(2)
        .map(|e| {
            if !sorted {
                return 0..pixels.len();
            }
            pixels.partition_point(|q| (q[1] as usize) < e[0])..pixels.partition_point(|q| (q[1] as usize) < e[1])
        })
        .collect();
    let per_band: Vec<Vec<Fragment>> = (0..bands)
        .into_par_iter()
        .map(|b| trace_band(width, edges[b]..edges[b + 1], pixels, ranges[b].clone(), corrected, p))
        .collect();
    let fragments = join_across_bands(per_band, &edges, pixels, corrected, p);
    let fragments = if p.max_gap_px > 0.0 {
        merge_collinear(fragments, corrected, p)
    } else {
        fragments
    };
    fragments
        .into_par_iter()
        .filter(|f| f.t1 - f.t0 >= p.min_length_px)
        .map(|f| f.ordered(corrected))
        .map(|f| Traced {
            start: f.at(f.t0),
            end: f.at(f.t1),
            chain: f.chain.iter().map(|&i| pixels[i as usize]).collect(),
        })
        .collect()
}

/// Joins the fragments of one band that end on its last row with those of the next band that continue them from
/// its first row (nearly parallel, each on the other's line, at most two pixels apart). The result keeps the order
/// of the fragments' seeds.
fn join_across_bands(
    per_band: Vec<Vec<Fragment>>,
    edges: &[usize],
    pixels: &[[u16; 2]],
    corrected: &[[f64; 2]],
    p: &TraceParams,
) -> Vec<Fragment> {
    let starts: Vec<usize> = per_band
        .iter()
        .scan(0, |n, band| {
            let s = *n;
            *n += band.len();
            Some(s)
        })
        .collect();
    let mut fragments: Vec<Fragment> = per_band.into_iter().flatten().collect();
    if starts.len() < 2 {
        return fragments;
    }
    let across = TraceParams { max_gap_px: 2.0, ..*p };
    let mut parent: Vec<usize> = (0..fragments.len()).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let on_row = |f: &Fragment, row: usize| f.chain.iter().any(|&i| pixels[i as usize][1] as usize == row);
    for b in 0..starts.len() - 1 {
        let boundary = edges[b + 1];
        let upper = starts[b]..starts[b + 1];
        let lower = starts[b + 1]..starts.get(b + 2).copied().unwrap_or(fragments.len());
        let below: Vec<usize> = lower.filter(|&j| on_row(&fragments[j], boundary)).collect();
        let mut taken = vec![false; below.len()];
        for i in upper.filter(|&i| boundary > 0 && on_row(&fragments[i], boundary - 1)) {
            if let Some(k) = (0..below.len()).find(|&k| !taken[k] && fragments[i].continued_by(&fragments[below[k]], &across)) {
                taken[k] = true;
                let (ri, rj) = (root(&mut parent, i), root(&mut parent, below[k]));
                parent[ri.max(rj)] = ri.min(rj);
            }
        }
    }
    // A group's root is its earliest fragment: the chains of the others move into it, in order.
    let mut grown = vec![false; fragments.len()];
    for i in 0..fragments.len() {
        let r = root(&mut parent, i);
        if r != i {
            let chain = std::mem::take(&mut fragments[i].chain);
            fragments[r].chain.extend(chain);
            grown[r] = true;
        }
    }
    fragments
        .into_iter()
        .zip(grown)
        .filter(|(f, _)| !f.chain.is_empty())
        .map(|(f, grown)| if grown { Fragment::new(f.chain, corrected) } else { f })
        .collect()
}

/// Traces the pixels `range` of `pixels`, all within `rows`, as if the image held only those rows.
fn trace_band(
    width: usize,
    rows: std::ops::Range<usize>,
    pixels: &[[u16; 2]],
    range: std::ops::Range<usize>,
    corrected: &[[f64; 2]],
    p: &TraceParams,
) -> Vec<Fragment> {
    const NONE: u32 = u32::MAX;
    let (row0, height) = (rows.start, rows.len());
    let mut index = vec![NONE; width * height];
    let local = |q: [u16; 2]| {
        let (c, r) = (q[0] as usize, q[1] as usize);
        (c < width && r >= row0 && r < row0 + height).then(|| (r - row0) * width + c)
    };
    for i in range.clone() {
        if let Some(k) = local(pixels[i]) {
            index[k] = i as u32;
        }
    }
    // Indexed from the band's first pixel.
    let first = range.start;
    let mut state = vec![Pixel::Free; range.len()];
    // Without joining, a chain shorter than the minimum length is dropped anyway; it gives its pixels back.
    let release_short = p.max_gap_px <= 0.0;
    let mut fragments = Vec::new();
    for seed in range {
        if state[seed - first] != Pixel::Free || local(pixels[seed]).is_none_or(|k| index[k] != seed as u32) {
            continue;
        }
        state[seed - first] = Pixel::Taken;
        let mut fit = Fit::default();
        fit.add(corrected[seed]);
        // The first two points stacked (for the first-two-points constraint) and the two arms.
        let mut first_two = [corrected[seed]; 2];
        let mut arms: [Vec<u32>; 2] = [Vec::new(), Vec::new()];
        // Direction of travel of the first arm's first step; the second arm leaves the seed the opposite way.
        let mut first_step: Option<[f64; 2]> = None;
        for (arm, arm_pixels) in arms.iter_mut().enumerate() {
            let mut end = seed as u32;
            let mut heading: Option<[f64; 2]> = if arm == 1 { first_step.map(|h| [-h[0], -h[1]]) } else { None };
            loop {
                let (ec, er) = (pixels[end as usize][0] as i32, pixels[end as usize][1] as i32);
                let line = constraint(&first_two, &fit);
                let here = corrected[end as usize];
                // The edge pixel at image (col, row) if it is in this band and in no chain yet.
                let free_at = |c: i32, r: i32| {
                    let r = r - row0 as i32;
                    if c < 0 || r < 0 || c >= width as i32 || r >= height as i32 {
                        return None;
                    }
                    let j = index[r as usize * width + c as usize];
                    (j != NONE && state[j as usize - first] != Pixel::Taken).then_some(j)
                };
                let mut best: Option<(f64, u32)> = None;
                for (dc, dr) in NEIGHBOURS {
                    let Some(j) = free_at(ec + dc, er + dr) else { continue };
                    let q = corrected[j as usize];
                    let step = [q[0] - here[0], q[1] - here[1]];
                    // Onwards only: a step must not turn back against the arm's heading.
                    if heading.is_some_and(|h| h[0] * step[0] + h[1] * step[1] <= 0.0) {
                        continue;
                    }
                    let score = match line {
                        None => 0.0,
                        Some((o, d)) => {
                            let dist = off_line(q, o, d);
                            if dist > p.max_distance_px {
                                continue;
                            }
                            dist
                        }
                    };
                    if best.is_none_or(|b| score < b.0) {
                        best = Some((score, j));
                    }
                }
                let jumped = || {
                    let (Some((o, d)), Some(h)) = (line, heading) else { return None };
                    if p.max_jump_px < 2.0 || fit.n < MIN_PIXELS_BEFORE_JUMP {
                        return None;
                    }
                    let at = |j: u32| {
                        let q = corrected[j as usize];
                        let along = h[0] * (q[0] - here[0]) + h[1] * (q[1] - here[1]);
                        (along, off_line(q, o, d))
                    };
                    let mut found: Option<(f64, f64, u32)> = None;
                    for k in 2..=p.max_jump_px as i32 {
                        let (cc, cr) = (ec + (h[0] * k as f64).round() as i32, er + (h[1] * k as f64).round() as i32);
                        for (dc, dr) in std::iter::once((0, 0)).chain(NEIGHBOURS) {
                            let Some(j) = free_at(cc + dc, cr + dr) else { continue };
                            let (along, off) = at(j);
                            if along <= 0.0 || along > p.max_jump_px + 1.0 || off > p.max_distance_px {
                                continue;
                            }
                            if found.is_none_or(|f| (along, off, j) < (f.0, f.1, f.2)) {
                                found = Some((along, off, j));
                            }
                        }
                        if found.is_some() {
                            break;
                        }
                    }
                    found.map(|f| f.2)
                };
                let Some(j) = best.map(|b| b.1).or_else(jumped) else { break };
                let q = corrected[j as usize];
                let step = [q[0] - here[0], q[1] - here[1]];
                // The heading follows the line (oriented the way the arm travels) once there is one.
                heading = Some(match line {
                    Some((_, d)) if d[0] * step[0] + d[1] * step[1] < 0.0 => [-d[0], -d[1]],
                    Some((_, d)) => d,
                    None => step,
                });
                if arm == 0 && first_step.is_none() {
                    first_step = Some(step);
                }
                state[j as usize - first] = Pixel::Taken;
                if fit.n < 2.0 {
                    first_two[1] = corrected[j as usize];
                }
                fit.add(corrected[j as usize]);
                arm_pixels.push(j);
                end = j;
            }
        }
        let mut chain: Vec<u32> = arms[1].iter().rev().copied().collect();
        chain.push(seed as u32);
        chain.extend(&arms[0]);
        if chain.len() < MIN_FRAGMENT_PIXELS {
            continue;
        }
        let fragment = Fragment::with_fit(chain, fit, corrected);
        // A chain reaching the band's first or last row may continue in the next band, so it is kept.
        let at_band_edge = || {
            fragment.chain.iter().any(|&i| {
                let r = pixels[i as usize][1] as usize;
                r == row0 || r + 1 == row0 + height
            })
        };
        if release_short && fragment.t1 - fragment.t0 < p.min_length_px && !at_band_edge() {
            // Brick joints meeting a lintel, seeded first in raster order, would otherwise each take one pixel of
            // it and cut it into pieces too short to keep. The pixels stay traversable but seed no other chain.
            for &i in &fragment.chain {
                state[i as usize - first] = Pixel::Tried;
            }
            continue;
        }
        fragments.push(fragment);
    }
    fragments
}

/// A band pixel's part in the tracing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Pixel {
    /// Neither in a chain nor a seed yet.
    Free,
    /// In a chain that was too short to keep: other chains may pass through it, but it seeds none.
    Tried,
    /// In a kept chain, or in the chain being traced.
    Taken,
}

/// A chain jumps a gap only once its line rests on this many pixels.
const MIN_PIXELS_BEFORE_JUMP: f64 = 6.0;

/// Fragments shorter than this many pixels are noise, not line pieces.
const MIN_FRAGMENT_PIXELS: usize = 4;

/// A traced chain (indices into the edge pixels) with its fitted line and extent along it.
#[derive(Debug, Clone)]
struct Fragment {
    chain: Vec<u32>,
    fit: Fit,
    c: [f64; 2],
    d: [f64; 2],
    t0: f64,
    t1: f64,
}

impl Fragment {
    fn new(chain: Vec<u32>, corrected: &[[f64; 2]]) -> Fragment {
        let mut fit = Fit::default();
        for &i in &chain {
            fit.add(corrected[i as usize]);
        }
        Fragment::with_fit(chain, fit, corrected)
    }
    fn with_fit(chain: Vec<u32>, fit: Fit, corrected: &[[f64; 2]]) -> Fragment {
        let (c, d) = fit.line();
        let (mut t0, mut t1) = (f64::INFINITY, f64::NEG_INFINITY);
        for &i in &chain {
            let q = corrected[i as usize];
            let t = (q[0] - c[0]) * d[0] + (q[1] - c[1]) * d[1];
            t0 = t0.min(t);
            t1 = t1.max(t);
        }
        Fragment { chain, fit, c, d, t0, t1 }
    }

    /// The chain ordered along the line, from one end to the other.
    fn ordered(mut self, corrected: &[[f64; 2]]) -> Fragment {
        let t = |i: u32| self.param(corrected[i as usize]);
        let mut keyed: Vec<(f64, u32)> = self.chain.iter().map(|&i| (t(i), i)).collect();
        keyed.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        self.chain = keyed.into_iter().map(|k| k.1).collect();
        self
    }
    fn at(&self, t: f64) -> [f64; 2] {
        [self.c[0] + self.d[0] * t, self.c[1] + self.d[1] * t]
    }
    fn distance(&self, q: [f64; 2]) -> f64 {
        ((q[0] - self.c[0]) * self.d[1] - (q[1] - self.c[1]) * self.d[0]).abs()
    }
    fn param(&self, q: [f64; 2]) -> f64 {
        (q[0] - self.c[0]) * self.d[0] + (q[1] - self.c[1]) * self.d[1]
    }
    /// Whether `other` continues this fragment: nearly parallel, on its line (both ways), and across a small gap.
    fn continued_by(&self, other: &Fragment, p: &TraceParams) -> bool {
        let cos = (self.d[0] * other.d[0] + self.d[1] * other.d[1]).abs();
        if cos < p.max_merge_angle_deg.to_radians().cos() {
            return false;
        }
        let (oa, ob) = (other.at(other.t0), other.at(other.t1));
        let (sa, sb) = (self.at(self.t0), self.at(self.t1));
        if self.distance(oa).max(self.distance(ob)) > p.max_distance_px || other.distance(sa).max(other.distance(sb)) > p.max_distance_px {
            return false;
        }
        let (u0, u1) = {
            let (x, y) = (self.param(oa), self.param(ob));
            (x.min(y), x.max(y))
        };
        let gap = (u0 - self.t1).max(self.t0 - u1);
        gap <= p.max_gap_px
    }
}

/// Joins collinear fragments across gaps (junctions, weak stretches), longest first, until nothing changes.
/// Deterministic: candidates are visited in a fixed order.
fn merge_collinear(mut fragments: Vec<Fragment>, corrected: &[[f64; 2]], p: &TraceParams) -> Vec<Fragment> {
    fragments.sort_by(|a, b| (b.t1 - b.t0).total_cmp(&(a.t1 - a.t0)).then(a.chain[0].cmp(&b.chain[0])));
    let mut alive = vec![true; fragments.len()];
    // Coarse grid of fragment endpoints, so each fragment only looks at its neighbours.
    let cell = (p.max_gap_px + p.max_distance_px).max(8.0) * 2.0;
    let key = |q: [f64; 2]| ((q[0] / cell).floor() as i64, (q[1] / cell).floor() as i64);
    let mut grid: std::collections::HashMap<(i64, i64), Vec<usize>> = Default::default();
    for (i, f) in fragments.iter().enumerate() {
        for q in [f.at(f.t0), f.at(f.t1)] {
            grid.entry(key(q)).or_default().push(i);
        }
    }
    for i in 0..fragments.len() {
        if !alive[i] {
            continue;
        }
        loop {
            let f = &fragments[i];
            let mut near: Vec<usize> = Vec::new();
            for q in [f.at(f.t0), f.at(f.t1)] {
                let (kx, ky) = key(q);
                for dx in -1..=1 {
                    for dy in -1..=1 {
                        if let Some(v) = grid.get(&(kx + dx, ky + dy)) {
                            near.extend(v.iter().copied().filter(|&j| j != i && alive[j]));
                        }
                    }
                }
            }
            near.sort_unstable();
            near.dedup();
            let Some(j) = near.into_iter().find(|&j| fragments[i].continued_by(&fragments[j], p)) else {
                break;
            };
            alive[j] = false;
            let other = std::mem::take(&mut fragments[j].chain);
            let mut fit = fragments[i].fit;
            for &k in &other {
                fit.add(corrected[k as usize]);
            }
            let mut chain = std::mem::take(&mut fragments[i].chain);
            chain.extend(other);
            fragments[i] = Fragment::with_fit(chain, fit, corrected);
            let f = &fragments[i];
            for q in [f.at(f.t0), f.at(f.t1)] {
                grid.entry(key(q)).or_default().push(i);
            }
        }
    }
    fragments.into_iter().zip(alive).filter(|(_, a)| *a).map(|(f, _)| f).collect()
}

/// A traced segment in measured pixel coordinates: endpoints and chain.
pub type MeasuredSegment = ([f64; 2], [f64; 2], Vec<[u16; 2]>);

/// Traces edge pixels of an image from `camera` in corrected coordinates (so that long lines near the corners stay
/// whole) and returns the segments with their endpoints back in measured pixels; segments whose endpoints do not
/// map back (beyond the correction model's fold) are dropped.
pub fn trace_measured(camera: &lineflow_photogrammetry::Camera, pixels: &[[u16; 2]], p: &TraceParams) -> Vec<MeasuredSegment> {
    let positions: Vec<[f64; 2]> = pixels.iter().map(|q| [q[0] as f64, q[1] as f64]).collect();
    trace_measured_at(camera, pixels, &positions, p)
}

/// Measured pixel positions corrected by `camera`'s correction model, in pixels: where [`trace`] fits its lines.
pub fn corrected_pixels(camera: &lineflow_photogrammetry::Camera, positions: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let ps = camera.pixel_size_mm;
    positions
        .par_iter()
        .map(|&q| {
            let i = camera.pixel_to_ideal(q);
            [i[0] / ps, i[1] / ps]
        })
        .collect()
}

/// [`trace_measured`] with each pixel's sub-pixel position (measured col, row; e.g. the gradient peaks of
/// `lineflow_imaging::subpixel_positions`): the lines are fitted to the positions, the chains keep the pixels. Edge
/// pixels sit on the integer grid, which biases a nearly vertical or horizontal line by up to half a pixel; line
/// intersection across images needs better than that.
pub fn trace_measured_at(
    camera: &lineflow_photogrammetry::Camera,
    pixels: &[[u16; 2]],
    positions: &[[f64; 2]],
    p: &TraceParams,
) -> Vec<MeasuredSegment> {
    let ps = camera.pixel_size_mm;
    let corrected = corrected_pixels(camera, positions);
    let traced = trace(camera.width as usize, camera.height as usize, pixels, &corrected, p);
    let measured = |c: [f64; 2]| camera.ideal_to_pixel([c[0] * ps, c[1] * ps]);
    traced
        .into_iter()
        .filter_map(|t| Some((measured(t.start)?, measured(t.end)?, t.chain)))
        .collect()
}
