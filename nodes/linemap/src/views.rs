//! The oriented images a map is built from: each image's pose, its 2-D segments indexed in ideal photo
//! coordinates, and every segment's interpretation plane (the plane through the perspective centre and the
//! segment, on which the 3-D edge must lie).
use std::sync::Arc;

use lineflow_linegeom::{FrameSegments, SlaveSegments};
use lineflow_messages::Segment2;
use lineflow_photogrammetry::{Camera, Pose, Vec3};

use lineflow_linegeom::Photo;

/// One oriented image and its segments.
#[derive(Debug, Clone)]
pub struct View {
    /// Frame number (ties are broken by it, so the map does not depend on arrival order).
    pub frame: u64,
    /// Exterior orientation.
    pub pose: Pose,
    /// Segments of at least the minimum length, ideal photo coordinates.
    pub segments: FrameSegments,
    /// Unit normal of each segment's interpretation plane, object space.
    pub normals: Vec<Vec3>,
    /// Largest |x| and |y| of the image's corners in ideal photo coordinates, mm.
    pub half_extent_mm: [f64; 2],
    /// The image's grey values, for the appearance test; without them the test has no say.
    pub photo: Option<Arc<Photo>>,
}

impl View {
    /// The view of `frame`, keeping segments of at least `min_length_px`.
    pub fn new(camera: &Camera, frame: u64, pose: Pose, segments: &[Segment2], min_length_px: f64) -> Self {
        let segments = FrameSegments::new(camera, segments, min_length_px);
        let normals = segments
            .ends
            .iter()
            .map(|[a, b]| {
                let n = pose.ray_of_ideal(camera, *a).cross(&pose.ray_of_ideal(camera, *b));
                n.try_normalize(1e-15).unwrap_or_else(Vec3::zeros)
            })
            .collect();
        let (w, h) = (camera.width as f64, camera.height as f64);
        let corners = [[0.0, 0.0], [w, 0.0], [0.0, h], [w, h]].map(|px| camera.pixel_to_ideal(px));
        let half_extent_mm = [0, 1].map(|k| corners.iter().map(|c| c[k].abs()).fold(0.0, f64::max));
        View {
            frame,
            pose,
            segments,
            normals,
            half_extent_mm,
            photo: None,
        }
    }

    /// The view with its image's grey values.
    pub fn with_photo(mut self, photo: Arc<Photo>) -> Self {
        self.photo = Some(photo);
        self
    }

    /// The view as the multi-view estimate takes it.
    pub fn as_slave(&self) -> SlaveSegments<'_> {
        SlaveSegments {
            pose: self.pose,
            segments: &self.segments,
        }
    }

    /// Number of segments.
    pub fn len(&self) -> usize {
        self.segments.ends.len()
    }

    /// Whether the view has no segments.
    pub fn is_empty(&self) -> bool {
        self.segments.ends.is_empty()
    }

    /// Metres per pixel across the line of sight at `point`.
    pub fn metres_per_px(&self, camera: &Camera, point: &Vec3) -> f64 {
        (point - self.pose.center).norm() * self.segments.pixel_mm / camera.focal_mm
    }

    /// Whether `point` projects into the image with `margin_px` to spare.
    pub fn sees(&self, camera: &Camera, point: &Vec3, margin_px: f64) -> bool {
        self.pose.project(camera, point).is_some_and(|px| camera.contains(px, margin_px))
    }
}

/// The views whose segments view `i`'s segments are paired with: the others, nearest first (so that the strong
/// hypotheses come early and the rest can stop once they cannot beat them; ties by index), the `max` nearest
/// when `max` is not 0.
pub fn partners(views: &[View], i: usize, max: usize) -> Vec<usize> {
    let distance = |j: usize| (views[j].pose.center - views[i].pose.center).norm();
    let mut order: Vec<usize> = (0..views.len()).filter(|&j| j != i).collect();
    order.sort_by(|&a, &b| distance(a).total_cmp(&distance(b)).then(a.cmp(&b)));
    if max > 0 {
        order.truncate(max);
    }
    order
}

/// The parameter along the line `origin + t·dir` of its point closest to the ray `center + u·ray`.
pub fn parameter_on_line(origin: &Vec3, dir: &Vec3, center: &Vec3, ray: &Vec3) -> Option<f64> {
    let w = origin - center;
    let b = dir.dot(ray);
    let denom = 1.0 - b * b;
    (denom > 1e-9).then(|| (b * ray.dot(&w) - dir.dot(&w)) / denom)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_photogrammetry::Mat3;

    #[test]
    fn partners_are_the_other_views_nearest_first_ties_by_index() {
        let camera = Camera::pinhole(100, 80, 0.01, 10.0);
        let at = |x: f64, z: f64| {
            let pose = Pose {
                center: Vec3::new(x, -25.0, z),
                rotation: Mat3::identity(),
            };
            View::new(&camera, 0, pose, &[], 15.0)
        };
        // A strip at z = 1.5 and one at 4.5; view 0 has views 1 and 3 at 1 m, view 2 at 2 m, view 4 at 3 m.
        let views = [at(0.0, 1.5), at(1.0, 1.5), at(2.0, 1.5), at(-1.0, 1.5), at(0.0, 4.5)];
        assert_eq!(partners(&views, 0, 0), vec![1, 3, 2, 4]);
        assert_eq!(partners(&views, 0, 2), vec![1, 3]);
        assert_eq!(partners(&views, 4, 1), vec![0]);
    }
}
