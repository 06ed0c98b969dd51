//! `lineflow ps` and `lineflow stop`: the runs of this machine (the registry of `lineflow_runtime::runs`).
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{bail, Result};
use lineflow_runtime::runs::{pid_alive, RunRecord};
use serde_json::json;

/// The graph's name and its node count, when its file can be read.
fn graph_of(run: &RunRecord) -> Option<(String, usize)> {
    let g = run.load_graph().ok()?;
    Some((g.name, g.nodes.len()))
}

/// Lists the running runs, newest first: id, supervisor pid, age, graph, nodes, output folder.
pub fn ps(as_json: bool) -> Result<ExitCode> {
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs());
    let runs: Vec<RunRecord> = RunRecord::list().into_iter().filter(RunRecord::is_running).collect();
    if as_json {
        for r in &runs {
            let (graph, nodes) = graph_of(r).unzip();
            let line = json!({
                "id": r.id, "pid": r.pid, "started_unix_s": r.started_unix_s, "graph": graph, "nodes": nodes,
                "out": r.out.as_ref().map(|o| o.display().to_string()),
            });
            println!("{line}");
        }
        return Ok(ExitCode::SUCCESS);
    }
    if runs.is_empty() {
        println!("no lineflow run is running");
        return Ok(ExitCode::SUCCESS);
    }
    println!("{:<12} {:>8} {:>8}  {:<20} {:>5}  out", "run", "pid", "age", "graph", "nodes");
    for r in &runs {
        let age = now.saturating_sub(r.started_unix_s);
        let (graph, nodes) = graph_of(r).map_or(("?".into(), "?".into()), |(g, n)| (g, n.to_string()));
        let out = r.out.as_ref().map_or("?".into(), |o| o.display().to_string());
        println!(
            "{:<12} {:>8} {:>5}:{:02}  {graph:<20} {nodes:>5}  {out}",
            r.id,
            r.pid,
            age / 60,
            age % 60
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// Stops run `id` as Ctrl-C would (SIGINT to its supervisor: the nodes stop, the recorder finishes its file) and
/// waits up to `wait` for it to end.
pub fn stop(id: &str, wait: Duration) -> Result<ExitCode> {
    let run = RunRecord::load(id)?;
    if !run.is_running() {
        bail!("run {id} is not running (its supervisor, pid {}, has ended)", run.pid);
    }
    if !run.interrupt() {
        bail!("run {id}: cannot signal its supervisor (pid {})", run.pid);
    }
    let start = Instant::now();
    // The supervisor removes the run's record as it ends; its process may linger a moment as a zombie.
    while pid_alive(run.pid) && RunRecord::load(id).is_ok_and(|r| r.is_running()) {
        if start.elapsed() > wait {
            bail!("run {id}: its supervisor (pid {}) did not end within {} s", run.pid, wait.as_secs());
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    println!("run {id} stopped");
    Ok(ExitCode::SUCCESS)
}
