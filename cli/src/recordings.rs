//! `lineflow replay`, `info`, `diff`, `export` and `recover`: working with recordings.
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Result};
use lineflow_recordings::replay::{playback_graph, recorded_programs, rerun_graph, Pace};
use lineflow_recordings::{tools, tools::Reading, Recording};
use lineflow_runtime::launch::Resolver;
use lineflow_runtime::run::Verbosity;

/// Options of `lineflow replay`.
pub struct ReplayArgs<'a> {
    /// The recording.
    pub recording: &'a Path,
    /// Re-run a graph on the recorded source topics.
    pub rerun: bool,
    /// Graph to re-run instead of the recorded one.
    pub graph: Option<&'a Path>,
    /// Parameter overrides.
    pub set: &'a [String],
    /// Output folder of a re-run.
    pub out: Option<PathBuf>,
    /// Start the programs the recorded launch file names without asking.
    pub yes: bool,
    /// Speed; 0 = as fast as possible.
    pub rate: f64,
    /// Loop (playback only).
    pub repeat: bool,
    /// Topics to play (playback only; default all).
    pub topics: &'a [String],
    /// What the terminal shows.
    pub verbosity: Verbosity,
}

/// `lineflow replay`.
pub fn replay(a: ReplayArgs<'_>) -> Result<ExitCode> {
    let rec = Recording::open(a.recording)?;
    if let Some(damage) = &rec.damage {
        eprintln!("warning: {}: {damage}; replaying what is readable", rec.path.display());
    }
    let resolver = Resolver::beside_current_exe();
    let pace = Pace {
        rate: a.rate,
        repeat: a.repeat,
    };
    if a.rerun {
        if a.repeat {
            bail!("--loop plays a recording for viewers; a --rerun runs the graph once");
        }
        let g = rerun_graph(&rec, a.graph, a.set, &resolver, pace)?;
        // A launch file of the user's own (--graph) starts what the user chose.
        let programs = if a.graph.is_none() {
            recorded_programs(&g, a.set)
        } else {
            Vec::new()
        };
        if !programs.is_empty() && !a.yes {
            confirm_programs(&rec, &programs)?;
        }
        let out = a.out.unwrap_or_else(|| rec.path.parent().unwrap_or(Path::new(".")).join("rerun"));
        eprintln!("re-running graph '{}' on {} -> {}", g.name, rec.path.display(), out.display());
        return lineflow_runtime::run::run_graph(&g, &out, None, a.verbosity);
    }
    if a.graph.is_some() || !a.set.is_empty() {
        bail!("--graph and --set apply to --rerun");
    }
    let g = playback_graph(&rec, a.topics, &resolver, pace)?;
    let out = a.out.unwrap_or_else(|| std::env::temp_dir().join("lineflow-replay"));
    eprintln!(
        "playing {} topics of {} (attach with `lineflow echo TOPIC` or `lineflow hz TOPIC`)",
        g.edges.len(),
        rec.path.display()
    );
    lineflow_runtime::run::run_graph(&g, &out, None, a.verbosity)
}

/// Shows the programs a recording's launch file would start and asks before starting them; without a terminal to
/// ask on, refuses.
fn confirm_programs(rec: &Recording, programs: &[(String, String)]) -> Result<()> {
    use std::io::{BufRead, IsTerminal, Write};
    let list: Vec<String> = programs.iter().map(|(n, c)| format!("  {n}: {c}")).collect();
    let list = list.join("\n");
    if !std::io::stdin().is_terminal() {
        bail!(
            "{}: the recorded launch file starts programs that are not lineflow stages:\n{list}\nnothing was started; \
             pass --yes to run them, or --graph with a launch file of your own",
            rec.path.display()
        );
    }
    eprintln!("The launch file stored in {}:\n", rec.path.display());
    eprintln!("{}\n", rec.run_meta("launch_text").unwrap_or_default());
    eprint!("It starts programs that are not lineflow stages:\n{list}\nStart them? [y/N] ");
    std::io::stderr().flush()?;
    let mut answer = String::new();
    std::io::stdin().lock().read_line(&mut answer)?;
    if !matches!(answer.trim(), "y" | "Y" | "yes") {
        bail!("not started");
    }
    Ok(())
}

/// `lineflow info`.
pub fn info(path: &Path, json: bool, verify: bool) -> Result<ExitCode> {
    let rec = Recording::open(path)?;
    let summary = tools::summarize(&rec, if verify { Reading::Messages } else { Reading::Index });
    match json {
        true => println!("{}", serde_json::to_string(&summary)?),
        false => print!("{}", tools::info(&summary)),
    }
    Ok(ExitCode::from(if summary.damaged { 2 } else { 0 }))
}

/// `lineflow diff`: exit status 0 when equal, 1 when they differ.
pub fn diff(a: &Path, b: &Path) -> Result<ExitCode> {
    let (ra, rb) = (Recording::open(a)?, Recording::open(b)?);
    let report = tools::diff(&ra, &rb)?;
    for t in &report.equal {
        println!("equal    {t}");
    }
    for d in &report.differ {
        println!("DIFFERS  {}: {}", d.topic, d.what);
    }
    if report.differ.is_empty() {
        println!("recordings are equal on all {} topics", report.equal.len());
        Ok(ExitCode::SUCCESS)
    } else {
        println!(
            "{} of {} topics differ",
            report.differ.len(),
            report.differ.len() + report.equal.len()
        );
        Ok(ExitCode::FAILURE)
    }
}

/// `lineflow recover`.
pub fn recover(path: &Path, out: &Path) -> Result<ExitCode> {
    let rec = Recording::open(path)?;
    let r = tools::recover(&rec, out)?;
    match &r.lost {
        Some(why) => eprintln!("recovered {} messages into {}; the rest is lost: {why}", r.messages, out.display()),
        None => eprintln!("recovered all {} messages into {}", r.messages, out.display()),
    }
    Ok(ExitCode::SUCCESS)
}

/// `lineflow export`: images (and edge maps) as PNG, 2-D lines as `lines2d.csv`, 3-D lines as `lines3d.csv` and
/// `.ply`, poses as `poses.csv` (formats of `conventions.md`).
pub fn export(path: &Path, topic: &str, out: &Path) -> Result<ExitCode> {
    let rec = Recording::open(path)?;
    let written = lineflow_recordings::export::export(&rec, topic, out)?;
    eprintln!("exported {written} into {}", out.display());
    Ok(ExitCode::SUCCESS)
}
