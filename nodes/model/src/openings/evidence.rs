//! What the images say about a predicted opening. The rows and columns of a façade predict where the openings the
//! 3-D lines missed are ([`super::grid`]); the 3-D lines often miss a side because it was matched in too few
//! images or at a wrong depth, while the images' 2-D lines show it plainly. A side predicted on the wall is
//! projected into every oriented image that sees it whole; an image sees the side where its 2-D lines run along the
//! projection (within the side's position tolerance, projected) over most of its length. A side the 3-D lines did
//! not give counts as seen where enough of the images that look at it show it (CSR's Refine and seed 004's fitting
//! put to work on a hypothesis: the images decide, the model's regularity only says where to look).
use lineflow_photogrammetry::{Camera, Vec3};

use super::sides::covered_share;
use super::MAX_SIDE_GAP_M;
use crate::refine::{cross, dot, sub, ImageLines};

/// A projected side shorter than this is not judged in that image, pixels.
const MIN_PROJECTED_PX: f64 = 15.0;
/// An image line lies on a side where both its ends lie within this of it, pixels (the lines' own noise).
const ON_SIDE_PX: f64 = 1.5;
/// An image shows a side where its lines cover at least this share of the side's projection, and run on at most
/// [`MAX_SIDE_GAP_M`] past either end, as the 3-D lines must ([`super::ends_within`]): a brick course or a storey
/// line runs on past where an opening's sill or head stops, and lies at every height.
const MIN_IMAGE_COVER: f64 = 0.4;
/// A side counts as seen in the images where at least this share of the images that look at it show it…
const MIN_IMAGE_SHARE: f64 = 0.5;
/// …and at least this many.
pub(super) const MIN_IMAGES: usize = 2;

/// The oriented images' 2-D lines and their camera.
#[derive(Clone, Copy)]
pub(crate) struct Evidence<'a> {
    pub(crate) camera: &'a Camera,
    pub(crate) images: &'a [ImageLines],
}

/// A side measured in the images: where they put it, and how many show it there of how many that look at it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Measured {
    /// How far from the predicted side, metres along the direction it was searched in.
    pub(crate) offset_m: f64,
    pub(crate) showing: usize,
    pub(crate) looking: usize,
}

impl Measured {
    /// At least [`MIN_IMAGES`] show it, and at least [`MIN_IMAGE_SHARE`] of those looking.
    pub(crate) fn seen(&self) -> bool {
        self.showing >= MIN_IMAGES && self.showing as f64 >= MIN_IMAGE_SHARE * self.looking as f64
    }
}

/// One image's view of a side: the image lines along it, as (offset across in metres at the side, interval along
/// it in ideal units), the projected length, the ideal units per metre across, and how far past the ends lines
/// may run, ideal units.
struct View {
    lines: Vec<(f64, (f64, f64))>,
    len: f64,
    units_per_m: f64,
    run_on: f64,
}

impl View {
    /// Whether the lines `offset_m` across show the side: they cover at least [`MIN_IMAGE_COVER`] of it, and none
    /// that reaches it runs on more than [`MAX_SIDE_GAP_M`] past its ends.
    fn shows(&self, offset_m: f64, pixel_mm: f64) -> bool {
        let tol = self.on_side_m(pixel_mm);
        let spans: Vec<(f64, f64)> = self.lines.iter().filter(|l| (l.0 - offset_m).abs() <= tol).map(|l| l.1).collect();
        let (lo, hi) = (-self.run_on, self.len + self.run_on);
        let runs_on = spans.iter().any(|&(a, b)| b > lo && a < hi && (a < lo || b > hi));
        !runs_on && covered_share(&spans, 0.0, self.len) >= MIN_IMAGE_COVER
    }

    /// [`ON_SIDE_PX`] at the side, metres across it: the lines' own noise.
    fn on_side_m(&self, pixel_mm: f64) -> f64 {
        ON_SIDE_PX * pixel_mm / self.units_per_m
    }
}

/// The positions across the side, metres, of every line any of `views` has along it.
fn offsets(views: &[View]) -> Vec<f64> {
    views.iter().flat_map(|v| v.lines.iter().map(|l| l.0)).collect()
}

impl Evidence<'_> {
    /// The side `a`–`b` measured in the images: every oriented image that sees it whole (both ends in the frame,
    /// at least [`MIN_PROJECTED_PX`] long) looks for 2-D lines along it within `reach_m` of it along `across`
    /// (both ends within [`ON_SIDE_PX`] of one position); the position where most images' lines cover at least
    /// [`MIN_IMAGE_COVER`] of the side without running on past its ends ([`MAX_SIDE_GAP_M`]) is the side's (the
    /// nearest to the prediction among equals). Lines of one edge agree on a position in object space; an edge
    /// behind the wall (a frame, a reveal) is seen at positions that differ with the viewpoint and gathers fewer
    /// images.
    pub(crate) fn measure(&self, a: &Vec3, b: &Vec3, across: &Vec3, reach_m: f64) -> Measured {
        let views = self.views(a, b, across, reach_m);
        let mut candidates = offsets(&views);
        candidates.sort_by(|x, y| x.abs().total_cmp(&y.abs()).then(x.total_cmp(y)));
        let mut best = Measured {
            offset_m: 0.0,
            showing: 0,
            looking: views.len(),
        };
        for c in candidates {
            let m = self.measured_at(&views, c);
            if m.showing > best.showing {
                best = m;
            }
        }
        best
    }

    /// How many of `views` show the side at `offset_m`.
    fn measured_at(&self, views: &[View], offset_m: f64) -> Measured {
        Measured {
            offset_m,
            showing: views.iter().filter(|v| v.shows(offset_m, self.camera.pixel_size_mm)).count(),
            looking: views.len(),
        }
    }

    /// Every position within `reach_m` of the side `a`–`b` along `across` where the images show it
    /// ([`Measured::seen`]), one per position (within the lines' noise of each other, the one most images show),
    /// in order along `across`.
    pub(crate) fn positions(&self, a: &Vec3, b: &Vec3, across: &Vec3, reach_m: f64) -> Vec<Measured> {
        let views = self.views(a, b, across, reach_m);
        let mut candidates = offsets(&views);
        candidates.sort_by(f64::total_cmp);
        // One position per edge: candidates closer than the lines' noise at the side belong to one.
        let noise_m = views.iter().map(|v| v.on_side_m(self.camera.pixel_size_mm)).fold(0.0, f64::max);
        let mut out: Vec<Measured> = Vec::new();
        for c in candidates {
            let m = self.measured_at(&views, c);
            if !m.seen() {
                continue;
            }
            match out.last_mut() {
                Some(last) if c - last.offset_m <= noise_m => {
                    if m.showing > last.showing {
                        *last = m;
                    }
                }
                _ => out.push(m),
            }
        }
        out
    }

    /// Where the images' lines along the side `a`–`b` start and end, for every image that shows the side
    /// ([`Measured::seen`]'s per-image test): as shares of the way from `a` to `b` (below 0 and above 1 where they run
    /// on past the ends), the union of the lines on the side.
    pub(crate) fn extents(&self, a: &Vec3, b: &Vec3, across: &Vec3) -> Vec<(f64, f64)> {
        let pixel_mm = self.camera.pixel_size_mm;
        self.views(a, b, across, 0.0)
            .iter()
            .filter(|v| v.shows(0.0, pixel_mm))
            .filter_map(|v| {
                let tol = v.on_side_m(pixel_mm);
                let on: Vec<(f64, f64)> = v
                    .lines
                    .iter()
                    .filter(|l| l.0.abs() <= tol && l.1 .1 > 0.0 && l.1 .0 < v.len)
                    .map(|l| l.1)
                    .collect();
                let lo = on.iter().map(|s| s.0).fold(f64::INFINITY, f64::min);
                let hi = on.iter().map(|s| s.1).fold(f64::NEG_INFINITY, f64::max);
                (lo < hi).then(|| (lo / v.len, hi / v.len))
            })
            .collect()
    }

    /// The views of the side `a`–`b` of every oriented image that sees it whole.
    fn views(&self, a: &Vec3, b: &Vec3, across: &Vec3, reach_m: f64) -> Vec<View> {
        self.images
            .iter()
            .filter_map(|image| self.view(image, a, b, across, reach_m))
            .collect()
    }

    /// `image`'s view of the side `a`–`b`; none where the image does not see it whole.
    fn view(&self, image: &ImageLines, a: &Vec3, b: &Vec3, across: &Vec3, reach_m: f64) -> Option<View> {
        let pose = image.pose()?;
        let (pa, pb) = (image.visible(self.camera, a)?, image.visible(self.camera, b)?);
        let d = sub(pb, pa);
        let len = d[0].hypot(d[1]);
        if len < MIN_PROJECTED_PX * self.camera.pixel_size_mm {
            return None;
        }
        let u = [d[0] / len, d[1] / len];
        // The projection's scale across the side, from a step small against the distance.
        const STEP_M: f64 = 0.01;
        let units_per_m = cross(u, sub(pose.project_ideal(self.camera, &(a + across * STEP_M))?, pa)) / STEP_M;
        if units_per_m.abs() < 1e-12 {
            return None;
        }
        let reach = reach_m * units_per_m.abs() + ON_SIDE_PX * self.camera.pixel_size_mm;
        let on_side = 2.0 * ON_SIDE_PX * self.camera.pixel_size_mm;
        let lines = image
            .near(pa, pb, reach)
            .filter_map(|s| {
                let (o0, o1) = (cross(u, sub(s[0], pa)), cross(u, sub(s[1], pa)));
                let (t0, t1) = (dot(sub(s[0], pa), u), dot(sub(s[1], pa), u));
                (o0.abs().max(o1.abs()) <= reach && (o0 - o1).abs() <= on_side)
                    .then(|| ((o0 + o1) / 2.0 / units_per_m, (t0.min(t1), t0.max(t1))))
            })
            .collect();
        Some(View {
            lines,
            len,
            units_per_m: units_per_m.abs(),
            run_on: MAX_SIDE_GAP_M * len / (b - a).norm(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_views::{cameras, image_lines};

    #[test]
    fn a_side_the_images_show_is_measured_where_they_put_it() {
        let (camera, poses) = cameras(&[-0.5, 0.0, 0.5]);
        let jamb = (Vec3::new(0.2, 0.0, 0.0), Vec3::new(0.2, 0.0, 1.0));
        let images: Vec<ImageLines> = poses.iter().map(|p| image_lines(&camera, p, &[jamb], 0.0)).collect();
        let evidence = Evidence {
            camera: &camera,
            images: &images,
        };
        // Predicted 4 cm to the right of where the images see it.
        let shift = Vec3::new(0.04, 0.0, 0.0);
        let m = evidence.measure(&(jamb.0 + shift), &(jamb.1 + shift), &Vec3::x(), 0.06);
        assert_eq!((m.showing, m.looking), (3, 3));
        assert!((m.offset_m + 0.04).abs() < 1e-3, "{m:?}");
        assert!(m.seen());
        // Beyond the reach, nothing.
        let far = Vec3::new(0.1, 0.0, 0.0);
        let m = evidence.measure(&(jamb.0 + far), &(jamb.1 + far), &Vec3::x(), 0.06);
        assert_eq!((m.showing, m.looking), (0, 3));
        assert!(!m.seen());
    }

    #[test]
    fn a_line_running_on_past_the_side_is_a_course_not_the_side() {
        let (camera, poses) = cameras(&[-0.5, 0.0, 0.5]);
        let head = (Vec3::new(0.0, 0.0, 1.0), Vec3::new(0.9, 0.0, 1.0));
        let course = (Vec3::new(-1.5, 0.0, 1.0), Vec3::new(2.0, 0.0, 1.0));
        let shows = |edge: (Vec3, Vec3)| {
            let images: Vec<ImageLines> = poses.iter().map(|p| image_lines(&camera, p, &[edge], 0.0)).collect();
            Evidence {
                camera: &camera,
                images: &images,
            }
            .measure(&head.0, &head.1, &Vec3::z(), 0.06)
            .showing
        };
        assert_eq!(shows(head), 3);
        assert_eq!(shows(course), 0);
        // A sill a little wider than the opening still shows its foot.
        let sill = (Vec3::new(-0.1, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0));
        assert_eq!(shows(sill), 3);
    }

    #[test]
    fn too_few_images_unoriented_images_or_no_lines_show_nothing() {
        let (camera, poses) = cameras(&[-0.5, 0.5]);
        let jamb = (Vec3::new(0.2, 0.0, 0.0), Vec3::new(0.2, 0.0, 1.0));
        let mut images: Vec<ImageLines> = poses.iter().map(|p| image_lines(&camera, p, &[jamb], 0.0)).collect();
        assert!(Evidence {
            camera: &camera,
            images: &images
        }
        .measure(&jamb.0, &jamb.1, &Vec3::x(), 0.06)
        .seen());
        images[1].set_pose(None);
        let m = Evidence {
            camera: &camera,
            images: &images,
        }
        .measure(&jamb.0, &jamb.1, &Vec3::x(), 0.06);
        assert_eq!((m.showing, m.looking), (1, 1));
        assert!(!m.seen(), "one image is no evidence");
        let empty: Vec<ImageLines> = poses.iter().map(|p| ImageLines::new(&camera, Some(*p), &[], 20.0)).collect();
        let m = Evidence {
            camera: &camera,
            images: &empty,
        }
        .measure(&jamb.0, &jamb.1, &Vec3::x(), 0.06);
        assert_eq!((m.showing, m.looking), (0, 2));
    }
}
