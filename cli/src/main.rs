//! `lineflow`: run launch graphs, process project folders, inspect running graphs, benchmark the transport.
mod attach;
mod bench;
mod doctor;
mod run;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

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
    },
    /// Print a topic's message rate once a second.
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
    /// Check shared memory and leftovers of crashed runs; --fix removes them.
    Doctor {
        /// Remove stale runs' shared memory and folders.
        #[arg(long)]
        fix: bool,
    },
    /// Benchmarks.
    Bench {
        #[command(subcommand)]
        what: bench::BenchCmd,
    },
}

fn main() -> ExitCode {
    lineflow_runtime::logging::init("lineflow");
    let cli = Cli::parse();
    let result = match cli.command {
        Cmd::Run { graph, set, out } => run::run(&graph, &set, &out, None),
        Cmd::Process { folder, out, graph, set } => run::process(&folder, out, graph, &set),
        Cmd::Topics { run } => attach::topics(run.as_deref()),
        Cmd::Echo { topic, run, count } => attach::echo(&topic, run.as_deref(), count),
        Cmd::Hz { topic, run, seconds } => attach::hz(&topic, run.as_deref(), seconds),
        Cmd::Doctor { fix } => doctor::doctor(fix),
        Cmd::Bench { what } => bench::bench(what),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
