//! `lineflow run` and `lineflow process`.
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use lineflow_runtime::chaos::Fault;
use lineflow_runtime::launch::{self, Resolver};
use lineflow_runtime::run::{launch_dir, run_graph, run_graph_with_faults, Verbosity};

/// Runs `host`'s part of a launch graph with `chaos`'s faults injected; prints the per-node summary and writes it to
/// `out/summary.txt`.
pub fn run(graph: &Path, set: &[String], host: &str, out: &Path, verbosity: Verbosity, chaos: &[Fault]) -> Result<ExitCode> {
    let resolver = Resolver::beside_current_exe();
    let whole = launch::load(graph, set, &resolver)?;
    let g = lineflow_runtime::hosts::part(&whole, host, &resolver)?;
    run_graph_with_faults(&g, out, None, verbosity, chaos)
}

/// Whether the launch file `graph` declares a node `name` (false when it cannot be read; loading it reports why).
fn has_node(graph: &Path, name: &str) -> bool {
    let Ok(text) = std::fs::read_to_string(graph) else { return false };
    let Ok(doc) = text.parse::<toml::Table>() else { return false };
    doc.get("node")
        .and_then(toml::Value::as_array)
        .is_some_and(|nodes| nodes.iter().any(|n| n.get("name").and_then(toml::Value::as_str) == Some(name)))
}

/// Runs a graph (default `launch/folder.toml`) over a project folder.
pub fn process(folder: &Path, out: Option<PathBuf>, graph: Option<PathBuf>, set: &[String], verbosity: Verbosity) -> Result<ExitCode> {
    // Bare photos: a nominal camera from the first one's EXIF, written where the user sees (and can replace) it.
    let camera_toml = folder.join("camera.toml");
    let first = lineflow_formats::project::list_images(&folder.join("images"))
        .ok()
        .and_then(|i| i.into_iter().next());
    if let (false, Some(photo)) = (camera_toml.exists(), first) {
        eprintln!(
            "{}: missing; a nominal camera from the EXIF of {}:",
            camera_toml.display(),
            photo.display()
        );
        lineflow_interop::import_exif(&photo, &camera_toml, None)?;
    }
    let project = lineflow_formats::project::Project::open(folder, false).map_err(|e| anyhow::anyhow!("{e}"))?;
    let graph = graph.unwrap_or_else(|| launch_dir().join("folder.toml"));
    if !graph.is_file() {
        bail!("{}: launch graph not found (pass --graph or set LINEFLOW_HOME)", graph.display());
    }
    let folder = std::fs::canonicalize(folder).with_context(|| format!("{}", folder.display()))?;
    let out = out.unwrap_or_else(|| folder.join("out"));
    let quoted = |p: &Path| format!("\"{}\"", p.display().to_string().replace('\\', "\\\\").replace('"', "\\\""));
    let mut set = set.to_vec();
    set.insert(0, format!("capture.folder={}", quoted(&folder)));
    // Poses supplied with the project (e.g. from another photogrammetry package) replace the orientation stage,
    // unless the caller chose the orientation's implementation or the graph has no node `orientation`.
    let supplied = folder.join("poses.csv");
    let own_orientation = !set.iter().any(|s| s.starts_with("orientation.impl=")) && has_node(&graph, "orientation");
    if supplied.is_file() && own_orientation {
        eprintln!("using the poses in {} in place of the orientation stage", supplied.display());
        set.push("orientation.impl=\"file\"".into());
        set.push(format!("orientation.poses={}", quoted(&supplied)));
    } else if own_orientation {
        // A nominal camera is self-calibrated, and the survey targets found for control points without
        // observations.
        lineflow_interop::bare::prepare(&folder, &out, &set, verbosity)?;
    }
    eprintln!(
        "processing {} images of {} with {}",
        project.images.len(),
        folder.display(),
        graph.display()
    );
    let g = launch::load(&graph, &set, &Resolver::beside_current_exe())?;
    run_graph(&g, &out, Some(project.images.len() as u64), verbosity)
}
