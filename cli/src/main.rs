//! `lineflow`: run launch graphs, process project folders, inspect running graphs, benchmark the transport.
mod attach;
mod doctor;
mod logs;
mod model_cmd;
mod ps;
mod record_cmd;
mod recordings;
mod run;
mod synth;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{CommandFactory, Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "lineflow",
    version,
    about = "Façade 3-D lines while the photos arrive: a graph of stages over iceoryx2 shared memory"
)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
}

/// What the terminal shows of a run.
#[derive(clap::Args, Clone, Copy)]
struct VerbosityArgs {
    /// No progress line and no node lines on the terminal (they are kept in OUT/logs/); the summary and errors
    /// still print.
    #[arg(short, long)]
    quiet: bool,
    /// The nodes log at debug level (LINEFLOW_LOG, when set, wins).
    #[arg(short, long, conflicts_with = "quiet")]
    verbose: bool,
    /// Print the run's summary on stdout as one JSON object (also kept in OUT/summary.json) instead of the table.
    #[arg(long)]
    json: bool,
}

/// The live viewer of a run (`run`, `process`).
#[derive(clap::Args, Clone, Copy)]
struct ViewArgs {
    /// Serve the run live to Foxglove: images, 2-D lines, cameras, 3-D lines and the model over the Foxglove
    /// WebSocket protocol on ws://127.0.0.1:8765 (docs/viewer.md; `[view]` in a launch file does the same).
    #[arg(long)]
    view: bool,
    /// Port of the live view (0: any free port, printed); implies --view.
    #[arg(long, value_name = "PORT")]
    view_port: Option<u16>,
}

impl ViewArgs {
    /// The `--set`s that add the viewer, after the user's own.
    fn with_sets(self, set: &[String]) -> Vec<String> {
        let mut all = set.to_vec();
        if self.view || self.view_port.is_some() {
            all.push("view.enabled=true".into());
        }
        if let Some(port) = self.view_port {
            all.push(format!("view.port={port}"));
        }
        all
    }
}

impl From<VerbosityArgs> for lineflow_runtime::run::Verbosity {
    fn from(a: VerbosityArgs) -> Self {
        Self {
            quiet: a.quiet,
            verbose: a.verbose,
            json: a.json,
        }
    }
}

#[derive(Subcommand)]
enum Cmd {
    /// Run a launch graph until every node has finished.
    Run {
        /// Launch file (TOML).
        graph: PathBuf,
        /// Override a node parameter: NODE.PARAM=VALUE (VALUE parses as TOML, else as a string). Repeatable.
        #[arg(long = "set", value_name = "NODE.PARAM=VALUE")]
        set: Vec<String>,
        /// Output folder of the run.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        /// Inject a fault: SIGKILL NODE once it has received FRAME, or SIGSTOP it for S s (docs/launch.md). Repeatable.
        #[arg(long, value_name = "NODE@FRAME[:stop=S]")]
        chaos: Vec<lineflow_runtime::chaos::Fault>,
        /// Run this host's part of a graph on several machines (`[hosts]`, docs/hosts.md); nodes that name no host
        /// are on `main`.
        #[arg(long, value_name = "NAME", default_value = lineflow_runtime::hosts::DEFAULT_HOST)]
        host: String,
        #[command(flatten)]
        view: ViewArgs,
        #[command(flatten)]
        verbosity: VerbosityArgs,
    },
    /// Process a project folder (images/, camera.toml, ...) and write results into FOLDER/out/.
    Process {
        /// Project folder (conventions: docs/formats.md).
        folder: PathBuf,
        /// Output folder [default: FOLDER/out].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Launch graph [default: launch/folder.toml].
        #[arg(long)]
        graph: Option<PathBuf>,
        /// Override a node parameter: NODE.PARAM=VALUE. Repeatable.
        #[arg(long = "set", value_name = "NODE.PARAM=VALUE")]
        set: Vec<String>,
        #[command(flatten)]
        view: ViewArgs,
        #[command(flatten)]
        verbosity: VerbosityArgs,
    },
    /// Show the nodes' logs a run keeps in OUT/logs/ (while it runs, or after).
    Logs {
        /// The run's output folder (`--out` of `lineflow run`, FOLDER/out of `lineflow process`).
        out: PathBuf,
        /// Only this node's log.
        node: Option<String>,
        /// Keep printing what the nodes append, until interrupted.
        #[arg(short, long)]
        follow: bool,
    },
    /// List the topics of a running graph.
    Topics {
        /// Run id [default: the newest running run].
        #[arg(long)]
        run: Option<String>,
    },
    /// Print the headers and payload sizes of a topic's messages as they arrive.
    Echo {
        /// Topic name.
        topic: String,
        /// Run id [default: the newest running run].
        #[arg(long)]
        run: Option<String>,
        /// Stop after this many messages.
        #[arg(long, short = 'n')]
        count: Option<u64>,
        /// One JSON object a line.
        #[arg(long, conflicts_with = "raw")]
        json: bool,
        /// The header's bytes and the payload's first 256 bytes in hex, instead of the fields.
        #[arg(long)]
        raw: bool,
        /// Elements of each payload sequence shown (lines, keypoints, ...); with --json every one unless given.
        #[arg(long)]
        elements: Option<usize>,
    },
    /// Print a topic's message rate, period (min, max, std) and bandwidth once a second.
    Hz {
        /// Topic name.
        topic: String,
        /// Run id [default: the newest running run].
        #[arg(long)]
        run: Option<String>,
        /// Stop after this many seconds.
        #[arg(long)]
        seconds: Option<u64>,
    },
    /// Play a recording back: every recorded topic for viewers, or (--rerun) a graph on the recorded source topics.
    Replay {
        /// The recording (.mcap).
        recording: PathBuf,
        /// Re-run a graph (default: the one stored in the recording) with its sources replaced by the recording,
        /// writing a new recording into --out.
        #[arg(long)]
        rerun: bool,
        /// With --rerun: run this launch graph instead of the recorded one (e.g. with a stage swapped).
        #[arg(long)]
        graph: Option<PathBuf>,
        /// With --rerun: override a node parameter, NODE.PARAM=VALUE. Repeatable.
        #[arg(long = "set", value_name = "NODE.PARAM=VALUE")]
        set: Vec<String>,
        /// Output folder of a re-run [default: rerun/ beside the recording].
        #[arg(long)]
        out: Option<PathBuf>,
        /// With --rerun: start the programs (non-stage executables) the recorded launch file names without asking.
        #[arg(long)]
        yes: bool,
        /// Speed relative to the recorded timing (2 = twice as fast).
        #[arg(long, conflicts_with = "max")]
        rate: Option<f64>,
        /// As fast as the graph goes, lossless (the default with --rerun).
        #[arg(long)]
        max: bool,
        /// Start again at the end (playback only).
        #[arg(long = "loop")]
        repeat: bool,
        /// Play only these topics (playback only). Repeatable.
        #[arg(long = "topic")]
        topics: Vec<String>,
        #[command(flatten)]
        verbosity: VerbosityArgs,
    },
    /// Summarise a recording: topics, counts, rates, duration, schemas, completeness.
    Info {
        /// The recording (.mcap).
        recording: PathBuf,
        /// Print one JSON object instead of the table.
        #[arg(long)]
        json: bool,
        /// Read every message and check every chunk's checksum (by default a finished file's summary is trusted,
        /// which takes milliseconds on a file of any size).
        #[arg(long)]
        verify: bool,
    },
    /// Attach to a running run and record chosen topics (every topic by default) into a new MCAP file, until the
    /// run ends, the topics end, or Ctrl-C.
    Record {
        /// Topics to record (repeat the option); every topic of the run when none is given.
        #[arg(long)]
        topic: Vec<String>,
        /// The recording file to write.
        #[arg(long)]
        out: PathBuf,
        /// Run id [default: the newest running run].
        #[arg(long)]
        run: Option<String>,
        /// How images are recorded: raw, png (lossless) or jpeg.
        #[arg(long, default_value = "raw")]
        images: lineflow_recordings::image_codec::ImageFormat,
    },
    /// Compare two recordings topic by topic, message by message; exit status 1 when they differ.
    Diff {
        /// First recording.
        a: PathBuf,
        /// Second recording.
        b: PathBuf,
    },
    /// Export a topic: images as PNG, 2-D and 3-D lines as CSV/PLY, poses as CSV.
    Export {
        /// The recording (.mcap).
        recording: PathBuf,
        /// Topic to export.
        #[arg(long)]
        topic: String,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
    },
    /// Rebuild a damaged recording (recorder killed, disk full) into a finished file with every readable message.
    Recover {
        /// The damaged recording.
        recording: PathBuf,
        /// The new file.
        #[arg(long)]
        out: PathBuf,
    },
    /// List the running runs: id, supervisor pid, age, graph, nodes, output folder.
    Ps {
        /// One JSON object a line.
        #[arg(long)]
        json: bool,
    },
    /// Stop a running run as Ctrl-C would: the nodes stop, the recorder finishes its file.
    Stop {
        /// Run id (`lineflow ps`).
        run: String,
        /// Seconds to wait for it to end.
        #[arg(long, default_value_t = 30)]
        wait: u64,
    },
    /// Shell completions on stdout, e.g. `lineflow completions bash > ~/.local/share/bash-completion/completions/lineflow`.
    Completions {
        /// bash, zsh, fish, elvish or powershell.
        shell: clap_complete::Shell,
    },
    /// Man pages: lineflow.1 and one per command (lineflow-run.1, ...), written into a folder.
    Man {
        /// Folder for the pages (created).
        #[arg(long, default_value = "man")]
        out: PathBuf,
    },
    /// Check shared memory and leftovers of crashed runs; --fix removes them.
    Doctor {
        /// Remove stale runs' shared memory and folders.
        #[arg(long)]
        fix: bool,
    },
    /// Write a synthetic scene (images with exact ground truth) as a project folder plus gt/.
    Synth(synth::SynthArgs),
    /// Evaluate a run's results against the ground truth of a synthetic scene; writes report.md with plots.
    Eval {
        /// Folder with the run's poses.csv, checkpoints.csv, lines2d.csv, lines3d.csv (any subset).
        results: PathBuf,
        /// Scene folder written by `lineflow synth` (holds gt/).
        #[arg(long)]
        gt: PathBuf,
        /// Report folder [default: RESULTS/eval].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Print the figures as one JSON object (also written to the report folder as metrics.json).
        #[arg(long)]
        json: bool,
    },
    /// Build the wire-frame model (model.obj, model.city.json) from a lines3d.csv, as the model stage does.
    Model {
        /// 3-D lines (lines3d.csv).
        lines: PathBuf,
        /// Camera poses (poses.csv): faces are oriented towards the cameras.
        #[arg(long)]
        poses: Option<PathBuf>,
        /// The images' 2-D lines (lines2d.csv): the openings a façade's rows and columns predict are looked for
        /// in them, and with `--set refine=true` Refine measures every edge again in them (needs --poses and
        /// --camera; docs/model.md).
        #[arg(long, requires_all = ["poses", "camera"])]
        lines2d: Option<PathBuf>,
        /// The camera the 2-D lines were measured with (camera.toml).
        #[arg(long, requires = "lines2d")]
        camera: Option<PathBuf>,
        /// Output folder [default: the lines' folder].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Override a model parameter: PARAM=VALUE (docs/model.md). Repeatable.
        #[arg(long = "set", value_name = "PARAM=VALUE")]
        set: Vec<String>,
    },
    /// Find the circular survey targets in a project's images, name them by control_points.csv (the layout of the
    /// targets intersected with the images' poses, in any frame) and add them to observations.csv, whose rows
    /// stay as they are (docs/formats.md, "Survey targets").
    Targets(lineflow_interop::targets::TargetsArgs),
    /// Class each line of a lines3d.csv as structure or texture, as the line stages do (docs/lines3d.md).
    Classify {
        /// 3-D lines (lines3d.csv).
        lines: PathBuf,
        /// Where to write them with their class (a lines3d.csv).
        #[arg(long)]
        out: PathBuf,
        /// The images' poses (poses.csv): with --camera, a line shown by few of the images seeing it is texture.
        #[arg(long, requires = "camera")]
        poses: Option<PathBuf>,
        /// The camera (camera.toml) of those images.
        #[arg(long, requires = "poses")]
        camera: Option<PathBuf>,
        /// A setting of the classing: PARAM=VALUE (neighbours, reach_m, band_m, corner_m, overshoot_m, parallel_deg, min_support, behind_m).
        #[arg(long = "set", value_name = "PARAM=VALUE")]
        set: Vec<String>,
    },
    /// Reproduce a seed document's experiment (seed001: collinearity vs essential-matrix orientation of a
    /// simulated stereo pair, Monte Carlo; seed004: model-image fitting of box buildings in synthetic aerial
    /// photos); prints Markdown tables.
    Experiment {
        /// Which experiment: seed001 or seed004.
        name: String,
        /// Trials per configuration [seed001: 500; seed004: 20 starts per building].
        #[arg(long)]
        trials: Option<u64>,
        /// Seed of the simulation.
        #[arg(long, default_value_t = 1)]
        seed: u64,
    },
    /// A camera.toml from another tool's calibration (OpenCV, COLMAP, Metashape), and back.
    Camera {
        #[command(subcommand)]
        what: lineflow_interop::CameraCmd,
    },
    /// poses.csv from a COLMAP model or a Metashape cameras export, in the survey's frame by a project's control points.
    Poses {
        #[command(subcommand)]
        what: lineflow_interop::PosesCmd,
    },
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        what: lineflow_bench::BenchCmd,
    },
}

fn main() -> ExitCode {
    lineflow_runtime::logging::init("lineflow");
    let cli = Cli::parse();
    let result = match cli.command {
        Cmd::Run {
            graph,
            set,
            out,
            chaos,
            host,
            view,
            verbosity,
        } => run::run(&graph, &view.with_sets(&set), &host, &out, verbosity.into(), &chaos),
        Cmd::Process {
            folder,
            out,
            graph,
            set,
            view,
            verbosity,
        } => run::process(&folder, out, graph, &view.with_sets(&set), verbosity.into()),
        Cmd::Logs { out, node, follow } => logs::logs(&out, node.as_deref(), follow),
        Cmd::Topics { run } => attach::topics(run.as_deref()),
        Cmd::Echo {
            topic,
            run,
            count,
            json,
            raw,
            elements,
        } => {
            let form = match (json, raw) {
                (_, true) => attach::EchoForm::Raw,
                (true, _) => attach::EchoForm::Json(elements.unwrap_or(usize::MAX)),
                _ => attach::EchoForm::Fields(elements.unwrap_or(3)),
            };
            attach::echo(&topic, run.as_deref(), count, form)
        }
        Cmd::Record { topic, out, run, images } => record_cmd::record(run.as_deref(), &topic, &out, images),
        Cmd::Hz { topic, run, seconds } => attach::hz(&topic, run.as_deref(), seconds),
        Cmd::Replay {
            recording,
            rerun,
            graph,
            set,
            out,
            yes,
            rate,
            max,
            repeat,
            topics,
            verbosity,
        } => recordings::replay(recordings::ReplayArgs {
            recording: &recording,
            rerun,
            graph: graph.as_deref(),
            set: &set,
            out,
            yes,
            // Playback for viewers keeps the recorded timing unless told otherwise; a re-run goes flat out.
            rate: if max { 0.0 } else { rate.unwrap_or(if rerun { 0.0 } else { 1.0 }) },
            repeat,
            topics: &topics,
            verbosity: verbosity.into(),
        }),
        Cmd::Info { recording, json, verify } => recordings::info(&recording, json, verify),
        Cmd::Diff { a, b } => recordings::diff(&a, &b),
        Cmd::Export { recording, topic, out } => recordings::export(&recording, &topic, &out),
        Cmd::Recover { recording, out } => recordings::recover(&recording, &out),
        Cmd::Doctor { fix } => doctor::doctor(fix),
        Cmd::Completions { shell } => {
            clap_complete::generate(shell, &mut Cli::command(), "lineflow", &mut std::io::stdout());
            Ok(ExitCode::SUCCESS)
        }
        Cmd::Man { out } => man_pages(&out),
        Cmd::Ps { json } => ps::ps(json),
        Cmd::Stop { run, wait } => ps::stop(&run, std::time::Duration::from_secs(wait)),
        Cmd::Synth(args) => synth::synth(args),
        Cmd::Eval { results, gt, out, json } => lineflow_eval::command(&results, &gt, out, json),
        Cmd::Classify {
            lines,
            out,
            poses,
            camera,
            set,
        } => model_cmd::classify(&lines, &out, poses.zip(camera), &set),
        Cmd::Model {
            lines,
            poses,
            lines2d,
            camera,
            out,
            set,
        } => {
            let refine = lines2d
                .as_deref()
                .zip(camera.as_deref())
                .map(|(lines2d, camera)| model_cmd::RefineInputs { lines2d, camera });
            model_cmd::model(&lines, poses.as_deref(), refine, out, &set)
        }
        Cmd::Targets(args) => lineflow_interop::targets::targets(args),
        Cmd::Experiment { name, trials, seed } => lineflow_bench::experiment(&name, trials, seed),
        Cmd::Camera { what } => lineflow_interop::camera(what),
        Cmd::Poses { what } => lineflow_interop::poses(what),
        Cmd::Bench { what } => lineflow_bench::bench(what),
    };
    lineflow_bench::reader::report_peak_rss();
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// `lineflow man`: one page for the tool and one for each command.
fn man_pages(out: &std::path::Path) -> anyhow::Result<ExitCode> {
    use anyhow::Context as _;
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    clap_mangen::generate_to(Cli::command(), out).with_context(|| format!("cannot write the man pages into {}", out.display()))?;
    let pages = std::fs::read_dir(out)?
        .flatten()
        .filter(|e| e.path().extension().is_some_and(|x| x == "1"));
    let dir = out.display();
    eprintln!("{} man pages in {dir} (read one with `man -l {dir}/lineflow.1`)", pages.count());
    Ok(ExitCode::SUCCESS)
}
