//! `lineflow-bridge`: the shell of the bridge between hosts (the library, `docs/hosts.md`).
fn main() -> std::process::ExitCode {
    lineflow_runtime::run_stage("bridge", "zenoh", &[("zenoh", lineflow_bridge::run)])
}
