//! Other tools' camera calibration files, read into OpenCV's lens model ([`OpenCvLens`]) and written from it:
//! OpenCV's `FileStorage` output of `calibrateCamera` (YAML, XML or JSON), COLMAP's `cameras.txt`, and Agisoft
//! Metashape's camera calibration XML. The conversion to this project's correction model is
//! [`lineflow_photogrammetry::camera_from_opencv`].
//!
//! Pixel conventions at the boundary (`conventions.md`, "Other tools' conventions"): OpenCV's principal point is in
//! our convention (pixel centres at integers); COLMAP's puts (0, 0) at the top-left corner (half a pixel off);
//! Metashape gives the principal point as an offset from the image centre, which needs no conversion. Metashape
//! names the decentering terms the other way round from OpenCV (its P1 is OpenCV's p2).
use std::path::Path;

use lineflow_photogrammetry::OpenCvLens;

use crate::colmap::{self, ColmapCamera};
pub use crate::foreign_file::ForeignFileError;
use crate::foreign_file::{xml_attribute, xml_elements, xml_text};

/// A camera read from another tool's file.
#[derive(Debug, Clone, PartialEq)]
pub struct ForeignCamera {
    /// Image size, pixels.
    pub width: u32,
    /// .
    pub height: u32,
    /// The lens, in OpenCV's model and our pixel convention.
    pub lens: OpenCvLens,
    /// The file's format, as a person names it ("COLMAP cameras.txt, OPENCV").
    pub format: String,
    /// What the reading left out or assumed (skew, a camera chosen among several), for the user to read.
    pub notes: Vec<String>,
}

/// The formats [`write`] can produce.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ForeignFormat {
    /// OpenCV `FileStorage` YAML, as `calibrateCamera` samples write it.
    OpenCvYaml,
    /// COLMAP `cameras.txt` with one OPENCV camera.
    Colmap,
    /// Agisoft Metashape calibration XML.
    Metashape,
}

/// Reads a calibration file; the format comes from the extension and the content. `camera_id` picks one camera of a
/// COLMAP file that holds several.
///
/// # Errors
/// When the file cannot be read, is none of the formats, or lacks the image size, focal length or principal point.
pub fn read(path: &Path, camera_id: Option<u32>) -> Result<ForeignCamera, ForeignFileError> {
    let fail = |message: String| ForeignFileError {
        path: path.to_owned(),
        message,
    };
    let bytes = std::fs::read(path).map_err(|e| fail(e.to_string()))?;
    let ext = path.extension().and_then(|e| e.to_str()).unwrap_or_default().to_ascii_lowercase();
    let out = match ext.as_str() {
        "bin" => colmap::cameras_binary(&bytes).and_then(|c| colmap(c, camera_id, "cameras.bin")),
        _ => std::str::from_utf8(&bytes)
            .map_err(|_| "not UTF-8 text: not a calibration file".to_owned())
            .and_then(|text| match ext.as_str() {
                "txt" => colmap::cameras_text(text).and_then(|c| colmap(c, camera_id, "cameras.txt")),
                "xml" if text.contains("<calibration") => metashape(text),
                "xml" => opencv(text, Syntax::Xml),
                "yml" | "yaml" => opencv(text, Syntax::Yaml),
                "json" => opencv(text, Syntax::Json),
                _ => Err(format!(
                "unknown extension {ext:?}: expected an OpenCV .yml/.yaml/.xml/.json, COLMAP cameras.txt or cameras.bin, or Metashape .xml"
            )),
            }),
    };
    let cam = out.map_err(fail)?;
    check(&cam).map_err(fail)?;
    Ok(cam)
}

fn check(c: &ForeignCamera) -> Result<(), String> {
    let l = &c.lens;
    if c.width == 0 || c.height == 0 || c.width > 100_000 || c.height > 100_000 {
        return Err(format!("image size {}x{} is not a camera's", c.width, c.height));
    }
    let finite = [l.fx, l.fy, l.cx, l.cy].iter().chain(&l.k).chain(&l.p).all(|v| v.is_finite());
    if !finite || l.fx <= 0.0 || l.fy <= 0.0 {
        return Err(format!(
            "focal length ({}, {}) px: must be positive and finite, as every coefficient",
            l.fx, l.fy
        ));
    }
    let (w, h) = (c.width as f64, c.height as f64);
    let size = w.max(h);
    if l.fx > 1000.0 * size || l.fy > 1000.0 * size || l.fx < 0.01 * size || l.fy < 0.01 * size {
        return Err(format!(
            "focal length ({}, {}) px is no lens's for a {}x{} image",
            l.fx, l.fy, c.width, c.height
        ));
    }
    if (l.cx - w / 2.0).abs() > w || (l.cy - h / 2.0).abs() > h {
        return Err(format!(
            "principal point ({}, {}) px lies far outside the {}x{} image",
            l.cx, l.cy, c.width, c.height
        ));
    }
    // The distortion at the frame's corners must be a number, and no more than the frame itself.
    let corner = [(-l.cx / l.fx), (w - l.cx) / l.fx, -l.cy / l.fy, (h - l.cy) / l.fy];
    for q in [
        [corner[0], corner[2]],
        [corner[1], corner[2]],
        [corner[0], corner[3]],
        [corner[1], corner[3]],
    ] {
        let d = l.distort(q);
        if !d.iter().all(|v| v.is_finite()) || (d[0] - q[0]).hypot(d[1] - q[1]) > 10.0 * q[0].hypot(q[1]).max(1.0) {
            return Err("the distortion coefficients run out of bounds within the frame".into());
        }
    }
    Ok(())
}

/// Which of OpenCV's `FileStorage` syntaxes.
#[derive(Clone, Copy)]
enum Syntax {
    Yaml,
    Xml,
    Json,
}

/// The camera-matrix and distortion keys OpenCV's samples, and the tools around it, write.
const MATRIX_KEYS: [&str; 5] = ["camera_matrix", "cameraMatrix", "K", "intrinsic_matrix", "intrinsics"];
const DISTORTION_KEYS: [&str; 5] = ["distortion_coefficients", "dist_coeffs", "distCoeffs", "D", "distortion"];

fn opencv(text: &str, syntax: Syntax) -> Result<ForeignCamera, String> {
    let json = match syntax {
        Syntax::Json => Some(serde_json::from_str::<serde_json::Value>(text).map_err(|e| format!("not JSON: {e}"))?),
        _ => None,
    };
    let numbers = |key: &str| -> Option<Vec<f64>> {
        match syntax {
            Syntax::Yaml => yaml_value(text, key),
            Syntax::Xml => xml_text(text, key).map(|t| xml_text(t, "data").unwrap_or(t)).map(parse_numbers),
            Syntax::Json => json_numbers(json.as_ref()?.get(key)?),
        }
    };
    let first = |keys: &[&str]| keys.iter().find_map(|k| numbers(k));
    let k = first(&MATRIX_KEYS).ok_or_else(|| format!("no camera matrix (one of {MATRIX_KEYS:?})"))?;
    if k.len() != 9 {
        return Err(format!("the camera matrix has {} values, not 9", k.len()));
    }
    let d = first(&DISTORTION_KEYS).unwrap_or_default();
    let size = |keys: [&str; 2]| keys.iter().find_map(|k| numbers(k)).and_then(|v| v.first().copied());
    let (Some(width), Some(height)) = (size(["image_width", "width"]), size(["image_height", "height"])) else {
        return Err("no image size (image_width and image_height)".into());
    };
    let mut notes = Vec::new();
    if k[1] != 0.0 {
        notes.push(format!("the skew {} is left out (this project's model has none)", k[1]));
    }
    let lens = opencv_lens([k[0], k[4], k[2], k[5]], &d, &mut notes)?;
    let name = match syntax {
        Syntax::Yaml => "OpenCV YAML",
        Syntax::Xml => "OpenCV XML",
        Syntax::Json => "OpenCV JSON",
    };
    Ok(ForeignCamera {
        width: pixels(width)?,
        height: pixels(height)?,
        lens,
        format: name.into(),
        notes,
    })
}

/// The lens of [fx, fy, cx, cy] and OpenCV's distortion vector (k1, k2, p1, p2[, k3[, k4, k5, k6[, …]]]).
fn opencv_lens(f: [f64; 4], d: &[f64], notes: &mut Vec<String>) -> Result<OpenCvLens, String> {
    if ![0, 4, 5, 8, 12, 14].contains(&d.len()) {
        return Err(format!("{} distortion coefficients: OpenCV writes 4, 5, 8, 12 or 14", d.len()));
    }
    if d.len() > 8 && d[8..].iter().any(|v| *v != 0.0) {
        notes.push("the thin-prism and tilt terms (s1–s4, τx, τy) are left out".into());
    }
    let at = |i: usize| d.get(i).copied().unwrap_or(0.0);
    Ok(OpenCvLens {
        fx: f[0],
        fy: f[1],
        cx: f[2],
        cy: f[3],
        k: [at(0), at(1), at(4), at(5), at(6), at(7)],
        p: [at(2), at(3)],
    })
}

fn pixels(v: f64) -> Result<u32, String> {
    ((1.0..=100_000.0).contains(&v) && v.fract() == 0.0)
        .then_some(v as u32)
        .ok_or_else(|| format!("image size {v} is not a whole number of pixels"))
}

fn parse_numbers(s: &str) -> Vec<f64> {
    s.split(|c: char| c.is_whitespace() || c == ',' || c == '[' || c == ']')
        .filter(|t| !t.is_empty())
        .map(|t| t.parse::<f64>().unwrap_or(f64::NAN))
        .collect()
}

/// The numbers of a top-level YAML key: a scalar (`image_width: 4000`) or an `!!opencv-matrix` whose `data: [...]`
/// may run over several lines.
fn yaml_value(text: &str, key: &str) -> Option<Vec<f64>> {
    let mut lines = text.lines();
    let rest = lines
        .by_ref()
        .find_map(|l| l.strip_prefix(key)?.trim_start().strip_prefix(':'))?
        .trim();
    if !rest.is_empty() && !rest.starts_with("!!") {
        return Some(parse_numbers(rest.trim_matches('"')));
    }
    let mut data = String::new();
    for line in lines {
        let t = line.trim();
        if !line.starts_with([' ', '\t']) && !t.is_empty() {
            break;
        }
        if data.is_empty() {
            if let Some(d) = t.strip_prefix("data:") {
                data.push_str(d);
            }
        } else {
            data.push(' ');
            data.push_str(t);
        }
        if !data.is_empty() && data.contains(']') {
            break;
        }
    }
    (!data.is_empty()).then(|| parse_numbers(&data))
}

fn json_numbers(v: &serde_json::Value) -> Option<Vec<f64>> {
    match v {
        serde_json::Value::Number(n) => Some(vec![n.as_f64()?]),
        serde_json::Value::Array(a) => a.iter().map(|x| x.as_f64()).collect(),
        serde_json::Value::Object(o) => json_numbers(o.get("data")?),
        _ => None,
    }
}

/// One camera of a COLMAP file chosen by `camera_id` (or the only one), as a lens.
fn colmap(cameras: Vec<ColmapCamera>, camera_id: Option<u32>, file: &str) -> Result<ForeignCamera, String> {
    let n = cameras.len();
    let chosen = match camera_id {
        Some(id) => cameras
            .into_iter()
            .find(|c| c.id == id)
            .ok_or_else(|| format!("no camera {id} in the file"))?,
        None if n == 1 => cameras.into_iter().next().ok_or("no camera in the file")?,
        None if n == 0 => return Err("no camera in the file".into()),
        None => {
            let ids: Vec<u32> = cameras.iter().map(|c| c.id).collect();
            return Err(format!("{n} cameras ({ids:?}): choose one with --camera-id"));
        }
    };
    let ColmapCamera {
        model,
        width,
        height,
        params: p,
        at,
        id,
    } = chosen;
    let unread =
        || format!("{at}: camera model {model} is not read (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, FULL_OPENCV are)");
    let n_params = colmap::parameter_count(&model).ok_or_else(unread)?;
    if p.len() != n_params {
        return Err(format!("{at}: {model} has {n_params} parameters, not {}", p.len()));
    }
    // COLMAP's principal point counts from the corner of the top-left pixel.
    let c = |i: usize| p[i] - 0.5;
    let mut notes = Vec::new();
    let lens = match model.as_str() {
        "SIMPLE_PINHOLE" => opencv_lens([p[0], p[0], c(1), c(2)], &[], &mut notes),
        "PINHOLE" => opencv_lens([p[0], p[1], c(2), c(3)], &[], &mut notes),
        "SIMPLE_RADIAL" => opencv_lens([p[0], p[0], c(1), c(2)], &[p[3], 0.0, 0.0, 0.0], &mut notes),
        "RADIAL" => opencv_lens([p[0], p[0], c(1), c(2)], &[p[3], p[4], 0.0, 0.0], &mut notes),
        "OPENCV" | "FULL_OPENCV" => opencv_lens([p[0], p[1], c(2), c(3)], &p[4..], &mut notes),
        _ => Err(unread()),
    }?;
    if n > 1 {
        notes.push(format!("camera {id} of {n}"));
    }
    Ok(ForeignCamera {
        width: pixels(width)?,
        height: pixels(height)?,
        lens,
        format: format!("COLMAP {file}, {model}"),
        notes,
    })
}

/// Metashape's calibration XML (`<calibration>` with `<width>`, `<height>`, `<f>`, `<cx>`, `<cy>` offsets from the
/// image centre, `<k1>`–`<k4>`, `<p1>`, `<p2>`, `<b1>`, `<b2>`).
fn metashape(text: &str) -> Result<ForeignCamera, String> {
    // A project export holds the initial calibration and the adjusted one: the adjusted is the camera.
    let all: Vec<(&str, &str)> = xml_elements(text, "calibration").collect();
    let calib = all
        .iter()
        .find(|(a, _)| xml_attribute(a, "class") == Some("adjusted"))
        .or(all.first())
        .map(|(_, body)| *body)
        .ok_or("no <calibration> element")?;
    let value = |tag: &str| -> Result<Option<f64>, String> {
        xml_text(calib, tag)
            .map(|t| {
                t.trim()
                    .parse::<f64>()
                    .map_err(|_| format!("<{tag}> {:?} is not a number", t.trim()))
            })
            .transpose()
    };
    let need = |tag: &str| value(tag)?.ok_or_else(|| format!("no <{tag}> in <calibration>"));
    if let Some(p) = xml_text(calib, "projection") {
        if p.trim() != "frame" {
            return Err(format!("projection {:?}: only frame (pinhole) cameras are read", p.trim()));
        }
    }
    // A calibration file names the size in elements, a project export in `<resolution width=… height=…/>`.
    let resolution = xml_elements(calib, "resolution").next().map(|(a, _)| a);
    let size = |tag: &str| -> Result<f64, String> {
        match (value(tag)?, resolution.and_then(|a| xml_attribute(a, tag))) {
            (Some(v), _) => Ok(v),
            (None, Some(a)) => a.trim().parse().map_err(|_| format!("<resolution {tag}={a:?}> is not a number")),
            (None, None) => Err(format!("no <{tag}> in <calibration>")),
        }
    };
    let (width, height, f) = (size("width")?, size("height")?, need("f")?);
    let or0 = |tag: &str| value(tag).map(|v| v.unwrap_or(0.0));
    let (b1, b2) = (or0("b1")?, or0("b2")?);
    let mut notes = Vec::new();
    if b2 != 0.0 {
        notes.push(format!("the skew b2 = {b2} is left out"));
    }
    if or0("k4")? != 0.0 {
        notes.push("k4 is left out".into());
    }
    let (w, h) = (pixels(width)?, pixels(height)?);
    let lens = OpenCvLens {
        fx: f + b1,
        fy: f,
        cx: (w as f64 - 1.0) / 2.0 + or0("cx")?,
        cy: (h as f64 - 1.0) / 2.0 + or0("cy")?,
        k: [or0("k1")?, or0("k2")?, or0("k3")?, 0.0, 0.0, 0.0],
        // Metashape's P1 multiplies (r² + 2x²) in x, where OpenCV has p2; its P2 is OpenCV's p1.
        p: [or0("p2")?, or0("p1")?],
    };
    Ok(ForeignCamera {
        width: w,
        height: h,
        lens,
        format: "Agisoft Metashape XML".into(),
        notes,
    })
}

/// The file of `lens` on a `width × height` sensor in `format`.
pub fn write(format: ForeignFormat, width: u32, height: u32, lens: &OpenCvLens) -> String {
    let l = lens;
    match format {
        ForeignFormat::OpenCvYaml => format!(
            "%YAML:1.0\n---\nimage_width: {width}\nimage_height: {height}\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ {:e}, 0., {:e}, 0., {:e}, {:e}, 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: {}\n   dt: d\n   data: [ {} ]\n",
            l.fx,
            l.cx,
            l.fy,
            l.cy,
            distortion_vector(l).len(),
            distortion_vector(l).iter().map(|v| format!("{v:e}")).collect::<Vec<_>>().join(", ")
        ),
        ForeignFormat::Colmap => format!(
            "# Camera list with one line of data per camera:\n#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n# Number of cameras: 1\n1 FULL_OPENCV {width} {height} {}\n",
            colmap::full_opencv_params(l).map(|v| v.to_string()).join(" ")
        ),
        ForeignFormat::Metashape => format!(
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<calibration>\n  <projection>frame</projection>\n  <width>{width}</width>\n  <height>{height}</height>\n  <f>{}</f>\n  <cx>{}</cx>\n  <cy>{}</cy>\n  <b1>{}</b1>\n  <k1>{}</k1>\n  <k2>{}</k2>\n  <k3>{}</k3>\n  <p1>{}</p1>\n  <p2>{}</p2>\n</calibration>\n",
            l.fy,
            l.cx - (width as f64 - 1.0) / 2.0,
            l.cy - (height as f64 - 1.0) / 2.0,
            l.fx - l.fy,
            l.k[0],
            l.k[1],
            l.k[2],
            l.p[1],
            l.p[0]
        ),
    }
}

/// OpenCV's distortion vector of a lens: (k1, k2, p1, p2, k3), and k4–k6 when the rational terms are used.
fn distortion_vector(l: &OpenCvLens) -> Vec<f64> {
    let mut d = vec![l.k[0], l.k[1], l.p[0], l.p[1], l.k[2]];
    if l.k[3..].iter().any(|v| *v != 0.0) {
        d.extend(&l.k[3..]);
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    fn read_text(name: &str, text: &str, camera_id: Option<u32>) -> Result<ForeignCamera, ForeignFileError> {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join(name);
        std::fs::write(&path, text).unwrap();
        read(&path, camera_id)
    }

    const OPENCV_YAML: &str = include_str!("../../fuzz/corpus/opencv_yaml/seed.yml");
    const OPENCV_XML: &str = include_str!("../../fuzz/corpus/opencv_xml/seed.xml");
    const OPENCV_JSON: &str = include_str!("../../fuzz/corpus/opencv_json/seed.json");
    const COLMAP: &str = include_str!("../../fuzz/corpus/colmap_cameras/seed.txt");
    const METASHAPE: &str = include_str!("../../fuzz/corpus/metashape_xml/seed.xml");

    #[test]
    #[allow(clippy::excessive_precision)] // the digits as the files write them
    fn opencv_files_of_every_syntax_give_the_same_camera() {
        let want = OpenCvLens {
            fx: 5.3591573396163199e+02,
            fy: 5.3591573396163199e+02,
            cx: 3.4228315473308373e+02,
            cy: 2.3557082909788173e+02,
            k: [
                -2.6637260909660682e-01,
                -3.8588898922304653e-02,
                2.3839153080878486e-01,
                0.0,
                0.0,
                0.0,
            ],
            p: [1.7831947042852964e-03, -2.8122100441115472e-04],
        };
        for (name, text) in [("c.yml", OPENCV_YAML), ("c.xml", OPENCV_XML), ("c.json", OPENCV_JSON)] {
            let c = read_text(name, text, None).unwrap();
            assert_eq!((c.width, c.height), (640, 480), "{name}");
            // serde_json's default float parsing may be one unit in the last place off.
            let l = c.lens;
            let diff = [l.fx - want.fx, l.fy - want.fy, l.cx - want.cx, l.cy - want.cy]
                .into_iter()
                .chain(l.k.iter().zip(&want.k).map(|(a, b)| a - b))
                .chain(l.p.iter().zip(&want.p).map(|(a, b)| a - b))
                .fold(0.0f64, |m, d| m.max(d.abs()));
            assert!(diff < 1e-14, "{name}: {l:?}");
            assert!(c.notes.is_empty(), "{name}: {:?}", c.notes);
        }
    }

    #[test]
    fn colmap_cameras_are_chosen_by_id_and_moved_to_our_pixel_convention() {
        let e = read_text("cameras.txt", COLMAP, None).unwrap_err().to_string();
        assert!(e.contains("2 cameras") && e.contains("--camera-id"), "{e}");
        let c = read_text("cameras.txt", COLMAP, Some(1)).unwrap();
        assert_eq!((c.width, c.height, c.format.as_str()), (3072, 2304, "COLMAP cameras.txt, OPENCV"));
        assert_eq!([c.lens.fx, c.lens.fy, c.lens.cx, c.lens.cy], [2559.68, 2560.12, 1535.9, 1152.4]);
        assert_eq!((c.lens.k[0], c.lens.k[1], c.lens.p), (-0.0204, 0.0012, [0.0002, -0.0001]));
        let s = read_text("cameras.txt", COLMAP, Some(2)).unwrap();
        assert_eq!((s.lens.fx, s.lens.fy, s.lens.k[0]), (1320.5, 1320.5, -0.031));
        let e = read_text("cameras.txt", COLMAP, Some(3)).unwrap_err().to_string();
        assert!(e.contains("no camera 3"), "{e}");
        let e = read_text("cameras.txt", "1 OPENCV_FISHEYE 10 10 1 1 5 5 0 0 0 0\n", None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("OPENCV_FISHEYE is not read"), "{e}");
        let e = read_text("cameras.txt", "1 OPENCV 10 10 1 1 5\n", None).unwrap_err().to_string();
        assert!(e.contains("line 1: OPENCV has 8 parameters"), "{e}");
    }

    #[test]
    fn metashape_terms_are_mapped_onto_opencvs() {
        let c = read_text("calib.xml", METASHAPE, None).unwrap();
        assert_eq!((c.width, c.height), (6000, 4000));
        assert_eq!([c.lens.fx, c.lens.fy], [5313.2, 5312.4]);
        assert_eq!([c.lens.cx, c.lens.cy], [2999.5 - 12.3, 1999.5 + 8.1]);
        assert_eq!(c.lens.p, [-0.0001, 0.0003], "Metashape's P1 is OpenCV's p2");
    }

    #[test]
    fn a_metashape_project_export_gives_its_adjusted_calibration() {
        let text = include_str!("../../fuzz/corpus/metashape_cameras/seed.xml");
        let c = read_text("cameras.xml", text, None).unwrap();
        assert_eq!((c.width, c.height), (4288, 2848));
        assert_eq!([c.lens.fx, c.lens.cx], [3201.1, 2143.5 - 19.4]);
    }

    #[test]
    fn every_written_format_reads_back_to_the_same_lens() {
        let lens = OpenCvLens {
            fx: 3012.25,
            fy: 3011.5,
            cx: 2010.75,
            cy: 1490.125,
            k: [-0.12, 0.09, -0.02, 0.0, 0.0, 0.0],
            p: [4e-4, -2e-4],
        };
        for (format, name) in [
            (ForeignFormat::OpenCvYaml, "c.yml"),
            (ForeignFormat::Colmap, "cameras.txt"),
            (ForeignFormat::Metashape, "c.xml"),
        ] {
            let back = read_text(name, &write(format, 4000, 3000, &lens), None).unwrap();
            assert_eq!((back.width, back.height), (4000, 3000));
            let l = back.lens;
            let close = [l.fx - lens.fx, l.fy - lens.fy, l.cx - lens.cx, l.cy - lens.cy]
                .iter()
                .chain(&[
                    l.k[0] - lens.k[0],
                    l.k[1] - lens.k[1],
                    l.k[2] - lens.k[2],
                    l.p[0] - lens.p[0],
                    l.p[1] - lens.p[1],
                ])
                .all(|d| d.abs() < 1e-9);
            assert!(close, "{format:?}: {l:?}");
        }
    }

    #[test]
    fn files_that_are_no_calibration_are_refused_by_name() {
        for (name, text, expect) in [
            ("c.yml", "image_width: 640\nimage_height: 480\n", "no camera matrix"),
            (
                "c.yml",
                "camera_matrix: !!opencv-matrix\n   data: [ 1, 0, 2 ]\nimage_width: 4\nimage_height: 4\n",
                "3 values, not 9",
            ),
            ("c.json", "{\"camera_matrix\": [1,0,1,0,1,1,0,0,1]}", "no image size"),
            ("c.json", "not json", "not JSON"),
            (
                "c.xml",
                "<calibration><projection>spherical</projection></calibration>",
                "only frame",
            ),
            ("c.xml", "<calibration><width>10</width><height>10</height></calibration>", "no <f>"),
            ("c.png", "x", "unknown extension"),
            (
                "c.yml",
                "image_width: 640\nimage_height: 480\nK: !!opencv-matrix\n   data: [ -5, 0, 1, 0, 5, 1, 0, 0, 1 ]\n",
                "must be positive",
            ),
        ] {
            let e = read_text(name, text, None).unwrap_err().to_string();
            assert!(e.contains(expect), "{name}: {e}");
        }
    }
}
