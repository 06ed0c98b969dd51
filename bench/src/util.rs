//! What the image benchmarks share: a full-size synthetic frame, median timing, and the Python/OpenCV reference.
use std::path::Path;
use std::process::Command;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use lineflow_messages::Encoding;
use lineflow_synthetic::Synthetic;

/// Median wall time of `reps` runs of `f`, seconds.
pub fn median_time(reps: usize, mut f: impl FnMut()) -> f64 {
    let mut t: Vec<f64> = (0..reps.max(1))
        .map(|_| {
            let s = Instant::now();
            f();
            s.elapsed().as_secs_f64()
        })
        .collect();
    t.sort_by(f64::total_cmp);
    t[t.len() / 2]
}

/// The middle frame of a preset at full size, in grey, also written as a PNG into `dir` for the reference.
pub fn synthetic_gray(preset: &str, dir: &Path) -> Result<(Vec<u8>, usize, usize, std::path::PathBuf)> {
    let syn = Synthetic::new(preset, 1.0, 1)?;
    let cam = *syn.camera();
    let (w, h) = (cam.width as usize, cam.height as usize);
    let rgb = syn.render(syn.poses().len() / 2);
    let mut gray = vec![0u8; w * h];
    lineflow_imaging::gray_into(Encoding::Rgb8, w, h, w * 3, &rgb, &mut gray)?;
    let png = dir.join("gray.png");
    image::save_buffer(&png, &gray, w as u32, h as u32, image::ExtendedColorType::L8)?;
    Ok((gray, w, h, png))
}

/// What the OpenCV reference scripts need.
pub const OPENCV_PACKAGES: &str = "opencv-python-headless numpy";

/// Runs a Python reference script that needs the pip `packages`; its standard output.
pub fn python_reference(script: &str, args: &[String], packages: &str) -> Result<String> {
    let py = Command::new("python3")
        .arg("-c")
        .arg(script)
        .args(args)
        .output()
        .context("cannot run python3")?;
    if !py.status.success() {
        bail!(
            "the Python reference failed (pip install {packages}): {}",
            String::from_utf8_lossy(&py.stderr).lines().last().unwrap_or("")
        );
    }
    Ok(String::from_utf8_lossy(&py.stdout).into_owned())
}
