//! Readers and writers for the result files of `conventions.md`, shared by the stages that write them, the
//! synthetic ground truth, and `lineflow eval`. Columns come in the documented order; a reader accepts extra
//! columns after them; a standard deviation that was not estimated is an empty field.
#![warn(missing_docs)]

pub mod colmap;
pub mod exif_camera;
pub mod foreign_camera;
pub mod foreign_file;
pub mod metashape;
pub mod natural;
pub mod project;

use std::io::Write;
use std::path::{Path, PathBuf};

pub use lineflow_messages::LineClass;
use lineflow_photogrammetry::{opk_from_rotation, rotation_from_opk, Pose, Vec3};

/// A result file that cannot be read or written; the message names the file and line.
#[derive(Debug, thiserror::Error)]
#[error("{path}:{line}: {message}")]
pub struct FormatError {
    /// The file.
    pub path: PathBuf,
    /// 1-based line (0 when not tied to a line).
    pub line: u64,
    /// What is wrong.
    pub message: String,
}

fn err(path: &Path, line: u64, message: impl Into<String>) -> FormatError {
    FormatError {
        path: path.to_owned(),
        line,
        message: message.into(),
    }
}

/// Header of `poses.csv`.
pub const POSES_HEADER: [&str; 13] = [
    "image",
    "X",
    "Y",
    "Z",
    "omega_deg",
    "phi_deg",
    "kappa_deg",
    "sX",
    "sY",
    "sZ",
    "s_omega_deg",
    "s_phi_deg",
    "s_kappa_deg",
];
/// Header of `checkpoints.csv`.
pub const CHECKPOINTS_HEADER: [&str; 4] = ["id", "dX", "dY", "dZ"];
/// Header of `lines2d.csv`.
pub const LINES2D_HEADER: [&str; 7] = ["image", "id", "col1", "row1", "col2", "row2", "n_pixels"];
/// The optional column of `lines3d.csv` after [`LINES3D_HEADER`]: `structure`, `texture` or empty.
pub const LINES3D_CLASS: &str = "class";

/// Header of `lines3d.csv`.
pub const LINES3D_HEADER: [&str; 10] = ["id", "X1", "Y1", "Z1", "X2", "Y2", "Z2", "n_points", "n_images", "rms_m"];

/// One row of `poses.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseRow {
    /// Image file name.
    pub image: String,
    /// Exterior orientation.
    pub pose: Pose,
    /// σ of X, Y, Z (metres), if estimated.
    pub sigma_center_m: Option<[f64; 3]>,
    /// σ of ω, φ, κ (degrees), if estimated.
    pub sigma_angles_deg: Option<[f64; 3]>,
}

/// One row of `checkpoints.csv`: estimated minus surveyed.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckRow {
    /// Point id.
    pub id: String,
    /// dX, dY, dZ in metres.
    pub delta_m: [f64; 3],
}

/// One row of `lines2d.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct Line2Row {
    /// Image file name.
    pub image: String,
    /// Segment id within the image.
    pub id: u64,
    /// First endpoint, measured pixels.
    pub start_px: [f64; 2],
    /// Second endpoint, measured pixels.
    pub end_px: [f64; 2],
    /// Pixels in the chain, if known.
    pub n_pixels: Option<u32>,
}

/// One row of `lines3d.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct Line3Row {
    /// Line id.
    pub id: String,
    /// First endpoint, metres.
    pub start: Vec3,
    /// Second endpoint, metres.
    pub end: Vec3,
    /// Supporting 3-D points, if known.
    pub n_points: Option<u32>,
    /// Supporting images, if known.
    pub n_images: Option<u32>,
    /// RMS of the points about the line, metres, if known.
    pub rms_m: Option<f64>,
    /// Structure or texture, where the line stage classed it (the optional `class` column).
    pub class: LineClass,
}

impl From<&lineflow_messages::Line3> for Line3Row {
    /// The row of a `Lines3D` element; ids are written `L<id>`.
    fn from(l: &lineflow_messages::Line3) -> Self {
        Line3Row {
            id: format!("L{}", l.id),
            start: Vec3::from(l.start_m),
            end: Vec3::from(l.end_m),
            n_points: Some(l.n_points),
            n_images: Some(l.n_images),
            rms_m: Some(l.rms_m),
            class: LineClass::from_code(l.class),
        }
    }
}

fn opt<T: std::fmt::Display>(v: Option<T>) -> String {
    v.map(|v| v.to_string()).unwrap_or_default()
}

fn create(path: &Path) -> Result<std::io::BufWriter<std::fs::File>, FormatError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| err(dir, 0, format!("cannot create folder: {e}")))?;
    }
    let f = std::fs::File::create(path).map_err(|e| err(path, 0, format!("cannot create: {e}")))?;
    Ok(std::io::BufWriter::new(f))
}

fn write_rows(path: &Path, header: &[&str], rows: impl Iterator<Item = Vec<String>>) -> Result<(), FormatError> {
    let mut out = create(path)?;
    let io = |e: std::io::Error| err(path, 0, format!("cannot write: {e}"));
    writeln!(out, "{}", header.join(",")).map_err(io)?;
    for row in rows {
        writeln!(out, "{}", row.join(",")).map_err(io)?;
    }
    out.flush().map_err(io)
}

/// Rows of a CSV file whose header starts with `header`, as string records with their line numbers.
/// A CSV file's data rows with their line numbers.
type Rows = Vec<(u64, csv::StringRecord)>;

fn read_rows(path: &Path, header: &[&str]) -> Result<Rows, FormatError> {
    Ok(read_rows_and_header(path, header)?.1)
}

/// The rows of a CSV file whose header starts with `header`, and the whole header (for the optional columns that
/// may follow).
fn read_rows_and_header(path: &Path, header: &[&str]) -> Result<(Vec<String>, Rows), FormatError> {
    let mut reader = csv::ReaderBuilder::new()
        .flexible(false)
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(|e| err(path, 0, format!("cannot read: {e}")))?;
    let found = reader.headers().map_err(|e| err(path, 1, e.to_string()))?.clone();
    let names: Vec<&str> = found.iter().collect();
    if names.len() < header.len() || names[..header.len()] != *header {
        return Err(err(
            path,
            1,
            format!("header must start with '{}', found '{}'", header.join(","), names.join(",")),
        ));
    }
    let mut rows = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| err(path, e.position().map_or(0, |p| p.line()), e.to_string()))?;
        let line = record.position().map_or(0, |p| p.line());
        rows.push((line, record));
    }
    Ok((names.iter().map(|n| n.to_string()).collect(), rows))
}

fn field<T: std::str::FromStr>(path: &Path, line: u64, rec: &csv::StringRecord, i: usize, name: &str) -> Result<T, FormatError> {
    let s = rec.get(i).unwrap_or("");
    s.parse()
        .map_err(|_| err(path, line, format!("column '{name}': cannot read '{s}'")))
}

fn optional<T: std::str::FromStr>(path: &Path, line: u64, rec: &csv::StringRecord, i: usize, name: &str) -> Result<Option<T>, FormatError> {
    match rec.get(i).unwrap_or("") {
        "" => Ok(None),
        _ => field(path, line, rec, i, name).map(Some),
    }
}

fn triple(path: &Path, line: u64, rec: &csv::StringRecord, first: usize, names: &[&str]) -> Result<Option<[f64; 3]>, FormatError> {
    let v = [
        optional(path, line, rec, first, names[first])?,
        optional(path, line, rec, first + 1, names[first + 1])?,
        optional(path, line, rec, first + 2, names[first + 2])?,
    ];
    Ok(match v {
        [Some(a), Some(b), Some(c)] => Some([a, b, c]),
        [None, None, None] => None,
        _ => {
            return Err(err(
                path,
                line,
                format!("columns {}..{}: give all three or none", names[first], names[first + 2]),
            ))
        }
    })
}

/// Writes `poses.csv`.
pub fn write_poses(path: &Path, rows: &[PoseRow]) -> Result<(), FormatError> {
    write_rows(
        path,
        &POSES_HEADER,
        rows.iter().map(|r| {
            let (o, p, k) = opk_from_rotation(&r.pose.rotation);
            let c = r.pose.center;
            let mut v = vec![r.image.clone(), format!("{:.6}", c.x), format!("{:.6}", c.y), format!("{:.6}", c.z)];
            v.extend([o, p, k].iter().map(|a| format!("{:.8}", a.to_degrees())));
            for s in [r.sigma_center_m, r.sigma_angles_deg] {
                v.extend((0..3).map(|i| opt(s.map(|s| format!("{:.6}", s[i])))));
            }
            v
        }),
    )
}

/// Reads `poses.csv`.
pub fn read_poses(path: &Path) -> Result<Vec<PoseRow>, FormatError> {
    let h = &POSES_HEADER;
    read_rows(path, h)?
        .into_iter()
        .map(|(line, rec)| {
            let f = |i: usize| field::<f64>(path, line, &rec, i, h[i]);
            let rotation = rotation_from_opk(f(4)?.to_radians(), f(5)?.to_radians(), f(6)?.to_radians());
            Ok(PoseRow {
                image: rec[0].to_string(),
                pose: Pose {
                    center: Vec3::new(f(1)?, f(2)?, f(3)?),
                    rotation,
                },
                sigma_center_m: triple(path, line, &rec, 7, h)?,
                sigma_angles_deg: triple(path, line, &rec, 10, h)?,
            })
        })
        .collect()
}

/// Writes `checkpoints.csv`.
pub fn write_checkpoints(path: &Path, rows: &[CheckRow]) -> Result<(), FormatError> {
    write_rows(
        path,
        &CHECKPOINTS_HEADER,
        rows.iter().map(|r| {
            let mut v = vec![r.id.clone()];
            v.extend(r.delta_m.iter().map(|d| format!("{d:.6}")));
            v
        }),
    )
}

/// Reads `checkpoints.csv`.
pub fn read_checkpoints(path: &Path) -> Result<Vec<CheckRow>, FormatError> {
    let h = &CHECKPOINTS_HEADER;
    read_rows(path, h)?
        .into_iter()
        .map(|(line, rec)| {
            let f = |i: usize| field::<f64>(path, line, &rec, i, h[i]);
            Ok(CheckRow {
                id: rec[0].to_string(),
                delta_m: [f(1)?, f(2)?, f(3)?],
            })
        })
        .collect()
}

/// Writes `lines2d.csv`.
pub fn write_lines2d(path: &Path, rows: &[Line2Row]) -> Result<(), FormatError> {
    Lines2dWriter::create(path)?.append(rows)
}

/// `lines2d.csv` written as the frames come, each frame's rows flushed at once: a stream of any length holds
/// none of them in memory, and a run that stops early keeps every frame written. [`write_lines2d`] is one append
/// of all the rows.
pub struct Lines2dWriter {
    out: std::io::BufWriter<std::fs::File>,
    path: std::path::PathBuf,
    rows: usize,
}

impl Lines2dWriter {
    /// Creates `path` (and its folder) with the header.
    ///
    /// # Errors
    /// When the file cannot be created or written.
    pub fn create(path: &Path) -> Result<Self, FormatError> {
        let mut out = create(path)?;
        writeln!(out, "{}", LINES2D_HEADER.join(",")).map_err(|e| err(path, 0, format!("cannot write: {e}")))?;
        Ok(Self {
            out,
            path: path.to_owned(),
            rows: 0,
        })
    }

    /// Appends `rows` and flushes them to the file.
    ///
    /// # Errors
    /// When the file cannot be written.
    pub fn append(&mut self, rows: &[Line2Row]) -> Result<(), FormatError> {
        let io = |e: std::io::Error| err(&self.path, 0, format!("cannot write: {e}"));
        for r in rows {
            let n_pixels = opt(r.n_pixels);
            let ([c1, r1], [c2, r2]) = (r.start_px, r.end_px);
            writeln!(self.out, "{},{},{c1:.3},{r1:.3},{c2:.3},{r2:.3},{n_pixels}", r.image, r.id).map_err(io)?;
        }
        self.rows += rows.len();
        self.out.flush().map_err(io)
    }

    /// The rows written so far.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// Reads `lines2d.csv`.
pub fn read_lines2d(path: &Path) -> Result<Vec<Line2Row>, FormatError> {
    let h = &LINES2D_HEADER;
    read_rows(path, h)?
        .into_iter()
        .map(|(line, rec)| {
            let f = |i: usize| field::<f64>(path, line, &rec, i, h[i]);
            Ok(Line2Row {
                image: rec[0].to_string(),
                id: field(path, line, &rec, 1, "id")?,
                start_px: [f(2)?, f(3)?],
                end_px: [f(4)?, f(5)?],
                n_pixels: optional(path, line, &rec, 6, "n_pixels")?,
            })
        })
        .collect()
}

/// A length in metres as `lines3d.csv` writes it (to the micrometre).
fn metres(v: f64) -> String {
    format!("{v:.6}")
}

/// `v` metres as `lines3d.csv` holds it once written and read back: what a stage reading a run's file gets, for a
/// stage reading the same value live to take alike.
pub fn metres_as_written(v: f64) -> f64 {
    metres(v).parse().unwrap_or(v)
}

/// Writes `lines3d.csv`.
pub fn write_lines3d(path: &Path, rows: &[Line3Row]) -> Result<(), FormatError> {
    write_rows(
        path,
        &[&LINES3D_HEADER[..], &[LINES3D_CLASS]].concat(),
        rows.iter().map(|r| {
            let mut v = vec![r.id.clone()];
            v.extend(r.start.iter().chain(r.end.iter()).map(|&c| metres(c)));
            v.extend([opt(r.n_points), opt(r.n_images), opt(r.rms_m.map(metres))]);
            v.push(r.class.name().to_string());
            v
        }),
    )
}

/// Reads `lines3d.csv`.
pub fn read_lines3d(path: &Path) -> Result<Vec<Line3Row>, FormatError> {
    let h = &LINES3D_HEADER;
    let (names, rows) = read_rows_and_header(path, h)?;
    let class_column = names.iter().position(|n| n == LINES3D_CLASS);
    rows.into_iter()
        .map(|(line, rec)| {
            let f = |i: usize| field::<f64>(path, line, &rec, i, h[i]);
            let class = match class_column.and_then(|i| rec.get(i)) {
                None => LineClass::Unknown,
                Some(word) => LineClass::from_name(word).ok_or_else(|| {
                    err(
                        path,
                        line,
                        format!("column '{LINES3D_CLASS}': '{word}' is no class (structure, texture or empty)"),
                    )
                })?,
            };
            Ok(Line3Row {
                id: rec[0].to_string(),
                start: Vec3::new(f(1)?, f(2)?, f(3)?),
                end: Vec3::new(f(4)?, f(5)?, f(6)?),
                n_points: optional(path, line, &rec, 7, h[7])?,
                n_images: optional(path, line, &rec, 8, h[8])?,
                rms_m: optional(path, line, &rec, 9, h[9])?,
                class,
            })
        })
        .collect()
}

/// A Wavefront OBJ file (`model.obj`) as lineflow writes and reads it: vertices, the vertex pairs of its `l`
/// elements (a polyline of k vertices gives k − 1 edges), and its `f` faces with the group (`g`) they are in.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ObjModel {
    /// Object coordinates, metres.
    pub vertices: Vec<Vec3>,
    /// Vertex index pairs.
    pub edges: Vec<[usize; 2]>,
    /// The edges of group `completed_edges`: not observed, completed behind an occluder (`docs/model.md`).
    pub hidden_edges: Vec<[usize; 2]>,
    /// The lines of group `surface_lines`: observed lines inside a wall's surface (mortar, tile and panel joints),
    /// no edges of the model.
    pub surface_lines: Vec<[usize; 2]>,
    /// (group, vertex indices of the face's ring).
    pub faces: Vec<(String, Vec<usize>)>,
}

/// Reads an OBJ file's vertices, lines, faces and groups; other statements are skipped.
pub fn read_obj(path: &Path) -> Result<ObjModel, FormatError> {
    let text = std::fs::read_to_string(path).map_err(|e| err(path, 0, format!("cannot read: {e}")))?;
    let mut obj = ObjModel::default();
    let mut group = String::new();
    for (k, raw) in text.lines().enumerate() {
        let line = k as u64 + 1;
        let mut words = raw.split_whitespace();
        let keyword = words.next();
        let indices = |words: std::str::SplitWhitespace, n: usize| {
            words
                .map(|w| {
                    let v = w.split('/').next().unwrap_or(w);
                    match v.parse::<i64>() {
                        Ok(i) if i > 0 && (i as usize) <= n => Ok(i as usize - 1),
                        Ok(i) if i < 0 && ((-i) as usize) <= n => Ok(n - (-i) as usize),
                        _ => Err(err(path, line, format!("'{w}' is not a vertex defined above"))),
                    }
                })
                .collect::<Result<Vec<usize>, _>>()
        };
        match keyword {
            Some("v") => {
                let xyz: Vec<f64> = words
                    .take(3)
                    .map(|w| w.parse::<f64>().map_err(|_| err(path, line, format!("'{w}' is not a number"))))
                    .collect::<Result<_, _>>()?;
                if xyz.len() != 3 || xyz.iter().any(|v| !v.is_finite()) {
                    return Err(err(path, line, "a vertex needs three finite coordinates"));
                }
                obj.vertices.push(Vec3::new(xyz[0], xyz[1], xyz[2]));
            }
            Some("l") => {
                let idx = indices(words, obj.vertices.len())?;
                let list = match group.as_str() {
                    "completed_edges" => &mut obj.hidden_edges,
                    "surface_lines" => &mut obj.surface_lines,
                    _ => &mut obj.edges,
                };
                list.extend(idx.windows(2).map(|w| [w[0], w[1]]));
            }
            Some("f") => {
                let idx = indices(words, obj.vertices.len())?;
                if idx.len() < 3 {
                    return Err(err(path, line, "a face needs at least three vertices"));
                }
                obj.faces.push((group.clone(), idx));
            }
            Some("g") => group = words.collect::<Vec<_>>().join(" "),
            _ => {}
        }
    }
    Ok(obj)
}

/// The wire-frame of an OBJ file: its vertices and the edges of its `l` elements but the hidden ones and the surface
/// lines
/// ([`read_obj`]).
pub fn read_obj_wireframe(path: &Path) -> Result<(Vec<Vec3>, Vec<[usize; 2]>), FormatError> {
    read_obj(path).map(|o| (o.vertices, o.edges))
}

/// Writes a run's 3-D lines into `dir` as `lines3d.csv` and `lines3d.ply`, and returns the CSV's path.
pub fn write_lines3d_results(dir: &Path, rows: &[Line3Row]) -> Result<std::path::PathBuf, FormatError> {
    write_lines3d_results_as(dir, "lines3d", rows)
}

/// [`write_lines3d_results`] under another name: `STEM.csv` and `STEM.ply` in `dir` (a second line stage of one
/// graph); returns the CSV's path.
pub fn write_lines3d_results_as(dir: &Path, stem: &str, rows: &[Line3Row]) -> Result<std::path::PathBuf, FormatError> {
    let csv = dir.join(format!("{stem}.csv"));
    write_lines3d(&csv, rows)?;
    write_lines_ply(&dir.join(format!("{stem}.ply")), rows)?;
    Ok(csv)
}

/// Writes 3-D segments as an ASCII PLY file of vertices and edges, readable by any 3-D viewer.
pub fn write_lines_ply(path: &Path, rows: &[Line3Row]) -> Result<(), FormatError> {
    let mut out = create(path)?;
    let io = |e: std::io::Error| err(path, 0, format!("cannot write: {e}"));
    write!(
        out,
        "ply\nformat ascii 1.0\ncomment lineflow 3-D line segments\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nelement edge {}\nproperty int vertex1\nproperty int vertex2\nend_header\n",
        2 * rows.len(),
        rows.len()
    )
    .map_err(io)?;
    for r in rows {
        for p in [r.start, r.end] {
            writeln!(out, "{:.6} {:.6} {:.6}", p.x, p.y, p.z).map_err(io)?;
        }
    }
    for i in 0..rows.len() {
        writeln!(out, "{} {}", 2 * i, 2 * i + 1).map_err(io)?;
    }
    out.flush().map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_obj_model_keeps_its_face_groups_its_hidden_edges_and_its_surface_lines_apart() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("model.obj");
        let text =
            "v 0 0 0\nv 1 0 0\nv 1 0 1\nv 0 0 1\ng Window\nf 1 2 3 4\ng edges\nl 1 2 3\ng completed_edges\nl 4 1\ng surface_lines\nl 1 3\n";
        std::fs::write(&path, text).unwrap();
        let obj = read_obj(&path).unwrap();
        assert_eq!(obj.faces, vec![("Window".to_string(), vec![0, 1, 2, 3])]);
        assert_eq!(obj.edges, vec![[0, 1], [1, 2]]);
        assert_eq!(obj.hidden_edges, vec![[3, 0]]);
        assert_eq!(obj.surface_lines, vec![[0, 2]]);
        assert_eq!(read_obj_wireframe(&path).unwrap().1, obj.edges);
        std::fs::write(&path, "v 0 0 0\nv 1 0 0\nf 1 2\n").unwrap();
        let e = read_obj(&path).unwrap_err().to_string();
        assert!(e.contains(":3") && e.contains("three vertices"), "{e}");
    }

    #[test]
    fn lines2d_written_frame_by_frame_is_the_file_written_at_once_and_each_frame_is_on_disk_when_appended() {
        let dir = tempfile::tempdir().unwrap();
        let row = |image: &str, id: u64, n_pixels: Option<u32>| Line2Row {
            image: image.into(),
            id,
            start_px: [1.0 + id as f64, 2.5],
            end_px: [30.125, 40.0],
            n_pixels,
        };
        let frames = [
            vec![row("a.png", 0, Some(31)), row("a.png", 1, None)],
            vec![],
            vec![row("b.png", 0, Some(7))],
        ];
        let (whole, streamed) = (dir.path().join("whole.csv"), dir.path().join("streamed.csv"));
        write_lines2d(&whole, &frames.concat()).unwrap();
        let mut w = Lines2dWriter::create(&streamed).unwrap();
        w.append(&frames[0]).unwrap();
        // Flushed: readable while the writer is still open.
        assert_eq!(read_lines2d(&streamed).unwrap().len(), 2);
        for f in &frames[1..] {
            w.append(f).unwrap();
        }
        assert_eq!(w.rows(), 3);
        drop(w);
        assert_eq!(std::fs::read(&streamed).unwrap(), std::fs::read(&whole).unwrap());
        // The layout of docs/conventions.md, three decimals, an unknown chain length left empty.
        assert_eq!(
            std::fs::read_to_string(&whole).unwrap(),
            "image,id,col1,row1,col2,row2,n_pixels\na.png,0,1.000,2.500,30.125,40.000,31\n\
             a.png,1,2.000,2.500,30.125,40.000,\nb.png,0,1.000,2.500,30.125,40.000,7\n"
        );
    }

    #[test]
    fn poses_round_trip_with_and_without_sigmas() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("poses.csv");
        let rows = vec![
            PoseRow {
                image: "a.png".into(),
                pose: Pose {
                    center: Vec3::new(1.0, -19.3, 1.6),
                    rotation: rotation_from_opk(1.8, 0.1, -0.02),
                },
                sigma_center_m: None,
                sigma_angles_deg: None,
            },
            PoseRow {
                image: "b.png".into(),
                pose: Pose {
                    center: Vec3::new(3.0, -19.0, 1.5),
                    rotation: rotation_from_opk(1.5, std::f64::consts::FRAC_PI_2, 0.0),
                },
                sigma_center_m: Some([0.01, 0.02, 0.03]),
                sigma_angles_deg: Some([0.1, 0.2, 0.3]),
            },
        ];
        write_poses(&path, &rows).unwrap();
        let back = read_poses(&path).unwrap();
        assert_eq!(back.len(), 2);
        for (a, b) in rows.iter().zip(&back) {
            assert_eq!(a.image, b.image);
            assert!((a.pose.center - b.pose.center).norm() < 1e-6);
            assert!((a.pose.rotation - b.pose.rotation).abs().max() < 1e-9);
            assert_eq!(a.sigma_center_m, b.sigma_center_m);
        }
    }

    #[test]
    fn bad_files_name_the_line_and_column() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lines3d.csv");
        std::fs::write(&path, "id,X1,Y1,Z1,X2,Y2,Z2,n_points,n_images,rms_m\nL1,0,0,0,1,1,x,,,\n").unwrap();
        let e = read_lines3d(&path).unwrap_err().to_string();
        assert!(e.contains(":2:") && e.contains("Z2"), "{e}");
        std::fs::write(&path, "id,X,Y\n").unwrap();
        assert!(read_lines3d(&path).unwrap_err().to_string().contains("header must start"));
        std::fs::write(
            &path,
            "id,X1,Y1,Z1,X2,Y2,Z2,n_points,n_images,rms_m,class\nL1,0,0,0,1,1,1,,,,edge\n",
        )
        .unwrap();
        let e = read_lines3d(&path).unwrap_err().to_string();
        assert!(e.contains(":2:") && e.contains("'edge' is no class"), "{e}");
    }

    #[test]
    fn the_class_column_round_trips_and_files_without_it_read_unclassed() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("lines3d.csv");
        let row = |id: &str, class| Line3Row {
            id: id.into(),
            start: Vec3::new(0.0, 0.0, 0.0),
            end: Vec3::new(1.0, 0.0, 0.0),
            n_points: Some(12),
            n_images: Some(3),
            rms_m: Some(0.004),
            class,
        };
        let rows = vec![
            row("L1", LineClass::Structure),
            row("L2", LineClass::Texture),
            row("L3", LineClass::Unknown),
        ];
        write_lines3d(&path, &rows).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("id,X1,Y1,Z1,X2,Y2,Z2,n_points,n_images,rms_m,class\n"), "{text}");
        assert!(
            text.contains(",structure\n") && text.contains(",texture\n") && text.ends_with(",\n"),
            "{text}"
        );
        assert_eq!(read_lines3d(&path).unwrap(), rows);
        // A file of another tool, without the column (and with one of its own after the ten named).
        std::fs::write(&path, "id,X1,Y1,Z1,X2,Y2,Z2,n_points,n_images,rms_m,score\nA,0,0,0,1,0,0,,,,0.9\n").unwrap();
        assert_eq!(read_lines3d(&path).unwrap()[0].class, LineClass::Unknown);
    }
}
