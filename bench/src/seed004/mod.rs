//! `lineflow experiment seed004`: seed 004's experiments (seed 004 §3, `docs/sources.md`) on synthetic aerial photos
//! of five box buildings with parapets, water tanks, shadows and noise: detector × weighting, the pull-in range
//! of each parameter, and the number of photos, with the seed's settings and with ours.
pub mod aerial;
pub mod experiment;

use std::fmt::Write;
use std::time::Instant;

use aerial::buildings;
use experiment::{detector_weighting_grid, pull_in, score_many, Detector, Prepared};
use lineflow_modelfit::parametric::box_param;
use lineflow_modelfit::FitParams;

/// Start perturbation of experiments 1 and 3: uniform within ±1.5 m and ±3°, inside the seed's pull-in range.
const PERTURB_M: f64 = 1.5;
const PERTURB_DEG: f64 = 3.0;

/// Our default settings: a wider first buffer (1.0 mm) shrinking by 0.1 mm per iteration to the seed's 0.05 mm.
pub fn ours() -> FitParams {
    FitParams {
        buffer_start_mm: 1.0,
        buffer_step_mm: 0.1,
        ..FitParams::default()
    }
}

pub fn experiment(trials: usize) -> String {
    let t0 = Instant::now();
    eprintln!("rendering 5 buildings x 4 photos and detecting edges (sobel, canny, log)...");
    let prepared: Vec<Prepared> = buildings().into_iter().map(Prepared::new).collect();
    eprintln!("  {:.1} s", t0.elapsed().as_secs_f64());
    let seed = FitParams::default();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "## Experiment 1: detector x weighting (5 buildings, 4 photos, {trials} starts per building within \
         ±{PERTURB_M} m / ±{PERTURB_DEG}°, seed's buffer 0.40 → 0.05 mm)\n"
    );
    let _ = writeln!(
        out,
        "| detector | weighting | correctness rate % | fits succeeded % | final RMS px |"
    );
    let _ = writeln!(out, "|---|---|---:|---:|---:|");
    for (d, w, s) in detector_weighting_grid(&prepared, &seed, trials, PERTURB_M, PERTURB_DEG) {
        let _ = writeln!(
            out,
            "| {} | {} | {:.1} | {:.1} | {:.2} |",
            d.name(),
            w.name(),
            s.rate(),
            s.success(),
            s.rms_px()
        );
    }
    eprintln!("experiment 1 done at {:.1} s", t0.elapsed().as_secs_f64());

    let _ = writeln!(
        out,
        "\n## Experiment 2: pull-in range (canny + combined, 4 photos; one parameter offset at a time in steps \
         of 0.25 m / 0.5°, mean of both sides over the buildings)\n"
    );
    let _ = writeln!(
        out,
        "| parameter | seed's settings | in the photo (mm) | ours | in the photo (mm) |"
    );
    let _ = writeln!(out, "|---|---:|---:|---:|---:|");
    // At 1 : 4000, 1 m on the ground is 0.25 mm in the photo.
    let mm_per_m = 152.0 / crate::seed004::aerial::FLYING_HEIGHT_M;
    for k in 0..7 {
        let (step, max) = if k == box_param::THETA {
            (0.5f64.to_radians(), 30f64.to_radians())
        } else {
            (0.25, 12.0)
        };
        let mean = |p: &FitParams| prepared.iter().map(|b| pull_in(b, k, step, max, 4, p)).sum::<f64>() / 5.0;
        let (a, b) = (mean(&seed), mean(&ours()));
        if k == box_param::THETA {
            let _ = writeln!(out, "| θ | ±{:.1}° | | ±{:.1}° | |", a.to_degrees(), b.to_degrees());
        } else {
            let _ = writeln!(
                out,
                "| {} | ±{:.2} m | ±{:.2} | ±{:.2} m | ±{:.2} |",
                box_param::NAMES[k],
                a,
                a * mm_per_m,
                b,
                b * mm_per_m
            );
        }
    }
    eprintln!("experiment 2 done at {:.1} s", t0.elapsed().as_secs_f64());

    let _ = writeln!(
        out,
        "\n## Experiment 3: number of photos (canny + combined, same starts as experiment 1)\n"
    );
    let _ = writeln!(
        out,
        "| photos | seed's settings: rate % | succeeded % | ours: rate % | succeeded % |"
    );
    let _ = writeln!(out, "|---:|---:|---:|---:|---:|");
    for n in 2..=4 {
        let a = score_many(&prepared, Detector::Canny, n, &seed, trials, PERTURB_M, PERTURB_DEG);
        let b = score_many(&prepared, Detector::Canny, n, &ours(), trials, PERTURB_M, PERTURB_DEG);
        let _ = writeln!(
            out,
            "| {n} | {:.1} | {:.1} | {:.1} | {:.1} |",
            a.rate(),
            a.success(),
            b.rate(),
            b.success()
        );
    }
    eprintln!("done in {:.1} s", t0.elapsed().as_secs_f64());
    out
}
