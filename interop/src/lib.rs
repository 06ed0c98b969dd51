//! Other tools' files. `lineflow poses import`: `poses.csv` from a COLMAP model or a Metashape cameras export
//! ([`poses`]). `lineflow camera import | export`: a project's `camera.toml` from another tool's calibration file
//! (OpenCV, COLMAP, Metashape) and back, through a least-squares fit between OpenCV's lens model and this project's
//! correction model ([`lineflow_photogrammetry::lens`]), with the fit's residual over the frame printed.
//! `lineflow targets`: a project's `observations.csv` from the survey targets in its images ([`targets`]).
#![warn(missing_docs)]

pub mod bare;
pub mod calibrate;
pub mod poses;
pub mod targets;

pub use poses::{poses, PosesCmd};

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use lineflow_formats::exif_camera::exif_camera;
use lineflow_formats::foreign_camera::{self, ForeignFormat};
use lineflow_formats::project::{is_image_name, read_camera, write_camera};
use lineflow_photogrammetry::{camera_from_opencv, opencv_from_camera, Camera, FitResidual};

/// Pixel pitch assumed when neither the file nor the user gives one, mm: only the ratio of the principal distance to
/// it enters the geometry, so any value gives the same rays, and millimetres of the right size read naturally.
pub const ASSUMED_PIXEL_SIZE_MM: f64 = 0.005;

/// A fit residual worth a warning, pixels: the converted model strays from the original in the corners.
const WARN_RESIDUAL_PX: f64 = 0.5;

/// `lineflow camera …`.
#[derive(Debug, clap::Subcommand)]
pub enum CameraCmd {
    /// Write camera.toml from another tool's calibration: OpenCV calibrateCamera output (.yml/.yaml/.xml/.json),
    /// COLMAP cameras.txt or cameras.bin (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV) or
    /// Agisoft Metashape calibration .xml; prints the conversion's residual over the frame. Given a photo
    /// (.jpg/.tif/.png), a nominal camera from its EXIF instead
    Import {
        /// The calibration file, or a photo whose EXIF gives a nominal camera.
        file: PathBuf,
        /// The camera.toml to write (an existing file only with --force).
        #[arg(long, default_value = "camera.toml")]
        out: PathBuf,
        /// The sensor's pixel pitch, mm (sets the scale of focal_mm; the rays do not depend on it) [default: the
        /// photo's EXIF, or 0.005 for a calibration file].
        #[arg(long)]
        pixel_size_mm: Option<f64>,
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

fn import(file: &Path, out: &Path, pixel_size_mm: Option<f64>, camera_id: Option<u32>, force: bool) -> Result<ExitCode> {
    if let Some(p) = pixel_size_mm.filter(|p| !(p.is_finite() && *p > 0.0)) {
        bail!("--pixel-size-mm {p}: must be a positive length");
    }
    if out.exists() && !force {
        bail!("{} exists: pass --force to overwrite it", out.display());
    }
    if is_image_name(file) {
        return import_exif(file, out, pixel_size_mm);
    }
    let pixel_size_mm = pixel_size_mm.unwrap_or(ASSUMED_PIXEL_SIZE_MM);
    let foreign = foreign_camera::read(file, camera_id)?;
    let Some((camera, fit)) = camera_from_opencv(&foreign.lens, foreign.width, foreign.height, pixel_size_mm) else {
        bail!(
            "{}: the lens does not invert over the {}x{} frame (distortion coefficients beyond their valid field?)",
            file.display(),
            foreign.width,
            foreign.height
        );
    };
    let header = format!(
        "# From {} ({}) by `lineflow camera import`; our correction model fitted over the frame: {fit}.\n",
        file.display(),
        foreign.format
    );
    write_camera(out, &camera, &header)?;
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

/// The first line of a nominal camera file begins so: `lineflow process` self-calibrates such a camera.
pub const NOMINAL_CAMERA_HEADER: &str = "# Nominal camera";

/// Writes `out` with a nominal camera from a photo's EXIF (`lineflow_formats::exif_camera`; the pixel pitch from
/// the EXIF unless given), printing what it took and a warning that it is no calibration.
///
/// # Errors
/// A photo without the EXIF to start from, a camera `camera.toml` would refuse, or `out` not writable.
pub fn import_exif(photo: &Path, out: &Path, pixel_size_mm: Option<f64>) -> Result<ExitCode> {
    let (width, height) = lineflow_capture::decode::image_size(photo)?;
    let exif = exif_camera(photo, width, height)?;
    let (pixel_size_mm, pitch_from) = match pixel_size_mm {
        Some(p) => (p, "--pixel-size-mm"),
        None => (exif.pixel_size_mm, exif.pitch_from.as_str()),
    };
    let camera = Camera {
        width,
        height,
        pixel_size_mm,
        focal_mm: exif.focal_mm,
        principal_point_mm: [0.0; 2],
        radial: [0.0; 3],
        decentering: [0.0; 2],
    };
    let header = format!(
        "{NOMINAL_CAMERA_HEADER} from the EXIF of {} ({}) by `lineflow camera import`: the focal length as the lens reports it, \
         the pixel pitch from {pitch_from}, the principal point at the centre, no distortion. A starting point, not a \
         calibration.\n",
        photo.display(),
        if exif.name.is_empty() { "camera unnamed" } else { &exif.name }
    );
    write_camera(out, &camera, &header)?;
    eprintln!(
        "{}: {width}x{height} px, f = {} mm, {pixel_size_mm:.5} mm pixels (from {pitch_from}) -> {}",
        photo.display(),
        exif.focal_mm,
        out.display()
    );
    for note in &exif.notes {
        eprintln!("note: {note}");
    }
    eprintln!(
        "warning: a nominal camera: the focal length is the lens's marked value (often 1-3 % off), the principal \
         point and the distortion are unknown. `lineflow process` estimates them first (self-calibration, \
         docs/orientation.md), which is weak on a flat façade from one strip; a calibrated camera (OpenCV, COLMAP, \
         Metashape: `lineflow camera import`) remains the way to survey-grade results"
    );
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
        import(&colmap, &toml, Some(0.0039), None, false).unwrap();
        let camera = read_camera(&toml).unwrap();
        assert_eq!((camera.width, camera.height, camera.pixel_size_mm), (3072, 2304, 0.0039));
        assert!((camera.focal_mm - 2559.68 * 0.0039).abs() < 1e-9);
        let e = import(&colmap, &toml, Some(0.0039), None, false).unwrap_err().to_string();
        assert!(e.contains("--force"), "{e}");
        let back = dir.path().join("back.txt");
        export(&toml, ExportFormat::Colmap, Some(&back)).unwrap();
        let again = foreign_camera::read(&back, None).unwrap();
        assert!((again.lens.cx - 1535.9).abs() < 1e-6 && (again.lens.cy - 1152.4).abs() < 1e-6);
        assert!((again.lens.k[0] + 0.0204).abs() < 1e-4, "k1 {}", again.lens.k[0]);
        assert!((again.lens.p[0] - 0.0002).abs() < 1e-5, "p1 {}", again.lens.p[0]);
    }

    #[test]
    fn a_photo_gives_a_nominal_camera_from_its_exif_turned_as_the_photo_is() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("camera.toml");
        // A 16 x 12 JPEG tagged "rotate 90°", 24 mm lens, 24 mm on full frame (fuzz/corpus/exif_camera).
        let seed = std::fs::read(concat!(env!("CARGO_MANIFEST_DIR"), "/../fuzz/corpus/exif_camera/seed.jpg")).unwrap();
        // Its EXIF (the APP1 segment after SOI) in a 640 x 480 JPEG.
        let app1_len = 2 + u16::from_be_bytes([seed[4], seed[5]]) as usize;
        let img = image::GrayImage::from_pixel(640, 480, image::Luma([128]));
        let mut jpeg = Vec::new();
        image::codecs::jpeg::JpegEncoder::new(&mut jpeg).encode_image(&img).unwrap();
        let photo = dir.path().join("IMG_0001.jpg");
        std::fs::write(&photo, [&jpeg[..2], &seed[2..2 + app1_len], &jpeg[2..]].concat()).unwrap();
        import(&photo, &out, None, None, false).unwrap();
        let camera = read_camera(&out).unwrap();
        assert_eq!((camera.width, camera.height, camera.focal_mm), (480, 640, 24.0));
        // Full frame's diagonal over the image's 800-pixel diagonal.
        assert!((camera.pixel_size_mm - 43.266_615_305_567_87 / 800.0).abs() < 1e-9, "{camera:?}");
        import(&photo, &out, Some(0.004), None, true).unwrap();
        assert_eq!(read_camera(&out).unwrap().pixel_size_mm, 0.004);
        // The 16 x 12 seed itself would have 2 mm pixels: no camera's, refused by name and not written.
        let tiny = dir.path().join("tiny.jpg");
        std::fs::write(&tiny, &seed).unwrap();
        let e = import(&tiny, &dir.path().join("t.toml"), None, None, false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("pixel") && !dir.path().join("t.toml").exists(), "{e}");
    }

    #[test]
    fn a_missing_file_and_a_bad_pixel_size_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("camera.toml");
        let e = import(&dir.path().join("none.yml"), &out, None, None, false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.yml"), "{e}");
        let e = import(&dir.path().join("none.yml"), &out, Some(-1.0), None, false)
            .unwrap_err()
            .to_string();
        assert!(e.contains("--pixel-size-mm"), "{e}");
        assert!(!out.exists());
    }
}
