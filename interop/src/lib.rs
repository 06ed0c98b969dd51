//! Other tools' files. `lineflow poses import`: `poses.csv` from a COLMAP model or a Metashape cameras export
//! ([`poses`]). `lineflow camera import | export`: a project's `camera.toml` from another tool's calibration file
//! (OpenCV, COLMAP, Metashape) and back, through a least-squares fit between OpenCV's lens model and this project's
//! correction model ([`lineflow_photogrammetry::lens`]), with the fit's residual over the frame printed.
#![warn(missing_docs)]

pub mod poses;

pub use poses::{poses, PosesCmd};

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use lineflow_formats::foreign_camera::{self, ForeignFormat};
use lineflow_formats::project::{read_camera, CameraFile};
use lineflow_photogrammetry::{camera_from_opencv, opencv_from_camera, FitResidual};

/// Pixel pitch assumed when neither the file nor the user gives one, mm: only the ratio of the principal distance to
/// it enters the geometry, so any value gives the same rays, and millimetres of the right size read naturally.
pub const ASSUMED_PIXEL_SIZE_MM: f64 = 0.005;

/// A fit residual worth a warning, pixels: the converted model strays from the original in the corners.
const WARN_RESIDUAL_PX: f64 = 0.5;

/// `lineflow camera …`.
#[derive(Debug, clap::Subcommand)]
pub enum CameraCmd {
    /// Write camera.toml from another tool's calibration: OpenCV calibrateCamera output (.yml/.yaml/.xml/.json),
    /// COLMAP cameras.txt (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV) or Agisoft
    /// Metashape calibration .xml; prints the conversion's residual over the frame
    Import {
        /// The calibration file.
        file: PathBuf,
        /// The camera.toml to write (an existing file only with --force).
        #[arg(long, default_value = "camera.toml")]
        out: PathBuf,
        /// The sensor's pixel pitch, mm (sets the scale of focal_mm; the rays do not depend on it).
        #[arg(long, default_value_t = ASSUMED_PIXEL_SIZE_MM)]
        pixel_size_mm: f64,
        /// The camera to take from a COLMAP file holding several.
        #[arg(long)]
        camera_id: Option<u32>,
        /// Overwrite `--out`.
        #[arg(long)]
        force: bool,
    },
    /// Write another tool's calibration file from a camera.toml (to stdout unless --out)
    Export {
        /// The camera.toml.
        camera: PathBuf,
        /// The format to write.
        #[arg(long, value_enum)]
        format: ExportFormat,
        /// The file to write.
        #[arg(long)]
        out: Option<PathBuf>,
    },
}

/// The formats `camera export` writes.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum ExportFormat {
    /// OpenCV FileStorage YAML (camera_matrix, distortion_coefficients).
    Opencv,
    /// COLMAP cameras.txt, one FULL_OPENCV camera.
    Colmap,
    /// Agisoft Metashape calibration XML.
    Metashape,
}

/// Runs a `lineflow camera` command.
///
/// # Errors
/// A file that cannot be read, parsed or written, a lens that does not invert over the frame, or an existing
/// `--out` without `--force`.
pub fn camera(cmd: CameraCmd) -> Result<ExitCode> {
    match cmd {
        CameraCmd::Import {
            file,
            out,
            pixel_size_mm,
            camera_id,
            force,
        } => import(&file, &out, pixel_size_mm, camera_id, force),
        CameraCmd::Export { camera, format, out } => export(&camera, format, out.as_deref()),
    }
}

fn import(file: &Path, out: &Path, pixel_size_mm: f64, camera_id: Option<u32>, force: bool) -> Result<ExitCode> {
    if !(pixel_size_mm.is_finite() && pixel_size_mm > 0.0) {
        bail!("--pixel-size-mm {pixel_size_mm}: must be a positive length");
    }
    if out.exists() && !force {
        bail!("{} exists: pass --force to overwrite it", out.display());
    }
    let foreign = foreign_camera::read(file, camera_id)?;
    let Some((camera, fit)) = camera_from_opencv(&foreign.lens, foreign.width, foreign.height, pixel_size_mm) else {
        bail!(
            "{}: the lens does not invert over the {}x{} frame (distortion coefficients beyond their valid field?)",
            file.display(),
            foreign.width,
            foreign.height
        );
    };
    let toml = toml::to_string(&CameraFile::of(&camera))?;
    let header = format!(
        "# From {} ({}) by `lineflow camera import`; our correction model fitted over the frame: {fit}.\n",
        file.display(),
        foreign.format
    );
    std::fs::write(out, header + &toml).with_context(|| format!("cannot write {}", out.display()))?;
    eprintln!(
        "{}: {}, {}x{} px, f = {:.2} px -> {} (f = {:.4} mm at {} mm pixels)",
        file.display(),
        foreign.format,
        foreign.width,
        foreign.height,
        (foreign.lens.fx + foreign.lens.fy) / 2.0,
        out.display(),
        camera.focal_mm,
        pixel_size_mm
    );
    for note in &foreign.notes {
        eprintln!("note: {note}");
    }
    if (foreign.lens.fx - foreign.lens.fy).abs() > 1e-6 * foreign.lens.fx {
        eprintln!(
            "note: fx {} and fy {} differ; this project's model has square pixels, so f is their mean (part of the residual)",
            foreign.lens.fx, foreign.lens.fy
        );
    }
    report_fit(&fit);
    Ok(ExitCode::SUCCESS)
}

fn export(path: &Path, format: ExportFormat, out: Option<&Path>) -> Result<ExitCode> {
    let camera = read_camera(path)?.camera();
    let Some((lens, fit)) = opencv_from_camera(&camera) else {
        bail!("{}: no OpenCV lens fits this camera over its frame", path.display());
    };
    let format = match format {
        ExportFormat::Opencv => ForeignFormat::OpenCvYaml,
        ExportFormat::Colmap => ForeignFormat::Colmap,
        ExportFormat::Metashape => ForeignFormat::Metashape,
    };
    let text = foreign_camera::write(format, camera.width, camera.height, &lens);
    match out {
        Some(o) => std::fs::write(o, text).with_context(|| format!("cannot write {}", o.display()))?,
        None => print!("{text}"),
    }
    report_fit(&fit);
    Ok(ExitCode::SUCCESS)
}

fn report_fit(fit: &FitResidual) {
    eprintln!("fit of the two lens models over the frame: {fit}");
    if fit.max_px > WARN_RESIDUAL_PX {
        eprintln!(
            "warning: the models differ by up to {:.2} px in the corners: the lens is beyond what three radial terms of the \
             other model follow; keep points near the corners out of precise work, or calibrate in this project's model",
            fit.max_px
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn import_then_export_gives_back_the_calibration() {
        let dir = tempfile::tempdir().unwrap();
        let colmap = dir.path().join("cameras.txt");
        std::fs::write(
            &colmap,
            "1 OPENCV 3072 2304 2559.68 2559.68 1536.4 1152.9 -0.0204 0.0012 0.0002 -0.0001\n",
        )
        .unwrap();
        let toml = dir.path().join("camera.toml");
        import(&colmap, &toml, 0.0039, None, false).unwrap();
        let camera = read_camera(&toml).unwrap();
        assert_eq!((camera.width, camera.height, camera.pixel_size_mm), (3072, 2304, 0.0039));
        assert!((camera.focal_mm - 2559.68 * 0.0039).abs() < 1e-9);
        let e = import(&colmap, &toml, 0.0039, None, false).unwrap_err().to_string();
        assert!(e.contains("--force"), "{e}");
        let back = dir.path().join("back.txt");
        export(&toml, ExportFormat::Colmap, Some(&back)).unwrap();
        let again = foreign_camera::read(&back, None).unwrap();
        assert!((again.lens.cx - 1535.9).abs() < 1e-6 && (again.lens.cy - 1152.4).abs() < 1e-6);
        assert!((again.lens.k[0] + 0.0204).abs() < 1e-4, "k1 {}", again.lens.k[0]);
        assert!((again.lens.p[0] - 0.0002).abs() < 1e-5, "p1 {}", again.lens.p[0]);
    }

    #[test]
    fn a_missing_file_and_a_bad_pixel_size_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("camera.toml");
        let e = import(&dir.path().join("none.yml"), &out, 0.005, None, false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.yml"), "{e}");
        let e = import(&dir.path().join("none.yml"), &out, -1.0, None, false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--pixel-size-mm"), "{e}");
        assert!(!out.exists());
    }
}
