//! `lineflow synth`: writes a synthetic scene as a project folder plus `gt/`; `lineflow bench render`.
use std::io::Write;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use image::ImageEncoder;
use lineflow_capture::synth::{write_project, Synthetic};

/// Options of `lineflow synth`.
pub struct SynthArgs<'a> {
    pub preset: &'a str,
    pub scale: f64,
    pub seed: u64,
    pub out: &'a Path,
    pub jpeg_quality: Option<u8>,
    pub noise_dn: Option<f64>,
}

pub fn synth(a: SynthArgs) -> Result<ExitCode> {
    let mut syn = Synthetic::new(a.preset, a.scale, a.seed)?;
    if let Some(q) = a.jpeg_quality {
        anyhow::ensure!((1..=100).contains(&q), "--jpeg must be 1-100, got {q}");
        syn.preset.sensor.jpeg_quality = q;
    }
    if let Some(n) = a.noise_dn {
        anyhow::ensure!(n >= 0.0, "--noise must be >= 0, got {n}");
        syn.preset.sensor.noise_dn = n;
    }
    if a.out.join("images").is_dir() && std::fs::read_dir(a.out.join("images"))?.next().is_some() {
        anyhow::bail!("{}: already holds images/; choose an empty folder", a.out.display());
    }
    let cam = *syn.camera();
    eprintln!(
        "{}: {} images of {}x{} (scale {}), seed {} -> {}",
        a.preset,
        syn.poses().len(),
        cam.width,
        cam.height,
        a.scale,
        a.seed,
        a.out.display()
    );
    let started = Instant::now();
    write_project(&syn, a.out, &mut |done, total| {
        let per = started.elapsed().as_secs_f64() / done as f64;
        eprint!(
            "\r  image {done}/{total}  {per:.2} s/image  ETA {:.0} s   ",
            per * (total - done) as f64
        );
        let _ = std::io::stderr().flush();
    })
    .with_context(|| format!("writing {}", a.out.display()))?;
    eprintln!(
        "\rwrote {} in {:.1} s (images, camera.toml, control_points.csv, observations.csv, site.toml, gt/)",
        a.out.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}

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
