//! `lineflow bench chaos`: every node of a graph SIGKILLed at three points of a run (a fifth, half and four fifths
//! of an undisturbed run's time), one run each: whether the run completes or ends with an error naming the node,
//! whether it ends at all, and whether its recording reads to its last chunk (#34's fault target). With `--stop S`
//! the node is SIGSTOPped for S seconds and then continued instead: a node that hangs and comes back must cost
//! nothing, so the run must complete and its recording be complete (every topic ended, nothing dropped).
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, Stdio};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use lineflow_recordings::Recording;
use lineflow_runtime::launch::{self, Resolver};

use crate::processes::node_pid;

/// Kill points as shares of the undisturbed run's time.
const POINTS: [f64; 3] = [0.2, 0.5, 0.8];

/// What one killed run did.
struct Outcome {
    /// The node's process was found and killed (else it had already finished).
    killed: bool,
    /// The run's exit status; `None` when it had to be stopped after the time limit.
    status: Option<i32>,
    /// The run's last error line names the node.
    named: bool,
    /// Messages read from the recording, and whether the read reached the file's end.
    messages: u64,
    readable: bool,
    /// Why the recording could not be read, when it could not.
    why: String,
    /// The recording says every topic ended and nothing was dropped or missed.
    complete: bool,
    seconds: f64,
}

/// What is done to the node.
#[derive(Clone, Copy)]
enum Fault {
    Kill,
    /// SIGSTOP, then SIGCONT after this long.
    Stop(Duration),
}

fn run_command(graph: &Path, sets: &[String], out: &Path) -> Result<Command> {
    let mut c = Command::new(std::env::current_exe().context("cannot find the lineflow executable")?);
    c.arg("run").arg(graph).arg("-q");
    for s in sets {
        c.args(["--set", s]);
    }
    c.arg("--out")
        .arg(out)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    Ok(c)
}

fn faulted_run(graph: &Path, sets: &[String], out: &Path, node: &str, after: Duration, fault: Fault, limit: Duration) -> Result<Outcome> {
    let start = Instant::now();
    let mut child = run_command(graph, sets, out)?.spawn().context("cannot start the run")?;
    std::thread::sleep(after);
    let pid = node_pid(child.id(), node);
    if let Some(pid) = pid {
        // SAFETY: plain signals to a process of this run.
        match fault {
            Fault::Kill => unsafe {
                libc::kill(pid, libc::SIGKILL);
            },
            Fault::Stop(pause) => {
                unsafe { libc::kill(pid, libc::SIGSTOP) };
                std::thread::sleep(pause);
                unsafe { libc::kill(pid, libc::SIGCONT) };
            }
        }
    }
    let status = loop {
        if let Some(s) = child.try_wait()? {
            break s.code();
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let stderr = child
        .stderr
        .take()
        .map(|mut e| {
            let mut s = String::new();
            let _ = std::io::Read::read_to_string(&mut e, &mut s);
            s
        })
        .unwrap_or_default();
    let named = stderr.lines().filter(|l| l.contains("error")).any(|l| l.contains(node));
    let (mut messages, mut readable, mut why, mut complete) = (0, false, String::new(), false);
    let file = out.join("recording.mcap");
    match Recording::open(&file) {
        // Killed while the supervisor was still starting the graph: no message flowed, so none can be lost.
        Err(_) if !file.exists() && stderr.contains("before the graph was connected") => {
            readable = true;
            why = "no file: nothing flowed before the kill".into();
        }
        Ok(rec) => {
            complete = rec.is_complete();
            let read = rec.for_each_message(|_| {
                messages += 1;
                Ok(())
            });
            // A file cut by the kill reads up to its last complete chunk; that is what `readable` asks.
            readable = read.is_ok() || !rec.is_finished();
            if let Err(e) = read {
                why = format!("{e:#}");
            }
        }
        Err(e) => why = format!("{e:#}"),
    }
    Ok(Outcome {
        killed: pid.is_some(),
        status,
        named,
        messages,
        readable,
        why,
        complete,
        seconds: start.elapsed().as_secs_f64(),
    })
}

/// Runs the benchmark on `graph` (with `sets`), every node at every point: SIGKILL, or SIGSTOP for `stop`.
pub fn bench_chaos(graph: &Path, sets: &[String], stop: Option<Duration>) -> Result<ExitCode> {
    let fault = stop.map_or(Fault::Kill, Fault::Stop);
    let dir = tempfile::Builder::new().prefix("lineflow-bench-chaos").tempdir()?;
    let g = launch::load(graph, sets, &Resolver::beside_current_exe())?;
    let start = Instant::now();
    let status = run_command(graph, sets, &dir.path().join("reference"))?.status()?;
    let reference = start.elapsed();
    if !status.success() {
        anyhow::bail!("the undisturbed run failed ({status})");
    }
    let what = match fault {
        Fault::Kill => "SIGKILLed".to_owned(),
        Fault::Stop(d) => format!("SIGSTOPped for {:.1} s, then continued,", d.as_secs_f64()),
    };
    println!(
        "{}: {} nodes, undisturbed run {:.1} s; each node {what} at {POINTS:?} of that time\n",
        graph.display(),
        g.nodes.len(),
        reference.as_secs_f64()
    );
    println!("| node | at | outcome | error names it | recording messages | readable | complete | s |");
    println!("|---|---|---|---|---|---|---|---|");
    let (mut cases, mut clear, mut hung, mut readable, mut complete) = (0, 0, 0, 0, 0);
    for node in &g.nodes {
        for (k, share) in POINTS.iter().enumerate() {
            let out: PathBuf = dir.path().join(format!("{}-{k}", node.name));
            let after = reference.mul_f64(*share);
            let limit = reference * 10 + Duration::from_secs(30) + stop.unwrap_or_default();
            let o = faulted_run(graph, sets, &out, &node.name, after, fault, limit)?;
            let outcome = match (o.killed, o.status) {
                (_, None) => "HUNG (stopped after 10× the run)".to_owned(),
                (false, Some(0)) => "had finished; run completed".to_owned(),
                (true, Some(0)) => "run completed".to_owned(),
                (_, Some(c)) => format!("run ended, exit {c}"),
            };
            cases += 1;
            hung += usize::from(o.status.is_none());
            clear += usize::from(o.status == Some(0) || o.named);
            readable += usize::from(o.readable);
            complete += usize::from(o.complete);
            println!(
                "| {} | {:.0} % | {outcome} | {} | {} | {} | {} | {:.1} |",
                node.name,
                share * 100.0,
                if o.status == Some(0) {
                    "-"
                } else if o.named {
                    "yes"
                } else {
                    "NO"
                },
                o.messages,
                match (o.readable, o.why.is_empty()) {
                    (true, true) => "yes".to_owned(),
                    (true, false) => format!("yes ({})", o.why),
                    (false, _) => format!("NO: {}", o.why),
                },
                if o.complete { "yes" } else { "no" },
                o.seconds
            );
        }
    }
    println!(
        "\n{cases} runs: {clear} completed or ended with an error naming the node, {hung} hung, {readable} \
         recordings readable to their last chunk, {complete} complete (every topic ended, nothing dropped)"
    );
    let ok = hung == 0
        && readable == cases
        && match fault {
            // A killed node may end the run: it must say which node, and the file must read to its last chunk.
            Fault::Kill => clear == cases,
            // A node that only paused must cost nothing.
            Fault::Stop(_) => complete == cases,
        };
    Ok(if ok { ExitCode::SUCCESS } else { ExitCode::FAILURE })
}
