//! `lineflow bench edges`: the edge detectors on a full-size synthetic façade frame, against OpenCV's `cv2.Canny`
//! (`opencv-python-headless`, L2 gradient, same thresholds) measured in the same run on the same image.
use std::process::ExitCode;

use anyhow::Result;
use lineflow_edges::{canny, log, sobel};

use crate::util::{median_time, python_reference, synthetic_gray, OPENCV_PACKAGES};

const OPENCV: &str = r#"
import sys, time, cv2, numpy as np
path, low, high, reps, out = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), int(sys.argv[4]), sys.argv[5]
img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
for threads in (1, 2):
    cv2.setNumThreads(threads)
    times = []
    for _ in range(reps):
        t = time.perf_counter(); e = cv2.Canny(img, low, high, L2gradient=True); times.append(time.perf_counter() - t)
    print(f"{threads} {sorted(times)[len(times)//2]}")
cv2.imwrite(out, e)
"#;

pub fn bench_edges(preset: &str, reps: usize, high: f64) -> Result<ExitCode> {
    let low = lineflow_edges::DEFAULT_LOW_RATIO * high;
    let dir = tempfile::tempdir()?;
    let (gray, w, h, png) = synthetic_gray(preset, dir.path())?;
    println!(
        "edges benchmark: {preset} frame, {w}x{h} ({:.1} MP), canny L2 low {low} high {high}, median of {reps}",
        (w * h) as f64 / 1e6
    );

    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let ours = |threads: &rayon::ThreadPool| median_time(reps, || threads.install(|| drop(canny(&gray, w, h, low, high))));
    let t1 = ours(&one);
    let two = rayon::ThreadPoolBuilder::new().num_threads(2).build()?;
    let t2 = ours(&two);
    let map = canny(&gray, w, h, low, high);

    let cv_out = dir.path().join("cv.png");
    let stdout = python_reference(
        OPENCV,
        &[
            png.display().to_string(),
            low.to_string(),
            high.to_string(),
            reps.to_string(),
            cv_out.display().to_string(),
        ],
        OPENCV_PACKAGES,
    )?;
    let times: Vec<f64> = stdout.lines().filter_map(|l| l.split_whitespace().nth(1)?.parse().ok()).collect();
    let cv = image::open(&cv_out)?.into_luma8();
    let (mut both, mut either, mut ours_n, mut cv_n) = (0usize, 0usize, 0usize, 0usize);
    for (m, c) in map.iter().zip(cv.as_raw()) {
        let (a, b) = (*m == 2, *c > 0);
        ours_n += a as usize;
        cv_n += b as usize;
        both += (a && b) as usize;
        either += (a || b) as usize;
    }
    let (cv1, cv2) = (
        times.first().copied().unwrap_or(f64::NAN),
        times.get(1).copied().unwrap_or(f64::NAN),
    );
    println!(
        "canny   1 thread {:7.1} ms   OpenCV 1 thread {:7.1} ms   ratio {:.2}x (target <= 1.5x)",
        t1 * 1e3,
        cv1 * 1e3,
        t1 / cv1
    );
    println!(
        "canny   2 threads {:6.1} ms   OpenCV 2 threads {:6.1} ms   speed-up {:.2}x",
        t2 * 1e3,
        cv2 * 1e3,
        t1 / t2
    );
    println!(
        "agreement: {ours_n} edge pixels, OpenCV {cv_n}; equal on {:.3} % of the pixels either marks (target >= 99 %)",
        100.0 * both as f64 / either.max(1) as f64
    );
    let ts = median_time(reps, || drop(sobel(&gray, w, h, high)));
    let tl = median_time(reps, || drop(log(&gray, w, h, 1.5, 40.0)));
    println!(
        "sobel   2 threads {:6.1} ms;  log (sigma 1.5) 2 threads {:6.1} ms",
        ts * 1e3,
        tl * 1e3
    );
    Ok(ExitCode::SUCCESS)
}
