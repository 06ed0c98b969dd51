//! Every parser a user's file or recording reaches, each with a valid seed file: the list that both fuzzers drive,
//! `lineflow bench fuzz` (a mutation fuzzer on any build) and the coverage-guided libFuzzer harness in `fuzz/`
//! (one fuzz target per parser, named by [`Target::key`]).
//!
//! The seeds are the files `fuzz/corpus/<key>/seed.*`, compiled in, so both fuzzers start from the same bytes and the
//! corpus libFuzzer grows beside them is replayed by this crate's tests on every test run.
use std::path::Path;

/// A parser and the valid file its inputs start from.
pub struct Target {
    /// Name of the format, as tables print it.
    pub name: &'static str,
    /// The fuzz target's name (`fuzz/fuzz_targets/<key>.rs`) and the corpus folder's (`fuzz/corpus/<key>`).
    pub key: &'static str,
    /// File name the input is written under (some readers go by the extension).
    pub file: &'static str,
    /// A valid file.
    pub seed: &'static [u8],
    /// Reads the file; an error is the right answer to bad bytes, a panic or an abort is a defect.
    pub parse: fn(&Path),
}

impl Target {
    /// Writes `input` to `dir` under the target's file name and parses it.
    pub fn run(&self, input: &[u8], dir: &Path) -> std::io::Result<()> {
        let path = dir.join(self.file);
        std::fs::write(&path, input)?;
        (self.parse)(&path);
        Ok(())
    }
}

/// The target with this key.
pub fn target(key: &str) -> Option<&'static Target> {
    TARGETS.iter().find(|t| t.key == key)
}

/// A folder for the inputs in memory where there is one: a disk makes the writes, not the parsers, the cost.
pub fn scratch() -> std::io::Result<tempfile::TempDir> {
    let shm = Path::new("/dev/shm");
    if shm.is_dir() {
        tempfile::tempdir_in(shm)
    } else {
        tempfile::tempdir()
    }
}

macro_rules! seed {
    ($key:literal, $file:literal) => {
        include_bytes!(concat!("../../fuzz/corpus/", $key, "/", $file))
    };
}

/// What `lineflow camera import` does with a calibration file: read it, then fit our lens model to it.
fn import_camera(p: &Path) {
    if let Ok(c) = lineflow_formats::foreign_camera::read(p, Some(1)) {
        let _ = lineflow_photogrammetry::camera_from_opencv(&c.lens, c.width, c.height, 0.005);
    }
}

/// Every target, in the order the benchmark prints them.
pub static TARGETS: &[Target] = &[
    Target {
        name: "launch TOML",
        key: "launch_toml",
        file: "graph.toml",
        seed: seed!("launch_toml", "seed.toml"),
        parse: |p| {
            let text = std::fs::read_to_string(p).unwrap_or_default();
            let _ = lineflow_runtime::launch::parse(p, &text, &[], &lineflow_runtime::launch::Resolver::beside_current_exe());
        },
    },
    Target {
        name: "camera.toml",
        key: "camera_toml",
        file: "camera.toml",
        seed: seed!("camera_toml", "seed.toml"),
        parse: |p| {
            let _ = lineflow_formats::project::read_camera(p);
        },
    },
    Target {
        name: "site.toml",
        key: "site_toml",
        file: "site.toml",
        seed: seed!("site_toml", "seed.toml"),
        parse: |p| {
            let _ = lineflow_formats::project::read_site(p);
        },
    },
    Target {
        name: "control_points.csv",
        key: "control_points_csv",
        file: "control_points.csv",
        seed: seed!("control_points_csv", "seed.csv"),
        parse: |p| {
            let _ = lineflow_formats::project::read_control_points(p);
        },
    },
    Target {
        name: "observations.csv",
        key: "observations_csv",
        file: "observations.csv",
        seed: seed!("observations_csv", "seed.csv"),
        parse: |p| {
            let images = [Path::new("IMG_0001.png").to_owned(), Path::new("IMG_0002.png").to_owned()];
            let _ = lineflow_formats::project::read_observations(p, &images);
        },
    },
    Target {
        name: "poses.csv",
        key: "poses_csv",
        file: "poses.csv",
        seed: seed!("poses_csv", "seed.csv"),
        parse: |p| {
            let _ = lineflow_formats::read_poses(p);
        },
    },
    Target {
        name: "checkpoints.csv",
        key: "checkpoints_csv",
        file: "checkpoints.csv",
        seed: seed!("checkpoints_csv", "seed.csv"),
        parse: |p| {
            let _ = lineflow_formats::read_checkpoints(p);
        },
    },
    Target {
        name: "lines2d.csv",
        key: "lines2d_csv",
        file: "lines2d.csv",
        seed: seed!("lines2d_csv", "seed.csv"),
        parse: |p| {
            let _ = lineflow_formats::read_lines2d(p);
        },
    },
    Target {
        name: "lines3d.csv",
        key: "lines3d_csv",
        file: "lines3d.csv",
        seed: seed!("lines3d_csv", "seed.csv"),
        parse: |p| {
            let _ = lineflow_formats::read_lines3d(p);
        },
    },
    Target {
        name: "OpenCV calibration YAML",
        key: "opencv_yaml",
        file: "calibration.yml",
        seed: seed!("opencv_yaml", "seed.yml"),
        parse: |p| {
            import_camera(p);
        },
    },
    Target {
        name: "OpenCV calibration XML",
        key: "opencv_xml",
        file: "calibration.xml",
        seed: seed!("opencv_xml", "seed.xml"),
        parse: |p| {
            import_camera(p);
        },
    },
    Target {
        name: "OpenCV calibration JSON",
        key: "opencv_json",
        file: "calibration.json",
        seed: seed!("opencv_json", "seed.json"),
        parse: |p| {
            import_camera(p);
        },
    },
    Target {
        name: "COLMAP cameras.txt",
        key: "colmap_cameras",
        file: "cameras.txt",
        seed: seed!("colmap_cameras", "seed.txt"),
        parse: |p| {
            import_camera(p);
        },
    },
    Target {
        name: "Metashape calibration XML",
        key: "metashape_xml",
        file: "calibration.xml",
        seed: seed!("metashape_xml", "seed.xml"),
        parse: |p| {
            import_camera(p);
        },
    },
    Target {
        name: "COLMAP images.txt",
        key: "colmap_images_txt",
        file: "images.txt",
        seed: seed!("colmap_images_txt", "seed.txt"),
        parse: |p| {
            let _ = lineflow_formats::colmap::read_images(p);
        },
    },
    Target {
        name: "COLMAP images.bin",
        key: "colmap_images_bin",
        file: "images.bin",
        seed: seed!("colmap_images_bin", "seed.bin"),
        parse: |p| {
            let _ = lineflow_formats::colmap::read_images(p);
        },
    },
    Target {
        name: "COLMAP cameras.bin",
        key: "colmap_cameras_bin",
        file: "cameras.bin",
        seed: seed!("colmap_cameras_bin", "seed.bin"),
        parse: |p| {
            import_camera(p);
        },
    },
    Target {
        name: "Metashape cameras XML",
        key: "metashape_cameras",
        file: "cameras.xml",
        seed: seed!("metashape_cameras", "seed.xml"),
        parse: |p| {
            let _ = lineflow_formats::metashape::read_cameras(p);
            import_camera(p);
        },
    },
    Target {
        name: "EXIF camera",
        key: "exif_camera",
        file: "photo.jpg",
        seed: seed!("exif_camera", "seed.jpg"),
        parse: |p| {
            let _ = lineflow_formats::exif_camera::exif_camera(p, 4000, 3000);
        },
    },
    Target {
        name: "OBJ model",
        key: "obj_model",
        file: "model.obj",
        seed: seed!("obj_model", "seed.obj"),
        parse: |p| {
            let _ = lineflow_formats::read_obj(p);
            let _ = lineflow_formats::read_obj_wireframe(p);
        },
    },
    Target {
        name: "PNG",
        key: "png",
        file: "image.png",
        seed: seed!("png", "seed.png"),
        parse: decode_image,
    },
    Target {
        name: "JPEG",
        key: "jpeg",
        file: "image.jpg",
        seed: seed!("jpeg", "seed.jpg"),
        parse: decode_image,
    },
    Target {
        name: "TIFF",
        key: "tiff",
        file: "image.tif",
        seed: seed!("tiff", "seed.tif"),
        parse: decode_image,
    },
    Target {
        name: "MCAP recording",
        key: "mcap",
        file: "recording.mcap",
        seed: seed!("mcap", "seed.mcap"),
        parse: read_recording,
    },
];

fn decode_image(p: &Path) {
    let _ = lineflow_capture::decode::decode_file(p);
}

/// Everything a user's recording goes through: open, both summaries, every message decoded, `recover`.
fn read_recording(p: &Path) {
    use lineflow_recordings::tools::{self, Reading};
    let Ok(rec) = lineflow_recordings::Recording::open(p) else { return };
    for reading in [Reading::Index, Reading::Messages] {
        let _ = tools::summarize(&rec, reading);
    }
    let _ = rec.for_each_message(|m| {
        if let Some(kind) = m.kind {
            let _ = lineflow_messages::schema::decode(kind, &m.data);
        }
        Ok(())
    });
    let _ = tools::recover(&rec, &p.with_extension("recovered.mcap"));
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn fuzz_dir() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz")
    }

    #[test]
    fn every_target_has_a_fuzz_target_and_a_corpus_and_its_seed_parses() {
        let dir = scratch().unwrap();
        for t in TARGETS {
            let harness = fuzz_dir().join("fuzz_targets").join(format!("{}.rs", t.key));
            assert!(harness.is_file(), "no libFuzzer target {}", harness.display());
            assert!(fuzz_dir().join("corpus").join(t.key).is_dir());
            t.run(t.seed, dir.path()).unwrap();
        }
        assert_eq!(target("mcap").map(|t| t.name), Some("MCAP recording"));
        assert!(target("nope").is_none());
    }

    /// The inputs libFuzzer kept (each reached code no other did) and the ones that once crashed a parser
    /// (`fuzz/regressions/<key>/`), replayed on every test run.
    #[test]
    fn every_corpus_and_regression_input_parses_without_a_panic() {
        let dir = scratch().unwrap();
        let mut replayed = 0;
        for t in TARGETS {
            for folder in ["corpus", "regressions"] {
                let Ok(entries) = std::fs::read_dir(fuzz_dir().join(folder).join(t.key)) else {
                    continue;
                };
                let mut files: Vec<PathBuf> = entries.flatten().map(|e| e.path()).collect();
                files.sort();
                for file in files {
                    let input = std::fs::read(&file).unwrap();
                    let outcome = std::panic::catch_unwind(|| t.run(&input, dir.path()));
                    assert!(matches!(outcome, Ok(Ok(()))), "{} panicked on {}", t.name, file.display());
                    replayed += 1;
                }
            }
        }
        assert!(replayed >= TARGETS.len());
    }
}
