//! `lineflow bench lines2d`: the default 2-D stage (Canny edges, then line tracing on the edges' sub-pixel
//! positions) on a full-size synthetic façade frame, timed per step and scored against the ground truth (length
//! recall and precision at 1.5 px and 5°, as `lineflow eval` scores `lines2d.csv`); our `lsd` and OpenCV's LSD
//! (`opencv-python-headless`) on the same image in the same run are the references.
use std::process::ExitCode;

use anyhow::Result;
use lineflow_eval::lines2d::score_image;
use lineflow_eval::Truth;
use lineflow_formats::Line2Row;
use lineflow_messages::Encoding;
use lineflow_synthetic::Synthetic;

use crate::util::{median_time, python_reference, OPENCV_PACKAGES};

const OPENCV_LSD: &str = r#"
import sys, time, cv2
path, reps = sys.argv[1], int(sys.argv[2])
img = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
cv2.setNumThreads(1)
try:
    lsd = cv2.createLineSegmentDetector()
except Exception as e:
    print(f"unavailable {e}")
    sys.exit(0)
times = []
for _ in range(reps):
    t = time.perf_counter(); lines = lsd.detect(img)[0]; times.append(time.perf_counter() - t)
print(f"time {sorted(times)[len(times)//2]}")
import numpy as np
for x1, y1, x2, y2 in (np.asarray(lines).reshape(-1, 4) if lines is not None else []):
    print(f"{x1} {y1} {x2} {y2}")
"#;

fn rows(image: &str, segments: impl Iterator<Item = ([f64; 2], [f64; 2])>, min_length_px: f64) -> Vec<Line2Row> {
    segments
        .filter(|(a, b)| (b[0] - a[0]).hypot(b[1] - a[1]) >= min_length_px)
        .enumerate()
        .map(|(id, (a, b))| Line2Row {
            image: image.to_owned(),
            id: id as u64,
            start_px: a,
            end_px: b,
            n_pixels: None,
        })
        .collect()
}

pub fn bench_lines2d(preset: &str, reps: usize, high: f64) -> Result<ExitCode> {
    let syn = Synthetic::new(preset, 1.0, 1)?;
    let cam = *syn.camera();
    let (w, h) = (cam.width as usize, cam.height as usize);
    let frame = syn.poses().len() / 2;
    let rgb = syn.render(frame);
    let mut gray = vec![0u8; w * h];
    let t_gray = median_time(reps, || {
        lineflow_imaging::gray_into(Encoding::Rgb8, w, h, w * 3, &rgb, &mut gray).expect("sizes match")
    });
    let truth = Truth::from_scene(syn);
    let image = truth.poses[frame].image.clone();
    let params = lineflow_lines2d::TraceParams::default();
    let low = lineflow_edges::DEFAULT_LOW_RATIO * high;
    println!(
        "lines2d benchmark: {preset} frame {frame}, {w}x{h} ({:.1} MP), canny L2 low {low} high {high}, trace min length {} px, median of {reps}, {} threads",
        (w * h) as f64 / 1e6,
        params.min_length_px,
        rayon::current_num_threads()
    );

    let map = lineflow_edges::canny(&gray, w, h, low, high);
    let t_canny = median_time(reps, || drop(lineflow_edges::canny(&gray, w, h, low, high)));
    let edge_pixels = lineflow_edges::pixels(&gray, w, h, &map);
    let t_pixels = median_time(reps, || drop(lineflow_edges::pixels(&gray, w, h, &map)));
    let positions = lineflow_imaging::subpixel_positions(&gray, w, h, &edge_pixels);
    let t_subpixel = median_time(reps, || drop(lineflow_imaging::subpixel_positions(&gray, w, h, &edge_pixels)));
    let pixels: Vec<[u16; 2]> = edge_pixels.iter().map(|e| [e.col, e.row]).collect();
    let traced = lineflow_lines2d::trace_measured_at(&cam, &pixels, &positions, &params);
    let t_trace = median_time(reps, || {
        drop(lineflow_lines2d::trace_measured_at(&cam, &pixels, &positions, &params))
    });
    let total = t_canny + t_pixels + t_subpixel + t_trace;
    // The tracing alone, on coordinates corrected beforehand: what the step costs beyond the correction model.
    let corrected = lineflow_lines2d::corrected_pixels(&cam, &positions);
    let t_trace_only = median_time(reps, || drop(lineflow_lines2d::trace(w, h, &pixels, &corrected, &params)));
    let ours = score_image(&truth, frame, &rows(&image, traced.iter().map(|t| (t.0, t.1)), 0.0));

    let found = lineflow_lines2d::lsd::lsd(&gray, w, h, params.min_length_px);
    let t_lsd = median_time(reps, || drop(lineflow_lines2d::lsd::lsd(&gray, w, h, params.min_length_px)));
    let lsd = score_image(&truth, frame, &rows(&image, found.iter().map(|s| (s.start, s.end)), 0.0));

    println!("step                         ms");
    println!(
        "grey conversion (the gray node) {:6.1}  (not counted: the stage reads the gray topic)",
        t_gray * 1e3
    );
    println!("canny                        {:7.1}", t_canny * 1e3);
    println!("edge pixels + gradients      {:7.1}", t_pixels * 1e3);
    println!("sub-pixel positions          {:7.1}", t_subpixel * 1e3);
    println!(
        "tracing + fitting            {:7.1}  (of which tracing on corrected coordinates {:.1}; {} edge pixels)",
        t_trace * 1e3,
        t_trace_only * 1e3,
        pixels.len()
    );
    println!(
        "edges + lines2d (trace)      {:7.1}   ratio to the 250 ms target {:.2}",
        total * 1e3,
        total / 0.25
    );
    let score = |name: &str, s: &lineflow_eval::lines2d::ImageScores, t: f64| {
        println!(
            "{name:<28} {:7.1} ms  {:6} segments  recall {:5.1} %  precision {:5.1} %  (target recall >= 93 %)",
            t * 1e3,
            s.n_estimated,
            100.0 * s.recall,
            100.0 * s.precision
        );
    };
    score("ours: canny + trace", &ours, total);
    score("ours: lsd (lsdetect)", &lsd, t_lsd);
    let channels = lineflow_imaging::rgb_planes(&rgb, w, h, w * 3);
    let [r, g, b] = &channels;
    let color = |planes: &lineflow_imaging::Planes| {
        let map = lineflow_edges::canny_in(planes, w, h, low, high);
        let found = lineflow_edges::pixels_in(planes, w, h, &map);
        let positions = lineflow_imaging::subpixel_positions_in(planes, w, h, &found);
        let pixels: Vec<[u16; 2]> = found.iter().map(|e| [e.col, e.row]).collect();
        lineflow_lines2d::trace_measured_at(&cam, &pixels, &positions, &params)
    };
    for (name, mode) in [
        ("ours: colour (plumb) + trace", lineflow_imaging::ColourEdges::Plumb),
        ("ours: colour (all) + trace", lineflow_imaging::ColourEdges::All),
    ] {
        let planes = lineflow_imaging::Planes::colour(&gray, r, g, b, mode);
        let t = median_time(reps, || drop(color(&planes)));
        let scores = score_image(&truth, frame, &rows(&image, color(&planes).iter().map(|t| (t.0, t.1)), 0.0));
        score(name, &scores, t);
    }

    let dir = tempfile::tempdir()?;
    let png = dir.path().join("gray.png");
    image::save_buffer(&png, &gray, w as u32, h as u32, image::ExtendedColorType::L8)?;
    match python_reference(OPENCV_LSD, &[png.display().to_string(), reps.to_string()], OPENCV_PACKAGES) {
        Ok(out) if out.starts_with("unavailable") => println!("OpenCV LSD: {}", out.trim()),
        Ok(out) => {
            let t: f64 = out
                .lines()
                .find_map(|l| l.strip_prefix("time ")?.trim().parse().ok())
                .unwrap_or(f64::NAN);
            let segs = out.lines().filter_map(|l| {
                let v: Vec<f64> = l.split_whitespace().filter_map(|x| x.parse().ok()).collect();
                // OpenCV puts pixel centres at integers, as we do.
                (v.len() == 4).then(|| ([v[0], v[1]], [v[2], v[3]]))
            });
            let cv = score_image(&truth, frame, &rows(&image, segs, params.min_length_px));
            score("OpenCV LSD, 1 thread", &cv, t);
            println!("ratio ours / OpenCV LSD time {:.2}", total / t);
        }
        Err(e) => println!("OpenCV LSD reference skipped: {e}"),
    }
    Ok(ExitCode::SUCCESS)
}
