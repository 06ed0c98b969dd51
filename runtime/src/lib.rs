//! The lineflow runtime: node SDK over iceoryx2, launch graphs, and the supervisor that runs them.
#![warn(missing_docs)]

pub mod chaos;
pub mod console;
pub mod describe;
pub mod env;
pub mod host_reports;
pub mod hosts;
pub mod launch;
pub mod logging;
pub mod node;
pub mod params;
pub mod ports;
pub mod report;
pub mod run;
pub mod runs;
pub mod seen;
pub mod shm;
pub mod supervisor;
pub mod tap;
pub mod transport;

/// The bound of the payload parts `Output::publish_parts` takes, re-exported so that nodes need no iceoryx2 dependency.
pub use iceoryx2::prelude::ZeroCopySend;
pub use node::{Flow, NodeContext, RunEnd, StatusWatch};
pub use params::{ParamError, StageParams};
pub use ports::{frames_to_publish, Input, Output, Received};

/// Runs a node's body and turns an error into one line on stderr (`[node] error: ...`, causes joined by `: `) and
/// exit status 1, instead of a debug dump with a backtrace.
pub fn run_node(body: impl FnOnce() -> anyhow::Result<()>) -> std::process::ExitCode {
    match body() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            let node = std::env::var(env::NODE).unwrap_or_else(|_| "node".into());
            // Not eprintln!: with the supervisor gone (its end of the pipe closed) that would panic instead.
            let _ = std::io::Write::write_all(&mut std::io::stderr(), format!("[{node}] error: {e:#}\n").as_bytes());
            std::process::ExitCode::FAILURE
        }
    }
}

/// One implementation of a stage: the process body given its context.
pub type Implementation = fn(NodeContext) -> anyhow::Result<()>;

/// A stage process's `main`: runs the implementation the launch file names in `impl` (or `default`) from
/// `implementations`, and refuses an unknown one with the list of those available.
pub fn run_stage(stage: &str, default: &str, implementations: &[(&str, Implementation)]) -> std::process::ExitCode {
    run_node(|| {
        let ctx = NodeContext::from_env()?;
        let chosen = ctx.implementation(default).to_owned();
        match implementations.iter().find(|(name, _)| *name == chosen) {
            Some((_, body)) => body(ctx),
            None => {
                let available: Vec<&str> = implementations.iter().map(|(name, _)| *name).collect();
                anyhow::bail!(
                    "node '{}': unknown {stage} impl '{chosen}' (available: {})",
                    ctx.name(),
                    available.join(", ")
                )
            }
        }
    })
}
