//! `lineflow-capture`: the capture stage (`impl = "synthetic"` or `"folder"`).
mod folder_node;
mod source;
mod synthetic_node;

use anyhow::Result;

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
}

fn body() -> Result<()> {
    let ctx = lineflow_runtime::NodeContext::from_env()?;
    match ctx.implementation("synthetic") {
        "synthetic" => synthetic_node::run(&ctx),
        "folder" => folder_node::run(&ctx),
        other => anyhow::bail!(
            "node '{}': unknown capture impl '{other}' (available: synthetic, folder)",
            ctx.name()
        ),
    }
}
