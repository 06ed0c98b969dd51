//! Edge detectors on images whose edges are known, and on bad input.
use lineflow_edges::{canny, log, pixels, sobel};
use lineflow_imaging::ColourEdges;

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

/// Glass against red brick (the synthetic façades' colours): a step of 60 levels in red but 12 in grey.
#[test]
fn colour_edges_are_found_in_the_strongest_channel() {
    let (w, h) = (40, 30);
    let (glass, brick) = ([47u8, 57, 68], [106u8, 53, 37]);
    let rgb: Vec<u8> = (0..w * h).flat_map(|i| if i % w < 20 { glass } else { brick }).collect();
    let mut gray = vec![0u8; w * h];
    lineflow_imaging::gray_into(lineflow_messages::Encoding::Rgb8, w, h, w * 3, &rgb, &mut gray).unwrap();
    let detector = lineflow_edges::Detector::Canny { low: 40.0, high: 100.0 };
    assert!(detector.detect(&gray, w, h).is_empty(), "the grey step is below the thresholds");
    let [r, g, b] = lineflow_imaging::rgb_planes(&rgb, w, h, w * 3);
    for mode in [ColourEdges::All, ColourEdges::Plumb] {
        let found = detector.detect_in(&lineflow_imaging::Planes::colour(&gray, &r, &g, &b, mode), w, h);
        assert_eq!(found.len(), h, "one edge pixel per row");
        assert!(found.iter().all(|p| p.col == 19 || p.col == 20));
        // The red channel's gradient: 4 × 59 levels, pointing right.
        assert!(found
            .iter()
            .all(|p| (p.magnitude - 236.0).abs() < 1e-3 && p.direction_rad.abs() < 1e-6));
    }
    // The same step lying level (a roof's tile course): found with every channel, not with plumb edges only.
    let level: Vec<u8> = (0..w * h).flat_map(|i| if i / w < 15 { glass } else { brick }).collect();
    let mut level_gray = vec![0u8; w * h];
    lineflow_imaging::gray_into(lineflow_messages::Encoding::Rgb8, w, h, w * 3, &level, &mut level_gray).unwrap();
    let [r, g, b] = lineflow_imaging::rgb_planes(&level, w, h, w * 3);
    let all = detector.detect_in(&lineflow_imaging::Planes::colour(&level_gray, &r, &g, &b, ColourEdges::All), w, h);
    assert_eq!(all.len(), w);
    let plumb = detector.detect_in(&lineflow_imaging::Planes::colour(&level_gray, &r, &g, &b, ColourEdges::Plumb), w, h);
    assert!(plumb.is_empty());
    let off = detector.detect_in(&lineflow_imaging::Planes::colour(&level_gray, &r, &g, &b, ColourEdges::Off), w, h);
    assert!(off.is_empty());
    // Grey planes give what the grey functions give.
    assert_eq!(
        detector.detect_in(&lineflow_imaging::Planes::gray(&gray), w, h),
        detector.detect(&gray, w, h)
    );
}
