//! Structure or texture, asked of the images: is there one surface on both sides of a 3-D line?
//!
//! A joint of a brick, tile or panel wall lies inside the wall: the bricks above and below a course, beside a
//! perpend, are one plane, and every image shows them where that plane puts them. An edge of the building has
//! one side that is no part of the surface on the other: a jamb's outer corner has the wall on one side and the
//! reveal, seen at a slant from some images and hidden from others, on the other; a head has the soffit below it,
//! an eaves line the roof above, a sill's nose the wall 6 cm behind it. So each side of the line is swept on its
//! own (Baillard & Zisserman's half-plane test, after their plane sweep of 2000): a narrow ribbon beside the line
//! in the image that sees it longest, carried by planes through that image's rays at depths around the line's,
//! correlated with every other image that sees it. A side whose ribbon the images agree on finds a surface there,
//! at the depth where they agree best. Both sides finding one surface at one depth is a line inside a surface:
//! texture. One side finding a surface and the other none, or another depth, is a step: structure. A side with too
//! little texture to correlate (plaster, glass, sky) has no say, and neither has the test then.
//!
//! The depth of the line itself plays no part beyond centring the sweep: a course matched one course off, in
//! front of its wall or behind it, still has the wall's bricks on both sides in the reference image, and the sweep
//! finds the wall's depth for both.
use lineflow_photogrammetry::{Camera, Pose, Vec3};

use crate::class::RuleError;
use crate::photo::{ncc, sample_rows, variance, Photo};

/// The settings of the test: the `sides` parameter of the line stages, a table (`sides = { width_px = 3 }`; what
/// it leaves out keeps its default).
#[derive(Debug, Clone, PartialEq, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SideRule {
    /// Off by default until measured on held-out buildings; `true` runs the test on the lines classed structure.
    pub enabled: bool,
    /// The ribbon of a side starts this far from the line, pixels of the reference image: the edge's own
    /// gradient agrees at the line's depth on both sides and would make every edge look like a line in a surface.
    pub gap_px: f64,
    /// Rows of a side's ribbon, one reference pixel apart.
    pub width_px: usize,
    /// The sweep covers this far in front of the line and behind it, metres.
    pub reach_m: f64,
    /// Most samples along the line (a longer line is sampled more sparsely).
    pub max_samples: usize,
    /// Most images compared with the reference (those that see the line longest).
    pub max_views: usize,
    /// Grey-value variance a side needs in the reference image to have a say.
    pub min_variance: f32,
    /// Mean correlation over the images at which a side finds a surface.
    pub min_correlation: f64,
    /// A side's peak must stand this much above its correlation `contrast_px` or more of parallax away.
    pub min_contrast: f64,
    /// See `min_contrast`, pixels of parallax in the image that sees depth best.
    pub contrast_px: f64,
    /// Two sides' surfaces lie at one depth when their depths differ by less than this much parallax in the image
    /// that sees depth best, pixels.
    pub same_px: f64,
    /// ... and by no more than this, metres. Where this much depth is less than `same_px` of parallax in the image
    /// that sees depth best (at the test scale, 0.3, a pixel is 10-15 cm of depth), a pane's edge and its frame 4 cm
    /// in front of it are alike to the images, and the test gives no texture verdict.
    pub same_m: f64,
}

impl Default for SideRule {
    fn default() -> Self {
        SideRule {
            enabled: false,
            gap_px: 2.5,
            width_px: 3,
            reach_m: 0.3,
            max_samples: 48,
            max_views: 17,
            min_variance: 9.0,
            min_correlation: 0.5,
            min_contrast: 0.15,
            contrast_px: 4.0,
            same_px: 0.5,
            same_m: 0.03,
        }
    }
}

impl SideRule {
    /// `Ok` for settings that make sense, else the first that does not.
    pub fn validate(&self) -> Result<(), RuleError> {
        let bad = |name: &str, requirement: &'static str, value: String| Err(RuleError::of("sides", name, requirement, value));
        if !(self.gap_px.is_finite() && self.gap_px >= 0.0) {
            return bad("gap_px", ">= 0", self.gap_px.to_string());
        }
        if self.width_px == 0 {
            return bad("width_px", ">= 1", self.width_px.to_string());
        }
        if !(self.reach_m.is_finite() && self.reach_m > 0.0) {
            return bad("reach_m", "> 0", self.reach_m.to_string());
        }
        if self.max_samples < 4 {
            return bad("max_samples", ">= 4", self.max_samples.to_string());
        }
        if self.max_views == 0 {
            return bad("max_views", ">= 1", self.max_views.to_string());
        }
        if !(self.min_variance.is_finite() && self.min_variance >= 0.0) {
            return bad("min_variance", ">= 0", self.min_variance.to_string());
        }
        if !(-1.0..=1.0).contains(&self.min_correlation) {
            return bad("min_correlation", "in [-1, 1]", self.min_correlation.to_string());
        }
        if !(self.min_contrast.is_finite() && self.min_contrast >= 0.0) {
            return bad("min_contrast", ">= 0", self.min_contrast.to_string());
        }
        if !(self.contrast_px.is_finite() && self.contrast_px > 0.0) {
            return bad("contrast_px", "> 0", self.contrast_px.to_string());
        }
        if !(self.same_m.is_finite() && self.same_m > 0.0) {
            return bad("same_m", "> 0", self.same_m.to_string());
        }
        if !(self.same_px.is_finite() && self.same_px > 0.0) {
            return bad("same_px", "> 0", self.same_px.to_string());
        }
        Ok(())
    }
}

/// One oriented image with its grey values.
#[derive(Debug, Clone, Copy)]
pub struct PhotoView<'a> {
    /// Exterior orientation.
    pub pose: &'a Pose,
    /// Grey values.
    pub photo: &'a Photo,
}

/// What the images say of the two sides of a line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Verdict {
    /// One surface on both sides, at one depth: a line inside it.
    Texture,
    /// A surface on one side, none or another depth on the other: an edge.
    Step,
    /// Too few images, too little texture, or no surface on either side.
    Unknown,
}

/// The sweep of one side: the depth (metres from the line, towards the reference camera positive) at which the
/// images agree best, and their mean correlation there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Peak {
    /// Depth of the best agreement, metres.
    pub depth_m: f64,
    /// Mean correlation of the images there.
    pub correlation: f64,
    /// By how much that stands above the correlation `contrast_px` or more of parallax away (infinite when the
    /// sweep reaches no such depth): a pattern that the parallax does not move, such as lines across a ribbon
    /// along the baseline, agrees at every depth and fixes none.
    pub contrast: f64,
}

/// The test's findings on one line.
#[derive(Debug, Clone, PartialEq)]
pub struct SideReport {
    /// The verdict.
    pub verdict: Verdict,
    /// Each side's peak, where the side has texture enough and images to compare.
    pub peaks: [Option<Peak>; 2],
    /// Parallax per metre of depth in the image that sees depth best, pixels (0 without a sweep).
    pub px_per_m: f64,
}

impl SideReport {
    fn unknown() -> Self {
        SideReport {
            verdict: Verdict::Unknown,
            peaks: [None, None],
            px_per_m: 0.0,
        }
    }
}

/// Sweeps the two sides of the segment `ends` through `views` (see the module's text).
pub fn sides(camera: &Camera, views: &[PhotoView], ends: &[Vec3; 2], rule: &SideRule) -> SideReport {
    let inside = |pose: &Pose, p: &Vec3| pose.project(camera, p).filter(|px| camera.contains(*px, 0.0));
    // The images that show the whole segment, longest first; ties go to the lower index, so that the report does not
    // depend on anything but the order of `views`.
    let mut seeing: Vec<(usize, f64)> = views
        .iter()
        .enumerate()
        .filter_map(|(k, v)| {
            let (a, b) = (inside(v.pose, &ends[0])?, inside(v.pose, &ends[1])?);
            let len = (b[0] - a[0]).hypot(b[1] - a[1]);
            (len >= 4.0).then_some((k, len))
        })
        .collect();
    seeing.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
    if seeing.len() < 3 {
        return SideReport::unknown();
    }
    let reference = &views[seeing[0].0];
    let others: Vec<&PhotoView> = seeing[1..].iter().take(rule.max_views).map(|&(k, _)| &views[k]).collect();
    let Some(ribbon) = Ribbon::new(camera, reference.pose, ends, seeing[0].1, rule) else {
        return SideReport::unknown();
    };
    let base = along_only(ribbon.sample(camera, reference, 0.0), ribbon.cols);
    let w = rule.width_px;
    let rows = [0..w, w..2 * w];
    let textured = rows.clone().map(|r| {
        let (spread, n) = variance(&base, ribbon.cols, r);
        2 * n >= w * ribbon.cols && spread >= rule.min_variance
    });
    if !textured.iter().any(|&t| t) {
        return SideReport::unknown();
    }
    // Parallax per metre of depth at the line's middle, in each image.
    let mid = (ends[0] + ends[1]) * 0.5;
    let mid_shift = ribbon.depth_shift(&(mid - reference.pose.center));
    let px_per_m = others
        .iter()
        .filter_map(|v| {
            let a = v.pose.project(camera, &mid)?;
            let b = v.pose.project(camera, &(mid + mid_shift * 0.01))?;
            Some((b[0] - a[0]).hypot(b[1] - a[1]) / 0.01)
        })
        .fold(0.0, f64::max);
    if px_per_m < 1e-6 {
        return SideReport::unknown();
    }
    // Half a pixel of parallax per step in the image that sees depth best.
    let step = 0.5 / px_per_m;
    let n = ((rule.reach_m / step).ceil() as i64).clamp(1, 64);
    // Each side's mean correlation at every depth, nearest the line first.
    let order: Vec<i64> = (0..=n).flat_map(|i| if i == 0 { vec![0] } else { vec![-i, i] }).collect();
    let mut profile = [vec![None; order.len()], vec![None; order.len()]];
    for (slot, &i) in order.iter().enumerate() {
        let depth = i as f64 * step;
        let mut sum = [0.0; 2];
        let mut count = [0usize; 2];
        for v in &others {
            let values = along_only(ribbon.sample(camera, v, depth), ribbon.cols);
            for s in (0..2).filter(|&s| textured[s]) {
                if let Some(c) = ncc(&base, rows[s].clone(), &values, rows[s].clone(), ribbon.cols) {
                    sum[s] += c;
                    count[s] += 1;
                }
            }
        }
        for s in 0..2 {
            profile[s][slot] = (count[s] >= 2).then(|| sum[s] / count[s] as f64);
        }
    }
    // Steps of half a pixel: a peak stands out from what lies `contrast_px` or more away.
    let apart = (2.0 * rule.contrast_px).round() as i64;
    let best = profile.map(|p| peak(&order, &p, apart, step));
    SideReport {
        verdict: verdict(&best, px_per_m, rule),
        peaks: best,
        px_per_m,
    }
}

/// The highest point of a profile over the depths `order` (steps of `step` metres; the first highest in that
/// order), and by how much it stands above every point `apart` steps or more from it.
fn peak(order: &[i64], profile: &[Option<f64>], apart: i64, step: f64) -> Option<Peak> {
    let (at, correlation) =
        order
            .iter()
            .zip(profile)
            .filter_map(|(&i, c)| c.map(|c| (i, c)))
            .fold(None, |best: Option<(i64, f64)>, (i, c)| match best {
                Some((_, b)) if b >= c => best,
                _ => Some((i, c)),
            })?;
    let rest = order
        .iter()
        .zip(profile)
        .filter(|(&i, _)| (i - at).abs() >= apart)
        .filter_map(|(_, c)| *c)
        .fold(f64::NEG_INFINITY, f64::max);
    // The depth between the steps: the parabola through the peak and its two neighbours.
    let at_step = |i: i64| order.iter().position(|&j| j == i).and_then(|k| profile[k]);
    let offset = match (at_step(at - 1), at_step(at + 1)) {
        (Some(l), Some(r)) if l + r - 2.0 * correlation < -1e-12 => (0.5 * (l - r) / (l + r - 2.0 * correlation)).clamp(-0.5, 0.5),
        _ => 0.0,
    };
    Some(Peak {
        depth_m: (at as f64 + offset) * step,
        correlation,
        contrast: correlation - rest,
    })
}

/// How many lines of each verdict a [`reclass`] gave, of those it tested.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SideCounts {
    /// Lines tested (those classed structure).
    pub tested: usize,
    /// Of those, found inside a surface and classed texture now.
    pub texture: usize,
    /// Found to be edges.
    pub step: usize,
}

/// Tests every line classed structure and classes texture those with one surface on both sides (a line the
/// class rules leave as structure is only ever moved to texture: the rules' texture lines are joints in a field,
/// of which next to none are edges). In parallel; the result does not depend on the number of threads.
pub fn reclass(lines: &mut [lineflow_messages::Line3], camera: &Camera, views: &[PhotoView], rule: &SideRule) -> SideCounts {
    use lineflow_messages::LineClass;
    use rayon::prelude::*;
    let verdicts: Vec<Option<Verdict>> = lines
        .par_iter()
        .map(|l| {
            (LineClass::from_code(l.class) == LineClass::Structure)
                .then(|| sides(camera, views, &[Vec3::from(l.start_m), Vec3::from(l.end_m)], rule).verdict)
        })
        .collect();
    let mut counts = SideCounts::default();
    for (l, v) in lines.iter_mut().zip(verdicts) {
        let Some(v) = v else { continue };
        counts.tested += 1;
        match v {
            Verdict::Texture => {
                l.class = LineClass::Texture.code();
                counts.texture += 1;
            }
            Verdict::Step => counts.step += 1,
            Verdict::Unknown => {}
        }
    }
    counts
}

/// What one side's sweep found.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Side {
    /// The images agree well there, at one depth more than at any other: a surface at that depth.
    Surface(f64),
    /// The images disagree at every depth: no surface facing them (a slanted reveal, what one image sees past an
    /// edge and another does not).
    Disagreed,
    /// They agree, but as well at other depths: a pattern the parallax does not move fixes no depth.
    Unfixed,
}

fn side(peak: &Option<Peak>, rule: &SideRule) -> Option<Side> {
    let p = peak.as_ref()?;
    Some(if p.correlation < rule.min_correlation {
        Side::Disagreed
    } else if p.contrast >= rule.min_contrast {
        Side::Surface(p.depth_m)
    } else {
        Side::Unfixed
    })
}

fn verdict(peaks: &[Option<Peak>; 2], px_per_m: f64, rule: &SideRule) -> Verdict {
    match (side(&peaks[0], rule), side(&peaks[1], rule)) {
        (Some(Side::Surface(a)), Some(Side::Surface(b))) => {
            let apart_px = (a - b).abs() * px_per_m;
            // Where `same_m` of depth is less than `same_px` of parallax, the images cannot tell a surface from one
            // `same_m` behind it, and a pane's edge from its frame: no texture verdict then.
            if apart_px <= rule.same_px && (a - b).abs() <= rule.same_m && px_per_m * rule.same_m >= rule.same_px {
                Verdict::Texture
            } else if apart_px > 3.0 * rule.same_px {
                Verdict::Step
            } else {
                Verdict::Unknown
            }
        }
        (Some(Side::Surface(_)), Some(Side::Disagreed)) | (Some(Side::Disagreed), Some(Side::Surface(_))) => Verdict::Step,
        _ => Verdict::Unknown,
    }
}

/// Each row of a grid of `cols` columns less its mean (of its finite values): what is left is what varies along
/// the line. The rows' means are the edge's own profile across the line, which every image shows alike at the
/// line's depth on both sides of an edge as much as of a joint; only the surface's pattern along it tells them apart.
fn along_only(mut values: Vec<f32>, cols: usize) -> Vec<f32> {
    for row in values.chunks_mut(cols) {
        let (sum, n) = row.iter().filter(|x| x.is_finite()).fold((0.0, 0), |(s, n), x| (s + x, n + 1));
        if n > 0 {
            let mean = sum / n as f32;
            row.iter_mut().for_each(|x| *x -= mean);
        }
    }
    values
}

/// The object-space samples of the two sides: `cols` along the line, `width_px` rows on each side of it (side 0
/// first, from the line outwards, then side 1), one reference pixel apart across, in the plane through the line that
/// faces the reference image; and for each, the shift per metre of depth along the reference image's ray through
/// it, so that the reference sees every sample at every depth in the same place.
struct Ribbon {
    points: Vec<Vec3>,
    shifts: Vec<Vec3>,
    cols: usize,
    /// The plane's normal, towards the reference camera.
    normal: Vec3,
}

impl Ribbon {
    fn new(camera: &Camera, reference: &Pose, ends: &[Vec3; 2], length_px: f64, rule: &SideRule) -> Option<Self> {
        let along = ends[1] - ends[0];
        let mid = (ends[0] + ends[1]) * 0.5;
        let to_camera = reference.center - mid;
        let unit = along.try_normalize(1e-12)?;
        let normal = (to_camera - unit * unit.dot(&to_camera)).try_normalize(1e-12)?;
        let across = unit.cross(&normal);
        let step = to_camera.norm() * camera.pixel_size_mm / camera.focal_mm;
        let cols = (length_px.floor() as usize).clamp(4, rule.max_samples);
        let w = rule.width_px;
        let mut points = Vec::with_capacity(2 * w * cols);
        for (sign, r) in (0..w).map(|r| (-1.0, r)).chain((0..w).map(|r| (1.0, r))) {
            let offset = across * (sign * (rule.gap_px + r as f64) * step);
            points.extend((0..cols).map(|c| ends[0] + along * ((c as f64 + 0.5) / cols as f64) + offset));
        }
        let mut ribbon = Ribbon {
            points,
            shifts: Vec::new(),
            cols,
            normal,
        };
        ribbon.shifts = ribbon.points.iter().map(|p| ribbon.depth_shift(&(p - reference.center))).collect();
        Some(ribbon)
    }

    /// How far a point seen along `ray` moves along it when its plane moves a metre towards the camera.
    fn depth_shift(&self, ray: &Vec3) -> Vec3 {
        let d = self.normal.dot(ray);
        if d.abs() < 1e-9 {
            Vec3::zeros()
        } else {
            ray / d
        }
    }

    /// The ribbon's grey values in `view` with its plane moved `depth` metres towards the reference camera (NaN
    /// where the view does not show a sample).
    fn sample(&self, camera: &Camera, view: &PhotoView, depth: f64) -> Vec<f32> {
        sample_rows(view.photo, self.points.len(), self.cols, |k| {
            view.pose.project(camera, &(self.points[k] + self.shifts[k] * depth))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_photogrammetry::rotation_from_opk;

    /// 1 cm per pixel at 12 m.
    fn camera() -> Camera {
        Camera::pinhole(400, 300, 0.005, 6.0)
    }

    /// Grey value of a 1.5 cm cell of a surface (a fixed random pattern), flat for u < -1.6 m.
    fn texture(u: f64, v: f64, surface: u64) -> u8 {
        if u < -1.6 {
            return 128;
        }
        let (i, j) = ((u / 0.015).floor() as i64 as u64, (v / 0.015).floor() as i64 as u64);
        let mut h = i.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ j.wrapping_mul(0xC2B2_AE3D_27D4_EB4F) ^ surface;
        h ^= h >> 29;
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        60 + (h >> 56) as u8 % 140
    }

    /// A wall y = 0 with a pier 0.3 m in front of it for x ≥ 0 (its front y = -0.3, its side x = 0), seen along
    /// `ray` from `from`.
    fn shade(from: &Vec3, ray: &Vec3) -> u8 {
        let hit = |y: f64| from + ray * ((y - from.y) / ray.y);
        let front = hit(-0.3);
        if front.x >= 0.0 {
            return texture(front.x, front.z, 1);
        }
        let wall = hit(0.0);
        if wall.x < 0.0 {
            return texture(wall.x, wall.z, 0);
        }
        // Between the pier's front and the wall, the ray crosses x = 0: the pier's side.
        let side = from + ray * ((0.0 - from.x) / ray.x);
        texture(side.y, side.z, 2)
    }

    fn views() -> Vec<(Pose, Photo)> {
        let cam = camera();
        (0..5)
            .map(|k| {
                let pose = Pose {
                    center: Vec3::new(k as f64 - 2.5, -12.0, 1.5),
                    rotation: rotation_from_opk(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
                };
                let gray = (0..cam.height as usize)
                    .flat_map(|r| (0..cam.width as usize).map(move |c| [c as f64, r as f64]))
                    .map(|px| shade(&pose.center, &pose.ray_of_pixel(&cam, px)))
                    .collect();
                (pose, Photo::new(cam.width as usize, cam.height as usize, gray).unwrap())
            })
            .collect()
    }

    #[test]
    fn one_surface_on_both_sides_is_texture_and_a_depth_step_is_an_edge() {
        let cam = camera();
        let rendered = views();
        let v: Vec<PhotoView> = rendered.iter().map(|(pose, photo)| PhotoView { pose, photo }).collect();
        let rule = SideRule::default();
        let plumb = |x: f64, y: f64| [Vec3::new(x, y, 0.8), Vec3::new(x, y, 2.2)];
        let verdict = |ends: [Vec3; 2]| sides(&cam, &v, &ends, &rule);
        // A line drawn on the wall, and one on the pier's front.
        assert_eq!(verdict(plumb(-1.0, 0.0)).verdict, Verdict::Texture);
        assert_eq!(verdict(plumb(0.8, -0.3)).verdict, Verdict::Texture);
        // The line on the wall placed 12 cm in front of it: the sweep still finds the wall on both sides.
        let misplaced = verdict(plumb(-1.0, -0.12));
        assert_eq!(misplaced.verdict, Verdict::Texture, "{misplaced:?}");
        let depth = misplaced.peaks[0].unwrap().depth_m;
        assert!((depth + 0.12).abs() < 0.03, "the wall lies 12 cm behind the line: {depth}");
        // The pier's corner: its front on one side, its side or the wall behind on the other.
        let corner = verdict(plumb(0.0, -0.3));
        assert_eq!(corner.verdict, Verdict::Step, "{corner:?}");
        // A level line on the wall: the parallax runs along it, the pattern still tells.
        assert_eq!(
            verdict([Vec3::new(-1.4, 0.0, 1.2), Vec3::new(-0.4, 0.0, 1.2)]).verdict,
            Verdict::Texture
        );
        // No texture on either side: no say.
        assert_eq!(verdict(plumb(-1.8, 0.0)).verdict, Verdict::Unknown);
        // Where 1 cm of depth is less than half a pixel of parallax, no texture verdict within 1 cm can be trusted.
        let fine = SideRule {
            same_m: 0.01,
            ..SideRule::default()
        };
        assert_eq!(sides(&cam, &v, &plumb(-1.0, 0.0), &fine).verdict, Verdict::Unknown);
        // Fewer than three images: no say.
        assert_eq!(sides(&cam, &v[..2], &plumb(-1.0, 0.0), &rule).verdict, Verdict::Unknown);
    }

    #[test]
    fn settings_out_of_range_are_named() {
        let bad = SideRule {
            width_px: 0,
            ..SideRule::default()
        };
        assert_eq!(bad.validate().unwrap_err().name, "sides.width_px");
        assert!(SideRule::default().validate().is_ok());
    }
}
