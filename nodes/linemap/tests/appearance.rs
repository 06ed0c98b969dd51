//! The appearance test on rendered images of a brick wall: two strips of cameras in front of the wall y = 0 whose
//! bricks each have their own shade. A mortar course placed at its true depth looks the same in every image; the
//! same course moved along the reference image's rays (where every image of that strip still sees it on the
//! course) is rejected by the images of the other strip.
use std::sync::Arc;

use lineflow_linemap::appearance::{agrees, compare, AppearanceParams};
use lineflow_linemap::{Photo, View};
use lineflow_photogrammetry::{rotation_from_opk, Camera, Pose, Vec3};

const ROW_M: f64 = 0.3;
const BRICK_M: f64 = 0.6;

fn camera() -> Camera {
    Camera::pinhole(400, 300, 0.05, 20.0)
}

/// Grey value of the wall at (x, z): mortar joints 3 cm wide, each brick (running bond) a shade of its own.
fn wall_gray(x: f64, z: f64) -> f64 {
    let row = (z / ROW_M).floor();
    let shift = if row as i64 % 2 == 0 { 0.0 } else { BRICK_M / 2.0 };
    let col = ((x + shift) / BRICK_M).floor();
    let (fz, fx) = (z - row * ROW_M, x + shift - col * BRICK_M);
    if fz < 0.03 || fx < 0.03 {
        return 200.0;
    }
    let h = ((row as i64).wrapping_mul(73_856_093) ^ (col as i64).wrapping_mul(19_349_663)) as u64;
    let h = h.wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
    60.0 + (h % 100) as f64
}

/// The wall as `pose` sees it, 3 × 3 samples a pixel.
fn render(cam: &Camera, pose: &Pose) -> Photo {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut gray = vec![0u8; w * h];
    for r in 0..h {
        for c in 0..w {
            let mut sum = 0.0;
            for (dy, dx) in (0..9).map(|k| (k / 3, k % 3)) {
                // Pixel centres at integer values (docs/conventions.md): samples at -1/3, 0 and +1/3.
                let px = [c as f64 + (dx as f64 - 1.0) / 3.0, r as f64 + (dy as f64 - 1.0) / 3.0];
                let ray = pose.ray_of_pixel(cam, px);
                let t = -pose.center.y / ray.y;
                let p = pose.center + ray * t;
                sum += wall_gray(p.x, p.z);
            }
            gray[r * w + c] = (sum / 9.0).round() as u8;
        }
    }
    Photo::new(w, h, gray).unwrap()
}

/// Two strips 3 m apart, 12 m from the wall, four images each.
fn views(cam: &Camera) -> Vec<View> {
    [1.0, 4.0]
        .iter()
        .flat_map(|&z| (0..4).map(move |k| Vec3::new(3.0 + 1.0 * k as f64, -12.0, z)))
        .enumerate()
        .map(|(f, center)| {
            let pose = Pose {
                center,
                rotation: rotation_from_opk(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
            };
            View::new(cam, f as u64, pose, &[], 15.0).with_photo(Arc::new(render(cam, &pose)))
        })
        .collect()
}

#[test]
fn a_course_at_its_depth_matches_and_one_off_it_does_not() {
    let cam = camera();
    let views = views(&cam);
    let all: Vec<usize> = (0..views.len()).collect();
    let p = AppearanceParams::default();
    // The joint at the bottom of course 8 (z = 2.4 m), 1.8 m long.
    let z = 8.0 * ROW_M + 0.015;
    let truth = [Vec3::new(3.7, 0.0, z), Vec3::new(5.5, 0.0, z)];
    let right = compare(&cam, &views, &all, &truth, &p).expect("a textured wall gives a verdict");
    assert!(right.median().unwrap() > 0.9, "{right:?}");
    assert_eq!(right.median_offset(), Some(0.0), "{right:?}");
    // The same joint 0.6 m in front of the wall along the rays of the reference image: that image sees it exactly
    // where it was, the other strip one course and more away.
    let c = views[right.reference].pose.center;
    let moved = truth.map(|e| c + (e - c) * ((-0.6 - c.y) / (e.y - c.y)));
    assert!(moved.iter().all(|e| (e.y + 0.6).abs() < 1e-9), "{moved:?}");
    let wrong = compare(&cam, &views, &all, &moved, &p).expect("a textured wall gives a verdict");
    assert!(wrong.median().unwrap() < 0.85, "{wrong:?}");
    // The decision, which stops comparing once more than half of the images reject, says the same.
    assert!(agrees(&cam, &views, &all, &truth, &p, 0.85, 0.5));
    assert!(!agrees(&cam, &views, &all, &moved, &p, 0.85, 0.5));
}

#[test]
fn no_verdict_without_photos_or_on_a_blank_wall() {
    let cam = camera();
    let mut views = views(&cam);
    let all: Vec<usize> = (0..views.len()).collect();
    let p = AppearanceParams::default();
    let line = [Vec3::new(3.7, 0.0, 2.415), Vec3::new(5.5, 0.0, 2.415)];
    let blank = Arc::new(Photo::new(400, 300, vec![128; 400 * 300]).unwrap());
    for v in &mut views {
        v.photo = Some(Arc::clone(&blank));
    }
    assert_eq!(compare(&cam, &views, &all, &line, &p), None, "a flat image cannot tell");
    for v in &mut views {
        v.photo = None;
    }
    assert_eq!(compare(&cam, &views, &all, &line, &p), None, "no photos, no say");
}
