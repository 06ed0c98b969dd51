//! `lineflow synth`: writes a synthetic scene as a project folder plus `gt/`; `lineflow bench render`.
use std::io::Write;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use lineflow_synthetic::{write_project, Synthetic};

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
