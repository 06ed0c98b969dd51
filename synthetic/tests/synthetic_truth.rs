//! The synthetic camera's ground truth agrees with its images: measured on the rendered gradient, not assumed.
use lineflow_photogrammetry::{Camera, Pose, Vec3};
use lineflow_synthetic::{SeenEdge, Sensor, Synthetic};

/// Grey value with bilinear interpolation (pixel centres at integers).
fn sample(img: &[f32], w: usize, h: usize, x: f64, y: f64) -> Option<f64> {
    if x < 0.0 || y < 0.0 || x > (w - 2) as f64 || y > (h - 2) as f64 {
        return None;
    }
    let (ix, iy) = (x as usize, y as usize);
    let (fx, fy) = (x - ix as f64, y - iy as f64);
    let at = |c: usize, r: usize| img[r * w + c] as f64;
    Some(
        at(ix, iy) * (1.0 - fx) * (1.0 - fy)
            + at(ix + 1, iy) * fx * (1.0 - fy)
            + at(ix, iy + 1) * (1.0 - fx) * fy
            + at(ix + 1, iy + 1) * fx * fy,
    )
}

/// Offset (pixels, along `normal`) of the strongest intensity step near `p`, if the step is clear.
fn edge_offset(img: &[f32], w: usize, h: usize, p: [f64; 2], normal: [f64; 2]) -> Option<f64> {
    const STEP: f64 = 0.05;
    const REACH: f64 = 1.5;
    let n = (2.0 * REACH / STEP) as i32;
    let profile: Vec<f64> = (0..=n + 2)
        .map(|i| {
            let s = -REACH - STEP + i as f64 * STEP;
            sample(img, w, h, p[0] + s * normal[0], p[1] + s * normal[1])
        })
        .collect::<Option<_>>()?;
    let grad: Vec<f64> = (1..profile.len() - 1)
        .map(|i| ((profile[i + 1] - profile[i - 1]) / (2.0 * STEP)).abs())
        .collect();
    let (k, &peak) = grad.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1))?;
    // Only clear steps: a contrast of 12 grey levels per pixel, peak away from the window's ends.
    if peak < 12.0 || k == 0 || k == grad.len() - 1 {
        return None;
    }
    // A second step nearby (a parallel edge, a mortar joint) makes the peak ambiguous.
    let rival = (1..grad.len() - 1)
        .filter(|&i| (i as i64 - k as i64).abs() > 8 && grad[i] >= grad[i - 1] && grad[i] >= grad[i + 1])
        .any(|i| grad[i] > 0.5 * peak);
    if rival {
        return None;
    }
    let (a, b, c) = (grad[k - 1], grad[k], grad[k + 1]);
    let sub = 0.5 * (a - c) / (a - 2.0 * b + c);
    Some(-REACH + (k as f64 + sub) * STEP)
}

fn gray(rgb: &[u8]) -> Vec<f32> {
    rgb.chunks(3)
        .map(|p| 0.299 * p[0] as f32 + 0.587 * p[1] as f32 + 0.114 * p[2] as f32)
        .collect()
}

/// Offsets of the projected ground-truth edges from the rendered edges, over the visible parts of every edge.
fn offsets(syn: &Synthetic, seen_edges: &[SeenEdge], frame: usize, rgb: &[u8]) -> Vec<(f64, [f64; 2], usize)> {
    let cam: &Camera = syn.camera();
    let pose: &Pose = &syn.poses()[frame];
    let (w, h) = (cam.width as usize, cam.height as usize);
    let img = gray(rgb);
    // Every model edge as a pixel polyline, to skip samples where another edge runs within 2.5 px: there the
    // blurred steps merge and the measurement, not the truth, is off.
    let polylines: Vec<Vec<[f64; 2]>> = syn
        .building
        .edges
        .iter()
        .map(|e| {
            let (a, b) = (Vec3::from(e.a), Vec3::from(e.b));
            (0..=8)
                .filter_map(|k| pose.project(cam, &(a + (b - a) * (k as f64 / 8.0))))
                .collect()
        })
        .collect();
    let boxes: Vec<[f64; 4]> = polylines
        .iter()
        .map(|l| {
            l.iter().fold([f64::MAX, f64::MAX, f64::MIN, f64::MIN], |b, p| {
                [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])]
            })
        })
        .collect();
    let near = |p: [f64; 2], line: &[[f64; 2]], b: &[f64; 4]| {
        let r = 2.5;
        if p[0] < b[0] - r || p[0] > b[2] + r || p[1] < b[1] - r || p[1] > b[3] + r {
            return false;
        }
        line.windows(2).any(|s| {
            let (d, e) = ([s[1][0] - s[0][0], s[1][1] - s[0][1]], [p[0] - s[0][0], p[1] - s[0][1]]);
            let t = ((d[0] * e[0] + d[1] * e[1]) / (d[0] * d[0] + d[1] * d[1]).max(1e-12)).clamp(0.0, 1.0);
            (e[0] - t * d[0]).hypot(e[1] - t * d[1]) < 2.5
        })
    };
    let mut out = Vec::new();
    for (index, seen) in seen_edges.iter().enumerate() {
        if !seen.frames.contains(&frame) {
            continue;
        }
        let (a, b) = (Vec3::from(seen.edge.a), Vec3::from(seen.edge.b));
        for k in 1..40 {
            let s = k as f64 / 40.0;
            let p = a + (b - a) * s;
            if !syn.world().visible(&pose.center, &p) {
                continue;
            }
            let (Some(px), Some(q)) = (pose.project(cam, &p), pose.project(cam, &(p + (b - a) * 0.002))) else {
                continue;
            };
            if !cam.contains(px, 4.0) {
                continue;
            }
            let d = [q[0] - px[0], q[1] - px[1]];
            let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
            if len < 1e-9 {
                continue;
            }
            // Skip points within 2 px of an endpoint: there the step belongs to two edges.
            let (pa, pb) = (pose.project(cam, &a), pose.project(cam, &b));
            let near_end = [pa, pb]
                .iter()
                .flatten()
                .any(|e| ((e[0] - px[0]).powi(2) + (e[1] - px[1]).powi(2)).sqrt() < 2.0);
            if near_end {
                continue;
            }
            let own = (Vec3::from(seen.edge.a), Vec3::from(seen.edge.b));
            let crowded = syn.building.edges.iter().zip(polylines.iter().zip(&boxes)).any(|(e, (line, b))| {
                let same = (Vec3::from(e.a) - own.0).norm() < 1e-9 && (Vec3::from(e.b) - own.1).norm() < 1e-9;
                !same && near(px, line, b)
            });
            if crowded {
                continue;
            }
            if let Some(off) = edge_offset(&img, w, h, px, [-d[1] / len, d[0] / len]) {
                out.push((off, px, index));
            }
        }
    }
    out
}

/// Each ground-truth edge's offset from the rendered step: the median over its clearly measured samples
/// (single samples are disturbed by texture and by neighbouring parallel edges a pixel away).
#[test]
fn projected_truth_lies_on_the_rendered_edges_corners_included() {
    // The strongest distortion of the presets (≈ 100 px at the corners of the full frame).
    let mut syn = Synthetic::new("a55-two-strips", 0.4, 3).unwrap();
    syn.preset.sensor = Sensor {
        noise_dn: 0.0,
        ..Sensor::default()
    };
    // Mortar joints and tile gaps run parallel to the edges a few pixels away; only geometry should make steps.
    syn.set_flat_textures(true);
    let cam = syn.camera();
    type Samples = Vec<(f64, [f64; 2])>;
    let mut per_edge: std::collections::BTreeMap<(usize, usize), Samples> = Default::default();
    // The ends of both strips put the building's corners into the image corners.
    let seen = syn.seen_edges();
    for frame in [0, 8, 9, 17] {
        let rgb = syn.render(frame);
        for (off, px, edge) in offsets(&syn, &seen, frame, &rgb) {
            per_edge.entry((frame, edge)).or_default().push((off, px));
        }
    }
    let mut all = Vec::new();
    let mut corner = Vec::new();
    for samples in per_edge.values().filter(|v| v.len() >= 8) {
        let mut v: Vec<f64> = samples.iter().map(|s| s.0).collect();
        v.sort_by(f64::total_cmp);
        let median = v[v.len() / 2].abs();
        all.push(median);
        let mid = samples[samples.len() / 2].1;
        let (u, v) = (mid[0] / cam.width as f64, mid[1] / cam.height as f64);
        let in_corner = !(0.2..=0.8).contains(&u) && !(0.2..=0.8).contains(&v);
        if in_corner {
            corner.push(median);
        }
    }
    all.sort_by(f64::total_cmp);
    corner.sort_by(f64::total_cmp);
    let max = all.last().copied().unwrap_or(f64::NAN);
    let corner_max = corner.last().copied().unwrap_or(f64::NAN);
    eprintln!(
        "{} edges measured: median {:.3} px, 95th percentile {:.3} px, max {max:.3} px; {} corner edges, max {corner_max:.3} px",
        all.len(),
        all[all.len() / 2],
        all[all.len() * 95 / 100],
        corner.len()
    );
    assert!(all.len() > 200, "only {} edges measured", all.len());
    assert!(max < 0.5, "an edge is {max} px off its rendered step");
    assert!(corner.len() >= 5 && corner_max < 0.5, "corner edges: {corner:?}");
}

#[test]
fn the_same_seed_gives_the_same_bytes_and_another_seed_does_not() {
    let a = Synthetic::new("d2x-strip", 0.08, 11).unwrap();
    let b = Synthetic::new("d2x-strip", 0.08, 11).unwrap();
    let c = Synthetic::new("d2x-strip", 0.08, 12).unwrap();
    assert_eq!(a.render(5), b.render(5));
    assert_ne!(a.render(5), c.render(5));
    assert_eq!(a.target_observations(), b.target_observations());
}

#[test]
fn presets_have_four_control_points_and_at_least_ten_check_points_seen_twice() {
    for name in lineflow_synthetic::PRESETS {
        let syn = Synthetic::new(name, 0.1, 1).unwrap();
        let obs = syn.target_observations();
        let seen_twice = |id: &str| obs.iter().filter(|o| o.id == id).count() >= 2;
        let control = syn.building.targets.iter().filter(|t| t.control && seen_twice(&t.id)).count();
        let check = syn.building.targets.iter().filter(|t| !t.control && seen_twice(&t.id)).count();
        assert_eq!(control, 4, "{name}: control points seen twice");
        assert!(check >= 10, "{name}: {check} check points seen twice");
        let edges = syn.seen_edges().len();
        assert!(edges > 200, "{name}: {edges} edges");
    }
}

#[test]
fn unknown_presets_and_bad_scales_are_refused_with_the_list() {
    let e = Synthetic::new("d3x", 1.0, 1).unwrap_err().to_string();
    assert!(e.contains("d2x-strip") && e.contains("roof"), "{e}");
    assert!(Synthetic::new("roof", 0.0, 1).is_err());
}
