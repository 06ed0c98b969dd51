//! `lineflow-view`: the live viewer the supervisor adds with `lineflow run --view` (`[view]` in a launch file).
fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("view", "foxglove", &[("foxglove", lineflow_view::live::run)])
}
