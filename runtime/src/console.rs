//! The run at the terminal: every node's output relayed line by line above one progress line (never into it), and
//! kept in `OUT/logs/NODE.log`, so that a run's logs outlive the terminal and `lineflow logs` can show them.
use std::fs::File;
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

/// The folder, inside a run's output folder, holding one log file per node.
pub const LOGS_DIR: &str = "logs";

/// The log file of node `node` of the run whose output folder is `out`.
pub fn log_path(out: &Path, node: &str) -> PathBuf {
    out.join(LOGS_DIR).join(format!("{node}.log"))
}

/// Starts a run's logs afresh: the log files of an earlier run into the same output folder are removed (the
/// instances of one run, restarts included, append to theirs).
pub fn clear_logs(out: &Path) {
    let _ = std::fs::remove_dir_all(out.join(LOGS_DIR));
}

/// What the terminal shows: node lines and, below them, the progress line.
pub struct Console {
    state: Mutex<State>,
}

struct State {
    /// stderr is a terminal: the progress line is redrawn in place; otherwise it is printed now and then.
    tty: bool,
    /// Node lines are shown (off with `-q`: they go to the log files only).
    echo: bool,
    /// The progress line on screen, empty when none.
    bar: String,
}

/// Where a relayed line came from.
#[derive(Clone, Copy)]
enum Stream {
    Out,
    Err,
}

impl Console {
    /// A console on this process's stderr; `echo`: show the nodes' lines (they are always written to the logs).
    pub fn new(echo: bool) -> Arc<Self> {
        use std::io::IsTerminal;
        Arc::new(Self {
            state: Mutex::new(State {
                tty: std::io::stderr().is_terminal(),
                echo,
                bar: String::new(),
            }),
        })
    }

    fn state(&self) -> std::sync::MutexGuard<'_, State> {
        // A panic while printing leaves nothing inconsistent: the state is a string and two flags.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Whether the progress line is redrawn in place (a terminal) rather than printed as lines.
    pub fn is_tty(&self) -> bool {
        self.state().tty
    }

    fn line(&self, stream: Stream, text: &str) {
        let s = self.state();
        if !s.echo {
            return;
        }
        let mut err = std::io::stderr().lock();
        if s.tty && !s.bar.is_empty() {
            let _ = write!(err, "\r\x1b[K");
        }
        // Write errors are ignored: a closed terminal must not stop the run (the log files still get every line).
        match stream {
            Stream::Err => {
                let _ = writeln!(err, "{text}");
            }
            Stream::Out => {
                let _ = err.flush();
                let mut out = std::io::stdout().lock();
                let _ = writeln!(out, "{text}");
                let _ = out.flush();
            }
        }
        if s.tty && !s.bar.is_empty() {
            let _ = write!(err, "{}", s.bar);
        }
        let _ = err.flush();
    }

    /// Shows `text` as the progress line: redrawn in place on a terminal, else printed as a line of its own.
    pub fn progress(&self, text: &str) {
        let mut s = self.state();
        let mut err = std::io::stderr().lock();
        if s.tty {
            let _ = write!(err, "\r{text}\x1b[K");
            s.bar = text.to_owned();
        } else {
            let _ = writeln!(err, "{text}");
        }
        let _ = err.flush();
    }

    /// Ends the progress line: what follows starts on a line of its own.
    pub fn end_progress(&self) {
        let mut s = self.state();
        if s.tty && !s.bar.is_empty() {
            let _ = writeln!(std::io::stderr());
        }
        s.bar.clear();
    }
}

/// Relays a spawned node's stdout and stderr (both must be piped): every line is appended to `log` (when it can be
/// opened) and shown on `console`. The threads end when the node's ends of the pipes close, at its exit; join them
/// before printing anything that must come after the node's last line.
pub fn relay(child: &mut std::process::Child, log: &Path, console: &Arc<Console>) -> Vec<JoinHandle<()>> {
    let file = open_log(log).map(|f| Arc::new(Mutex::new(f)));
    let mut threads = Vec::new();
    let streams: [(Option<Box<dyn Read + Send>>, Stream); 2] = [
        (child.stdout.take().map(|s| Box::new(s) as Box<dyn Read + Send>), Stream::Out),
        (child.stderr.take().map(|s| Box::new(s) as Box<dyn Read + Send>), Stream::Err),
    ];
    for (pipe, stream) in streams {
        let Some(pipe) = pipe else { continue };
        let (file, console) = (file.clone(), Arc::clone(console));
        threads.push(std::thread::spawn(move || pump(pipe, stream, file.as_deref(), &console)));
    }
    threads
}

fn open_log(path: &Path) -> Option<File> {
    let opened = path
        .parent()
        .map_or(Ok(()), std::fs::create_dir_all)
        .and_then(|()| File::options().create(true).append(true).open(path));
    match opened {
        Ok(f) => Some(f),
        Err(e) => {
            tracing::warn!("cannot keep the node's log in {}: {e}", path.display());
            None
        }
    }
}

fn pump(pipe: impl Read, stream: Stream, file: Option<&Mutex<File>>, console: &Console) {
    let mut reader = BufReader::new(pipe);
    let mut buf = Vec::new();
    loop {
        buf.clear();
        match reader.read_until(b'\n', &mut buf) {
            Ok(0) => return,
            Ok(_) => {}
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(_) => return,
        }
        if let Some(f) = file {
            let _ = f.lock().unwrap_or_else(PoisonError::into_inner).write_all(&buf);
        }
        let text = String::from_utf8_lossy(&buf);
        console.line(stream, text.trim_end_matches(['\n', '\r']));
    }
}

/// How far one node has come: frames received on its inputs (the highest frame number plus one), or all of them
/// once it has finished.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeProgress {
    /// Node name.
    pub name: String,
    /// Frames received so far.
    pub frames: u64,
    /// Whether the node has finished its work.
    pub finished: bool,
    /// Whether the node's inputs tell how far the run is: not a source (it has none; its consumers tell), nor the
    /// recorder (it hears every topic and ends last by design).
    pub tracked: bool,
}

/// Stages named on the progress line as behind, at most.
const BEHIND_SHOWN: usize = 3;

/// The progress line of a run: frames in (the furthest node), the stages behind it with their counts (the slowest
/// first), an ETA from the slowest stage's rate, and, once every frame is in everywhere, the stages still working.
/// `total`: the frames the source will produce, when known.
pub fn progress_line(nodes: &[NodeProgress], total: Option<u64>, elapsed: Duration) -> String {
    let secs = elapsed.as_secs_f64();
    let clock = |s: f64| {
        let s = s.round() as u64;
        format!("{}:{:02}", s / 60, s % 60)
    };
    let working: Vec<&NodeProgress> = nodes.iter().filter(|n| n.tracked && !n.finished).collect();
    let furthest = nodes.iter().filter(|n| n.tracked).map(|n| n.frames).max().unwrap_or(0);
    let of_total = |n: u64| total.map_or(n.to_string(), |t| format!("{}/{t}", n.min(t)));
    let mut line = format!("[lineflow] {}  frames in {}", clock(secs), of_total(furthest));
    let slowest = working.iter().min_by_key(|n| n.frames);
    let all_in = total.is_some_and(|t| working.iter().all(|n| n.frames >= t));
    match (slowest, total) {
        (None, _) => {}
        (Some(_), Some(_)) if all_in => {
            let names: Vec<&str> = working.iter().map(|n| n.name.as_str()).collect();
            line += &format!("  finishing: {}", names.join(", "));
        }
        (Some(s), _) => {
            let mut behind: Vec<&&NodeProgress> = working.iter().filter(|n| n.frames < furthest).collect();
            behind.sort_by_key(|n| n.frames);
            if behind.is_empty() {
                behind.push(s);
            }
            let shown: Vec<String> = behind
                .iter()
                .take(BEHIND_SHOWN)
                .map(|n| format!("{} {}", n.name, n.frames))
                .collect();
            let more = behind.len().saturating_sub(BEHIND_SHOWN);
            line += &format!(
                "  behind: {}{}",
                shown.join(", "),
                if more > 0 { format!(" +{more}") } else { String::new() }
            );
            if let Some(t) = total {
                let eta = if s.frames > 0 && secs > 0.0 {
                    clock(t.saturating_sub(s.frames) as f64 * secs / s.frames as f64)
                } else {
                    "?".into()
                };
                line += &format!("  ETA {eta}");
            }
        }
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(name: &str, frames: u64, finished: bool) -> NodeProgress {
        NodeProgress {
            name: name.into(),
            frames,
            finished,
            tracked: true,
        }
    }

    #[test]
    fn the_line_names_the_stages_behind_and_the_eta_not_the_frames_captured() {
        let nodes = [
            node("features", 18, false),
            node("orientation", 12, false),
            node("linemap", 6, false),
            node("recorder", 18, false),
        ];
        let line = progress_line(&nodes, Some(18), Duration::from_secs(60));
        assert_eq!(
            line,
            "[lineflow] 1:00  frames in 18/18  behind: linemap 6, orientation 12  ETA 2:00"
        );
    }

    #[test]
    fn with_every_frame_in_the_line_says_which_stages_are_still_working() {
        let nodes = [node("features", 18, true), node("linemap", 18, false), node("model", 18, false)];
        let line = progress_line(&nodes, Some(18), Duration::from_secs(75));
        assert_eq!(line, "[lineflow] 1:15  frames in 18/18  finishing: linemap, model");
    }

    #[test]
    fn without_a_known_total_there_is_no_eta() {
        let source = NodeProgress {
            tracked: false,
            ..node("capture", 0, false)
        };
        let nodes = [source, node("features", 4, false), node("orientation", 3, false)];
        let line = progress_line(&nodes, None, Duration::from_secs(5));
        assert_eq!(line, "[lineflow] 0:05  frames in 4  behind: orientation 3");
    }
}
