//! `lineflow bench render`: the synthetic renderer against the 12 MP / 1 s target.
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use image::ImageEncoder;
use lineflow_synthetic::Synthetic;

/// Renders full-size frames of a preset and reports the time per frame against the 1 s target for 12 MP, with
/// PNG encoding of the same frame (excluded from the target) measured alongside for scale.
pub fn bench_render(preset: &str, frames: usize, scale: f64) -> Result<ExitCode> {
    let syn = Synthetic::new(preset, scale, 1)?;
    let cam = *syn.camera();
    let mp = cam.width as f64 * cam.height as f64 / 1e6;
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    println!(
        "render benchmark: {preset}, {}x{} ({mp:.1} MP), {} faces, {threads} threads",
        cam.width,
        cam.height,
        syn.building.faces.len()
    );
    // The first frame also allocates the working buffers; a camera streams many.
    let _ = syn.render(0);
    let n = frames.min(syn.poses().len()).max(1);
    let mut times = Vec::new();
    let mut last = Vec::new();
    for k in 0..n {
        let t = Instant::now();
        last = syn.render(k * syn.poses().len() / n);
        times.push(t.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let median = times[times.len() / 2];
    let t = Instant::now();
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png).write_image(&last, cam.width, cam.height, image::ExtendedColorType::Rgb8)?;
    let encode = t.elapsed().as_secs_f64();
    let per_12mp = median * 12.0 / mp;
    println!(
        "render  median {:.3} s/frame over {n} frames ({:.1} MP/s); scaled to 12 MP: {per_12mp:.3} s (target 1.0 s: {:.2}x)",
        median,
        mp / median,
        per_12mp
    );
    println!("PNG encoding of the same frame: {encode:.3} s ({:.2}x the render)", encode / median);
    Ok(ExitCode::SUCCESS)
}
