//! `lineflow synth`: writes a synthetic scene as a project folder plus `gt/`; `lineflow bench render`.
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use lineflow_synthetic::{write_project, write_project_files, Synthetic};

/// Options of `lineflow synth`.
#[derive(clap::Args)]
pub struct SynthArgs {
    /// Preset: d2x-strip, a55-two-strips, convergent, roof.
    #[arg(long, default_value = "a55-two-strips")]
    preset: String,
    /// Image size relative to the preset (the field of view stays); 0.13 gives about 640 px wide.
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
    /// Seed of everything random.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output folder.
    #[arg(long)]
    out: PathBuf,
    /// Write JPEG images at this quality instead of PNG.
    #[arg(long)]
    jpeg: Option<u8>,
    /// Sensor noise, standard deviation in grey levels [default: 1.5].
    #[arg(long)]
    noise: Option<f64>,
    /// Made like a camera's photos: JPEG (quality 92 unless --jpeg) with EXIF, no camera.toml and no
    /// observations.csv (both kept in gt/).
    #[arg(long)]
    bare: bool,
    /// The project files and gt/ without rendering the images: enough for `lineflow eval` of a run of the
    /// synthetic camera node, which renders its own.
    #[arg(long, conflicts_with_all = ["bare", "jpeg"])]
    no_images: bool,
}

pub fn synth(a: SynthArgs) -> Result<ExitCode> {
    let mut syn = Synthetic::new(&a.preset, a.scale, a.seed)?;
    if let Some(q) = a.jpeg.or(a.bare.then_some(92)) {
        anyhow::ensure!((1..=100).contains(&q), "--jpeg must be 1-100, got {q}");
        syn.preset.sensor.jpeg_quality = q;
    }
    if let Some(n) = a.noise {
        anyhow::ensure!(n >= 0.0, "--noise must be >= 0, got {n}");
        syn.preset.sensor.noise_dn = n;
    }
    if a.out.join("images").is_dir() && std::fs::read_dir(a.out.join("images"))?.next().is_some() {
        anyhow::bail!("{}: already holds images/; choose an empty folder", a.out.display());
    }
    let cam = *syn.camera();
    if a.no_images {
        write_project_files(&syn, &a.out).with_context(|| format!("writing {}", a.out.display()))?;
        eprintln!(
            "wrote {}: {} (no images)",
            a.out.display(),
            lineflow_synthetic::PROJECT_FILES.join(", ")
        );
        return Ok(ExitCode::SUCCESS);
    }
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
    write_project(&syn, &a.out, &mut |done, total| {
        let per = started.elapsed().as_secs_f64() / done as f64;
        eprint!(
            "\r  image {done}/{total}  {per:.2} s/image  ETA {:.0} s   ",
            per * (total - done) as f64
        );
        let _ = std::io::stderr().flush();
    })
    .with_context(|| format!("writing {}", a.out.display()))?;
    if a.bare {
        lineflow_synthetic::make_bare(&syn, &a.out)?;
    }
    let what = if a.bare {
        "JPEG images with EXIF, control_points.csv, site.toml; camera.toml and observations.csv in gt/"
    } else {
        "images, camera.toml, control_points.csv, observations.csv, site.toml, gt/"
    };
    eprintln!("\rwrote {} in {:.1} s ({what})", a.out.display(), started.elapsed().as_secs_f64());
    Ok(ExitCode::SUCCESS)
}
