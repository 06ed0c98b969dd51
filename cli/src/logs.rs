//! `lineflow logs`: the nodes' output that a run keeps in `OUT/logs/NODE.log`, while it runs or after.
use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Duration;

use anyhow::{bail, Context, Result};
use lineflow_runtime::console::{log_path, LOGS_DIR};

/// Prints the log of `node` (every node's, one after another, when `None`) of the run whose output folder is
/// `out`; with `follow`, then prints what the nodes append until interrupted.
pub fn logs(out: &Path, node: Option<&str>, follow: bool) -> Result<ExitCode> {
    let files = log_files(out, node)?;
    let mut offsets = vec![0u64; files.len()];
    let many = files.len() > 1;
    for (file, offset) in files.iter().zip(&mut offsets) {
        if many {
            println!("==> {} <==", file.display());
        }
        *offset = print_from(file, 0)?;
    }
    if !follow {
        return Ok(ExitCode::SUCCESS);
    }
    loop {
        std::thread::sleep(Duration::from_millis(200));
        for (file, offset) in files.iter().zip(&mut offsets) {
            *offset = print_from(file, *offset)?;
        }
    }
}

/// The log files to show, checked to exist, with a message naming what is there when they do not.
fn log_files(out: &Path, node: Option<&str>) -> Result<Vec<PathBuf>> {
    let dir = out.join(LOGS_DIR);
    if !dir.is_dir() {
        bail!(
            "{}: no {LOGS_DIR}/ folder; pass the output folder of a run (`--out` of `lineflow run`, FOLDER/out of `lineflow process`)",
            out.display()
        );
    }
    let mut all: Vec<PathBuf> = std::fs::read_dir(&dir)
        .with_context(|| format!("cannot list {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "log"))
        .collect();
    all.sort();
    match node {
        None if all.is_empty() => bail!("{}: no node logs yet", dir.display()),
        None => Ok(all),
        Some(name) => {
            let path = log_path(out, name);
            if !path.is_file() {
                let names: Vec<String> = all
                    .iter()
                    .filter_map(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
                    .collect();
                bail!("{}: no log of node '{name}' (nodes with logs: {})", dir.display(), names.join(", "));
            }
            Ok(vec![path])
        }
    }
}

/// Prints `path` from byte `offset` to its end; returns the new end.
fn print_from(path: &Path, offset: u64) -> Result<u64> {
    let mut f = std::fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let len = f.metadata().map(|m| m.len()).unwrap_or(0);
    // A log that shrank was started again (a new run into the same folder): show it from its start.
    let from = if len < offset { 0 } else { offset };
    f.seek(SeekFrom::Start(from))?;
    let mut bytes = Vec::new();
    f.read_to_end(&mut bytes)?;
    let mut stdout = std::io::stdout().lock();
    stdout.write_all(&bytes)?;
    stdout.flush()?;
    Ok(from + bytes.len() as u64)
}
