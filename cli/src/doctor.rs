//! `lineflow doctor`: shared memory and leftovers of crashed runs.
use std::process::ExitCode;

use anyhow::Result;
use lineflow_runtime::runs::RunRecord;
use lineflow_runtime::shm;

/// Reports free `/dev/shm`, running and stale runs; with `fix`, removes what stale runs left behind.
pub fn doctor(fix: bool) -> Result<ExitCode> {
    let free = shm::free_bytes(std::path::Path::new(shm::SHM_DIR));
    println!(
        "{}: {} free",
        shm::SHM_DIR,
        free.map(shm::human_bytes).unwrap_or_else(|| "unknown".into())
    );
    let mut stale = 0;
    for run in RunRecord::list() {
        let files = shm::files_with_prefix(&run.prefix);
        let bytes: u64 = files.iter().filter_map(|f| std::fs::metadata(f).ok()).map(|m| m.len()).sum();
        if run.is_running() {
            println!("run {}: running (pid {}), {} shared-memory files", run.id, run.pid, files.len());
            continue;
        }
        if files.is_empty() && !run.root.exists() && run.ended {
            continue;
        }
        stale += 1;
        println!(
            "run {}: stale ({} files, {} apparent size){}",
            run.id,
            files.len(),
            shm::human_bytes(bytes),
            if run.ended { "" } else { ", supervisor died" }
        );
        if fix {
            let n = shm::remove_prefixed(&run.prefix);
            run.remove();
            println!("  removed {n} files and {}", run.dir().display());
        }
    }
    if stale == 0 {
        println!("no stale runs");
    } else if !fix {
        println!("{stale} stale run(s): `lineflow doctor --fix` removes them");
        return Ok(ExitCode::from(2));
    }
    Ok(ExitCode::SUCCESS)
}
