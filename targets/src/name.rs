//! Detections named by the surveyed points they fit.
//!
//! Plain circular targets carry no code, so a detection is named by where it is: the detections of all images are
//! intersected into 3-D points with the images' poses (any frame: the similarity found next takes it into the control
//! frame), and the similarity that lays the most of those points onto the surveyed ones, each within
//! [`NameSettings::match_m`], names them. It is sought from triangles of points spread over the block whose shape
//! matches a triangle of surveyed points. A layout symmetric on a wall fits turned about it too, so of similarities
//! that pair as many the one is kept that puts no camera behind the wall a target it sees is on (the site's walls,
//! where known), then no camera upside down (the frame is Z up: held upright or on its side, an image's up does not
//! point down), then leaves the fewest surveyed points unseen where an image shows their place; a layout two
//! similarities fit equally well by all of these (a regular grid seen in part) is refused rather than guessed.
//! Surveyed points seen in too few images to be intersected are then looked for at their projections.
use lineflow_photogrammetry::intersect::{intersect_rays, similarity, Similarity};
use lineflow_photogrammetry::{polygon_normal, Camera, Pose, Vec3};

use crate::Detection;

/// One image's targets, with its pose.
#[derive(Debug, Clone)]
pub struct TargetView {
    /// The image's frame number.
    pub frame: usize,
    /// Its pose, in the frame the naming starts from.
    pub pose: Pose,
    /// Its detections.
    pub detections: Vec<Detection>,
}

/// How detections are grouped and named.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NameSettings {
    /// A detection shows a 3-D point when it lies within this of the point's projection, pixels.
    pub reproject_px: f64,
    /// A target is intersected from at least this many images.
    pub min_views: usize,
    /// The least angle between two rays of an intersection, degrees.
    pub min_ray_angle_deg: f64,
    /// An intersected target lies within this of its surveyed point once laid onto them, metres.
    pub match_m: f64,
    /// The intersected targets whose triangles are tried (the best-seen, then spread over the block).
    pub max_seeds: usize,
}

impl Default for NameSettings {
    fn default() -> Self {
        NameSettings {
            reproject_px: 2.0,
            min_views: 3,
            min_ray_angle_deg: 1.0,
            match_m: 0.1,
            max_seeds: 12,
        }
    }
}

/// A plane surveyed targets may lie on, seen only from the side its normal points to: a wall of `site.toml`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Face {
    /// A point of the plane, in the surveyed points' frame.
    pub point: Vec3,
    /// Its outward unit normal.
    pub outward: Vec3,
}

impl Face {
    /// The plane of a wall given as its corners counter-clockwise seen from outside (`site.toml`), if it has an
    /// area.
    pub fn of_wall(corners: &[[f64; 3]]) -> Option<Face> {
        let ring: Vec<Vec3> = corners.iter().map(|&c| Vec3::from(c)).collect();
        let outward = polygon_normal(&ring)?;
        Some(Face {
            point: ring.iter().sum::<Vec3>() / ring.len() as f64,
            outward,
        })
    }
}

/// A surveyed point lies on a face when within this of its plane, metres.
const ON_FACE_M: f64 = 0.3;

/// A detection named by a surveyed point: a row of `observations.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct Named {
    /// The image's frame number.
    pub frame: usize,
    /// The surveyed point's id.
    pub id: String,
    /// The detection's centre, pixels.
    pub centre: [f64; 2],
}

/// What the naming found.
#[derive(Debug, Clone)]
pub struct Naming {
    /// The named detections, by frame, then id.
    pub observations: Vec<Named>,
    /// From the poses' frame into the surveyed points'.
    pub similarity: Similarity,
    /// Targets intersected from `min_views` images or more.
    pub intersected: usize,
    /// Of those, how many lie on a surveyed point.
    pub matched: usize,
    /// Their RMS distance from it after the similarity, metres.
    pub rms_m: f64,
    /// The surveyed points no detection was named for.
    pub unseen: Vec<String>,
}

/// Why detections could not be named.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NamingError {
    /// Too few targets could be intersected.
    #[error(
        "only {found} targets were seen in {min_views} or more images (4 are needed to name them by their layout); \
         were the poses computed for these images, and are the targets large enough to be found (2.4 px or more across their disc)?"
    )]
    TooFewIntersected {
        /// Targets intersected.
        found: usize,
        /// Images each needed.
        min_views: usize,
    },
    /// Too few surveyed points to fit a layout to.
    #[error("control_points.csv has {0} points; at least 4 are needed to name targets by their layout")]
    TooFewPoints(usize),
    /// No similarity laid four targets, and half of those found, onto surveyed points.
    #[error(
        "the {intersected} targets found fit no layout of the surveyed points (at best {best} of them within {match_m} m): \
         are control_points.csv and the images of the same site?"
    )]
    NoFit {
        /// Targets intersected.
        intersected: usize,
        /// The most laid onto surveyed points by one similarity.
        best: usize,
        /// The tolerance.
        match_m: f64,
    },
    /// Two similarities fit as many targets, and neither is less plausible.
    #[error(
        "the targets' layout is ambiguous: two different namings each lay {matched} of the {intersected} targets found \
         onto surveyed points, with the cameras upright, in front of the walls and missing as few surveyed points (a \
         regular grid seen in part, or a symmetric one on a wall site.toml does not give?); measure a few targets by hand in \
         observations.csv"
    )]
    Ambiguous {
        /// Targets laid onto surveyed points by either naming.
        matched: usize,
        /// Targets intersected.
        intersected: usize,
    },
}

/// A target intersected from its detections: the point and the (view, detection) pairs that show it.
#[derive(Debug, Clone)]
struct Intersected {
    point: Vec3,
    seen: Vec<(usize, usize)>,
}

/// Names the detections of `views` by the surveyed `points` (id, coordinates), on the site's `faces` (may be
/// empty).
///
/// # Errors
/// Too few targets or points, no layout that fits, or one that fits two ways ([`NamingError`]).
pub fn name(
    views: &[TargetView],
    camera: &Camera,
    points: &[(String, Vec3)],
    faces: &[Face],
    s: &NameSettings,
) -> Result<Naming, NamingError> {
    if points.len() < 4 {
        return Err(NamingError::TooFewPoints(points.len()));
    }
    let targets = intersect_all(views, camera, s);
    if targets.len() < 4 {
        return Err(NamingError::TooFewIntersected {
            found: targets.len(),
            min_views: s.min_views,
        });
    }
    let block: Vec<Vec3> = targets.iter().map(|t| t.point).collect();
    let surveyed: Vec<Vec3> = points.iter().map(|p| p.1).collect();
    let tied = best_layouts(&block, &surveyed, s)?;
    let fit = most_plausible(tied, &targets, views, camera, &surveyed, faces, s)?;

    // Named: every detection of a matched target, then each surveyed point's projection where it lies near a
    // detection no target claimed (a point seen in too few images to be intersected, or missed by one).
    let mut claimed: Vec<Vec<bool>> = views.iter().map(|v| vec![false; v.detections.len()]).collect();
    let mut observations = Vec::new();
    let mut named = vec![false; points.len()];
    for &(t, q) in &fit.pairs {
        for &(v, d) in &targets[t].seen {
            claimed[v][d] = true;
            observations.push(Named {
                frame: views[v].frame,
                id: points[q].0.clone(),
                centre: views[v].detections[d].centre,
            });
        }
        named[q] = true;
    }
    for (q, (id, xyz)) in points.iter().enumerate() {
        let target = fit.pairs.iter().find(|p| p.1 == q).map(|p| &targets[p.0]);
        let in_block = target.map_or_else(|| inverse(&fit.similarity, xyz), |t| t.point);
        for (v, view) in views.iter().enumerate() {
            if target.is_some_and(|t| t.seen.iter().any(|s| s.0 == v)) {
                continue;
            }
            if let Some(d) = nearest(view, camera, &in_block, s.reproject_px, &claimed[v]) {
                claimed[v][d] = true;
                named[q] = true;
                observations.push(Named {
                    frame: view.frame,
                    id: id.clone(),
                    centre: view.detections[d].centre,
                });
            }
        }
    }
    observations.sort_by(|a, b| a.frame.cmp(&b.frame).then_with(|| a.id.cmp(&b.id)));
    Ok(Naming {
        observations,
        similarity: fit.similarity,
        intersected: targets.len(),
        matched: fit.pairs.len(),
        rms_m: fit.rms_m,
        unseen: points.iter().zip(&named).filter(|(_, &n)| !n).map(|(p, _)| p.0.clone()).collect(),
    })
}

/// `x` taken back from the similarity's target frame into its source frame.
fn inverse(sim: &Similarity, x: &Vec3) -> Vec3 {
    sim.rotation.transpose() * (x - sim.translation) / sim.scale
}

/// The detection of `view` nearest `point`'s projection within `tolerance` pixels, among those not `taken`.
fn nearest(view: &TargetView, camera: &Camera, point: &Vec3, tolerance: f64, taken: &[bool]) -> Option<usize> {
    let px = view.pose.project(camera, point)?;
    view.detections
        .iter()
        .enumerate()
        .filter(|(d, _)| !taken[*d])
        .map(|(d, det)| (d, (det.centre[0] - px[0]).hypot(det.centre[1] - px[1])))
        .filter(|&(_, e)| e <= tolerance)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(d, _)| d)
}

/// The targets seen in `min_views` images or more: from every pair of detections whose rays meet (within
/// `reproject_px` of both), the best-seen first, each detection claimed once.
fn intersect_all(views: &[TargetView], camera: &Camera, s: &NameSettings) -> Vec<Intersected> {
    let ray = |v: usize, d: usize| {
        let pose = &views[v].pose;
        (pose.center, pose.ray_of_pixel(camera, views[v].detections[d].centre))
    };
    let min_angle = s.min_ray_angle_deg.to_radians();
    let none_taken: Vec<Vec<bool>> = views.iter().map(|v| vec![false; v.detections.len()]).collect();
    let mut hypotheses: Vec<Intersected> = Vec::new();
    for a in 0..views.len() {
        for b in a + 1..views.len() {
            for da in 0..views[a].detections.len() {
                for db in 0..views[b].detections.len() {
                    let Some((point, angle)) = intersect_rays(&[ray(a, da), ray(b, db)]) else {
                        continue;
                    };
                    if angle < min_angle
                        || nearest(&views[a], camera, &point, s.reproject_px, &none_taken[a]) != Some(da)
                        || nearest(&views[b], camera, &point, s.reproject_px, &none_taken[b]) != Some(db)
                    {
                        continue;
                    }
                    let seen: Vec<(usize, usize)> = (0..views.len())
                        .filter_map(|v| nearest(&views[v], camera, &point, s.reproject_px, &none_taken[v]).map(|d| (v, d)))
                        .collect();
                    if seen.len() >= s.min_views {
                        hypotheses.push(Intersected { point, seen });
                    }
                }
            }
        }
    }
    // The best-seen first; the sort is stable, so ties keep the order of the pairs.
    hypotheses.sort_by_key(|h| std::cmp::Reverse(h.seen.len()));
    let mut claimed = none_taken;
    let mut targets = Vec::new();
    for h in hypotheses {
        let free: Vec<(usize, usize)> = h.seen.iter().copied().filter(|&(v, d)| !claimed[v][d]).collect();
        if free.len() < s.min_views {
            continue;
        }
        let rays: Vec<(Vec3, Vec3)> = free.iter().map(|&(v, d)| ray(v, d)).collect();
        let Some((point, _)) = intersect_rays(&rays) else { continue };
        // Each ray again against the point of all of them: one wrong detection must not stay in.
        let seen: Vec<(usize, usize)> = free
            .into_iter()
            .filter(|&(v, d)| {
                views[v].pose.project(camera, &point).is_some_and(|px| {
                    let c = views[v].detections[d].centre;
                    (c[0] - px[0]).hypot(c[1] - px[1]) <= s.reproject_px
                })
            })
            .collect();
        if seen.len() < s.min_views {
            continue;
        }
        for &(v, d) in &seen {
            claimed[v][d] = true;
        }
        targets.push(Intersected { point, seen });
    }
    targets
}

/// A similarity and the (target, surveyed point) pairs it lays within the tolerance.
#[derive(Debug, Clone)]
struct Layout {
    similarity: Similarity,
    pairs: Vec<(usize, usize)>,
    rms_m: f64,
}

/// Each target paired with the nearest surveyed point within `match_m` after `sim`, each point with one target
/// (the nearest of those that chose it).
fn pairs_under(sim: &Similarity, block: &[Vec3], surveyed: &[Vec3], match_m: f64) -> Layout {
    let mut best: Vec<Option<(usize, f64)>> = vec![None; surveyed.len()];
    for (t, p) in block.iter().enumerate() {
        let x = sim.apply(p);
        let near = surveyed
            .iter()
            .enumerate()
            .map(|(q, y)| (q, (x - y).norm()))
            .filter(|&(_, d)| d <= match_m)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((q, d)) = near {
            if best[q].is_none_or(|(_, e)| d < e) {
                best[q] = Some((t, d));
            }
        }
    }
    let mut pairs: Vec<(usize, usize)> = best.iter().enumerate().filter_map(|(q, b)| b.map(|(t, _)| (t, q))).collect();
    pairs.sort_unstable();
    let sum: f64 = best.iter().flatten().map(|(_, d)| d * d).sum();
    Layout {
        similarity: *sim,
        rms_m: (sum / pairs.len().max(1) as f64).sqrt(),
        pairs,
    }
}

/// The similarities from the targets' frame into the surveyed points' that pair the most targets, each refined on
/// its pairs, one for each different pairing, the best fitting first.
fn best_layouts(block: &[Vec3], surveyed: &[Vec3], s: &NameSettings) -> Result<Vec<Layout>, NamingError> {
    // Shapes of the surveyed triangles, every ordering: the sides ab, ac, bc.
    let n = surveyed.len();
    let dist = |a: &Vec3, b: &Vec3| (a - b).norm();
    let mut triangles = Vec::new();
    for a in 0..n {
        for b in 0..n {
            for c in 0..n {
                if a != b && a != c && b != c {
                    let sides = [
                        dist(&surveyed[a], &surveyed[b]),
                        dist(&surveyed[a], &surveyed[c]),
                        dist(&surveyed[b], &surveyed[c]),
                    ];
                    if well_shaped(sides) {
                        triangles.push(([a, b, c], sides));
                    }
                }
            }
        }
    }
    let seeds = spread(block, s.max_seeds);
    let mut tied: Vec<Layout> = Vec::new();
    for (n, &i) in seeds.iter().enumerate() {
        for (m, &j) in seeds.iter().enumerate().skip(n + 1) {
            for &k in &seeds[m + 1..] {
                let sides = [dist(&block[i], &block[j]), dist(&block[i], &block[k]), dist(&block[j], &block[k])];
                if !well_shaped(sides) {
                    continue;
                }
                for (abc, q) in &triangles {
                    let scale = q[0] / sides[0];
                    if (1..3).any(|m| (q[m] - scale * sides[m]).abs() > 0.03 * q[m]) {
                        continue;
                    }
                    let from = [block[i], block[j], block[k]];
                    let to = abc.map(|a| surveyed[a]);
                    let Some(sim) = similarity(&from, &to) else { continue };
                    let layout = refined(pairs_under(&sim, block, surveyed, s.match_m), block, surveyed, s.match_m);
                    consider(layout, &mut tied);
                }
            }
        }
    }
    let most = tied.first().map_or(0, |l| l.pairs.len());
    // Four pairs can be a coincidence among many surveyed points; most targets found are surveyed ones.
    if most < 4 || 2 * most < block.len() {
        return Err(NamingError::NoFit {
            intersected: block.len(),
            best: most,
            match_m: s.match_m,
        });
    }
    tied.sort_by(|a, b| a.rms_m.total_cmp(&b.rms_m));
    Ok(tied)
}

/// Up to `count` of the targets, spread over the block: the best-seen first (the block is in that order), then
/// each time the one farthest from those taken. The best-seen alone can all lie on one row, whose triangles are
/// flat.
fn spread(block: &[Vec3], count: usize) -> Vec<usize> {
    let mut taken: Vec<usize> = Vec::new();
    let mut gap = vec![f64::INFINITY; block.len()];
    while taken.len() < count.min(block.len()) {
        // The first of the farthest: the best-seen among equals.
        let next = (0..block.len())
            .filter(|t| !taken.contains(t))
            .fold(None, |best: Option<usize>, t| match best {
                Some(b) if gap[b] >= gap[t] => Some(b),
                _ => Some(t),
            })
            .expect("fewer taken than targets");
        taken.push(next);
        for (t, g) in gap.iter_mut().enumerate() {
            *g = g.min((block[t] - block[next]).norm());
        }
    }
    taken
}

/// Whether a triangle of these sides is worth fitting a similarity to: no side under a tenth of the longest,
/// and not flat (its height over the longest side at least a tenth of that side).
fn well_shaped([a, b, c]: [f64; 3]) -> bool {
    let longest = a.max(b).max(c);
    let s = 0.5 * (a + b + c);
    let area = (s * (s - a) * (s - b) * (s - c)).max(0.0).sqrt();
    longest > 0.0 && a.min(b).min(c) >= 0.1 * longest && 2.0 * area / longest >= 0.1 * longest
}

/// The layout's similarity fitted to all its pairs, and the pairs again under it, twice.
fn refined(mut layout: Layout, block: &[Vec3], surveyed: &[Vec3], match_m: f64) -> Layout {
    for _ in 0..2 {
        if layout.pairs.len() < 3 {
            break;
        }
        let from: Vec<Vec3> = layout.pairs.iter().map(|p| block[p.0]).collect();
        let to: Vec<Vec3> = layout.pairs.iter().map(|p| surveyed[p.1]).collect();
        let Some(sim) = similarity(&from, &to) else { break };
        layout = pairs_under(&sim, block, surveyed, match_m);
    }
    layout
}

/// Keeps in `tied` the layouts with the most pairs, one for each pairing (the one of smallest RMS).
fn consider(layout: Layout, tied: &mut Vec<Layout>) {
    let most = tied.first().map_or(0, |l| l.pairs.len());
    if layout.pairs.len() > most {
        tied.clear();
        tied.push(layout);
    } else if layout.pairs.len() == most {
        match tied.iter_mut().find(|l| l.pairs == layout.pairs) {
            Some(same) if layout.rms_m < same.rms_m => *same = layout,
            Some(_) => {}
            None => tied.push(layout),
        }
    }
}

/// Of layouts that pair as many targets, the one with the fewest cameras behind a face a target they see is on,
/// then the fewest upside down, then the fewest surveyed points missed; refused when two are equal in all three.
fn most_plausible(
    tied: Vec<Layout>,
    targets: &[Intersected],
    views: &[TargetView],
    camera: &Camera,
    surveyed: &[Vec3],
    faces: &[Face],
    s: &NameSettings,
) -> Result<Layout, NamingError> {
    let matched = tied[0].pairs.len();
    let mut ranked: Vec<((usize, usize, usize), Layout)> = tied
        .into_iter()
        .map(|l| {
            let rank = (
                cameras_behind(&l, targets, views, surveyed, faces),
                upside_down(&l, views),
                missed(&l, views, camera, surveyed, faces, s),
            );
            (rank, l)
        })
        .collect();
    // Stable: equal ranks keep the order of best fit.
    ranked.sort_by_key(|r| r.0);
    if ranked.len() > 1 && ranked[0].0 == ranked[1].0 {
        return Err(NamingError::Ambiguous {
            matched,
            intersected: targets.len(),
        });
    }
    Ok(ranked.swap_remove(0).1)
}

/// The face a surveyed point lies on: the nearest within [`ON_FACE_M`].
fn face_of<'a>(point: &Vec3, faces: &'a [Face]) -> Option<&'a Face> {
    faces
        .iter()
        .map(|f| (f, (point - f.point).dot(&f.outward).abs()))
        .filter(|&(_, d)| d <= ON_FACE_M)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(f, _)| f)
}

/// How many (camera, target) sightings of the layout look at the back of the face the target's point is on.
fn cameras_behind(layout: &Layout, targets: &[Intersected], views: &[TargetView], surveyed: &[Vec3], faces: &[Face]) -> usize {
    layout
        .pairs
        .iter()
        .filter_map(|&(t, q)| face_of(&surveyed[q], faces).map(|f| (t, q, f)))
        .map(|(t, q, f)| {
            targets[t]
                .seen
                .iter()
                .filter(|&&(v, _)| (layout.similarity.apply(&views[v].pose.center) - surveyed[q]).dot(&f.outward) <= 0.0)
                .count()
        })
        .sum()
}

/// How many images the layout turns upside down: their up (photo y) more than 120° from the frame's Z.
fn upside_down(layout: &Layout, views: &[TargetView]) -> usize {
    views
        .iter()
        .filter(|v| (layout.similarity.rotation * v.pose.rotation.transpose() * Vec3::y()).z < -0.5)
        .count()
}

/// How many times a surveyed point, under the layout, falls well inside an image that faces it with no detection
/// there.
fn missed(layout: &Layout, views: &[TargetView], camera: &Camera, surveyed: &[Vec3], faces: &[Face], s: &NameSettings) -> usize {
    let none_taken: Vec<bool> = views
        .iter()
        .map(|v| v.detections.len())
        .max()
        .map_or(Vec::new(), |n| vec![false; n]);
    let mut count = 0;
    for view in views {
        // Far enough inside for the whole ring (twice the disc's radius) to have been in the image.
        let largest = view.detections.iter().map(|d| d.radius_px).fold(2.5, f64::max);
        let center = layout.similarity.apply(&view.pose.center);
        for point in surveyed {
            if face_of(point, faces).is_some_and(|f| (center - point).dot(&f.outward) <= 0.0) {
                continue;
            }
            let in_block = inverse(&layout.similarity, point);
            let inside = view
                .pose
                .project(camera, &in_block)
                .is_some_and(|px| camera.contains(px, 4.0 * largest));
            if inside && nearest(view, camera, &in_block, s.reproject_px, &none_taken).is_none() {
                count += 1;
            }
        }
    }
    count
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_photogrammetry::{look_at, rotation_from_opk};

    /// A façade of targets on y = 0 (x 0–20 m, z 1–10 m, an irregular choice of a 7 × 4 grid) and a strip of
    /// cameras 20 m in front looking at it.
    fn site() -> (Camera, Vec<Pose>, Vec<(String, Vec3)>) {
        let camera = Camera::pinhole(2000, 1500, 0.005, 12.0);
        let poses = (0..9)
            .map(|k| {
                let center = Vec3::new(2.0 + 2.0 * k as f64, -20.0, 4.0);
                Pose {
                    center,
                    rotation: look_at(&center, &(center + Vec3::y()), &Vec3::z()),
                }
            })
            .collect();
        let mut points = Vec::new();
        for col in 0..7 {
            for row in 0..4 {
                if (col * 3 + row * 5) % 7 != 2 {
                    points.push((
                        format!("P{col}{row}"),
                        Vec3::new(3.0 * col as f64 + 1.0, 0.0, 2.5 * row as f64 + 1.5),
                    ));
                }
            }
        }
        (camera, poses, points)
    }

    /// Every point's projection in every image, as a detection, with false detections where `clutter`.
    fn views(camera: &Camera, poses: &[Pose], points: &[(String, Vec3)], clutter: bool) -> Vec<TargetView> {
        poses
            .iter()
            .enumerate()
            .map(|(frame, pose)| {
                let mut detections: Vec<Detection> = points
                    .iter()
                    .filter_map(|p| pose.project(camera, &p.1))
                    .filter(|px| camera.contains(*px, 10.0))
                    .map(|centre| Detection {
                        centre,
                        radius_px: 3.0,
                        contrast: 200.0,
                    })
                    .collect();
                if clutter {
                    detections.push(Detection {
                        centre: [100.0 + 37.0 * frame as f64, 700.0],
                        radius_px: 3.0,
                        contrast: 200.0,
                    });
                }
                detections
            })
            .enumerate()
            .map(|(frame, detections)| TargetView {
                frame,
                pose: poses[frame],
                detections,
            })
            .collect()
    }

    /// The poses in another frame: scaled by 0.37, turned and shifted, as a run without control points leaves them.
    fn elsewhere(poses: &[Pose]) -> Vec<Pose> {
        let r = rotation_from_opk(0.3, -0.2, 1.1);
        poses
            .iter()
            .map(|p| Pose {
                center: 0.37 * (r * p.center) + Vec3::new(100.0, -40.0, 7.0),
                rotation: p.rotation * r.transpose(),
            })
            .collect()
    }

    /// The views with their poses moved [`elsewhere`].
    fn seen_elsewhere(truth: &[TargetView]) -> Vec<TargetView> {
        let poses: Vec<Pose> = truth.iter().map(|v| v.pose).collect();
        truth
            .iter()
            .zip(elsewhere(&poses))
            .map(|(v, pose)| TargetView { pose, ..v.clone() })
            .collect()
    }

    #[test]
    fn targets_are_named_from_poses_in_another_frame() {
        let (camera, poses, points) = site();
        let truth = views(&camera, &poses, &points, true);
        let views = seen_elsewhere(&truth);
        let naming = name(&views, &camera, &points, &[], &NameSettings::default()).expect("named");
        assert_eq!(naming.matched, naming.intersected);
        assert!(naming.rms_m < 1e-6, "{}", naming.rms_m);
        // Every true detection named right, the clutter not at all.
        let expected: usize = truth.iter().map(|v| v.detections.len() - 1).sum();
        assert_eq!(naming.observations.len(), expected);
        for o in &naming.observations {
            let p = &points.iter().find(|p| p.0 == o.id).expect("a surveyed id").1;
            let px = poses[o.frame].project(&camera, p).expect("in front");
            assert!((px[0] - o.centre[0]).hypot(px[1] - o.centre[1]) < 1e-6, "{o:?}");
        }
        assert!(naming.unseen.is_empty(), "{:?}", naming.unseen);
        assert!((naming.similarity.scale - 1.0 / 0.37).abs() < 1e-6);
    }

    #[test]
    fn a_point_missing_from_the_survey_names_nothing_and_an_unseen_point_is_listed() {
        let (camera, poses, mut points) = site();
        let views = views(&camera, &poses, &points, false);
        let gone = points.remove(5);
        points.push(("FAR".into(), Vec3::new(60.0, 0.0, 3.0)));
        let naming = name(&views, &camera, &points, &[], &NameSettings::default()).expect("named");
        assert!(naming.observations.iter().all(|o| o.id != gone.0));
        assert_eq!(naming.unseen, vec!["FAR".to_string()]);
        assert_eq!(naming.matched + 1, naming.intersected);
    }

    #[test]
    fn a_full_regular_grid_seen_in_part_is_refused_as_ambiguous() {
        let camera = Camera::pinhole(2000, 1500, 0.005, 12.0);
        let (_, poses, _) = site();
        let grid: Vec<(String, Vec3)> = (0..12)
            .flat_map(|col| {
                (0..4).map(move |row| {
                    (
                        format!("G{col}{row}"),
                        Vec3::new(3.0 * col as f64 - 6.0, 0.0, 2.5 * row as f64 + 1.5),
                    )
                })
            })
            .collect();
        // The cameras see x from about -6 to 26 m and the grid continues beyond: a shift by a column fits the
        // part seen as well, and shows a target wherever the survey has one.
        let views = views(&camera, &poses, &grid, false);
        let err = name(&views, &camera, &grid, &[], &NameSettings::default()).expect_err("ambiguous");
        assert!(matches!(err, NamingError::Ambiguous { .. }), "{err}");
    }

    #[test]
    fn a_symmetric_grid_on_a_wall_is_named_once_the_wall_is_known() {
        let (camera, poses, _) = site();
        // A full 7 × 4 grid, all in view: turned half a turn about its vertical axis it is the same grid with the
        // cameras behind the wall, about its normal with them upside down.
        let grid: Vec<(String, Vec3)> = (0..7)
            .flat_map(|col| {
                (0..4).map(move |row| {
                    (
                        format!("G{col}{row}"),
                        Vec3::new(3.0 * col as f64 + 1.0, 0.0, 2.5 * row as f64 + 1.5),
                    )
                })
            })
            .collect();
        let truth = views(&camera, &poses, &grid, false);
        let views = seen_elsewhere(&truth);
        let err = name(&views, &camera, &grid, &[], &NameSettings::default()).expect_err("ambiguous without the wall");
        assert!(matches!(err, NamingError::Ambiguous { .. }), "{err}");
        let wall = Face {
            point: Vec3::zeros(),
            outward: -Vec3::y(),
        };
        let naming = name(&views, &camera, &grid, &[wall], &NameSettings::default()).expect("named");
        assert_eq!(naming.matched, grid.len());
        for o in &naming.observations {
            let p = &grid.iter().find(|p| p.0 == o.id).expect("a surveyed id").1;
            let px = poses[o.frame].project(&camera, p).expect("in front");
            assert!((px[0] - o.centre[0]).hypot(px[1] - o.centre[1]) < 1e-6, "{o:?}");
        }
    }

    #[test]
    fn the_seeds_leave_a_row_of_best_seen_targets_for_the_rest_of_the_block() {
        // Twelve on one row first, as the best-seen can be, then two rows more.
        let block: Vec<Vec3> = (0..3)
            .flat_map(|row| (0..12).map(move |col| Vec3::new(col as f64, 0.0, 3.0 * row as f64)))
            .collect();
        let seeds = spread(&block, 12);
        assert_eq!(seeds[0], 0);
        assert!(seeds.iter().any(|&t| block[t].z > 0.0), "{seeds:?}");
        let mut unique = seeds.clone();
        unique.sort_unstable();
        unique.dedup();
        assert_eq!(unique.len(), 12);
        assert_eq!(spread(&block[..5], 12).len(), 5);
    }

    #[test]
    fn too_few_targets_or_points_and_another_site_are_errors() {
        let (camera, poses, points) = site();
        let few: Vec<(String, Vec3)> = points[..3].to_vec();
        let v = views(&camera, &poses, &few, false);
        assert!(matches!(
            name(&v, &camera, &points, &[], &NameSettings::default()),
            Err(NamingError::TooFewIntersected { found: 3, .. })
        ));
        assert_eq!(
            name(&v, &camera, &few, &[], &NameSettings::default()).unwrap_err(),
            NamingError::TooFewPoints(3)
        );
        // Surveyed points of another site: as many, anywhere on a wall of the same size.
        let other: Vec<(String, Vec3)> = (0..points.len() as u64)
            .map(|k| {
                let u = |part| lineflow_photogrammetry::random::unit(lineflow_photogrammetry::random::hash(&[k, part]));
                (format!("O{k}"), Vec3::new(20.0 * u(1), 0.0, 1.0 + 9.0 * u(2)))
            })
            .collect();
        let v = views(&camera, &poses, &points, false);
        assert!(matches!(
            name(&v, &camera, &other, &[], &NameSettings::default()),
            Err(NamingError::NoFit { .. })
        ));
    }
}
