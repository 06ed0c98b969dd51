//! Free-vertex fitting of a façade wire-frame (a wall with recessed windows) seen from a strip of photos, on
//! edge pixels sampled along the true projected edges: the start's in-plane errors are removed, depth is held.
use lineflow_modelfit::wireframe::facade_params;
use lineflow_modelfit::{fit_wireframe, EdgeObservation, ImageEdges};
use lineflow_photogrammetry::{rotation_from_opk, Camera, Pose, Vec3};

fn camera() -> Camera {
    Camera::pinhole(2000, 1400, 0.0055, 17.6)
}

/// A 12 × 6 m wall at Y = 0 with three 1.2 × 1.5 m windows recessed by 0.15 m: outline, opening and frame.
fn facade() -> (Vec<Vec3>, Vec<[usize; 2]>) {
    let mut v = Vec::new();
    let mut e = Vec::new();
    let mut rect = |x0: f64, z0: f64, x1: f64, z1: f64, y: f64, v: &mut Vec<Vec3>| {
        let b = v.len();
        v.extend([[x0, y, z0], [x1, y, z0], [x1, y, z1], [x0, y, z1]].map(Vec3::from));
        e.extend((0..4).map(|k| [b + k, b + (k + 1) % 4]));
        b
    };
    rect(0.0, 0.0, 12.0, 6.0, 0.0, &mut v);
    let mut reveals = Vec::new();
    for k in 0..3 {
        let x = 1.5 + 3.8 * k as f64;
        let a = rect(x, 2.0, x + 1.2, 3.5, 0.0, &mut v);
        let b = rect(x, 2.0, x + 1.2, 3.5, 0.15, &mut v);
        reveals.extend((0..4).map(|i| [a + i, b + i]));
    }
    e.extend(reveals);
    (v, e)
}

/// Two strips, one at 1.5 m and one at 4.5 m, so that the recessed frame separates from the opening's edge
/// above and below as well as at the sides.
fn strip() -> Vec<Pose> {
    (0..12)
        .map(|i| Pose {
            center: Vec3::new(1.0 + 2.0 * (i / 2) as f64, -15.0, if i % 2 == 0 { 1.5 } else { 4.5 }),
            rotation: rotation_from_opk(90f64.to_radians(), 0.0, 0.0),
        })
        .collect()
}

fn perfect(vertices: &[Vec3], edges: &[[usize; 2]], pose: &Pose) -> ImageEdges {
    let c = camera();
    let mut obs = Vec::new();
    for e in edges {
        let (Some(p), Some(q)) = (pose.project_ideal(&c, &vertices[e[0]]), pose.project_ideal(&c, &vertices[e[1]])) else {
            continue;
        };
        let len = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
        let steps = (len / c.pixel_size_mm) as usize;
        for i in 1..steps {
            let s = i as f64 / steps as f64;
            let xy = [p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1])];
            let half = [c.width as f64 / 2.0 * c.pixel_size_mm, c.height as f64 / 2.0 * c.pixel_size_mm];
            if xy[0].abs() < half[0] && xy[1].abs() < half[1] {
                obs.push(EdgeObservation {
                    xy,
                    gradient: [(q[1] - p[1]) / len, -(q[0] - p[0]) / len],
                    relative: 1.0,
                });
            }
        }
    }
    ImageEdges::from_observations(c, *pose, obs)
}

#[test]
fn in_plane_errors_are_removed_and_depth_is_held() {
    let (truth, edges) = facade();
    let images: Vec<ImageEdges> = strip().iter().map(|p| perfect(&truth, &edges, p)).collect();
    // Every vertex off by about a pixel and a half (6 mm at 15 m) in X and Z, and 5 mm in depth.
    let start: Vec<Vec3> = truth
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let s = |k: usize| if (i * 7 + k * 3) % 5 < 2 { -1.0 } else { 1.0 };
            v + Vec3::new(0.006 * s(0), 0.005 * s(1), 0.006 * s(2))
        })
        .collect();
    let fit = fit_wireframe(&start, &edges, &[], &images, &facade_params(camera().pixel_size_mm));
    assert_eq!(fit.failed, 0, "{:?}", fit.failures);
    assert!(fit.fitted.iter().all(|&f| f), "every vertex is pinned by two edges");
    // Where an opening's edge and its frame's edge behind it project within a pixel of each other, their pixels
    // mix: a millimetre or so of error remains there, a quarter of a pixel.
    let mut sq = 0.0;
    for (i, (got, want)) in fit.vertices.iter().zip(&truth).enumerate() {
        let d = got - want;
        assert!(d.x.abs() < 1.5e-3 && d.z.abs() < 1.5e-3, "vertex {i} in-plane error {d:?}");
        assert!(d.y.abs() < 0.006, "vertex {i} depth {d:?}");
        sq += d.x * d.x + d.z * d.z;
    }
    let rms = (sq / truth.len() as f64).sqrt();
    assert!(rms < 1e-3, "in-plane RMS {rms} m from 8.5 mm (a fifth of a pixel)");
    // The fit stops once no vertex moves by 0.5 mm, about a tenth of a pixel here.
    assert!(
        fit.residual_rms_mm / camera().pixel_size_mm < 0.2,
        "{}",
        fit.summary(camera().pixel_size_mm)
    );
}

/// A part of the model outside every image keeps its start and is reported unpinned; the rest is fitted.
#[test]
fn a_part_outside_the_images_is_left_as_it_was_and_the_rest_fitted() {
    let (truth, mut edges) = facade();
    let images: Vec<ImageEdges> = strip().iter().map(|p| perfect(&truth, &edges, p)).collect();
    let mut start: Vec<Vec3> = truth.iter().map(|v| v + Vec3::new(0.004, 0.0, -0.004)).collect();
    // A stray rectangle 200 m to the side.
    let b = start.len();
    start.extend([[200.0, 0.0, 1.0], [201.0, 0.0, 1.0], [201.0, 0.0, 2.0], [200.0, 0.0, 2.0]].map(Vec3::from));
    edges.extend((0..4).map(|k| [b + k, b + (k + 1) % 4]));
    let fit = fit_wireframe(&start, &edges, &[], &images, &facade_params(camera().pixel_size_mm));
    assert_eq!(fit.vertices[b..], start[b..], "the stray part moved");
    assert!(fit.fitted[b..].iter().all(|f| !f), "the stray part counts as fitted");
    let worst = (0..b).map(|v| (fit.vertices[v] - truth[v]).xz().norm()).fold(0.0, f64::max);
    assert!(worst < 1.5e-3, "the façade was not fitted: worst in-plane error {worst} m");
}
