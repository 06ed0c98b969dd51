//! `lineflow bench` and `lineflow experiment`: every benchmark and seed experiment, each printing its figures
//! beside a reference measured in the same run. The `lineflow` command parses [`BenchCmd`] and calls [`bench`].
mod bridge;
mod buildings;
mod bundle;
mod chaos;
mod edges;
mod features;
mod final_lines;
pub mod fuzz;
mod layers;
mod linemap;
mod linematch;
mod lines2d;
pub mod model;
mod modelfit;
mod multiview;
mod processes;
pub mod reader;
pub mod record;
mod render;
pub mod seed001;
pub mod seed004;
mod sides;
mod soak;
mod stream;
mod targets;
mod transport;
mod util;
mod view;

use std::process::ExitCode;

use anyhow::Result;
use clap::Subcommand;

#[derive(Subcommand)]
pub enum BenchCmd {
    /// iceoryx2 vs Unix-socket latency and throughput for 64 B to 48 MB payloads.
    Transport {
        /// Messages per case at 30 Hz.
        #[arg(long, default_value_t = 60)]
        paced: u64,
        /// Scale the flat-out message counts (1.0 = 20000 x 64 B ... 60 x 48 MB).
        #[arg(long, default_value_t = 1.0)]
        flat_scale: f64,
        /// Between hosts instead: Zenoh against a TCP copy at 48 MB, and 12 MP frames at 5 frames/s across a
        /// loopback bridge (docs/hosts.md).
        #[arg(long)]
        zenoh: bool,
        /// With --zenoh: 48 MB messages per copy.
        #[arg(long, default_value_t = 20)]
        messages: usize,
        /// With --zenoh: 12 MP frames streamed.
        #[arg(long, default_value_t = 30)]
        frames: usize,
    },
    /// Synthetic renderer: seconds per full-size frame against the 12 MP / 1 s target.
    Render {
        /// Preset.
        #[arg(long, default_value = "d2x-strip")]
        preset: String,
        /// Frames to time.
        #[arg(long, default_value_t = 5)]
        frames: usize,
        /// Image scale (1 = the preset's full size).
        #[arg(long, default_value_t = 1.0)]
        scale: f64,
    },
    /// The survey-target detector on rendered frames of a preset at several scales, against the targets' true
    /// projections (found, false, centre RMS beside a thresholded centroid, time beside a PNG decode), and the
    /// naming from the true poses moved into another frame.
    Targets {
        /// Preset.
        #[arg(long, default_value = "a55-two-strips")]
        preset: String,
        /// Image scales, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "1,0.5,0.3")]
        scales: Vec<f64>,
        /// Frames per scale, spread over the stations (0: every station).
        #[arg(long, default_value_t = 0)]
        frames: usize,
        /// Seed of the scene.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// Edge detectors on a full-size synthetic frame against OpenCV's Canny (needs opencv-python-headless).
    Edges {
        /// Preset.
        #[arg(long, default_value = "d2x-strip")]
        preset: String,
        /// Repetitions per measurement.
        #[arg(long, default_value_t = 5)]
        reps: usize,
        /// Canny high threshold (low = 0.4 × high), as the edges node's default.
        #[arg(long, default_value_t = lineflow_edges::DEFAULT_HIGH)]
        high: f64,
    },
    /// The default 2-D stage (Canny + line tracing) on a full-size synthetic frame: time per step, recall and
    /// precision against the ground truth, beside our LSD and OpenCV's LSD (needs opencv-python-headless).
    Lines2d {
        /// Preset.
        #[arg(long, default_value = "d2x-strip")]
        preset: String,
        /// Repetitions per measurement.
        #[arg(long, default_value_t = 3)]
        reps: usize,
        /// Canny high threshold (low = 0.4 × high), as the edges node's default.
        #[arg(long, default_value_t = lineflow_edges::DEFAULT_HIGH)]
        high: f64,
    },
    /// SURF on a full-size synthetic frame against OpenCV's SIFT and ORB (needs opencv-python-headless).
    Features {
        /// Preset.
        #[arg(long, default_value = "d2x-strip")]
        preset: String,
        /// Repetitions per measurement.
        #[arg(long, default_value_t = 3)]
        reps: usize,
        /// Hessian threshold (the stage's default).
        #[arg(long, default_value_t = 100.0)]
        threshold: f32,
    },
    /// Full bundle adjustment of a thesis-size block (33 images, ~2,500 points, ~11,000 observations).
    Bundle {
        /// Images.
        #[arg(long, default_value_t = 33)]
        cameras: usize,
        /// Tie points.
        #[arg(long, default_value_t = 2500)]
        points: usize,
    },
    /// The linematch stage: one master with all its lines against six slaves, every window mode.
    Linematch {
        /// Preset.
        #[arg(long, default_value = "d2x-strip")]
        preset: String,
        /// Image scale (1 = the preset's full size).
        #[arg(long, default_value_t = 1.0)]
        scale: f64,
        /// Repetitions per measurement.
        #[arg(long, default_value_t = 1)]
        reps: usize,
        /// Write every matched point of the master (segment, X, Y, Z, depth, SNCC, window, from the lines) to this
        /// CSV, with the true poses, and skip the timing: for seeing where a stage places a building's edges.
        #[arg(long)]
        points: Option<std::path::PathBuf>,
    },
    /// The model stage on the preset's true edges with noise: vertex RMSE, edge precision and recall, time.
    Model {
        /// Preset.
        #[arg(long, default_value = "d2x-strip")]
        preset: String,
        /// Endpoint noise levels, σ per coordinate in ground sample distances. Repeatable.
        #[arg(long = "sigma-gsd", default_values_t = vec![0.5, 1.0, 2.0])]
        sigma_gsd: Vec<f64>,
        /// Repetitions per timing.
        #[arg(long, default_value_t = 3)]
        reps: usize,
        /// Override a model parameter, PARAM=VALUE (VALUE as TOML; `sigma_m` is the noise level's). Repeatable.
        #[arg(long = "set", value_name = "PARAM=VALUE")]
        set: Vec<String>,
        /// Also write, per noise level, the noisy lines, the true lines and the model into this folder.
        #[arg(long)]
        out: Option<std::path::PathBuf>,
    },
    /// The modelfit stage: a façade model built from the preset's true edges with noise and fitted to the edge
    /// pixels of every frame; vertex RMSE before and after, time against the 1 s target and a dense reference.
    Modelfit {
        /// Preset.
        #[arg(long, default_value = "d2x-strip")]
        preset: String,
        /// Endpoint noise of the lines the model is built from, σ in ground sample distances.
        #[arg(long = "sigma-gsd", default_value_t = 1.0)]
        sigma_gsd: f64,
        /// Use only the first N frames [default: all].
        #[arg(long)]
        frames: Option<usize>,
        /// Edge-pixel weighting: equal, magnitude, angle or combined.
        #[arg(long, default_value = "combined")]
        weighting: String,
        /// Repetitions per timing.
        #[arg(long, default_value_t = 3)]
        reps: usize,
        /// Skip the one-system reference (slow).
        #[arg(long)]
        no_reference: bool,
        /// Edge pixels at their pixel centres, without the sub-pixel refinement.
        #[arg(long)]
        no_subpixel: bool,
        /// Render the façade with untextured materials, so that only geometry and shading make edges.
        #[arg(long)]
        flat_textures: bool,
    },
    /// Orientation while the photos arrive: renders a synthetic folder, runs `launch/orientation-stream.toml` on it
    /// at 1 frame/s and reports each frame's first pose against the next frame's arrival, the camera centres against
    /// the truth, and COLMAP's on the same images where `pycolmap` installs.
    Stream {
        /// Preset.
        #[arg(long, default_value = "d2x-strip")]
        preset: String,
        /// Image scale (0.5 = about 3 MP for the D2X).
        #[arg(long, default_value_t = 0.5)]
        scale: f64,
        /// Seed of the scene.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Frames per second delivered.
        #[arg(long, default_value_t = 1.0)]
        fps: f64,
        /// Launch graph [default: launch/orientation-stream.toml].
        #[arg(long)]
        graph: Option<std::path::PathBuf>,
        /// Parameter override NODE.KEY=VALUE (repeatable), e.g. `--set capture.fps=2`.
        #[arg(long)]
        set: Vec<String>,
        /// Keep the run's results in this folder [default: a temporary one].
        #[arg(long)]
        out: Option<std::path::PathBuf>,
        /// Skip the COLMAP reference.
        #[arg(long)]
        no_colmap: bool,
    },
    /// The 3-D lines on held-out buildings (`PRESET@N`, N from 1000 up) beside the preset's own, tuned building:
    /// the shipped demo graph as real processes, one row per building, and the worst.
    Buildings {
        /// Preset whose cameras film every building.
        #[arg(long, default_value = "a55-two-strips")]
        preset: String,
        /// Image scale.
        #[arg(long, default_value_t = 0.3)]
        scale: f64,
        /// Seed of the scenes.
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Held-out building variants, comma-separated.
        #[arg(long, value_delimiter = ',', default_value = "1001,1002,1003,1004,1005")]
        variants: Vec<u64>,
        /// Launch graph [default: launch/demo.toml].
        #[arg(long)]
        graph: Option<std::path::PathBuf>,
        /// Parameter override NODE.KEY=VALUE (repeatable), applied to every run.
        #[arg(long)]
        set: Vec<String>,
        /// Keep the runs' results in this folder [default: a temporary one].
        #[arg(long)]
        out: Option<std::path::PathBuf>,
    },
    /// The linemap algorithm again, in this process, on a finished run's lines2d.csv and poses.csv of a synthetic
    /// building, scored against its truth (for trying parameters on tuning buildings, PRESET@N with N < 1000).
    Linemap(linemap::LinemapBench),
    /// linefit's depth layers again, in this process, on a finished run's final lines of a synthetic building,
    /// scored before and after (for trying their settings on tuning buildings, PRESET@N with N < 1000).
    Layers(layers::LayersBench),
    /// linefit's multi-view re-estimate again, in this process, on a finished run's final lines of a synthetic
    /// building, with the defaults and with the given settings, both scored (for trying its settings on tuning
    /// buildings, PRESET@N with N < 1000).
    Multiview(multiview::MultiviewBench),
    /// The half-plane test (one surface on both sides of a line makes it texture) on a finished run's final lines
    /// of a synthetic building, its images rendered again, scored before and after (for trying its settings on
    /// tuning buildings, PRESET@N with N < 1000).
    Sides(sides::SidesBench),
    /// Every parser a user's file reaches, fed mutated copies of valid files: executions, panics, slowest call.
    Fuzz {
        /// Mutated inputs per parser.
        #[arg(long, default_value_t = 100_000)]
        executions: u64,
        /// Seed of the mutations (the same seed finds the same inputs).
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// The recorder node: MB/s of raw 12 MP RGB frames written with nothing dropped, against the disk.
    Record {
        /// Frames.
        #[arg(long, default_value_t = 30)]
        frames: usize,
        /// The frames: a noisy pattern (`--width` × `--height`) or the synthetic camera's façade at full size.
        #[arg(long, value_enum, default_value = "noise")]
        source: record::FrameSource,
        /// Frame width (noise).
        #[arg(long, default_value_t = 4288)]
        width: u32,
        /// Frame height (noise).
        #[arg(long, default_value_t = 2848)]
        height: u32,
        /// The recorder's image previews for viewers (longest side; 0 = off), as in `[record] preview_max_px`.
        #[arg(long, default_value_t = 1280)]
        preview_max_px: u32,
    },
    /// Faults: every node of a graph SIGKILLed (or SIGSTOPped for a while, `--stop`) at three points of a run, one
    /// run each; whether each run completes or names the node, and whether its recording reads to the last chunk.
    Chaos {
        /// The graph.
        #[arg(long, default_value = "launch/demo.toml")]
        graph: std::path::PathBuf,
        /// Parameter overrides (NODE.PARAM=VALUE), as for `lineflow run`.
        #[arg(long = "set", default_values_t = ["capture.scale=0.06".to_owned()])]
        set: Vec<String>,
        /// SIGSTOP the node for this many seconds, then SIGCONT, instead of SIGKILL: a node that hangs and comes
        /// back; the run must then complete with nothing lost.
        #[arg(long, value_name = "SECONDS")]
        stop: Option<f64>,
    },
    /// Hours of streaming: the synthetic camera's strip repeated at a steady rate through a whole graph, every
    /// node's memory, shared memory and open files sampled (soak.csv, soak.svg); memory growth after the warm-up,
    /// drops, and a frame's latency at the end against the start. Exit status 1 on a drop.
    Soak(soak::Soak),
    /// The live view's cost and latency: the 2-D stages on full-size frames without and with the viewer and a
    /// WebSocket client; the wall-time ratio and, per channel, capture-to-client latency.
    View {
        /// Scene preset (d2x-strip: 4288 x 2848, 12 MP).
        #[arg(long, default_value = "d2x-strip")]
        preset: String,
        /// Image size relative to the preset.
        #[arg(long, default_value_t = 1.0)]
        scale: f64,
        /// Frames per run.
        #[arg(long, default_value_t = 8)]
        frames: u64,
        /// Runs without and with the viewer, alternating; their medians are compared.
        #[arg(long, default_value_t = 3)]
        pairs: usize,
    },
    /// Recordings larger than memory: `info`, `info --verify` and `export` of one topic as child processes, their
    /// wall time and peak RSS, against a plain read of the file.
    Reader {
        /// Size of the recording written for the test, GB.
        #[arg(long, default_value_t = 10.0)]
        gb: f64,
        /// Where to write it (a temporary folder, removed after, by default).
        #[arg(long)]
        dir: Option<std::path::PathBuf>,
        /// One JSON object instead of the table.
        #[arg(long)]
        json: bool,
    },
    /// (internal) the subscribing side of the iceoryx2 benchmark.
    #[command(hide = true)]
    IoxSub {
        prefix: String,
        root: String,
        size: usize,
        count: u64,
    },
    /// (internal) the reading side of the socket benchmark.
    #[command(hide = true)]
    UdsSub { path: String, size: usize, count: u64 },
}

/// `lineflow experiment NAME`: a seed document's experiment, its tables on stdout.
///
/// # Errors
/// An unknown experiment.
pub fn experiment(name: &str, trials: Option<u64>, seed: u64) -> Result<ExitCode> {
    match name {
        "seed001" => print!("{}", seed001::experiment(trials.unwrap_or(500).max(1), seed)),
        "seed004" => print!("{}", seed004::experiment(trials.unwrap_or(20).max(1) as usize)),
        other => anyhow::bail!("unknown experiment '{other}' (available: seed001, seed004)"),
    }
    Ok(ExitCode::SUCCESS)
}

pub fn bench(cmd: BenchCmd) -> Result<ExitCode> {
    match cmd {
        BenchCmd::IoxSub { prefix, root, size, count } => transport::iox_sub(&prefix, &root, size, count).map(|_| ExitCode::SUCCESS),
        BenchCmd::UdsSub { path, size, count } => transport::uds_sub(&path, size, count).map(|_| ExitCode::SUCCESS),
        BenchCmd::Transport {
            zenoh: true,
            messages,
            frames,
            ..
        } => bridge::bridge_bench(messages, frames),
        BenchCmd::Transport { paced, flat_scale, .. } => transport::transport_bench(paced, flat_scale),
        BenchCmd::Render { preset, frames, scale } => render::bench_render(&preset, frames, scale),
        BenchCmd::Edges { preset, reps, high } => edges::bench_edges(&preset, reps, high),
        BenchCmd::Targets {
            preset,
            scales,
            frames,
            seed,
        } => targets::bench_targets(targets::TargetsArgs {
            preset: &preset,
            scales: &scales,
            frames,
            seed,
        }),
        BenchCmd::Lines2d { preset, reps, high } => lines2d::bench_lines2d(&preset, reps, high),
        BenchCmd::Features { preset, reps, threshold } => features::bench_features(&preset, reps, threshold),
        BenchCmd::Model {
            preset,
            sigma_gsd,
            reps,
            set,
            out,
        } => model::bench_model(&preset, &sigma_gsd, reps, &set, out.as_deref()),
        BenchCmd::Modelfit {
            preset,
            sigma_gsd,
            frames,
            weighting,
            reps,
            no_reference,
            no_subpixel,
            flat_textures,
        } => modelfit::bench_modelfit(modelfit::Args {
            preset: &preset,
            sigma_gsd,
            frames,
            weighting: lineflow_modelfit::Weighting::parse(&weighting).map_err(anyhow::Error::msg)?,
            reps,
            reference: !no_reference,
            subpixel: !no_subpixel,
            flat_textures,
        }),
        BenchCmd::Linematch {
            preset,
            scale,
            reps,
            points,
        } => linematch::bench_linematch(&preset, scale, reps, points.as_deref()),
        BenchCmd::Linemap(args) => linemap::bench_linemap(&args),
        BenchCmd::Layers(args) => layers::bench_layers(&args),
        BenchCmd::Multiview(args) => multiview::bench_multiview(&args),
        BenchCmd::Sides(args) => sides::bench_sides(&args),
        BenchCmd::Bundle { cameras, points } => bundle::bench_bundle(cameras, points),
        BenchCmd::Fuzz { executions, seed } => fuzz::bench_fuzz(executions, seed),
        BenchCmd::Buildings {
            preset,
            scale,
            seed,
            variants,
            graph,
            set,
            out,
        } => buildings::bench_buildings(buildings::BuildingsArgs {
            preset: &preset,
            scale,
            seed,
            variants: &variants,
            graph: graph.as_deref(),
            set: &set,
            out,
        }),
        BenchCmd::Stream {
            preset,
            scale,
            seed,
            fps,
            graph,
            set,
            out,
            no_colmap,
        } => stream::bench_stream(stream::StreamArgs {
            preset: &preset,
            scale,
            seed,
            fps,
            graph: graph.as_deref(),
            set: &set,
            out,
            no_colmap,
        }),
        BenchCmd::Record {
            frames,
            source,
            width,
            height,
            preview_max_px,
        } => record::bench_record(frames, source, width, height, preview_max_px),
        BenchCmd::Reader { gb, dir, json } => reader::bench_reader(gb, dir, json),
        BenchCmd::View {
            preset,
            scale,
            frames,
            pairs,
        } => view::bench_view(&preset, scale, frames, pairs),
        BenchCmd::Soak(s) => soak::bench_soak(&s),
        BenchCmd::Chaos { graph, set, stop } => chaos::bench_chaos(&graph, &set, stop.map(std::time::Duration::from_secs_f64)),
    }
}
