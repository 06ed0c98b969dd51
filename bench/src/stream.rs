//! `lineflow bench stream`: orientation while the photos arrive (issue #6). Renders a synthetic scene into a project
//! folder (the D2X strip at half size by default), runs `launch/orientation-stream.toml` on it as real processes
//! over iceoryx2 with the folder delivering one frame per second, as a camera would (rendering is not part of the
//! measurement), then reads the run's recording: per frame, the time from the frame's arrival to its first pose,
//! against the time until the next frame arrives. Where `pycolmap` installs, COLMAP's incremental mapper then runs
//! on the same images, and both sets of camera centres are scored against the truth after a similarity alignment.
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use lineflow_eval::Truth;
use lineflow_formats::PoseRow;
use lineflow_messages::schema::{decode, decode_view, read_elements, read_pod, Decoded};
use lineflow_messages::{ImageHeader, MessageKind, Pose};
use lineflow_photogrammetry::intersect::similarity;
use lineflow_photogrammetry::Vec3;
use lineflow_recordings::Recording;
use lineflow_runtime::launch::{self, Resolver};
use lineflow_synthetic::Synthetic;

use crate::util::python_reference;

/// COLMAP on a folder of images with our interior orientation held fixed: SIFT, sequential matching, the
/// incremental mapper; prints `name X Y Z` per registered image of the largest model, then the seconds taken.
const COLMAP: &str = r#"
import sys, time, pycolmap
images, work, model, params = sys.argv[1:5]
db = work + "/database.db"
reader = pycolmap.ImageReaderOptions()
reader.camera_model = model
reader.camera_params = params
t = time.perf_counter()
pycolmap.extract_features(db, images, camera_mode=pycolmap.CameraMode.SINGLE, reader_options=reader, device=pycolmap.Device.cpu)
pycolmap.match_sequential(db, device=pycolmap.Device.cpu)
opts = pycolmap.IncrementalPipelineOptions()
opts.ba_refine_focal_length = False
opts.ba_refine_principal_point = False
opts.ba_refine_extra_params = False
opts.random_seed = 1
models = pycolmap.incremental_mapping(db, images, work + "/sparse", opts)
if not models:
    sys.exit("COLMAP registered no model")
rec = max(models.values(), key=lambda r: r.num_reg_images())
for image in rec.images.values():
    if image.has_pose:
        c = image.projection_center()
        print(image.name, c[0], c[1], c[2])
print("seconds", time.perf_counter() - t)
"#;

/// Options of `lineflow bench stream`.
pub struct StreamArgs<'a> {
    /// Synthetic preset, image scale and seed.
    pub preset: &'a str,
    pub scale: f64,
    pub seed: u64,
    /// Frames per second delivered.
    pub fps: f64,
    /// Launch graph (default: the shipped `orientation-stream.toml`).
    pub graph: Option<&'a Path>,
    /// Parameter overrides.
    pub set: &'a [String],
    /// Output folder (default: a temporary one).
    pub out: Option<PathBuf>,
    /// Skip the COLMAP reference.
    pub no_colmap: bool,
}

/// Per frame: when it arrived and when its first oriented pose was published (recorder clock, ns).
#[derive(Default, Clone, Copy)]
struct FrameTimes {
    arrived: Option<u64>,
    first_pose: Option<u64>,
}

pub fn bench_stream(a: StreamArgs<'_>) -> Result<ExitCode> {
    if !(a.fps > 0.0 && a.fps.is_finite()) {
        bail!("--fps must be > 0 for a streaming benchmark (got {})", a.fps);
    }
    let graph = a
        .graph
        .map(Path::to_owned)
        .unwrap_or_else(|| lineflow_runtime::run::launch_dir().join("orientation-stream.toml"));
    let tmp = tempfile::tempdir()?;
    let project = tmp.path().join("project");
    let scene = Synthetic::new(a.preset, a.scale, a.seed).map_err(|e| anyhow::anyhow!("{e}"))?;
    eprintln!("writing the {} scene at scale {} to {}", a.preset, a.scale, project.display());
    lineflow_synthetic::write_project(&scene, &project, &mut |_, _| {})?;
    let mut set = vec![
        format!("capture.folder={}", toml_string(&project)),
        format!("capture.fps={}", a.fps),
    ];
    set.extend(a.set.iter().cloned());
    let g = launch::load(&graph, &set, &Resolver::beside_current_exe())?;
    let truth = Truth::from_scene(scene);
    let frames = truth.poses.len();
    let out = a.out.unwrap_or_else(|| tmp.path().join("run"));
    let cam = truth.scene.camera();
    println!(
        "stream benchmark: {} on {} at scale {} ({}x{}, {frames} frames at {} frame/s) -> {}",
        graph.display(),
        a.preset,
        a.scale,
        cam.width,
        cam.height,
        a.fps,
        out.display()
    );
    if lineflow_runtime::run::run_graph(&g, &out, Some(frames as u64), Default::default())? != ExitCode::SUCCESS {
        bail!("the run failed; see {}", out.display());
    }

    let times = frame_times(&out.join("recording.mcap"))?;
    report_latency(&times, 1e9 / a.fps);

    let centres = |rows: &[PoseRow]| -> BTreeMap<String, Vec3> { rows.iter().map(|r| (stem(&r.image), r.pose.center)).collect() };
    let true_centres = centres(&truth.poses);
    let ours = centres(&lineflow_formats::read_poses(&out.join("poses.csv"))?);
    let gsd = truth.gsd_m();
    println!("camera centres against the truth (GSD {:.1} mm):", gsd * 1e3);
    print_centres(
        "lineflow, control points only",
        &centre_errors(&ours, &true_centres, false),
        frames,
        gsd,
    );
    print_centres(
        "lineflow, similarity onto truth",
        &centre_errors(&ours, &true_centres, true),
        frames,
        gsd,
    );
    if a.no_colmap {
        return Ok(ExitCode::SUCCESS);
    }
    match colmap_centres(&out, &project.join("images"), tmp.path()) {
        Ok((centres, seconds)) => print_centres(
            &format!("COLMAP {seconds:.0} s, similarity onto truth"),
            &centre_errors(&centres, &true_centres, true),
            frames,
            gsd,
        ),
        Err(e) => println!("(no COLMAP reference: {e:#})"),
    }
    Ok(ExitCode::SUCCESS)
}

/// A path as a TOML string for a `--set` override.
fn toml_string(p: &Path) -> String {
    toml::Value::String(p.display().to_string()).to_string()
}

/// An image's name without its extension: the recording's export, COLMAP and `poses.csv` differ only there.
fn stem(name: &str) -> String {
    Path::new(name)
        .file_stem()
        .map_or(name.into(), |s| s.to_string_lossy().into_owned())
}

/// Arrival of each frame on `images` and the first oriented pose of it on `poses`, from the recorder's clock.
fn frame_times(recording: &Path) -> Result<BTreeMap<u64, FrameTimes>> {
    let rec = Recording::open(recording)?;
    let mut times: BTreeMap<u64, FrameTimes> = BTreeMap::new();
    let mut scratch = Decoded::default();
    rec.for_each_message(|m| {
        match (m.topic.as_str(), m.kind) {
            ("images", Some(MessageKind::Image)) => {
                // The header alone: the pixels are not copied.
                let (header, _) = decode_view(MessageKind::Image, &m.data, &mut scratch)?;
                let h: ImageHeader = read_pod(header);
                times.entry(h.stamp.frame).or_default().arrived.get_or_insert(m.log_time);
            }
            ("poses", Some(MessageKind::Poses)) => {
                let d = decode(MessageKind::Poses, &m.data)?;
                for p in read_elements::<Pose>(&d.payload) {
                    if p.flags & Pose::ORIENTED != 0 {
                        times.entry(p.frame).or_default().first_pose.get_or_insert(m.log_time);
                    }
                }
            }
            _ => {}
        }
        Ok(())
    })?;
    Ok(times)
}

/// Prints the latency of each frame's first pose against its deadline, the next frame's arrival. The first frame
/// has no pose of its own until a second frame gives it a partner, so its latency counts from that arrival.
fn report_latency(times: &BTreeMap<u64, FrameTimes>, period_ns: f64) {
    let l = latencies(times, period_ns);
    if l.posed.is_empty() {
        println!("no frame was oriented");
        return;
    }
    let mut sorted: Vec<f64> = l.posed.iter().map(|p| p.1).collect();
    sorted.sort_by(f64::total_cmp);
    let q = |f: f64| sorted[((sorted.len() - 1) as f64 * f).round() as usize] / 1e6;
    println!(
        "first pose after arrival ({} of {} frames oriented): median {:.0} ms, p90 {:.0} ms, max {:.0} ms; frame period {:.0} ms, max / period {:.2}",
        l.posed.len(),
        l.frames,
        q(0.5),
        q(0.9),
        q(1.0),
        period_ns / 1e6,
        q(1.0) * 1e6 / period_ns
    );
    if !l.late.is_empty() {
        let list: Vec<String> = l.late.iter().map(|(f, t)| format!("{f} ({:.0} ms)", t / 1e6)).collect();
        println!(
            "{} frames had no pose before the next frame arrived: {}",
            l.late.len(),
            list.join(", ")
        );
    }
    if !l.unoriented.is_empty() {
        println!("never oriented: frames {:?}", l.unoriented);
    }
    if l.late.is_empty() && l.unoriented.is_empty() {
        println!("every frame had its first pose before the next frame arrived: target met");
    } else {
        println!("target NOT met");
    }
}

/// Each frame's first-pose latency against its deadline.
#[derive(Debug, Default, PartialEq)]
struct Latencies {
    /// Frames that arrived.
    frames: usize,
    /// (frame, latency ns) of every oriented frame.
    posed: Vec<(u64, f64)>,
    /// (frame, latency ns) of the frames whose first pose came after the next frame's arrival.
    late: Vec<(u64, f64)>,
    /// Frames that arrived and were never oriented.
    unoriented: Vec<u64>,
}

/// The latency of each frame's first pose, from its arrival to the next frame's (or one period when it is the last).
/// The first frame has no pose of its own until a second frame gives it a partner, so it is timed from that arrival.
fn latencies(times: &BTreeMap<u64, FrameTimes>, period_ns: f64) -> Latencies {
    let arrivals: Vec<(u64, u64)> = times.iter().filter_map(|(f, t)| Some((*f, t.arrived?))).collect();
    let mut out = Latencies {
        frames: arrivals.len(),
        ..Latencies::default()
    };
    for (i, &(frame, _)) in arrivals.iter().enumerate() {
        let Some(posed) = times[&frame].first_pose else {
            out.unoriented.push(frame);
            continue;
        };
        let k = if i == 0 && arrivals.len() > 1 { 1 } else { i };
        let from = arrivals[k].1;
        let deadline = arrivals.get(k + 1).map_or(from as f64 + period_ns, |a| a.1 as f64);
        let latency = posed.saturating_sub(from) as f64;
        out.posed.push((frame, latency));
        if posed as f64 > deadline {
            out.late.push((frame, latency));
        }
    }
    out
}

/// Camera-centre errors (name, metres) of `estimated` against `truth`, optionally after the least-squares
/// similarity of the estimate onto the truth (as any reconstruction without control must be scored).
fn centre_errors(estimated: &BTreeMap<String, Vec3>, truth: &BTreeMap<String, Vec3>, align: bool) -> Vec<f64> {
    let pairs: Vec<(Vec3, Vec3)> = estimated.iter().filter_map(|(name, c)| Some((*c, *truth.get(name)?))).collect();
    let (from, to): (Vec<Vec3>, Vec<Vec3>) = pairs.into_iter().unzip();
    let moved: Vec<Vec3> = match align.then(|| similarity(&from, &to)).flatten() {
        Some(s) => from.iter().map(|c| s.apply(c)).collect(),
        None if align => return Vec::new(),
        None => from,
    };
    moved.iter().zip(&to).map(|(a, b)| (a - b).norm()).collect()
}

fn print_centres(label: &str, errors: &[f64], frames: usize, gsd: f64) {
    if errors.is_empty() {
        println!("  {label:<40} no centres to score");
        return;
    }
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let max = errors.iter().copied().fold(0.0, f64::max);
    println!(
        "  {label:<40} {:>2} of {frames} images  RMS {:6.1} mm  max {:6.1} mm  ({:.2} / {:.2} GSD)",
        errors.len(),
        rms * 1e3,
        max * 1e3,
        rms / gsd,
        max / gsd
    );
}

/// Runs COLMAP on the project's images with the camera our orientation exported.
fn colmap_centres(out: &Path, images: &Path, work: &Path) -> Result<(BTreeMap<String, Vec3>, f64)> {
    let cameras = out.join("colmap/cameras.txt");
    let text = std::fs::read_to_string(&cameras).with_context(|| format!("cannot read {}", cameras.display()))?;
    let camera = text
        .lines()
        .find(|l| !l.starts_with('#') && !l.trim().is_empty())
        .context("cameras.txt holds no camera")?;
    let f: Vec<&str> = camera.split_whitespace().collect();
    if f.len() < 5 {
        bail!("{}: cannot read the camera line '{camera}'", cameras.display());
    }
    let colmap = work.join("colmap");
    std::fs::create_dir_all(colmap.join("sparse"))?;
    let args = [images.to_owned(), colmap].map(|p| p.display().to_string());
    let stdout = python_reference(
        COLMAP,
        &[args[0].clone(), args[1].clone(), f[1].to_owned(), f[4..].join(",")],
        "pycolmap",
    )?;
    let mut centres = BTreeMap::new();
    let mut seconds = f64::NAN;
    for line in stdout.lines() {
        let v: Vec<&str> = line.split_whitespace().collect();
        match v[..] {
            ["seconds", s] => seconds = s.parse().unwrap_or(f64::NAN),
            [name, x, y, z] => {
                let p = |s: &str| s.parse::<f64>().context("COLMAP printed a bad number");
                centres.insert(stem(name), Vec3::new(p(x)?, p(y)?, p(z)?));
            }
            _ => {}
        }
    }
    Ok((centres, seconds))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_is_late_when_its_first_pose_comes_after_the_next_frame_and_the_first_counts_from_the_second() {
        let ms = 1_000_000u64;
        let times: BTreeMap<u64, FrameTimes> = [
            // Posed with the second frame: 500 ms after the second frame's arrival, before the third's.
            (0, Some(0), Some(1500 * ms)),
            (1, Some(1000 * ms), Some(2100 * ms)),
            (2, Some(2000 * ms), None),
            // The last frame's deadline is one period after it.
            (3, Some(3000 * ms), Some(3900 * ms)),
        ]
        .into_iter()
        .map(|(f, arrived, first_pose)| (f, FrameTimes { arrived, first_pose }))
        .collect();
        let l = latencies(&times, 1e9);
        assert_eq!(l.frames, 4);
        assert_eq!(l.posed, vec![(0, 500e6), (1, 1100e6), (3, 900e6)]);
        assert_eq!(l.late, vec![(1, 1100e6)]);
        assert_eq!(l.unoriented, vec![2]);
    }
}
