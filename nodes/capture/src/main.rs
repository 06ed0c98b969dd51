//! `lineflow-capture`: the capture stage (`impl = "folder"`).
mod folder_node;

use anyhow::Result;

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
}

fn body() -> Result<()> {
    let ctx = lineflow_runtime::NodeContext::from_env()?;
    match ctx.implementation("folder") {
        "folder" => folder_node::run(&ctx),
        other => anyhow::bail!("node '{}': unknown capture impl '{other}' (available: folder)", ctx.name()),
    }
}
