//! Shared harness of the end-to-end tests: a sandbox per test (its own state folder, so run ids, iceoryx2
//! prefixes and output folders never collide and tests run in parallel), the Python environment of the tests that
//! run Python, and helpers to find processes.
mod python;

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

pub use python::{python, python_path};

/// The folder of the built binaries (`target/<profile>`).
pub fn bin_dir() -> PathBuf {
    // target/<profile>/deps/pipeline-<hash> -> target/<profile>
    let exe = std::env::current_exe().unwrap();
    let dir = exe.parent().unwrap().parent().unwrap().to_path_buf();
    assert!(
        dir.join("lineflow").is_file(),
        "build the binaries first: `cargo build --workspace` ({} has no lineflow)",
        dir.display()
    );
    dir
}

/// A test's private state folder.
pub struct Sandbox {
    dir: tempfile::TempDir,
}

impl Default for Sandbox {
    fn default() -> Self {
        Self::new()
    }
}

impl Sandbox {
    /// A new sandbox.
    pub fn new() -> Self {
        Self {
            dir: tempfile::tempdir().unwrap(),
        }
    }
    /// Its folder.
    pub fn path(&self) -> &Path {
        self.dir.path()
    }
    /// `lineflow ARGS` with this sandbox's state folder; nodes written in Python (`#!/usr/bin/env python3`) find
    /// the tests' Python environment first on `PATH`.
    pub fn lineflow(&self, args: &[&str]) -> Command {
        let mut c = Command::new(bin_dir().join("lineflow"));
        c.args(args)
            .env("PATH", python_path())
            .env("LINEFLOW_STATE_DIR", self.path().join("state"))
            .env("LINEFLOW_LOG", "info")
            .stdin(Stdio::null());
        c
    }
    /// `lineflow run GRAPH --out OUT`, to be spawned (a run watched, stopped or killed while it goes).
    pub fn run_command(&self, graph: &Path, out: &Path) -> Command {
        self.lineflow(&["run", graph.to_str().unwrap(), "--out", out.to_str().unwrap()])
    }
    /// Runs `lineflow ARGS` to the end, echoing its stderr.
    pub fn run(&self, args: &[&str]) -> Output {
        let out = self.lineflow(args).output().unwrap();
        eprintln!("--- lineflow {}\n{}", args.join(" "), String::from_utf8_lossy(&out.stderr));
        out
    }
    /// `lineflow synth --preset PRESET --scale SCALE` into `NAME` in the sandbox: a scene with its ground truth.
    pub fn synth(&self, name: &str, preset: &str, scale: &str) -> PathBuf {
        let scene = self.path().join(name);
        let r = self.run(&["synth", "--preset", preset, "--scale", scale, "--out", scene.to_str().unwrap()]);
        assert!(r.status.success(), "synth {preset} at {scale} failed");
        scene
    }
    /// A project folder with `n` images of `w`x`h` pixels: PNG (8-bit RGB and 16-bit grey), JPEG and TIFF, names in
    /// an order that only natural sorting gets right.
    pub fn project(&self, n: usize, w: u32, h: u32) -> PathBuf {
        let root = self.path().join("project");
        std::fs::create_dir_all(root.join("images")).unwrap();
        std::fs::write(
            root.join("camera.toml"),
            format!("width = {w}\nheight = {h}\npixel_size_mm = 0.0055\nfocal_mm = 17.6\n"),
        )
        .unwrap();
        for k in 0..n {
            let img = image::RgbImage::from_fn(w, h, |x, y| {
                image::Rgb([(x * 7 + k as u32 * 13) as u8, (y * 5) as u8, ((x ^ y) + k as u32) as u8])
            });
            let name = format!("IMG_{}", k + 1);
            match k % 4 {
                0 => img.save(root.join("images").join(format!("{name}.png"))).unwrap(),
                1 => image::DynamicImage::ImageRgb8(img)
                    .to_luma16()
                    .save(root.join("images").join(format!("{name}.PNG")))
                    .unwrap(),
                2 => img.save(root.join("images").join(format!("{name}.jpg"))).unwrap(),
                _ => img.save(root.join("images").join(format!("{name}.tif"))).unwrap(),
            }
        }
        root
    }
    /// Writes a launch file.
    pub fn graph(&self, name: &str, text: &str) -> PathBuf {
        let p = self.path().join(name);
        std::fs::write(&p, text).unwrap();
        p
    }
}

/// Children of `pid` whose command name starts with `comm_prefix`.
pub fn children_of(pid: u32, comm_prefix: &str) -> Vec<u32> {
    std::fs::read_dir("/proc")
        .unwrap()
        .flatten()
        .filter_map(|e| e.file_name().to_str()?.parse::<u32>().ok())
        .filter(|p| {
            let stat = std::fs::read_to_string(format!("/proc/{p}/stat")).unwrap_or_default();
            let (comm, rest) = match (stat.find('('), stat.rfind(')')) {
                (Some(a), Some(b)) => (&stat[a + 1..b], &stat[b + 2..]),
                _ => return false,
            };
            let ppid: u32 = rest.split(' ').nth(1).and_then(|s| s.parse().ok()).unwrap_or(0);
            ppid == pid && comm.starts_with(comm_prefix)
        })
        .collect()
}

/// A file of the repository.
/// A launch file `name` in the sandbox: the images of `folder` into a node run from `script` (an executable, not a
/// stage: e.g. the Python Sobel node) on the `edges` port, and `stats` on both.
pub fn executable_edges_graph(sb: &Sandbox, name: &str, folder: &Path, script: &Path) -> PathBuf {
    sb.graph(
        name,
        &format!(
            r#"
[[node]]
name = "capture"
stage = "capture"
impl = "folder"
params = {{ folder = "{}" }}

[[node]]
name = "edges"
executable = "{}"
params = {{ threshold = 100.0 }}

[[node]]
name = "stats"
stage = "stats"

[[edge]]
topic = "images"
type = "Image"
from = "capture"
to = ["edges", "stats"]

[[edge]]
topic = "edges"
type = "EdgeMap"
from = "edges"
to = ["stats"]
"#,
            folder.display(),
            script.display()
        ),
    )
}

pub fn repo_file(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..").join(rel)
}

/// The run id a finished run wrote at the head of `OUT/summary.txt`.
pub fn run_id(out: &Path) -> String {
    let s = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    s.split_whitespace().nth(1).unwrap().to_owned()
}

/// The files of run `id` in `/dev/shm`.
pub fn shm_files(id: &str) -> Vec<std::fs::DirEntry> {
    std::fs::read_dir("/dev/shm")
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().contains(&format!("lf{id}_")))
        .collect()
}

/// Asserts that the run whose output folder is `out` left no shared memory and no run folder behind.
pub fn assert_nothing_left(sandbox: &Sandbox, out: &Path) {
    assert_nothing_left_in(&sandbox.path().join("state"), out);
}

/// [`assert_nothing_left`] for a run whose supervisor had the state folder `state` (`LINEFLOW_STATE_DIR`).
pub fn assert_nothing_left_in(state: &Path, out: &Path) {
    let id = run_id(out);
    let left = shm_files(&id);
    assert!(left.is_empty(), "run {id} left {left:?} in /dev/shm");
    let runs = state.join("runs");
    assert!(
        !runs.exists() || std::fs::read_dir(&runs).unwrap().next().is_none(),
        "run folder left in {}",
        runs.display()
    );
}
