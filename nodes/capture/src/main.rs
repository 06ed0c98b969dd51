//! `lineflow-capture`: the capture stage's process (`impl = "synthetic"` or `"folder"`).
mod folder_node;
mod source;
mod synthetic_node;

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage(
        "capture",
        "synthetic",
        &[("synthetic", synthetic_node::run), ("folder", folder_node::run)],
    )
}
