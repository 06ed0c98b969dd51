//! Agisoft Metashape's camera export (File → Export → Cameras, `.xml`): each aligned camera's `<transform>` (camera to
//! chunk, a row-major 4 × 4 matrix; Metashape's camera looks along +z with y down) and the chunk's `<transform>`
//! (`<rotation>`, `<translation>`, `<scale>`: chunk to world), read into poses in this project's convention.
use std::path::Path;

use lineflow_photogrammetry::{Mat3, Pose, Vec3};

use crate::foreign_file::{xml_attribute, xml_elements, xml_text, ForeignFileError};

/// The aligned cameras of a Metashape cameras XML, by label, and notes on what was left out.
#[derive(Debug, Clone, PartialEq)]
pub struct MetashapeCameras {
    /// (label, pose) of every aligned camera, in file order. Labels are often file names without their extension.
    pub cameras: Vec<(String, Pose)>,
    /// Cameras without a transform (not aligned), a geocentric world frame, and the like.
    pub notes: Vec<String>,
}

/// Reads a Metashape cameras XML.
///
/// # Errors
/// When the file cannot be read, has no `<cameras>`, or a transform that does not parse.
pub fn read_cameras(path: &Path) -> Result<MetashapeCameras, ForeignFileError> {
    let fail = |message: String| ForeignFileError {
        path: path.to_owned(),
        message,
    };
    let text = std::fs::read_to_string(path).map_err(|e| fail(e.to_string()))?;
    cameras(&text).map_err(fail)
}

fn numbers<const N: usize>(text: &str, what: &str) -> Result<[f64; N], String> {
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|t| t.parse::<f64>().map_err(|_| format!("{what}: {t:?} is not a number")))
        .collect::<Result<_, _>>()?;
    let n = v.len();
    v.try_into().map_err(|_| format!("{what}: {n} numbers, not {N}"))
}

/// Parses the text of a cameras XML.
///
/// # Errors
/// No `<cameras>`, or a transform that does not parse.
pub fn cameras(text: &str) -> Result<MetashapeCameras, String> {
    let list = xml_text(text, "cameras").ok_or("no <cameras> element: not a Metashape cameras export")?;
    let mut notes = Vec::new();
    // Chunk to world: the first transform after the cameras (the chunk's own in older exports, its first
    // component's in newer ones); before them stand only the sensors.
    let after = text.find("</cameras>").map_or("", |k| &text[k..]);
    let (rotation, translation, scale) = match xml_text(after, "transform") {
        Some(t) => (
            xml_text(t, "rotation").map(|r| numbers::<9>(r, "chunk rotation")).transpose()?,
            xml_text(t, "translation")
                .map(|r| numbers::<3>(r, "chunk translation"))
                .transpose()?,
            xml_text(t, "scale").map(|r| numbers::<1>(r, "chunk scale")).transpose()?,
        ),
        None => {
            notes.push("no chunk transform: the poses are in the chunk's own frame".into());
            (None, None, None)
        }
    };
    let r = rotation.map_or(Mat3::identity(), |r| Mat3::from_row_slice(&r));
    let t = translation.map_or(Vec3::zeros(), Vec3::from);
    let s = scale.map_or(1.0, |s| s[0]);
    if t.norm() > 1e6 {
        notes.push("the world frame is geocentric (the chunk has a geographic reference): pass --project to bring the poses into the survey's frame".into());
    }
    let flip = Mat3::from_diagonal(&Vec3::new(1.0, -1.0, -1.0));
    let mut cameras = Vec::new();
    let mut unaligned = 0;
    for (attributes, body) in xml_elements(list, "camera") {
        let label = xml_attribute(attributes, "label").unwrap_or_default();
        let Some(transform) = xml_text(body, "transform") else {
            unaligned += 1;
            continue;
        };
        let m = numbers::<16>(transform, &format!("camera {label:?} transform"))?;
        let to_chunk = Mat3::new(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10]);
        let center = Vec3::new(m[3], m[7], m[11]);
        let to_world = r * to_chunk;
        let pose = Pose {
            center: s * (r * center) + t,
            rotation: flip * to_world.transpose(),
        };
        if !pose.center.iter().chain(pose.rotation.iter()).all(|v| v.is_finite()) {
            return Err(format!("camera {label:?}: a transform that is no pose"));
        }
        cameras.push((label.to_owned(), pose));
    }
    if unaligned > 0 {
        notes.push(format!("{unaligned} cameras are not aligned (no transform) and are left out"));
    }
    Ok(MetashapeCameras { cameras, notes })
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_photogrammetry::{look_at, Camera};

    #[test]
    fn a_camera_transform_and_the_chunk_transform_give_our_pose() {
        let truth = {
            let c = Vec3::new(2.0, -12.0, 1.6);
            Pose {
                center: c,
                rotation: look_at(&c, &Vec3::new(1.0, 0.0, 3.0), &Vec3::z()),
            }
        };
        // The chunk frame: the world scaled by 1/2, turned about z by 90°, shifted.
        let (s, r, t) = (
            2.0,
            Mat3::new(0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0),
            Vec3::new(100.0, 200.0, 10.0),
        );
        let center_chunk = r.transpose() * (truth.center - t) / s;
        let cam_to_world = (Mat3::from_diagonal(&Vec3::new(1.0, -1.0, -1.0)) * truth.rotation).transpose();
        let cam_to_chunk = r.transpose() * cam_to_world;
        let m = |i: usize, j: usize| cam_to_chunk[(i, j)];
        let transform = format!(
            "{} {} {} {} {} {} {} {} {} {} {} {} 0 0 0 1",
            m(0, 0),
            m(0, 1),
            m(0, 2),
            center_chunk.x,
            m(1, 0),
            m(1, 1),
            m(1, 2),
            center_chunk.y,
            m(2, 0),
            m(2, 1),
            m(2, 2),
            center_chunk.z
        );
        let rot: Vec<String> = r.transpose().iter().map(|v| v.to_string()).collect();
        let xml = format!(
            "<?xml version=\"1.0\"?>\n<document version=\"1.5.0\">\n  <chunk label=\"Chunk 1\">\n    <sensors next_id=\"1\">\n      <sensor id=\"0\" label=\"cam\" type=\"frame\"/>\n    </sensors>\n    <cameras next_id=\"2\">\n      <camera id=\"0\" sensor_id=\"0\" label=\"IMG_0001\">\n        <transform>{transform}</transform>\n      </camera>\n      <camera id=\"1\" sensor_id=\"0\" label=\"IMG_0002\"/>\n    </cameras>\n    <transform>\n      <rotation locked=\"true\">{}</rotation>\n      <translation locked=\"true\">{} {} {}</translation>\n      <scale locked=\"true\">{s}</scale>\n    </transform>\n  </chunk>\n</document>\n",
            rot.join(" "),
            t.x,
            t.y,
            t.z
        );
        let got = cameras(&xml).unwrap();
        assert_eq!(got.cameras.len(), 1);
        assert_eq!(got.cameras[0].0, "IMG_0001");
        assert!(got.notes.iter().any(|n| n.contains("1 cameras are not aligned")), "{:?}", got.notes);
        let pose = got.cameras[0].1;
        assert!((pose.center - truth.center).norm() < 1e-9, "{pose:?}");
        let camera = Camera::pinhole(1000, 800, 0.01, 20.0);
        let x = Vec3::new(1.3, 0.0, 2.9);
        let (a, b) = (pose.project(&camera, &x).unwrap(), truth.project(&camera, &x).unwrap());
        assert!((a[0] - b[0]).hypot(a[1] - b[1]) < 1e-9);
        assert!(cameras("<document/>").unwrap_err().contains("no <cameras>"));
    }

    #[test]
    fn the_sample_export_gives_its_two_aligned_cameras_in_the_world_frame() {
        let got = cameras(include_str!("../../fuzz/corpus/metashape_cameras/seed.xml")).unwrap();
        assert_eq!(
            got.cameras.iter().map(|c| c.0.as_str()).collect::<Vec<_>>(),
            ["IMG_0001", "IMG_0002"]
        );
        let pose = got.cameras[1].1;
        assert!((pose.center - Vec3::new(1000.0, 1988.0, 51.5)).norm() < 1e-12);
        // Camera 2 looks along +Y (our worked example: ω = 90°), image y up along +Z.
        assert!((pose.axis() - Vec3::y()).norm() < 1e-12 && (pose.rotation.row(1).transpose() - Vec3::z()).norm() < 1e-12);
    }
}
