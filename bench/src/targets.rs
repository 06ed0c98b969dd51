//! `lineflow bench targets`: the survey-target detector on rendered frames of a synthetic preset, against the true
//! projections of its targets: how many of the targets in view are found, how far their centres lie from the
//! truth (beside the plain centroid of the thresholded disc, a simple blob detector's centre, measured in the same
//! run on the same detections), false detections, and the time per frame beside decoding the frame's PNG. Then the
//! naming: the true poses moved into another frame (scaled, turned, shifted, as a run without control points
//! leaves them), and how many detections get the right name.
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use image::ImageEncoder;
use lineflow_messages::Encoding;
use lineflow_photogrammetry::{rotation_from_opk, Pose, Vec3};
use lineflow_synthetic::Synthetic;
use lineflow_targets::{detect, name, DetectSettings, Detection, Face, NameSettings, TargetView};

/// Options of `lineflow bench targets`.
pub struct TargetsArgs<'a> {
    /// Preset.
    pub preset: &'a str,
    /// Image scales, each measured on its own.
    pub scales: &'a [f64],
    /// Frames rendered per scale, spread over the preset's stations (0: every station).
    pub frames: usize,
    /// Seed of the scene.
    pub seed: u64,
}

/// A detection within this many pixels of a true target is that target's.
const FOUND_PX: f64 = 3.0;

pub fn bench_targets(a: TargetsArgs<'_>) -> Result<ExitCode> {
    println!(
        "targets benchmark: {} (seed {}), {} frames per scale; a target counts as found within {FOUND_PX} px",
        a.preset, a.seed, a.frames
    );
    println!(
        "{:>5} {:>8} {:>9} {:>8} {:>7} {:>12} {:>14} {:>9} {:>9} {:>7} {:>8}",
        "scale", "disc px", "in view", "found", "false", "centre RMS", "centroid RMS", "ratio", "ms/frame", "PNG ms", "named"
    );
    let mut all_met = true;
    for &scale in a.scales {
        let syn = Synthetic::new(a.preset, scale, a.seed)?;
        let camera = *syn.camera();
        let (w, h) = (camera.width as usize, camera.height as usize);
        let truth = lineflow_synthetic::truth::observe_targets(syn.world(), &camera, syn.poses(), &syn.building.targets, 0.0, a.seed);
        let n = syn.poses().len();
        let count = if a.frames == 0 { n } else { a.frames.min(n) };
        let frames: Vec<usize> = (0..count).map(|k| k * n / count).collect();
        let (mut in_view, mut found, mut false_hits) = (0usize, 0usize, 0usize);
        let (mut err2, mut plain2, mut detect_s, mut decode_s) = (0.0, 0.0, 0.0, 0.0);
        let mut disc = Vec::new();

        let mut views = Vec::new();
        for &frame in &frames {
            let rgb = syn.render(frame);
            let mut gray = vec![0u8; w * h];
            lineflow_imaging::gray_into(Encoding::Rgb8, w, h, w * 3, &rgb, &mut gray)?;
            let png = png_of(&gray, w, h)?;
            let t = Instant::now();
            let decoded = image::load_from_memory_with_format(&png, image::ImageFormat::Png)?;
            decode_s += t.elapsed().as_secs_f64();
            drop(decoded);
            let t = Instant::now();
            let detections = detect(&gray, w, h, &DetectSettings::default());
            detect_s += t.elapsed().as_secs_f64();
            let here: Vec<[f64; 2]> = truth.iter().filter(|o| o.frame == frame).map(|o| o.px).collect();
            in_view += here.len();
            for d in &detections {
                match here.iter().map(|t| distance(t, &d.centre)).min_by(f64::total_cmp) {
                    Some(e) if e <= FOUND_PX => {
                        let t = here
                            .iter()
                            .min_by(|x, y| distance(x, &d.centre).total_cmp(&distance(y, &d.centre)))
                            .expect("one");
                        found += 1;
                        err2 += e * e;

                        plain2 += distance(t, &thresholded_centroid(&gray, w, h, d)).powi(2);
                        disc.push(d.radius_px);
                    }
                    _ => false_hits += 1,
                }
            }
            views.push((frame, detections));
        }
        let named = naming_share(&syn, &views);

        let rms = (err2 / found.max(1) as f64).sqrt();
        let plain = (plain2 / found.max(1) as f64).sqrt();
        disc.sort_by(f64::total_cmp);
        let share = found as f64 / in_view.max(1) as f64;
        all_met &= share >= 0.98 && rms <= 0.1;
        println!(
            "{scale:>5.2} {:>8.1} {in_view:>9} {:>7.1}% {false_hits:>7} {:>9.3} px {:>11.3} px {:>8.2}x {:>9.1} {:>7.1} {named:>8}",
            2.0 * disc.get(disc.len() / 2).copied().unwrap_or(f64::NAN),
            100.0 * share,
            rms,
            plain,
            rms / plain,
            1e3 * detect_s / frames.len() as f64,
            1e3 * decode_s / frames.len() as f64,
        );
    }
    println!(
        "targets (#31): >= 98 % of the targets in view found, centre RMS <= 0.1 px: {}",
        if all_met {
            "met at every scale"
        } else {
            "not met at every scale (see the rows)"
        }
    );
    Ok(ExitCode::SUCCESS)
}

fn distance(a: &[f64; 2], b: &[f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

fn png_of(gray: &[u8], w: usize, h: usize) -> Result<Vec<u8>> {
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png).write_image(gray, w as u32, h as u32, image::ExtendedColorType::L8)?;
    Ok(png)
}

/// The plain centroid of the pixels brighter than halfway between the disc and the ring, within twice the disc's
/// radius of the detection: a simple blob detector's centre.
fn thresholded_centroid(gray: &[u8], w: usize, h: usize, d: &Detection) -> [f64; 2] {
    let reach = 2.0 * d.radius_px;
    let (x0, x1) = (
        (d.centre[0] - reach).floor().max(0.0) as usize,
        ((d.centre[0] + reach).ceil() as usize).min(w - 1),
    );
    let (y0, y1) = (
        (d.centre[1] - reach).floor().max(0.0) as usize,
        ((d.centre[1] + reach).ceil() as usize).min(h - 1),
    );
    let inside = |x: usize, y: usize| distance(&[x as f64, y as f64], &d.centre) <= reach;
    let levels: Vec<f64> = (y0..=y1)
        .flat_map(|y| (x0..=x1).map(move |x| (x, y)))
        .filter(|&(x, y)| inside(x, y))
        .map(|(x, y)| f64::from(gray[y * w + x]))
        .collect();
    let (lo, hi) = levels
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
    let mid = 0.5 * (lo + hi);
    let (mut n, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for y in y0..=y1 {
        for x in x0..=x1 {
            if inside(x, y) && f64::from(gray[y * w + x]) > mid {
                n += 1.0;
                sx += x as f64;
                sy += y as f64;
            }
        }
    }
    [sx / n, sy / n]
}

/// Named right / detections on true targets, with the true poses moved into another frame.
fn naming_share(syn: &Synthetic, views: &[(usize, Vec<Detection>)]) -> String {
    let r = rotation_from_opk(0.4, -0.3, 2.0);
    let moved = |p: &Pose| Pose {
        center: 0.2 * (r * p.center) + Vec3::new(500.0, -20.0, 3.0),
        rotation: p.rotation * r.transpose(),
    };
    let target_views: Vec<TargetView> = views
        .iter()
        .map(|(frame, detections)| TargetView {
            frame: *frame,
            pose: moved(&syn.poses()[*frame]),
            detections: detections.clone(),
        })
        .collect();
    let points: Vec<(String, Vec3)> = syn.building.targets.iter().map(|t| (t.id.clone(), Vec3::from(t.xyz))).collect();
    let camera = syn.camera();
    let faces: Vec<Face> = syn.approximate_walls().iter().filter_map(|(_, c)| Face::of_wall(c)).collect();
    match name(&target_views, camera, &points, &faces, &NameSettings::default()) {
        Ok(naming) => {
            let right = naming
                .observations
                .iter()
                .filter(|o| {
                    let p = points.iter().find(|p| p.0 == o.id).expect("a surveyed id").1;
                    syn.poses()[o.frame]
                        .project(camera, &p)
                        .is_some_and(|px| distance(&px, &o.centre) <= FOUND_PX)
                })
                .count();
            format!("{right}/{}", naming.observations.len())
        }
        Err(e) => format!("no: {e}"),
    }
}
