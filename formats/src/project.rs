//! A project folder as `conventions.md` defines it: `images/`, `camera.toml`, and optional survey data.
use std::path::{Path, PathBuf};

use lineflow_messages::{fixed_str, ControlPoint, Observation, Wall};
use lineflow_photogrammetry::Camera;
use serde::{Deserialize, Serialize};

/// What is wrong with a project folder; every message names the file (and line, for CSV and TOML).
#[derive(Debug, thiserror::Error)]
pub enum ProjectError {
    /// A required file or folder is missing.
    #[error("{0}: missing (a project folder needs images/ and camera.toml, see docs/formats.md)")]
    Missing(PathBuf),
    /// A file cannot be read.
    #[error("{path}: {message}")]
    Read {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A file's content is invalid.
    #[error("{path}:{line}: {message}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// Line number (1-based; 0 when unknown).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// `images/` holds no image.
    #[error("{0}: no images (*.png, *.jpg, *.jpeg, *.tif, *.tiff)")]
    NoImages(PathBuf),
}

/// `camera.toml`.
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CameraFile {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Pixel pitch, millimetres.
    pub pixel_size_mm: f64,
    /// Principal distance, millimetres.
    pub focal_mm: f64,
    /// Principal point, millimetres.
    #[serde(default)]
    pub principal_point_mm: [f64; 2],
    /// k1, k2, k3.
    #[serde(default)]
    pub radial: [f64; 3],
    /// p1, p2.
    #[serde(default)]
    pub decentering: [f64; 2],
}

impl CameraFile {
    /// The camera this file describes.
    pub fn camera(&self) -> Camera {
        Camera {
            width: self.width,
            height: self.height,
            pixel_size_mm: self.pixel_size_mm,
            focal_mm: self.focal_mm,
            principal_point_mm: self.principal_point_mm,
            radial: self.radial,
            decentering: self.decentering,
        }
    }

    /// The file of a camera.
    pub fn of(c: &Camera) -> CameraFile {
        CameraFile {
            width: c.width,
            height: c.height,
            pixel_size_mm: c.pixel_size_mm,
            focal_mm: c.focal_mm,
            principal_point_mm: c.principal_point_mm,
            radial: c.radial,
            decentering: c.decentering,
        }
    }

    fn validate(&self, path: &Path) -> Result<(), ProjectError> {
        let bad = |m: String| {
            Err(ProjectError::Invalid {
                path: path.to_owned(),
                line: 0,
                message: m,
            })
        };
        if self.width == 0 || self.height == 0 || self.width > 65535 || self.height > 65535 {
            return bad(format!("width and height must be in 1..=65535, got {}x{}", self.width, self.height));
        }
        if !(self.pixel_size_mm > 0.0 && self.pixel_size_mm < 1.0) {
            return bad(format!("pixel_size_mm must be in (0, 1), got {}", self.pixel_size_mm));
        }
        if !(self.focal_mm > 0.0 && self.focal_mm < 10_000.0) {
            return bad(format!("focal_mm must be in (0, 10000), got {}", self.focal_mm));
        }
        if !self
            .principal_point_mm
            .iter()
            .chain(&self.radial)
            .chain(&self.decentering)
            .all(|v| v.is_finite())
        {
            return bad("principal_point_mm, radial and decentering must be finite".into());
        }
        Ok(())
    }
}

/// A project folder, read and checked.
#[derive(Debug, Clone)]
pub struct Project {
    /// The folder.
    pub root: PathBuf,
    /// The camera.
    pub camera: CameraFile,
    /// Image files in natural file-name order.
    pub images: Vec<PathBuf>,
    /// Control and check points (empty when the file is absent).
    pub control_points: Vec<ControlPoint>,
    /// Observations of those points, with frame numbers from the image order.
    pub observations: Vec<Observation>,
    /// Walls of `site.toml`.
    pub walls: Vec<Wall>,
}

impl Project {
    /// Reads a project folder. With `allow_no_images` (watch mode), an empty `images/` is accepted.
    ///
    /// # Errors
    /// The first problem found, naming its file.
    pub fn open(root: &Path, allow_no_images: bool) -> Result<Self, ProjectError> {
        if !root.is_dir() {
            return Err(ProjectError::Missing(root.to_owned()));
        }
        let camera = read_camera(&root.join("camera.toml"))?;
        let images_dir = root.join("images");
        if !images_dir.is_dir() {
            return Err(ProjectError::Missing(images_dir));
        }
        let images = list_images(&images_dir)?;
        if images.is_empty() && !allow_no_images {
            return Err(ProjectError::NoImages(images_dir));
        }
        let control_points = optional(&root.join("control_points.csv"), read_control_points)?;
        let observations = optional(&root.join("observations.csv"), |p| read_observations(p, &images))?;
        let walls = optional(&root.join("site.toml"), read_site)?;
        Ok(Self {
            root: root.to_owned(),
            camera,
            images,
            control_points,
            observations,
            walls,
        })
    }
}

fn optional<T>(path: &Path, read: impl FnOnce(&Path) -> Result<Vec<T>, ProjectError>) -> Result<Vec<T>, ProjectError> {
    if path.exists() {
        read(path)
    } else {
        Ok(Vec::new())
    }
}

fn read_text(path: &Path) -> Result<String, ProjectError> {
    std::fs::read_to_string(path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            ProjectError::Missing(path.to_owned())
        } else {
            ProjectError::Read {
                path: path.to_owned(),
                message: e.to_string(),
            }
        }
    })
}

fn toml_error(path: &Path, text: &str, e: toml::de::Error) -> ProjectError {
    let line = e
        .span()
        .map(|s| text[..s.start.min(text.len())].matches('\n').count() + 1)
        .unwrap_or(0);
    ProjectError::Invalid {
        path: path.to_owned(),
        line,
        message: e.message().to_owned(),
    }
}

/// Writes `camera.toml`, `header` (comment lines) first, refusing a camera that [`read_camera`] would refuse.
///
/// # Errors
/// An invalid camera (named as the reader names it) or a file that cannot be written.
pub fn write_camera(path: &Path, camera: &Camera, header: &str) -> Result<(), ProjectError> {
    let file = CameraFile::of(camera);
    file.validate(path)?;
    let fail = |message: String| ProjectError::Read {
        path: path.to_owned(),
        message,
    };
    let toml = toml::to_string(&file).map_err(|e| fail(e.to_string()))?;
    std::fs::write(path, format!("{header}{toml}")).map_err(|e| fail(format!("cannot write: {e}")))
}

/// Reads and checks `camera.toml`.
///
/// # Errors
/// When it is missing, malformed or out of range.
pub fn read_camera(path: &Path) -> Result<CameraFile, ProjectError> {
    let text = read_text(path)?;
    let cam: CameraFile = toml::from_str(&text).map_err(|e| toml_error(path, &text, e))?;
    cam.validate(path)?;
    Ok(cam)
}

/// Whether `path` has an image extension the capture reads (any case of png, jpg, jpeg, tif, tiff).
pub fn is_image_name(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| matches!(e.to_ascii_lowercase().as_str(), "png" | "jpg" | "jpeg" | "tif" | "tiff"))
}

/// The image files of a folder in natural file-name order (hidden and partial files skipped).
///
/// # Errors
/// When the folder cannot be listed.
pub fn list_images(dir: &Path) -> Result<Vec<PathBuf>, ProjectError> {
    let entries = std::fs::read_dir(dir).map_err(|e| ProjectError::Read {
        path: dir.to_owned(),
        message: e.to_string(),
    })?;
    let mut images: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.is_file() && is_image_name(p))
        .filter(|p| !p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.starts_with('.')))
        .collect();
    images.sort_by(|a, b| crate::natural::natural_cmp(&file_name(a), &file_name(b)));
    Ok(images)
}

/// The file name of a path as a string.
pub fn file_name(p: &Path) -> String {
    p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
}

fn csv_rows(path: &Path, expected: &[&str]) -> Result<Vec<(usize, csv::StringRecord)>, ProjectError> {
    let text = read_text(path)?;
    let mut rdr = csv::ReaderBuilder::new().trim(csv::Trim::All).from_reader(text.as_bytes());
    let header = rdr
        .headers()
        .map_err(|e| ProjectError::Invalid {
            path: path.to_owned(),
            line: 1,
            message: e.to_string(),
        })?
        .clone();
    let got: Vec<&str> = header.iter().collect();
    if got.len() < expected.len() || got[..expected.len()] != *expected {
        return Err(ProjectError::Invalid {
            path: path.to_owned(),
            line: 1,
            message: format!("header must start with {}, got {}", expected.join(","), got.join(",")),
        });
    }
    let mut rows = Vec::new();
    for r in rdr.records() {
        let r = r.map_err(|e| ProjectError::Invalid {
            path: path.to_owned(),
            line: e.position().map(|p| p.line() as usize).unwrap_or(0),
            message: e.to_string(),
        })?;
        let line = r.position().map(|p| p.line() as usize).unwrap_or(0);
        if r.iter().all(str::is_empty) {
            continue;
        }
        rows.push((line, r));
    }
    Ok(rows)
}

fn field_f64(path: &Path, line: usize, r: &csv::StringRecord, i: usize, name: &str, allow_empty: bool) -> Result<f64, ProjectError> {
    let s = r.get(i).unwrap_or("");
    if s.is_empty() && allow_empty {
        return Ok(f64::NAN);
    }
    s.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| ProjectError::Invalid {
            path: path.to_owned(),
            line,
            message: format!("{name} must be a finite number, got '{s}'"),
        })
}

fn point_id(path: &Path, line: usize, s: &str) -> Result<[u8; 16], ProjectError> {
    if s.is_empty() || s.len() > 16 {
        return Err(ProjectError::Invalid {
            path: path.to_owned(),
            line,
            message: format!("point id must be 1-16 bytes, got '{s}'"),
        });
    }
    Ok(fixed_str(s))
}

/// Reads `control_points.csv`.
///
/// # Errors
/// The first malformed row, with its line.
pub fn read_control_points(path: &Path) -> Result<Vec<ControlPoint>, ProjectError> {
    let mut ids = std::collections::BTreeSet::new();
    csv_rows(path, &["id", "X", "Y", "Z", "sx", "sy", "sz", "role"])?
        .into_iter()
        .map(|(line, r)| {
            let id = r.get(0).unwrap_or("");
            if !ids.insert(id.to_owned()) {
                return Err(ProjectError::Invalid {
                    path: path.to_owned(),
                    line,
                    message: format!("duplicate point id '{id}'"),
                });
            }
            let f = |i, n| field_f64(path, line, &r, i, n, false);
            let s = |i, n| field_f64(path, line, &r, i, n, true);
            let role = match r.get(7).unwrap_or("") {
                "control" => ControlPoint::CONTROL,
                "check" => ControlPoint::CHECK,
                other => {
                    return Err(ProjectError::Invalid {
                        path: path.to_owned(),
                        line,
                        message: format!("role must be 'control' or 'check', got '{other}'"),
                    })
                }
            };
            Ok(ControlPoint {
                id: point_id(path, line, id)?,
                xyz: [f(1, "X")?, f(2, "Y")?, f(3, "Z")?],
                sigma_m: [s(4, "sx")?, s(5, "sy")?, s(6, "sz")?],
                role,
                reserved: 0,
            })
        })
        .collect()
}

/// Reads `observations.csv`; `image` names are matched against the project's images to give frame numbers.
///
/// # Errors
/// The first malformed row or unknown image, with its line.
pub fn read_observations(path: &Path, images: &[PathBuf]) -> Result<Vec<Observation>, ProjectError> {
    let names: Vec<String> = images.iter().map(|p| file_name(p)).collect();
    csv_rows(path, &["image", "point_id", "col", "row"])?
        .into_iter()
        .map(|(line, r)| {
            let image = r.get(0).unwrap_or("");
            let frame = names.iter().position(|n| n == image).ok_or_else(|| ProjectError::Invalid {
                path: path.to_owned(),
                line,
                message: format!("image '{image}' is not in images/"),
            })?;
            Ok(Observation {
                frame: frame as u64,
                point_id: point_id(path, line, r.get(1).unwrap_or(""))?,
                col: field_f64(path, line, &r, 2, "col", false)?,
                row: field_f64(path, line, &r, 3, "row", false)?,
            })
        })
        .collect()
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SiteFile {
    #[serde(default)]
    wall: Vec<WallEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WallEntry {
    name: String,
    corners: Vec<[f64; 3]>,
}

/// Reads `site.toml`.
///
/// # Errors
/// When it is malformed, or a wall has fewer than 3 or more than 16 corners.
pub fn read_site(path: &Path) -> Result<Vec<Wall>, ProjectError> {
    let text = read_text(path)?;
    let site: SiteFile = toml::from_str(&text).map_err(|e| toml_error(path, &text, e))?;
    site.wall
        .iter()
        .map(|w| {
            if !(3..=Wall::MAX_CORNERS).contains(&w.corners.len()) || w.corners.iter().flatten().any(|v| !v.is_finite()) {
                return Err(ProjectError::Invalid {
                    path: path.to_owned(),
                    line: 0,
                    message: format!(
                        "wall '{}' needs 3 to {} finite corners, has {}",
                        w.name,
                        Wall::MAX_CORNERS,
                        w.corners.len()
                    ),
                });
            }
            Ok(Wall::new(&w.name, &w.corners))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder() -> tempfile::TempDir {
        let d = tempfile::tempdir().unwrap();
        std::fs::create_dir(d.path().join("images")).unwrap();
        std::fs::write(
            d.path().join("camera.toml"),
            "width = 8\nheight = 6\npixel_size_mm = 0.005\nfocal_mm = 20.0\n",
        )
        .unwrap();
        for n in ["IMG_10.png", "IMG_2.PNG", "notes.txt"] {
            std::fs::write(d.path().join("images").join(n), b"x").unwrap();
        }
        d
    }

    #[test]
    fn images_come_in_natural_order_and_other_files_are_ignored() {
        let d = folder();
        let sut = Project::open(d.path(), false).unwrap();
        let names: Vec<_> = sut.images.iter().map(|p| file_name(p)).collect();
        assert_eq!(names, ["IMG_2.PNG", "IMG_10.png"]);
    }

    #[test]
    fn malformed_files_are_reported_with_file_and_line() {
        let d = folder();
        std::fs::write(
            d.path().join("control_points.csv"),
            "id,X,Y,Z,sx,sy,sz,role\nC1,1,2,3,,,,control\nC2,1,x,3,,,,check\n",
        )
        .unwrap();
        let err = Project::open(d.path(), false).unwrap_err().to_string();
        assert!(err.contains("control_points.csv:3: Y must be a finite number"), "{err}");

        std::fs::write(d.path().join("control_points.csv"), "id,X,Y,Z,sx,sy,sz,role\nC1,1,2,3,,,,control\n").unwrap();
        std::fs::write(d.path().join("observations.csv"), "image,point_id,col,row\nIMG_3.png,C1,1,2\n").unwrap();
        let err = Project::open(d.path(), false).unwrap_err().to_string();
        assert!(err.contains("observations.csv:2: image 'IMG_3.png' is not in images/"), "{err}");

        std::fs::write(d.path().join("observations.csv"), "image,point_id,col,row\nIMG_10.png,C1,1,2\n").unwrap();
        let sut = Project::open(d.path(), false).unwrap();
        assert_eq!(sut.observations[0].frame, 1);
        assert!(sut.control_points[0].sigma_m[0].is_nan());

        std::fs::write(
            d.path().join("camera.toml"),
            "width = 8\nheight = 6\npixel_size_mm = 0.005\nfocal = 20.0\n",
        )
        .unwrap();
        let err = Project::open(d.path(), false).unwrap_err().to_string();
        assert!(err.contains("camera.toml:4"), "{err}");
        std::fs::remove_file(d.path().join("camera.toml")).unwrap();
        let err = Project::open(d.path(), false).unwrap_err().to_string();
        assert!(err.contains("camera.toml: missing"), "{err}");
    }

    #[test]
    fn site_walls_are_read() {
        let d = folder();
        std::fs::write(
            d.path().join("site.toml"),
            "[[wall]]\nname = \"south\"\ncorners = [[0.0,0.0,0.0],[30.0,0.0,0.0],[30.0,0.0,20.0],[0.0,0.0,20.0]]\n",
        )
        .unwrap();
        let sut = Project::open(d.path(), false).unwrap();
        assert_eq!(sut.walls[0].name(), "south");
        assert_eq!(sut.walls[0].corners().len(), 4);
    }

    #[test]
    fn an_empty_images_folder_is_an_error() {
        let d = folder();
        for n in ["IMG_10.png", "IMG_2.PNG"] {
            std::fs::remove_file(d.path().join("images").join(n)).unwrap();
        }
        assert!(matches!(Project::open(d.path(), false), Err(ProjectError::NoImages(_))));
        assert!(Project::open(d.path(), true).is_ok());
    }
}
