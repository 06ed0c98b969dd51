//! 3-D lines: the thesis's tables (endpoint perpendicular distances and angles to the matched reference edge),
//! the success rate, and LIMAP-style precision and recall at several tolerances, against the true edges and
//! against the true surfaces, for all, horizontal, vertical and depth edges, and for the lines of each class the
//! line stage gave them (structure, texture).
use lineflow_formats::{Line3Row, LineClass};
use lineflow_photogrammetry::{Pose, Vec3};
use rayon::prelude::*;

use crate::geometry::{bounds, class_on_walls, polygon_distance, segment_grid, Class, Grid, Seg, WallPlane};
use crate::resolvable::{inseparable, most_recoverable, resolvable};
use crate::Truth;

/// Samples per segment for the coverage metrics.
const SAMPLES: usize = 20;
/// An estimate is matched to a reference edge within this angle, degrees.
const MATCH_ANGLE_DEG: f64 = 10.0;

/// Scores at one tolerance.
#[derive(Debug, Clone)]
pub struct AtTolerance {
    /// "5 mm", "2 GSD", ...
    pub label: String,
    pub tau_m: f64,
    /// Share of estimated segments whose mean distance to the nearest true edge is within τ.
    pub segment_precision: f64,
    /// Share of estimated length within τ of a true edge.
    pub length_precision: f64,
    /// Share of true length within τ of an estimated segment.
    pub length_recall: f64,
    /// Share of estimated length within τ of a true surface.
    pub surface_precision: f64,
}

/// Which estimates and true edges one row of the scores is about.
#[derive(Debug, Clone, Copy)]
enum Subset {
    /// Estimates and true edges of one direction on their wall (all with `None`).
    Edges(Option<Class>),
    /// The estimates the line stage classed so, against every true edge.
    Lines(LineClass),
}

/// Scores of one class of edges.
#[derive(Debug, Clone)]
pub struct ClassScores {
    pub class: &'static str,
    pub n_true: usize,
    pub n_estimated: usize,
    /// Share of true edges of at least 0.5 m that are recovered (see `docs/eval.md`).
    pub success_rate: f64,
    /// True edges of at least 0.5 m that the images resolve from their parallel neighbours ([`crate::resolvable`]).
    pub n_resolvable: usize,
    /// Share of those that are recovered.
    pub success_resolvable: f64,
    /// The highest success rate the images allow: the share of the edges of at least 0.5 m that any set of lines
    /// could recover when of two edges no two images show apart, and more than 4 GSD apart, only one can be ([`crate::resolvable::most_recoverable`]).
    pub success_ceiling: f64,
    pub at: Vec<AtTolerance>,
}

#[derive(Debug, Clone)]
pub struct Lines3dReport {
    pub gsd_m: f64,
    pub estimated: Vec<Seg>,
    pub truth: Vec<Seg>,
    /// For each estimate: index of the matched true edge.
    pub matched: Vec<Option<usize>>,
    /// Perpendicular distances of matched endpoints to their true edge (the thesis's table), metres.
    pub endpoint_m: Vec<f64>,
    /// Angles of matched estimates to their true edge, degrees.
    pub angle_deg: Vec<f64>,
    /// The same over true edges of at least 1 m.
    pub angle_long_deg: Vec<f64>,
    /// Mean endpoint distance of each estimate (NaN when unmatched), for plots.
    pub error_m: Vec<f64>,
    pub classes: Vec<ClassScores>,
    /// Each true edge as scored (in the order of `truth`).
    pub true_edges: Vec<TrueEdge>,
}

/// One true edge as the scores saw it.
#[derive(Debug, Clone)]
pub struct TrueEdge {
    /// What it belongs to in the synthetic scene.
    pub kind: &'static str,
    pub class: Class,
    /// The images resolve it from its parallel neighbours.
    pub resolvable: bool,
    /// Recovered (edges of at least 0.5 m; `None` for shorter ones, which the success rate does not count).
    pub found: Option<bool>,
    /// A neighbour no two images show apart from it, more than 4 GSD away, was recovered: a line placed from the
    /// images could not have recovered this one as well ([`crate::resolvable::inseparable`]).
    pub partner_found: bool,
    /// For a missed edge: the nearest line within 2° and 10 cm over its length that overlaps it ([`nearest_line`]).
    pub nearest: Option<NearestLine>,
}

/// The estimated line nearest a true edge (within 2° and [`NEAREST_REACH_M`] at both its ends, overlapping it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NearestLine {
    /// From the edge's midpoint to the line, square to the edge, metres.
    pub offset: Vec3,
    /// Share of the edge's length the line spans.
    pub coverage: f64,
}

/// How far [`nearest_line`] looks, metres.
pub const NEAREST_REACH_M: f64 = 0.1;

/// The estimate of `est` that lies nearest the true edge `g` (the smallest larger distance of its two ends from
/// the edge's line), among those within 2° and [`NEAREST_REACH_M`] that overlap it.
fn nearest_line(g: &Seg, est: &[Seg], grid: &Grid) -> Option<NearestLine> {
    candidates(g, grid, NEAREST_REACH_M)
        .iter()
        .map(|&i| &est[i as usize])
        .filter(|e| g.angle_deg(e) <= 2.0)
        .filter_map(|e| {
            let worst = g.line_distance(&e.a).max(g.line_distance(&e.b));
            let (s, t) = (g.param(&e.a), g.param(&e.b));
            let coverage = s.max(t).min(1.0) - s.min(t).max(0.0);
            (worst <= NEAREST_REACH_M && coverage > 0.0).then_some((worst, e, coverage))
        })
        .min_by(|x, y| x.0.total_cmp(&y.0))
        .map(|(_, e, coverage)| {
            let mid = g.at(0.5);
            let on_line = e.at(e.param(&mid));
            let across = on_line - mid;
            NearestLine {
                offset: across - g.dir() * across.dot(&g.dir()),
                coverage,
            }
        })
}

/// How many true edges of one kind (at least 0.5 m) were recovered.
#[derive(Debug, Clone)]
pub struct KindScores {
    pub kind: &'static str,
    /// True edges of this kind of at least 0.5 m.
    pub n_long: usize,
    pub n_found: usize,
    /// Of those the images resolve from their parallel neighbours.
    pub n_resolvable: usize,
    pub n_found_resolvable: usize,
}

/// Tolerances: 5, 10, 20, 50 mm and 1, 2, 5 GSD.
pub fn tolerances(gsd_m: f64) -> Vec<(String, f64)> {
    let mut t: Vec<(String, f64)> = [5.0, 10.0, 20.0, 50.0].iter().map(|mm| (format!("{mm} mm"), mm / 1000.0)).collect();
    t.extend([1.0, 2.0, 5.0].iter().map(|k| (format!("{k} GSD"), k * gsd_m)));
    t
}

/// Distance to the nearest item, exact up to the grid's reach (beyond it: infinity).
fn nearest(p: &Vec3, grid: &Grid, distance: impl Fn(usize) -> f64) -> f64 {
    grid.near(p).iter().map(|&i| distance(i as usize)).fold(f64::INFINITY, f64::min)
}

pub fn evaluate(truth: &Truth, rows: &[Line3Row]) -> Lines3dReport {
    let gsd = truth.gsd_m();
    let est: Vec<Seg> = rows.iter().map(|r| Seg::new(r.start, r.end)).collect();
    let gt: Vec<Seg> = truth.lines.iter().map(|r| Seg::new(r.start, r.end)).collect();
    let faces: Vec<Vec<Vec3>> = truth.scene.building.faces.iter().map(|f| f.corners()).collect();
    let poses: Vec<Pose> = truth.poses.iter().map(|p| p.pose).collect();
    let resolved = resolvable(truth.scene.camera(), &poses, &gt);
    // Edges within two tolerances (2 GSD each) of each other can both lie within 2 GSD of one line.
    let pairs = inseparable(truth.scene.camera(), &poses, &gt, 4.0 * gsd);

    // Match each estimate to the nearby, nearly parallel true edge its endpoints lie closest to.
    let match_reach = (5.0 * gsd).max(0.1);
    let (lo, hi) = bounds(gt.iter().flat_map(|s| [&s.a, &s.b]).chain(est.iter().flat_map(|s| [&s.a, &s.b])));
    let match_grid = segment_grid(&gt, match_reach, (lo - Vec3::repeat(1.0), hi + Vec3::repeat(1.0)));
    let matched: Vec<Option<usize>> = est
        .par_iter()
        .map(|e| {
            let mid = e.at(0.5);
            match_grid
                .near(&mid)
                .iter()
                .map(|&i| (i as usize, &gt[i as usize]))
                .filter(|(_, g)| g.angle_deg(e) <= MATCH_ANGLE_DEG && g.distance(&mid) <= match_reach)
                .map(|(i, g)| (i, (g.line_distance(&e.a) + g.line_distance(&e.b)) / 2.0))
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .map(|(i, _)| i)
        })
        .collect();
    let mut endpoint_m = Vec::new();
    let mut angle_deg = Vec::new();
    let mut angle_long_deg = Vec::new();
    let mut error_m = Vec::new();
    for (e, m) in est.iter().zip(&matched) {
        match m {
            Some(i) => {
                let g = &gt[*i];
                let (da, db) = (g.line_distance(&e.a), g.line_distance(&e.b));
                endpoint_m.extend([da, db]);
                angle_deg.push(g.angle_deg(e));
                if g.length() >= 1.0 {
                    angle_long_deg.push(g.angle_deg(e));
                }
                error_m.push((da + db) / 2.0);
            }
            None => error_m.push(f64::NAN),
        }
    }

    let taus = tolerances(gsd);
    // Distances computed once, through grids that answer up to the largest tolerance: estimate samples to edges
    // and to surfaces, true samples to estimates.
    let reach = taus.iter().map(|t| t.1).fold(0.0, f64::max) * 1.01;
    let (lo, hi) = bounds(gt.iter().flat_map(|s| [&s.a, &s.b]).chain(est.iter().flat_map(|s| [&s.a, &s.b])));
    let region = (lo - Vec3::repeat(1.0), hi + Vec3::repeat(1.0));
    let gt_grid = segment_grid(&gt, reach, region);
    let est_grid = segment_grid(&est, reach, region);
    let mut face_grid = Grid::new(reach.max(0.25), region.0, region.1);
    for (i, f) in faces.iter().enumerate() {
        let (flo, fhi) = bounds(f.iter());
        face_grid.insert(i as u32, flo, fhi, reach);
    }
    let est_samples: Vec<Vec<(f64, f64, f64)>> = est
        .par_iter()
        .map(|e| {
            e.samples(SAMPLES)
                .map(|(p, w)| {
                    (
                        nearest(&p, &gt_grid, |i| gt[i].distance(&p)),
                        nearest(&p, &face_grid, |i| polygon_distance(&p, &faces[i])),
                        w,
                    )
                })
                .collect()
        })
        .collect();
    let gt_samples: Vec<Vec<(f64, f64)>> = gt
        .par_iter()
        .map(|g| {
            g.samples(SAMPLES)
                .map(|(p, w)| (nearest(&p, &est_grid, |i| est[i].distance(&p)), w))
                .collect()
        })
        .collect();

    let walls: Vec<WallPlane> = truth
        .scene
        .building
        .walls
        .iter()
        .filter_map(|(_, corners)| WallPlane::new(corners.iter().map(|&p| Vec3::from(p)).collect()))
        .collect();
    let est_class: Vec<Class> = est.iter().map(|s| class_on_walls(s, &walls)).collect();
    let gt_class: Vec<Class> = gt.iter().map(|s| class_on_walls(s, &walls)).collect();
    // Edge classes score the estimates and true edges of one direction; the line stage's classes (when the lines
    // carry them) score the lines of one class against every true edge, recall and success by those lines alone.
    let line_class: Vec<LineClass> = rows.iter().map(|r| r.class).collect();
    let classed = line_class.iter().any(|&c| c != LineClass::Unknown);
    let mut subsets: Vec<(&'static str, Subset)> = vec![
        ("all", Subset::Edges(None)),
        ("horizontal", Subset::Edges(Some(Class::Horizontal))),
        ("vertical", Subset::Edges(Some(Class::Vertical))),
        ("depth", Subset::Edges(Some(Class::Depth))),
    ];
    if classed {
        subsets.push(("structure lines", Subset::Lines(LineClass::Structure)));
        subsets.push(("texture lines", Subset::Lines(LineClass::Texture)));
    }
    let mut true_edges = score_true_edges(truth, &gt, &gt_class, &resolved, |g| recovered(g, &est, &est_grid, reach, gsd));
    let partner_found: Vec<bool> = pairs
        .iter()
        .map(|js| js.iter().any(|&j| true_edges[j].found == Some(true)))
        .collect();
    let near_grid = segment_grid(&est, NEAREST_REACH_M, region);
    for ((e, p), g) in true_edges.iter_mut().zip(partner_found).zip(&gt) {
        e.partner_found = p;
        if e.found == Some(false) {
            e.nearest = nearest_line(g, &est, &near_grid);
        }
    }
    let classes = subsets
        .iter()
        .map(|&(name, subset)| {
            let (ei, gi): (Vec<usize>, Vec<usize>) = match subset {
                Subset::Edges(class) => (
                    (0..est.len()).filter(|&i| class.is_none_or(|c| est_class[i] == c)).collect(),
                    (0..gt.len()).filter(|&i| class.is_none_or(|c| gt_class[i] == c)).collect(),
                ),
                Subset::Lines(c) => ((0..est.len()).filter(|&i| line_class[i] == c).collect(), (0..gt.len()).collect()),
            };
            // A depth edge is 0.1-0.5 m long and ends on the lines around its opening: every estimate counts as covering
            // it at its ends. Its recall counts depth estimates only (horizontal and vertical keep their definition
            // against all estimates, for comparison with earlier figures).
            let own = matches!(subset, Subset::Edges(Some(Class::Depth)) | Subset::Lines(_));
            let own_est: Vec<Seg> = if own { ei.iter().map(|&i| est[i]).collect() } else { Vec::new() };
            let own_grid = own.then(|| segment_grid(&own_est, reach, region));
            let depth_samples: Option<Vec<Vec<(f64, f64)>>> = own_grid.as_ref().map(|grid| {
                let mut samples = vec![Vec::new(); gt.len()];
                for &i in &gi {
                    samples[i] = gt[i]
                        .samples(SAMPLES)
                        .map(|(p, w)| (nearest(&p, grid, |k| own_est[k].distance(&p)), w))
                        .collect();
                }
                samples
            });
            let at = taus
                .iter()
                .map(|(label, tau)| {
                    let share = |num: f64, den: f64| if den > 0.0 { num / den } else { f64::NAN };
                    let seg_ok = ei
                        .iter()
                        .filter(|&&i| est_samples[i].iter().map(|s| s.0).sum::<f64>() / SAMPLES as f64 <= *tau)
                        .count();
                    let (mut within, mut on_surface, mut total) = (0.0, 0.0, 0.0);
                    for &i in &ei {
                        for &(d, ds, w) in &est_samples[i] {
                            total += w;
                            within += if d <= *tau { w } else { 0.0 };
                            on_surface += if ds <= *tau { w } else { 0.0 };
                        }
                    }
                    let (mut covered, mut gt_total) = (0.0, 0.0);
                    for &i in &gi {
                        let samples = depth_samples.as_ref().map_or(&gt_samples[i], |d| &d[i]);
                        for &(d, w) in samples {
                            gt_total += w;
                            covered += if d <= *tau { w } else { 0.0 };
                        }
                    }
                    AtTolerance {
                        label: label.clone(),
                        tau_m: *tau,
                        segment_precision: share(seg_ok as f64, ei.len() as f64),
                        length_precision: share(within, total),
                        length_recall: share(covered, gt_total),
                        surface_precision: share(on_surface, total),
                    }
                })
                .collect();
            let long: Vec<usize> = gi.iter().copied().filter(|&i| gt[i].length() >= 0.5).collect();
            // Every estimate recovers the same edges for every class of edges: taken from the scores of each edge.
            let found: Vec<bool> = long
                .iter()
                .map(|&i| match (&own_grid, subset) {
                    (Some(grid), Subset::Lines(_)) => recovered(&gt[i], &own_est, grid, reach, gsd),
                    _ => true_edges[i].found == Some(true),
                })
                .collect();
            let share = |n: usize, of: usize| if of == 0 { f64::NAN } else { n as f64 / of as f64 };
            let n_resolvable = long.iter().filter(|&&i| resolved[i]).count();
            let found_resolvable = long.iter().zip(&found).filter(|(&i, &f)| f && resolved[i]).count();
            ClassScores {
                class: name,
                n_true: gi.len(),
                n_estimated: ei.len(),
                success_rate: share(found.iter().filter(|&&f| f).count(), long.len()),
                n_resolvable,
                success_resolvable: share(found_resolvable, n_resolvable),
                success_ceiling: share(most_recoverable(&long, &pairs), long.len()),
                at,
            }
        })
        .collect();

    Lines3dReport {
        gsd_m: gsd,
        estimated: est,
        truth: gt,
        matched,
        endpoint_m,
        angle_deg,
        angle_long_deg,
        error_m,
        classes,
        true_edges,
    }
}

/// What the scene says each true edge belongs to: the kind of the scene's edge with its endpoints ("other" when the
/// truth came from elsewhere), so the report says which parts of the building the lines miss.
fn score_true_edges(truth: &Truth, gt: &[Seg], class: &[Class], resolved: &[bool], found: impl Fn(&Seg) -> bool) -> Vec<TrueEdge> {
    // Files hold micrometres: the scene's edge whose ends both lie within 0.1 mm (a few thousand edges, once).
    let edges: Vec<(Vec3, Vec3, &'static str)> = truth
        .scene
        .building
        .edges
        .iter()
        .map(|e| (Vec3::from(e.a), Vec3::from(e.b), e.kind))
        .collect();
    let kind_of = |g: &Seg| {
        let near = |p: &Vec3, q: &Vec3| (p - q).norm() < 1e-4;
        edges
            .iter()
            .find(|(a, b, _)| (near(a, &g.a) && near(b, &g.b)) || (near(a, &g.b) && near(b, &g.a)))
            .map_or("other", |e| e.2)
    };
    gt.iter()
        .enumerate()
        .map(|(i, g)| TrueEdge {
            kind: kind_of(g),
            class: class[i],
            resolvable: resolved[i],
            found: (g.length() >= 0.5).then(|| found(g)),
            partner_found: false,
            nearest: None,
        })
        .collect()
}

impl Lines3dReport {
    /// Success by what the true edges belong to (opening, sill, cornice, roof, ...; synthetic scenes only): the true
    /// edges of at least 0.5 m found, by kind, most numerous first.
    pub fn kinds(&self) -> Vec<KindScores> {
        kind_scores(&self.true_edges)
    }
}

fn kind_scores(edges: &[TrueEdge]) -> Vec<KindScores> {
    let mut kinds: Vec<KindScores> = Vec::new();
    for e in edges {
        let Some(f) = e.found else { continue };
        let at = match kinds.iter().position(|k| k.kind == e.kind) {
            Some(at) => at,
            None => {
                kinds.push(KindScores {
                    kind: e.kind,
                    n_long: 0,
                    n_found: 0,
                    n_resolvable: 0,
                    n_found_resolvable: 0,
                });
                kinds.len() - 1
            }
        };
        let k = &mut kinds[at];
        k.n_long += 1;
        k.n_found += f as usize;
        k.n_resolvable += e.resolvable as usize;
        k.n_found_resolvable += (f && e.resolvable) as usize;
    }
    kinds.sort_by(|a, b| b.n_long.cmp(&a.n_long).then(a.kind.cmp(b.kind)));
    kinds
}

/// The estimates `grid` lists near the edge `g`, sampled every `reach` metres along it (the grid's reach), each once.
fn candidates(g: &Seg, grid: &Grid, reach: f64) -> Vec<u32> {
    let n = (g.length() / reach).ceil() as usize + 1;
    let mut near: Vec<u32> = (0..=n)
        .flat_map(|k| grid.near(&g.at(k as f64 / n as f64)).iter().copied())
        .collect();
    near.sort_unstable();
    near.dedup();
    near
}

/// A true edge is recovered when estimates within 2 GSD and 2° of it cover at least half of its length.
/// Candidates come from the estimates' grid (`reach` ≥ 5 GSD): sampling the edge every `reach` metres finds every
/// estimate within 2 GSD of it.
fn recovered(g: &Seg, est: &[Seg], grid: &Grid, reach: f64, gsd: f64) -> bool {
    let mut spans: Vec<(f64, f64)> = candidates(g, grid, reach)
        .iter()
        .map(|&i| &est[i as usize])
        .filter(|e| g.angle_deg(e) <= 2.0 && g.line_distance(&e.a) <= 2.0 * gsd && g.line_distance(&e.b) <= 2.0 * gsd)
        .map(|e| {
            let (s, t) = (g.param(&e.a), g.param(&e.b));
            (s.min(t).max(0.0), s.max(t).min(1.0))
        })
        .filter(|(s, t)| t > s)
        .collect();
    spans.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (mut covered, mut end) = (0.0, 0.0f64);
    for (s, t) in spans {
        let s = s.max(end);
        if t > s {
            covered += t - s;
            end = t;
        }
    }
    covered >= 0.5
}
