//! Edge detectors on images whose edges are known, and on bad input.
use lineflow_edges::{canny, log, pixels, sobel};

fn step(w: usize, h: usize, at: usize) -> Vec<u8> {
    (0..w * h).map(|i| if i % w < at { 40 } else { 200 }).collect()
}

#[test]
fn a_vertical_step_gives_one_pixel_wide_edges_at_the_step() {
    let (w, h) = (40, 30);
    let img = step(w, h, 20);
    for (name, map) in [
        ("canny", canny(&img, w, h, 40.0, 100.0)),
        ("sobel", sobel(&img, w, h, 100.0)),
        ("log", log(&img, w, h, 1.0, 40.0)),
    ] {
        let px = pixels(&img, w, h, &map);
        assert_eq!(px.len(), h, "{name}: one edge pixel per row, got {}", px.len());
        assert!(
            px.iter().all(|p| p.col == 19 || p.col == 20),
            "{name}: {:?}",
            px.iter().map(|p| p.col).collect::<Vec<_>>()
        );
        assert!(px.iter().all(|p| p.direction_rad.abs() < 1e-6), "{name}: gradient points right");
        assert!(px.iter().all(|p| (p.magnitude - 640.0).abs() < 1e-3), "{name}: 4 × 160 grey levels");
    }
}

#[test]
fn hysteresis_keeps_weak_pixels_connected_to_strong_ones_only() {
    let (w, h) = (60, 20);
    // Left half: a strong step; right half: the same edge continues, weaker; a separate weak edge below.
    let mut img = vec![100u8; w * h];
    for y in 0..10 {
        for x in 0..w {
            img[y * w + x] = if x < 30 { 180 } else { 130 };
        }
    }
    let strong_only = pixels(&img, w, h, &canny(&img, w, h, 150.0, 150.0)).len();
    let linked = pixels(&img, w, h, &canny(&img, w, h, 100.0, 150.0)).len();
    assert!(
        linked > strong_only,
        "weak continuation of a strong edge is kept: {linked} vs {strong_only}"
    );
}

#[test]
fn empty_tiny_constant_and_noise_images_never_panic() {
    for (w, h) in [(0, 0), (1, 1), (1, 7), (7, 1), (2, 2)] {
        let img = vec![77u8; w * h];
        assert!(pixels(&img, w, h, &canny(&img, w, h, 40.0, 100.0)).is_empty());
        assert!(pixels(&img, w, h, &sobel(&img, w, h, 100.0)).is_empty());
        assert!(pixels(&img, w, h, &log(&img, w, h, 1.5, 40.0)).is_empty());
    }
    let (w, h) = (64, 48);
    let mut s = 12345u64;
    let noise: Vec<u8> = (0..w * h)
        .map(|_| {
            s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (s >> 56) as u8
        })
        .collect();
    let _ = pixels(&noise, w, h, &canny(&noise, w, h, 40.0, 100.0));
    let _ = pixels(&noise, w, h, &log(&noise, w, h, 1.5, 40.0));
}
