//! Running a graph for a person at a terminal: the shipped launch graphs' folder, and a run whose per-node summary
//! is printed and kept in `out/summary.txt` (and as JSON in `out/summary.json`). `lineflow run`, `process`, `replay --rerun` and the benchmarks that
//! run the shipped graphs share it.
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Result;

use crate::chaos::Fault;
use crate::launch;
use crate::supervisor::{self, RunOptions};

/// How much of a run the terminal shows (`-q`, `-v`).
#[derive(Debug, Clone, Copy, Default)]
pub struct Verbosity {
    /// No progress line and no node lines (they are still kept in `out/logs/`); the summary and errors print.
    pub quiet: bool,
    /// The nodes log at debug level (unless `LINEFLOW_LOG` says otherwise).
    pub verbose: bool,
    /// The summary goes to stdout as one JSON object (`out/summary.json`) instead of the table.
    pub json: bool,
}

/// Runs a resolved graph; prints the per-node summary and writes it to `out/summary.txt`. The nodes' lines are
/// shown above a progress line and kept in `out/logs/NODE.log`.
pub fn run_graph(g: &launch::Graph, out: &Path, expected_frames: Option<u64>, verbosity: Verbosity) -> Result<ExitCode> {
    run_graph_with_faults(g, out, expected_frames, verbosity, &[])
}

/// [`run_graph`] with faults injected (`lineflow run --chaos`); the summary says which struck.
pub fn run_graph_with_faults(
    g: &launch::Graph,
    out: &Path,
    expected_frames: Option<u64>,
    verbosity: Verbosity,
    chaos: &[Fault],
) -> Result<ExitCode> {
    let opts = RunOptions {
        out: out.to_owned(),
        expected_frames,
        progress: !verbosity.quiet,
        echo_logs: !verbosity.quiet,
        node_log_level: (verbosity.verbose && std::env::var_os("LINEFLOW_LOG").is_none()).then(|| "debug".into()),
        connect_timeout: None,
        chaos: chaos.to_vec(),
    };
    crate::host_reports::clear_reports(out);
    let outcome = supervisor::run(g, &opts)?;
    let reports = crate::host_reports::read_reports(out);
    let mut table = outcome.table() + &crate::host_reports::table(&reports);
    for (fault, struck) in &outcome.faults {
        table += &format!(
            "chaos: {fault}: {}\n",
            if *struck {
                "struck"
            } else {
                "did not strike (the node ended first)"
            }
        );
    }
    let mut json = outcome.json(&g.source);
    if !reports.is_empty() {
        json["hosts"] = serde_json::to_value(&reports)?;
    }
    let json = json.to_string();
    if verbosity.json {
        println!("{json}");
    } else {
        eprint!("{table}");
    }
    let _ = std::fs::write(out.join("summary.json"), json + "\n");
    let _ = std::fs::write(
        out.join("summary.txt"),
        format!(
            "run {}  graph {}  wall {:.2} s\n{table}",
            outcome.run_id,
            g.source.display(),
            outcome.wall.as_secs_f64()
        ),
    );
    match outcome.error {
        None => {
            eprintln!(
                "run {} finished in {:.2} s; results in {}",
                outcome.run_id,
                outcome.wall.as_secs_f64(),
                out.display()
            );
            Ok(ExitCode::SUCCESS)
        }
        Some(e) => {
            eprintln!("error: run {} failed: {e}", outcome.run_id);
            Ok(ExitCode::FAILURE)
        }
    }
}

/// The folder holding the shipped launch graphs: `$LINEFLOW_HOME/launch`, `./launch`, beside the build tree
/// (`target/<profile>/lineflow`), or in the source tree the binaries were built from (a `CARGO_TARGET_DIR`
/// elsewhere).
pub fn launch_dir() -> PathBuf {
    if let Some(home) = std::env::var_os("LINEFLOW_HOME") {
        return PathBuf::from(home).join("launch");
    }
    let here = PathBuf::from("launch");
    if here.is_dir() {
        return here;
    }
    // target/<profile>/lineflow -> repository root
    let beside_build = std::env::current_exe()
        .ok()
        .and_then(|e| e.ancestors().nth(3).map(|r| r.join("launch")));
    let source_tree = Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(|r| r.join("launch"));
    beside_build.into_iter().chain(source_tree).find(|p| p.is_dir()).unwrap_or(here)
}
