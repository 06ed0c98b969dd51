//! COLMAP's sparse model as files: `cameras.txt` / `cameras.bin` and `images.txt` / `images.bin` (the formats of
//! COLMAP's `read_write_model.py`). The cameras become lenses in [`crate::foreign_camera`]; the images become poses
//! in this project's convention: COLMAP's camera looks along +z with y down, ours along −z with y up, so
//! `M = diag(1, −1, −1) · R` and the centre is `−Rᵀ t`.
use std::path::Path;

use lineflow_photogrammetry::{Mat3, Pose, Vec3};
use nalgebra::{Quaternion, UnitQuaternion};

use crate::foreign_file::ForeignFileError;

/// One camera line (or record) of a COLMAP model.
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapCamera {
    /// CAMERA_ID.
    pub id: u32,
    /// MODEL, by name.
    pub model: String,
    /// WIDTH, pixels.
    pub width: f64,
    /// HEIGHT, pixels.
    pub height: f64,
    /// PARAMS.
    pub params: Vec<f64>,
    /// Where it is in the file ("line 4", "camera record 2"), for messages.
    pub at: String,
}

/// One registered image of a COLMAP model.
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapImage {
    /// NAME (a path relative to COLMAP's image folder).
    pub name: String,
    /// CAMERA_ID.
    pub camera_id: u32,
    /// The pose in this project's convention, in the model's frame.
    pub pose: Pose,
}

/// COLMAP's camera models by their id in the binary files, with their parameter counts.
const MODELS: [(&str, usize); 11] = [
    ("SIMPLE_PINHOLE", 3),
    ("PINHOLE", 4),
    ("SIMPLE_RADIAL", 4),
    ("RADIAL", 5),
    ("OPENCV", 8),
    ("OPENCV_FISHEYE", 8),
    ("FULL_OPENCV", 12),
    ("FOV", 5),
    ("SIMPLE_RADIAL_FISHEYE", 4),
    ("RADIAL_FISHEYE", 5),
    ("THIN_PRISM_FISHEYE", 12),
];

/// How many parameters a COLMAP camera model has; `None` for a model COLMAP does not define.
pub fn parameter_count(model: &str) -> Option<usize> {
    MODELS.iter().find(|(name, _)| *name == model).map(|(_, n)| *n)
}

/// COLMAP's `FULL_OPENCV` parameters `fx fy cx cy k1 k2 p1 p2 k3 k4 k5 k6` of a lens (principal point moved half a
/// pixel to COLMAP's convention).
pub fn full_opencv_params(l: &lineflow_photogrammetry::OpenCvLens) -> [f64; 12] {
    [
        l.fx,
        l.fy,
        l.cx + 0.5,
        l.cy + 0.5,
        l.k[0],
        l.k[1],
        l.p[0],
        l.p[1],
        l.k[2],
        l.k[3],
        l.k[4],
        l.k[5],
    ]
}

/// Reads the cameras of `cameras.txt`.
///
/// # Errors
/// A line that is not `CAMERA_ID MODEL WIDTH HEIGHT PARAMS…`, named by its number.
pub fn cameras_text(text: &str) -> Result<Vec<ColmapCamera>, String> {
    data_lines(text)
        .map(|(n, f)| {
            let bad = |what: &str| format!("line {n}: {what}");
            if f.len() < 4 {
                return Err(bad("expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS…"));
            }
            let num = |s: &str| s.parse::<f64>().map_err(|_| bad(&format!("{s:?} is not a number")));
            Ok(ColmapCamera {
                id: f[0].parse().map_err(|_| bad("the camera id is not a number"))?,
                model: f[1].to_owned(),
                width: num(f[2])?,
                height: num(f[3])?,
                params: f[4..].iter().map(|s| num(s)).collect::<Result<_, _>>()?,
                at: format!("line {n}"),
            })
        })
        .collect()
}

/// Reads the cameras of `cameras.bin`.
///
/// # Errors
/// A file that ends early or names an unknown camera model.
pub fn cameras_binary(bytes: &[u8]) -> Result<Vec<ColmapCamera>, String> {
    let mut r = Reader { bytes, at: 0 };
    let n = r.count("cameras", 24)?;
    (0..n)
        .map(|k| {
            let id = r.u32()?;
            let model_id = r.u32()? as usize;
            let (model, n_params) = *MODELS
                .get(model_id)
                .ok_or_else(|| format!("camera record {}: unknown camera model id {model_id}", k + 1))?;
            let (width, height) = (r.u64()? as f64, r.u64()? as f64);
            let params = (0..n_params).map(|_| r.f64()).collect::<Result<_, _>>()?;
            Ok(ColmapCamera {
                id,
                model: model.to_owned(),
                width,
                height,
                params,
                at: format!("camera record {}", k + 1),
            })
        })
        .collect()
}

/// Reads the registered images of `images.txt` or `images.bin` (by the extension).
///
/// # Errors
/// When the file cannot be read or is not such a file.
pub fn read_images(path: &Path) -> Result<Vec<ColmapImage>, ForeignFileError> {
    let fail = |message: String| ForeignFileError {
        path: path.to_owned(),
        message,
    };
    let bytes = std::fs::read(path).map_err(|e| fail(e.to_string()))?;
    let images = if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("bin")) {
        images_binary(&bytes)
    } else {
        String::from_utf8(bytes)
            .map_err(|_| "not UTF-8 text: not an images.txt".to_owned())
            .and_then(|t| images_text(&t))
    };
    let images = images.map_err(fail)?;
    if images.is_empty() {
        return Err(fail("no registered image".into()));
    }
    Ok(images)
}

/// Reads `images.txt`: per image, `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`, then a line of its 2-D points.
///
/// # Errors
/// A pose line that does not parse, named by its number.
pub fn images_text(text: &str) -> Result<Vec<ColmapImage>, String> {
    let mut out = Vec::new();
    // The 2-D point lines can be empty, so pose and point lines are told apart by position, not by content.
    let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim_start().starts_with('#'));
    while let Some((n, line)) = lines.next() {
        if line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split_whitespace().collect();
        let bad = |what: &str| format!("line {}: {what}", n + 1);
        if f.len() < 10 {
            return Err(bad("expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME"));
        }
        let num = |s: &str| s.parse::<f64>().map_err(|_| bad(&format!("{s:?} is not a number")));
        let q = [num(f[1])?, num(f[2])?, num(f[3])?, num(f[4])?];
        let t = [num(f[5])?, num(f[6])?, num(f[7])?];
        out.push(ColmapImage {
            name: f[9..].join(" "),
            camera_id: f[8].parse().map_err(|_| bad("the camera id is not a number"))?,
            pose: pose_of(q, t).ok_or_else(|| bad("the rotation is no unit quaternion"))?,
        });
        lines.next(); // its 2-D points
    }
    Ok(out)
}

/// Reads `images.bin`.
///
/// # Errors
/// A file that ends early or holds no unit quaternion.
pub fn images_binary(bytes: &[u8]) -> Result<Vec<ColmapImage>, String> {
    let mut r = Reader { bytes, at: 0 };
    let n = r.count("images", 64)?;
    (0..n)
        .map(|k| {
            let _image_id = r.u32()?;
            let q = [r.f64()?, r.f64()?, r.f64()?, r.f64()?];
            let t = [r.f64()?, r.f64()?, r.f64()?];
            let camera_id = r.u32()?;
            let name = r.name()?;
            let points = r.count("2-D points", 24)?;
            r.skip(points * 24)?;
            let pose = pose_of(q, t).ok_or_else(|| format!("image record {}: the rotation is no unit quaternion", k + 1))?;
            Ok(ColmapImage { name, camera_id, pose })
        })
        .collect()
}

/// Our pose of COLMAP's (qw, qx, qy, qz) and t (world to camera); `None` for a quaternion far from unit length.
fn pose_of(q: [f64; 4], t: [f64; 3]) -> Option<Pose> {
    let quat = Quaternion::new(q[0], q[1], q[2], q[3]);
    let norm = quat.norm();
    if !norm.is_finite() || (norm - 1.0).abs() > 1e-3 || !t.iter().all(|v| v.is_finite()) {
        return None;
    }
    let r: Mat3 = UnitQuaternion::from_quaternion(quat).to_rotation_matrix().into_inner();
    Some(Pose {
        center: -(r.transpose() * Vec3::from(t)),
        rotation: Mat3::from_diagonal(&Vec3::new(1.0, -1.0, -1.0)) * r,
    })
}

/// The data lines of a text file (1-based number, fields), comments and blank lines left out.
fn data_lines(text: &str) -> impl Iterator<Item = (usize, Vec<&str>)> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
        .map(|(n, l)| (n + 1, l.split_whitespace().collect()))
}

/// Little-endian reads with the file's end checked.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let b = self
            .bytes
            .get(self.at..self.at + N)
            .ok_or_else(|| format!("the file ends early (byte {} of {})", self.at, self.bytes.len()))?;
        self.at += N;
        Ok(b.try_into().expect("N bytes"))
    }
    fn u32(&mut self) -> Result<u32, String> {
        self.take::<4>().map(u32::from_le_bytes)
    }
    fn u64(&mut self) -> Result<u64, String> {
        self.take::<8>().map(u64::from_le_bytes)
    }
    fn f64(&mut self) -> Result<f64, String> {
        self.take::<8>().map(f64::from_le_bytes)
    }
    fn skip(&mut self, n: usize) -> Result<(), String> {
        self.at = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or("the file ends early")?;
        Ok(())
    }
    /// A record count, checked against what is left of the file (each record at least `min_size` bytes), so that a
    /// damaged count cannot ask for more memory than the file could fill.
    fn count(&mut self, what: &str, min_size: usize) -> Result<usize, String> {
        let n = self.u64()?;
        let left = (self.bytes.len() - self.at) as u64;
        if n.saturating_mul(min_size as u64) > left {
            return Err(format!("{n} {what} claimed, but only {left} bytes follow"));
        }
        Ok(n as usize)
    }
    /// A NUL-terminated UTF-8 name.
    fn name(&mut self) -> Result<String, String> {
        let rest = &self.bytes[self.at..];
        let end = rest
            .iter()
            .position(|&b| b == 0)
            .ok_or("an image name without its terminating NUL")?;
        let name = std::str::from_utf8(&rest[..end])
            .map_err(|_| "an image name that is not UTF-8")?
            .to_owned();
        self.at += end + 1;
        Ok(name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_photogrammetry::{look_at, Camera};

    /// COLMAP's (q, t) of one of our poses, as the orientation stage's export writes them.
    fn colmap_of(pose: &Pose) -> ([f64; 4], [f64; 3]) {
        let r = Mat3::from_diagonal(&Vec3::new(1.0, -1.0, -1.0)) * pose.rotation;
        let q = UnitQuaternion::from_matrix(&r);
        let t = -(r * pose.center);
        ([q.w, q.i, q.j, q.k], [t.x, t.y, t.z])
    }

    fn poses() -> Vec<Pose> {
        [-3.0, 0.5, 4.0]
            .iter()
            .map(|&x| {
                let c = Vec3::new(x, -12.0, 1.6);
                Pose {
                    center: c,
                    rotation: look_at(&c, &Vec3::new(x * 0.5, 0.0, 3.0), &Vec3::z()),
                }
            })
            .collect()
    }

    fn assert_same(a: &Pose, b: &Pose) {
        assert!((a.center - b.center).norm() < 1e-9, "{a:?} {b:?}");
        assert!((a.rotation - b.rotation).norm() < 1e-9, "{a:?} {b:?}");
    }

    #[test]
    fn images_txt_gives_back_our_poses_and_colmaps_projection_agrees() {
        let mut text = String::from("# Image list with two lines of data per image:\n");
        for (k, p) in poses().iter().enumerate() {
            let (q, t) = colmap_of(p);
            text += &format!(
                "{} {} {} {} {} {} {} {} 1 IMG {k}.jpg\n",
                k + 1,
                q[0],
                q[1],
                q[2],
                q[3],
                t[0],
                t[1],
                t[2]
            );
            text += if k == 1 { "\n" } else { "10.5 20.5 -1 30.5 40.5 7\n" };
        }
        let images = images_text(&text).unwrap();
        assert_eq!(images.len(), 3);
        assert_eq!(images[2].name, "IMG 2.jpg");
        for (got, want) in images.iter().zip(poses()) {
            assert_same(&got.pose, &want);
        }
        // A point projects where COLMAP's pinhole puts it, half a pixel apart.
        let camera = Camera::pinhole(1000, 800, 0.01, 20.0);
        let x = Vec3::new(0.3, 0.0, 2.4);
        let (q, t) = colmap_of(&poses()[0]);
        let r = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));
        let c = r * x + Vec3::from(t);
        let ours = images[0].pose.project(&camera, &x).unwrap();
        let colmap = [2000.0 * c.x / c.z + 500.0, 2000.0 * c.y / c.z + 400.0];
        assert!((colmap[0] - (ours[0] + 0.5)).abs() < 1e-6 && (colmap[1] - (ours[1] + 0.5)).abs() < 1e-6);
    }

    #[test]
    fn images_bin_reads_as_images_txt_does() {
        let mut b: Vec<u8> = 3u64.to_le_bytes().to_vec();
        for (k, p) in poses().iter().enumerate() {
            let (q, t) = colmap_of(p);
            b.extend((k as u32 + 1).to_le_bytes());
            q.iter().chain(&t).for_each(|v| b.extend(v.to_le_bytes()));
            b.extend(1u32.to_le_bytes());
            b.extend(format!("img{k}.png\0").bytes());
            b.extend(1u64.to_le_bytes());
            [1.5f64, 2.5].iter().for_each(|v| b.extend(v.to_le_bytes()));
            b.extend((-1i64).to_le_bytes());
        }
        let images = images_binary(&b).unwrap();
        assert_eq!(
            images.iter().map(|i| i.name.as_str()).collect::<Vec<_>>(),
            ["img0.png", "img1.png", "img2.png"]
        );
        for (got, want) in images.iter().zip(poses()) {
            assert_same(&got.pose, &want);
        }
        for cut in [3, 30, 60, b.len() - 20] {
            let e = images_binary(&b[..b.len() - cut]).unwrap_err();
            assert!(
                e.contains("ends early") || e.contains("bytes follow") || e.contains("NUL"),
                "{cut}: {e}"
            );
        }
        let mut huge = b.clone();
        huge[..8].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(images_binary(&huge).unwrap_err().contains("claimed"));
    }

    #[test]
    fn cameras_bin_reads_as_cameras_txt_does() {
        let text = cameras_text("# c\n2 OPENCV 3072 2304 2559.68 2560.12 1536.4 1152.9 -0.0204 0.0012 0.0002 -0.0001\n").unwrap();
        let mut b: Vec<u8> = 1u64.to_le_bytes().to_vec();
        b.extend(2u32.to_le_bytes());
        b.extend(4u32.to_le_bytes());
        b.extend(3072u64.to_le_bytes());
        b.extend(2304u64.to_le_bytes());
        text[0].params.iter().for_each(|v| b.extend(v.to_le_bytes()));
        let bin = cameras_binary(&b).unwrap();
        assert_eq!((bin[0].id, &bin[0].model, &bin[0].params), (2, &text[0].model, &text[0].params));
        b[12] = 99;
        assert!(cameras_binary(&b).unwrap_err().contains("unknown camera model id 99"));
    }

    #[test]
    fn a_model_the_orientation_stage_wrote_reads_alike_as_text_and_binary() {
        let txt = images_text(include_str!("../../fuzz/corpus/colmap_images_txt/seed.txt")).unwrap();
        let bin = images_binary(include_bytes!("../../fuzz/corpus/colmap_images_bin/seed.bin")).unwrap();
        assert_eq!(txt.len(), 3);
        assert_eq!(txt, bin);
        let cameras = cameras_binary(include_bytes!("../../fuzz/corpus/colmap_cameras_bin/seed.bin")).unwrap();
        assert_eq!((cameras[0].model.as_str(), cameras[0].params.len()), ("FULL_OPENCV", 12));
    }

    #[test]
    fn a_bad_pose_line_is_named() {
        let e = images_text("1 0.5 0.5 0.5 0.5 0 0 x 1 a.jpg\n\n").unwrap_err();
        assert!(e.contains("line 1") && e.contains("\"x\""), "{e}");
        let e = images_text("1 2 0 0 0 0 0 0 1 a.jpg\n\n").unwrap_err();
        assert!(e.contains("unit quaternion"), "{e}");
    }
}
