//! End-to-end tests: real `lineflow` supervisors, real node processes, real iceoryx2 services, real image files.
//! Every test has its own state folder, so the run ids, iceoryx2 prefixes and output folders never collide and
//! the tests run in parallel.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Output, Stdio};
use std::time::{Duration, Instant};

use lineflow_e2e::*;
use lineflow_stats::fnv1a64;

fn direct_graph(folder: &Path, extra_capture: &str, edge_extra: &str) -> String {
    format!(
        r#"
[[node]]
name = "capture"
stage = "capture"
impl = "folder"
params = {{ folder = "{}" {extra_capture} }}

[[node]]
name = "stats"
stage = "stats"

[[edge]]
topic = "images"
type = "Image"
from = "capture"
to = ["stats"]
{edge_extra}
"#,
        folder.display()
    )
}

fn chain_graph(folder: &Path, fps: u32, history: usize) -> String {
    format!(
        r#"
[[node]]
name = "capture"
stage = "capture"
impl = "folder"
params = {{ folder = "{}", fps = {fps} }}

[[node]]
name = "gray"
stage = "convert"
impl = "gray"
restart = "on-failure"
backoff_ms = 300

[[node]]
name = "stats"
stage = "stats"
remap = {{ images = "gray" }}

[[edge]]
topic = "images"
type = "Image"
from = "capture"
to = ["gray"]
depth = 4
history = {history}

[[edge]]
topic = "gray"
type = "Image"
from = "gray"
to = ["stats"]
"#,
        folder.display()
    )
}

/// (frame, image name, checksum) rows of `frames.csv`.
fn frames(out: &Path) -> Vec<(u64, String, String)> {
    let text = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            (f[0].parse().unwrap(), f[1].to_owned(), f[6].to_owned())
        })
        .collect()
}

fn summary_row(out: &Path, node: &str) -> Vec<String> {
    let s = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    s.lines()
        .find(|l| l.split_whitespace().next() == Some(node))
        .unwrap()
        .split_whitespace()
        .map(str::to_owned)
        .collect()
}

#[test]
fn folder_capture_delivers_every_frame_once_in_order_and_byte_identical() {
    let sb = Sandbox::new();
    let folder = sb.project(12, 64, 48);
    let graph = sb.graph("g.toml", &direct_graph(&folder, "", ""));
    let out = sb.path().join("out");
    let r = sb.run(&["run", graph.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(r.status.success());
    let rows = frames(&out);
    let names: Vec<_> = (1..=12)
        .map(|k| ["png", "PNG", "jpg", "tif"][(k - 1) % 4])
        .enumerate()
        .map(|(i, ext)| format!("IMG_{}.{ext}", i + 1))
        .collect();
    assert_eq!(rows.iter().map(|r| r.0).collect::<Vec<_>>(), (0..12).collect::<Vec<_>>());
    for (row, name) in rows.iter().zip(&names) {
        assert_eq!(&row.1, name);
        let decoded = lineflow_capture::decode_file(&folder.join("images").join(name)).unwrap();
        assert_eq!(row.2, format!("{:016x}", fnv1a64(&decoded.bytes)), "{name} differs");
    }
    assert_nothing_left(&sb, &out);
}

#[test]
fn process_streams_a_folder_with_progress_and_keeps_every_nodes_log_in_its_out_folder() {
    let sb = Sandbox::new();
    let folder = sb.project(5, 80, 60);
    let graph = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../launch/folder.toml");
    let r = sb.run(&["process", folder.to_str().unwrap(), "--graph", graph.to_str().unwrap()]);
    assert!(r.status.success());
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(stderr.contains("frames in 5/5"), "no progress shown: {stderr}");
    let out = folder.join("out");
    assert_eq!(frames(&out).len(), 5);
    // The node's lines reach the terminal and its log file alike; `lineflow logs` shows the file.
    let log = std::fs::read_to_string(out.join("logs/capture.log")).unwrap();
    assert!(log.contains("[capture] INFO  5 frames published"), "capture.log: {log}");
    assert!(stderr.contains("[capture] INFO  5 frames published"));
    let shown = sb.run(&["logs", out.to_str().unwrap(), "capture"]);
    assert!(shown.status.success());
    assert_eq!(String::from_utf8_lossy(&shown.stdout), log);
    let missing = sb.run(&["logs", out.to_str().unwrap(), "no-such-node"]);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("nodes with logs: capture"));
    // -q: the summary and nothing of the nodes on the terminal, the logs kept all the same.
    let q = sb.run(&["process", folder.to_str().unwrap(), "--graph", graph.to_str().unwrap(), "-q"]);
    assert!(q.status.success());
    let quiet = String::from_utf8_lossy(&q.stderr);
    assert!(
        !quiet.contains("[capture]") && !quiet.contains("frames in") && quiet.contains("finished in"),
        "{quiet}"
    );
    assert!(std::fs::read_to_string(out.join("logs/capture.log"))
        .unwrap()
        .contains("5 frames published"));
    // --json: the summary on stdout as one object, the same as summary.json and the table.
    let j = sb.run(&[
        "process",
        folder.to_str().unwrap(),
        "--graph",
        graph.to_str().unwrap(),
        "-q",
        "--json",
    ]);
    assert!(j.status.success());
    let json: serde_json::Value = serde_json::from_slice(&j.stdout).unwrap();
    let kept: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(json, kept);
    assert_eq!(json["ok"], true);
    assert_eq!(json["run"].as_str().unwrap(), run_id(&out));
    let capture = json["nodes"].as_array().unwrap().iter().find(|n| n["name"] == "capture").unwrap();
    assert_eq!(capture["status"], "ok");
    assert_eq!(capture["out"].as_u64().unwrap().to_string(), summary_row(&out, "capture")[3]);
    assert_nothing_left(&sb, &out);
}

/// Starts the chain graph, calls `fault` with the pid of the process whose name starts with `comm` once `gray` has
/// run a while, and waits for the run to end.
fn fault_mid_run(sb: &Sandbox, history: usize, comm: &str, fault: impl FnOnce(i32)) -> (Output, PathBuf) {
    let folder = sb.project(40, 48, 32);
    let graph = sb.graph("g.toml", &chain_graph(&folder, 20, history));
    let out = sb.path().join("out");
    let child = sb.run_command(&graph, &out).stderr(Stdio::piped()).spawn().unwrap();
    let start = Instant::now();
    while children_of(child.id(), comm).is_empty() {
        assert!(start.elapsed() < Duration::from_secs(20), "{comm} never started");
        std::thread::sleep(Duration::from_millis(10));
    }
    // The first process seen may be the short-lived `--describe` run, and a fixed wait (700 ms here once) can end
    // before a loaded machine has connected the graph: gray is mid-run once a message of its own has been seen.
    while !sb.run(&["echo", "gray", "-n", "1"]).status.success() {
        assert!(start.elapsed() < Duration::from_secs(30), "gray never published");
        std::thread::sleep(Duration::from_millis(50));
    }
    let found = children_of(child.id(), comm);
    assert_eq!(found.len(), 1, "one {comm} process mid-run");
    fault(found[0] as i32);
    let r = child.wait_with_output().unwrap();
    eprintln!("{}", String::from_utf8_lossy(&r.stderr));
    (r, out)
}

/// Starts the chain graph, SIGKILLs `gray` once it has run a while, and waits for the run to end.
fn kill_gray_mid_run(sb: &Sandbox, history: usize) -> (Output, PathBuf) {
    // SAFETY: signalling a process this test started (a child of our child).
    fault_mid_run(sb, history, "lineflow-conver", |pid| unsafe {
        libc::kill(pid, libc::SIGKILL);
    })
}

/// Ctrl-Z and `fg`, a debugger, a suspended laptop: a node stopped and continued (SIGSTOP, SIGCONT) wakes from its
/// wait with EINTR, which iceoryx2's WaitSet reports as an interrupt. It must wait on, not quit as on Ctrl-C:
/// nothing is lost and the run completes.
#[test]
fn a_node_stopped_and_continued_mid_run_loses_nothing() {
    let sb = Sandbox::new();
    let (r, out) = fault_mid_run(&sb, 0, "lineflow-stats", |pid| {
        // SAFETY: signalling a process this test started (a child of our child).
        unsafe { libc::kill(pid, libc::SIGSTOP) };
        std::thread::sleep(Duration::from_millis(1500));
        unsafe { libc::kill(pid, libc::SIGCONT) };
    });
    assert!(r.status.success(), "run failed");
    for node in ["capture", "gray", "stats"] {
        let row = summary_row(&out, node);
        assert_eq!(
            (row[4].as_str(), row[9].as_str()),
            ("0", "-"),
            "{node}: drops and missed frames {row:?}"
        );
    }
    let got: Vec<u64> = frames(&out).iter().map(|r| r.0).collect();
    assert_eq!(got, (0..40).collect::<Vec<_>>(), "every frame exactly once, in order");
    assert_nothing_left(&sb, &out);
}

#[test]
fn a_killed_middle_node_is_restarted_and_misses_nothing_when_the_edge_keeps_history() {
    let sb = Sandbox::new();
    let (r, out) = kill_gray_mid_run(&sb, 64);
    assert!(r.status.success(), "run failed");
    let row = summary_row(&out, "gray");
    assert_eq!(row[8], "1", "gray restarts: {row:?}");
    assert_eq!(row[9], "-", "gray missed frames: {row:?}");
    assert_eq!(summary_row(&out, "stats")[9], "-", "stats missed frames");
    let got: Vec<u64> = frames(&out).iter().map(|r| r.0).collect();
    assert_eq!(got, (0..40).collect::<Vec<_>>(), "every frame exactly once, in order");
    assert_nothing_left(&sb, &out);
}

#[test]
fn a_killed_middle_node_without_history_names_exactly_the_frames_it_missed() {
    let sb = Sandbox::new();
    let (r, out) = kill_gray_mid_run(&sb, 0);
    assert!(r.status.success(), "run failed");
    let row = summary_row(&out, "gray");
    assert_eq!(row[8], "1");
    assert_ne!(row[9], "-", "frames were sent while gray was down; the summary must name them");
    // Every frame that did not arrive is named by the node that missed it (gray, or stats for frames lost in flight).
    let named = format!("{},{}", row[9], summary_row(&out, "stats")[9]);
    let missed: BTreeSet<u64> = named
        .split(',')
        .filter(|r| *r != "-")
        .flat_map(|r| match r.split_once('-') {
            Some((a, b)) => (a.parse::<u64>().unwrap()..=b.parse().unwrap()).collect::<Vec<_>>(),
            None => vec![r.parse().unwrap()],
        })
        .collect();
    let got: Vec<u64> = frames(&out).iter().map(|r| r.0).collect();
    assert!(got.windows(2).all(|w| w[0] < w[1]), "in order, no duplicates: {got:?}");
    let got: BTreeSet<u64> = got.into_iter().collect();
    assert!(got.is_disjoint(&missed), "a frame both missed and delivered");
    assert_eq!(
        got.union(&missed).copied().collect::<Vec<_>>(),
        (0..40).collect::<Vec<_>>(),
        "delivered + missed = all"
    );
    assert_nothing_left(&sb, &out);
}

/// Runs the chain graph (40 frames at 20 frames/s, `gray` restarted on failure) with `lineflow run --chaos`.
fn chain_with_chaos(sb: &Sandbox, history: usize, chaos: &[&str]) -> (Output, PathBuf, serde_json::Value) {
    let folder = sb.project(40, 48, 32);
    let graph = sb.graph("g.toml", &chain_graph(&folder, 20, history));
    let out = sb.path().join("out");
    let mut args = vec!["run", graph.to_str().unwrap(), "--out", out.to_str().unwrap()];
    for c in chaos {
        args.extend(["--chaos", c]);
    }
    let r = sb.run(&args);
    let summary = std::fs::read_to_string(out.join("summary.json")).map_or(serde_json::Value::Null, |t| serde_json::from_str(&t).unwrap());
    (r, out, summary)
}

/// `--chaos`: the supervisor itself kills `gray` after frame 10 and stops `stats` for a second after frame 20; with
/// history on the edge the restarted `gray` misses nothing, and the summary says both faults struck.
#[test]
fn faults_injected_by_run_chaos_strike_once_and_a_restarted_node_misses_nothing() {
    let sb = Sandbox::new();
    let (r, out, summary) = chain_with_chaos(&sb, 64, &["gray@10", "stats@20:stop=1"]);
    assert!(r.status.success(), "run failed");
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(stderr.contains("chaos: SIGKILL to 'gray' after frame 10: struck"), "{stderr}");
    assert!(
        stderr.contains("chaos: SIGSTOP to 'stats' after frame 20 for 1.0 s: struck"),
        "{stderr}"
    );
    let faults = summary["chaos"].as_array().unwrap();
    assert_eq!(faults.len(), 2);
    assert!(faults.iter().all(|f| f["struck"] == true), "{faults:?}");
    assert_eq!(faults[0]["node"], "gray");
    assert_eq!(faults[1]["stop_s"], 1.0);
    let row = summary_row(&out, "gray");
    assert_eq!(
        (row[8].as_str(), row[9].as_str()),
        ("1", "-"),
        "gray restarted once, missed nothing: {row:?}"
    );
    assert_eq!(summary_row(&out, "stats")[9], "-", "stats missed frames");
    let got: Vec<u64> = frames(&out).iter().map(|r| r.0).collect();
    assert_eq!(got, (0..40).collect::<Vec<_>>(), "every frame exactly once, in order");
    assert_nothing_left(&sb, &out);
}

/// A node without a restart policy killed by `--chaos` ends the run with an error naming it; a fault whose frame
/// never comes is reported as not struck; a fault on a node the graph lacks is refused before anything runs.
#[test]
fn run_chaos_names_the_killed_node_and_refuses_an_unknown_one() {
    let sb = Sandbox::new();
    let (r, out, summary) = chain_with_chaos(&sb, 0, &["stats@5", "gray@1000"]);
    assert!(!r.status.success());
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(stderr.contains("node 'stats' was killed by signal 9"), "{stderr}");
    assert_eq!(
        summary_row(&out, "stats")[1..3].join(" "),
        "signal 9",
        "the killed node keeps its signal in the summary"
    );
    assert!(
        stderr.contains("chaos: SIGKILL to 'gray' after frame 1000: did not strike"),
        "{stderr}"
    );
    assert_eq!(summary["chaos"][0]["struck"], true);

    let fresh = Sandbox::new();
    let (r, out, _) = chain_with_chaos(&fresh, 0, &["nosuch@3"]);
    assert_eq!(r.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(
        stderr.contains("the graph has no node 'nosuch' (its nodes: capture, gray, stats, recorder)"),
        "{stderr}"
    );
    assert!(!out.join("summary.json").exists());
    let graph = fresh.path().join("g.toml");
    let r = fresh.run(&["run", graph.to_str().unwrap(), "--chaos", "gray@x"]);
    assert_eq!(r.status.code(), Some(2), "clap's usage error");
    assert!(String::from_utf8_lossy(&r.stderr).contains("the frame is not a whole number"));
}

/// The soak benchmark's short version: the demo graph fed the synthetic camera's repeated strip past its last
/// pose, every node sampled; the figures are printed, not asserted (timing), the harness's outputs are.
#[test]
fn bench_soak_samples_every_node_of_a_repeated_stream_and_reports_the_targets() {
    let sb = Sandbox::new();
    let out = sb.path().join("soak");
    let demo = repo_file("launch/demo.toml");
    let r = sb.run(&[
        "bench",
        "soak",
        "--graph",
        demo.to_str().unwrap(),
        "--minutes",
        "0.4",
        "--fps",
        "2",
        "--scale",
        "0.06",
        "--every",
        "0.5",
        "--out",
        out.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    eprintln!("{stdout}");
    assert!(r.status.success(), "no drops");
    let csv = std::fs::read_to_string(out.join("soak.csv")).unwrap();
    let graph: toml::Table = std::fs::read_to_string(&demo).unwrap().parse().unwrap();
    let nodes: Vec<&str> = graph["node"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|n| n["name"].as_str())
        .collect();
    assert!(nodes.len() >= 10, "{nodes:?}");
    for node in nodes.iter().chain(&["recorder"]) {
        assert!(csv.lines().any(|l| l.split(',').nth(1) == Some(node)), "no samples of {node}");
        assert!(stdout.contains(&format!("| {node} |")), "no row for {node}");
    }
    assert!(stdout.contains("drops on the edges: 0 (target 0)"));
    assert!(
        stdout.contains("| private memory (MB) | private growth |"),
        "the nodes' own memory beside RSS"
    );
    assert!(stdout.contains("frame latency"));
    let svg = std::fs::read_to_string(out.join("soak.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>") && svg.matches("<polyline").count() > 10);
    // 48 frames from a strip of fewer: the camera went past its last pose with new frame numbers.
    let capture = std::fs::read_to_string(out.join("run/logs/capture.log")).unwrap();
    assert!(capture.contains("48 frames published"), "{capture}");
}

#[test]
fn a_type_mismatched_graph_is_refused_before_any_node_runs() {
    let sb = Sandbox::new();
    let folder = sb.project(2, 16, 16);
    let text = chain_graph(&folder, 0, 0).replace("topic = \"gray\"\ntype = \"Image\"", "topic = \"gray\"\ntype = \"Lines2D\"");
    let graph = sb.graph("bad.toml", &text);
    let r = sb.run(&["run", graph.to_str().unwrap(), "--out", sb.path().join("out").to_str().unwrap()]);
    assert!(!r.status.success());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("bad.toml") && err.contains("edge 'gray'") && err.contains("type mismatch"),
        "{err}"
    );
    assert!(!sb.path().join("out/frames.csv").exists(), "nothing may have run");
}

#[test]
fn bad_input_gets_one_clear_line_and_a_non_zero_exit() {
    let sb = Sandbox::new();
    let folder = sb.project(3, 16, 16);
    let graph = sb.graph("g.toml", &direct_graph(&folder, "", ""));
    let out = sb.path().join("out");
    let run = |extra: &[&str]| {
        let mut args = vec!["run", graph.to_str().unwrap(), "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        sb.run(&args)
    };
    let expect = |r: Output, needle: &str| {
        assert!(!r.status.success(), "expected failure for {needle}");
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(err.contains(needle), "expected '{needle}' in: {err}");
        assert!(!err.contains("panicked"), "{err}");
    };
    expect(run(&["--set", "capture.fsp=3"]), "unknown field `fsp`");
    expect(run(&["--set", "nobody.x=1"]), "no node 'nobody'");
    std::fs::write(folder.join("images/IMG_2.PNG"), b"\x89PNG\r\n\x1a\nnot really").unwrap();
    expect(run(&[]), "IMG_2.PNG");
    std::fs::remove_file(folder.join("images/IMG_2.PNG")).unwrap();
    image::RgbImage::new(17, 16).save(folder.join("images/IMG_2.png")).unwrap();
    expect(run(&[]), "image is 17x16 but camera.toml says 16x16");
    std::fs::write(sb.path().join("broken.toml"), "[[node]]\nname = \"a\"\nstage = ").unwrap();
    expect(sb.run(&["run", sb.path().join("broken.toml").to_str().unwrap()]), "broken.toml");
    let exits = sb.graph(
        "exits.toml",
        &direct_graph(&folder, "", "").replace("stage = \"stats\"", "executable = \"/bin/false\""),
    );
    expect(sb.run(&["run", exits.to_str().unwrap()]), "node 'stats'");
    std::fs::remove_file(folder.join("camera.toml")).unwrap();
    expect(sb.run(&["process", folder.to_str().unwrap()]), "camera.toml: missing");
}

#[test]
fn watch_mode_reads_a_jpeg_written_in_chunks_once_and_complete() {
    let sb = Sandbox::new();
    let folder = sb.project(1, 64, 48);
    let graph = sb.graph(
        "g.toml",
        &direct_graph(&folder, ", watch = true, idle_timeout_s = 20, settle_ms = 200", ""),
    );
    let out = sb.path().join("out");
    let child = sb.run_command(&graph, &out).spawn().unwrap();
    let img = image::RgbImage::from_fn(64, 48, |x, y| image::Rgb([x as u8 * 3, y as u8 * 5, 77]));
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 90)
        .encode_image(&img)
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let target = folder.join("images/IMG_2.jpg");
    {
        use std::io::Write;
        let mut f = std::fs::File::create(&target).unwrap();
        // Pauses longer than the settle time: only the JPEG trailer check keeps the half-written file unread.
        for chunk in jpeg.chunks(jpeg.len() / 3 + 1) {
            f.write_all(chunk).unwrap();
            f.flush().unwrap();
            std::thread::sleep(Duration::from_millis(600));
        }
    }
    std::thread::sleep(Duration::from_millis(800));
    std::fs::write(folder.join("STOP"), b"").unwrap();
    let r = child.wait_with_output().unwrap();
    assert!(r.status.success());
    let rows = frames(&out);
    assert_eq!(rows.iter().map(|r| r.1.as_str()).collect::<Vec<_>>(), ["IMG_1.png", "IMG_2.jpg"]);
    let decoded = lineflow_capture::decode_file(&target).unwrap();
    assert_eq!(rows[1].2, format!("{:016x}", fnv1a64(&decoded.bytes)));
}

#[test]
fn the_demo_graph_runs_the_synthetic_camera_and_gives_the_same_bytes_twice() {
    let sb = Sandbox::new();
    let demo = repo_file("launch/demo.toml");
    let mut outputs = Vec::new();
    for k in 0..2 {
        let out = sb.path().join(format!("out{k}"));
        let r = sb.run(&[
            "run",
            demo.to_str().unwrap(),
            "--set",
            "capture.scale=0.06",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(r.status.success(), "demo run {k} failed");
        let rows = frames(&out);
        assert_eq!(rows.len(), 18, "a55-two-strips has 18 frames");
        assert_eq!(rows[0].1, "IMG_0001.png");
        let report = std::fs::read_to_string(out.join("eval/report.md")).expect("the live eval node wrote no report");
        assert!(report.contains("a55-two-strips") && report.contains("18 images"), "{report}");
        assert_nothing_left(&sb, &out);
        let edges = std::fs::read_to_string(out.join("edges.csv")).unwrap();
        assert_eq!(edges.lines().count(), 19, "an edge map per frame");
        let lines = std::fs::read_to_string(out.join("lines2d.csv")).unwrap();
        assert!(
            lines.starts_with("image,id,col1,row1,col2,row2,n_pixels\n") && lines.lines().count() > 100,
            "{lines}"
        );
        assert!(report.contains("Length recall"), "the live eval scored no 2-D lines");
        if k == 0 {
            // The live sink scores each frame's 2-D lines as they come; the whole run's file, scored at once,
            // gives the same figures.
            let live: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("eval/metrics.json")).unwrap()).unwrap();
            let scene = sb.synth("scene", "a55-two-strips", "0.06");
            let r = sb.run(&["eval", out.to_str().unwrap(), "--gt", scene.to_str().unwrap(), "--json"]);
            let offline: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
            assert!(live["lines2d"]["recall"].as_f64().unwrap() > 0.0, "{live}");
            assert_eq!(live["lines2d"]["images"], offline["lines2d"]["images"]);
            // lines2d.csv keeps the endpoints to 1/1000 px.
            for key in ["recall", "precision"] {
                let (a, b) = (live["lines2d"][key].as_f64().unwrap(), offline["lines2d"][key].as_f64().unwrap());
                assert!((a - b).abs() < 1e-4, "{key}: live {a}, offline {b}");
            }
        }
        outputs.push((rows, edges + &lines));
    }
    assert_eq!(outputs[0], outputs[1], "two runs of the synthetic camera differ");
    // The tiny demo with one more parameter set, into `out`.
    let run_with = |set: &str, out: &Path| {
        sb.run(&[
            "run",
            demo.to_str().unwrap(),
            "--set",
            "capture.scale=0.06",
            "--set",
            set,
            "--out",
            out.to_str().unwrap(),
        ])
    };
    // Swapping the edge detector is a launch-file parameter.
    for detector in ["sobel", "log"] {
        let out = sb.path().join(detector);
        let r = run_with(&format!("edges.impl={detector}"), &out);
        assert!(r.status.success(), "{detector} run failed:\n{}", String::from_utf8_lossy(&r.stderr));
        let edges = std::fs::read_to_string(out.join("edges.csv")).unwrap();
        assert!(edges.lines().skip(1).all(|l| l.split(',').nth(1) == Some(detector)), "{edges}");
        assert!(!outputs[0].1.starts_with(&edges));
    }
    // Every other frame as a master: the others pass on without points, and no stage downstream misses a frame.
    let out = sb.path().join("every_other_master");
    let r = run_with("linematch.master_every=2", &out);
    let log = String::from_utf8_lossy(&r.stderr).into_owned();
    assert!(r.status.success(), "master_every run failed:\n{log}");
    let masters: usize = log
        .lines()
        .find_map(|l| {
            l.split(" masters matched")
                .next()
                .filter(|_| l.contains(" masters matched"))?
                .split_whitespace()
                .last()?
                .parse()
                .ok()
        })
        .expect("no masters line");
    assert!(masters <= 9, "{masters} masters of 18 frames:\n{log}");
    for node in ["linematch", "linefit", "model", "eval"] {
        let row = summary_row(&out, node);
        assert_eq!(row[9], "-", "{node} missed frames: {row:?}");
    }
}

/// A small synthetic project folder (`convergent` at scale 0.06, 12 images) with its ground truth.
fn small_convergent_scene(sb: &Sandbox) -> PathBuf {
    let scene = sb.path().join("scene");
    let r = sb.run(&[
        "synth",
        "--preset",
        "convergent",
        "--scale",
        "0.06",
        "--seed",
        "4",
        "--out",
        scene.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "synth failed");
    scene
}

#[test]
fn a_synth_folder_loads_through_the_folder_capture_and_evaluates() {
    let sb = Sandbox::new();
    let scene = small_convergent_scene(&sb);
    for f in std::iter::once("images/IMG_0012.png").chain(lineflow_synthetic::PROJECT_FILES) {
        assert!(scene.join(f).is_file(), "synth wrote no {f}");
    }
    let r = sb.run(&["process", scene.to_str().unwrap()]);
    assert!(r.status.success());
    assert_eq!(frames(&scene.join("out")).len(), 12);

    // The truth scores perfectly against itself.
    let results = sb.path().join("results");
    std::fs::create_dir_all(&results).unwrap();
    std::fs::copy(scene.join("gt/poses.csv"), results.join("poses.csv")).unwrap();
    std::fs::copy(scene.join("gt/lines3d.csv"), results.join("lines3d.csv")).unwrap();
    let r = sb.run(&["eval", results.to_str().unwrap(), "--gt", scene.to_str().unwrap()]);
    assert!(r.status.success());
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(
        stdout.contains("centre RMS 0.0 mm") && stdout.contains("success rate 100.0 %"),
        "{stdout}"
    );
    let report = std::fs::read_to_string(results.join("eval/report.md")).unwrap();
    assert!(report.contains("## 3-D lines") && report.contains("lines3d_front.png"));
    assert!(results.join("eval/lines3d_front.png").is_file());

    // Classing: the true edges as if each were shown by one image only. With the cameras, every edge that more
    // than one image sees is then weak, and with no strong line to turn a corner with, texture.
    let truth = std::fs::read_to_string(scene.join("gt/lines3d.csv")).unwrap();
    let weak: Vec<String> = truth
        .lines()
        .enumerate()
        .map(|(k, l)| {
            let mut cols: Vec<&str> = l.split(',').collect();
            if k > 0 {
                cols[8] = "1";
            }
            cols.join(",")
        })
        .collect();
    let weak_csv = results.join("weak.csv");
    std::fs::write(&weak_csv, weak.join("\n") + "\n").unwrap();
    let texture_count = |extra: &[&str]| -> usize {
        let out = results.join("classed.csv");
        let mut args = vec!["classify", weak_csv.to_str().unwrap(), "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let r = sb.run(&args);
        let stdout = String::from_utf8_lossy(&r.stdout).to_string();
        assert!(r.status.success(), "{stdout}{}", String::from_utf8_lossy(&r.stderr));
        figure_after(&stdout, "structure, ", "") as usize
    };
    let (poses, camera) = (scene.join("gt/poses.csv"), scene.join("camera.toml"));
    let by_field = texture_count(&[]);
    let by_support = texture_count(&["--poses", poses.to_str().unwrap(), "--camera", camera.to_str().unwrap()]);
    let n = truth.lines().count() - 1;
    assert!(
        by_field < n / 10 && by_support > n / 2,
        "{by_field} and {by_support} texture of {n}"
    );
    let x = results.join("x.csv");
    let refused = |extra: &[&str], named: &str| {
        let mut args = vec!["classify", weak_csv.to_str().unwrap(), "--out", x.to_str().unwrap(), "--poses"];
        args.push(poses.to_str().unwrap());
        args.extend_from_slice(extra);
        let r = sb.run(&args);
        assert!(
            !r.status.success() && String::from_utf8_lossy(&r.stderr).contains(named),
            "{extra:?}"
        );
    };
    refused(&[], "--camera");
    let missing = scene.join("no-camera.toml");
    refused(&["--camera", missing.to_str().unwrap()], "no-camera.toml");

    // Nothing to evaluate against: one clear line.
    let r = sb.run(&["eval", results.to_str().unwrap(), "--gt", results.to_str().unwrap()]);
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("scene.json"));
    // An unknown preset names the available ones.
    let r = sb.run(&["synth", "--preset", "nikon", "--out", sb.path().join("x").to_str().unwrap()]);
    assert!(!r.status.success() && String::from_utf8_lossy(&r.stderr).contains("d2x-strip"));
}

#[test]
fn the_features_stage_publishes_surf_keypoints_that_the_recording_keeps() {
    let sb = Sandbox::new();
    let graph = sb.graph(
        "features.toml",
        r#"
[[node]]
name = "capture"
stage = "capture"
impl = "synthetic"
params = { preset = "a55-two-strips", scale = 0.15, seed = 1, fps = 0 }

[[node]]
name = "features"
stage = "features"
impl = "surf"
params = { hessian_threshold = 50.0 }

[[edge]]
topic = "images"
type = "Image"
from = "capture"
to = ["features"]

# Recorded only: the matcher is not built yet.
[[edge]]
topic = "keypoints"
type = "Keypoints"
from = "features"
to = []
"#,
    );
    let out = sb.path().join("out");
    let r = sb.run(&["run", graph.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(r.status.success());
    let info = String::from_utf8_lossy(&sb.run(&["info", out.join("recording.mcap").to_str().unwrap()]).stdout).into_owned();
    let row = info.lines().find(|l| l.starts_with("keypoints ")).expect("keypoints recorded");
    let f: Vec<&str> = row.split_whitespace().collect();
    assert_eq!(f[1], "18", "{info}");
    // 18 frames of keypoints (24 B) with 64 float descriptors (256 B): hundreds per frame.
    let mb: f64 = f[2].parse().unwrap();
    assert!(mb > 18.0 * 100.0 * 280.0 / 1e6, "too few keypoints: {info}");
    assert!(info.contains("keypoints/annotations"), "{info}");
    let bad = sb.run(&[
        "run",
        graph.to_str().unwrap(),
        "--set",
        "features.octaves=9",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("octaves must be in 1..=6, got 9"));
}

#[test]
fn the_demo_graph_orients_both_strips_and_extracts_3d_lines_and_a_model_the_same_way_twice() {
    let sb = Sandbox::new();
    let demo = repo_file("launch/demo.toml");
    let (mut poses, mut lines, mut models) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..2 {
        let out = sb.path().join(format!("out{k}"));
        let r = sb.run(&[
            "run",
            demo.to_str().unwrap(),
            "--set",
            "capture.scale=0.3",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(r.status.success(), "demo run failed");
        let text = std::fs::read_to_string(out.join("poses.csv")).expect("no poses.csv");
        assert!(text.starts_with("image,X,Y,Z,omega_deg,phi_deg,kappa_deg,sX,sY,sZ,"), "{text}");
        assert_eq!(text.lines().count(), 19, "every frame of a55-two-strips oriented:\n{text}");
        assert!(text.contains("IMG_0018.png"), "{text}");
        let checks = std::fs::read_to_string(out.join("checkpoints.csv")).expect("no checkpoints.csv");
        let deltas: Vec<[f64; 3]> = checks
            .lines()
            .skip(1)
            .map(|l| {
                let v: Vec<f64> = l.split(',').skip(1).map(|x| x.parse().unwrap()).collect();
                [v[0], v[1], v[2]]
            })
            .collect();
        assert!(deltas.len() >= 10, "{checks}");
        // GSD of the a55 preset at scale 0.3: 6.7 mm / 0.3.
        let gsd = 0.0067 / 0.3;
        for axis in 0..3 {
            let rmse = (deltas.iter().map(|d| d[axis] * d[axis]).sum::<f64>() / deltas.len() as f64).sqrt();
            assert!(rmse < 1.5 * gsd, "check-point RMSE on axis {axis}: {rmse} m (GSD {gsd} m)");
        }
        let report = std::fs::read_to_string(out.join("eval/report.md")).unwrap();
        assert!(report.contains("| 18 | 0 |"), "the live eval saw missing poses:\n{report}");
        poses.push(text);
        let lines3d = std::fs::read_to_string(out.join("lines3d.csv")).expect("no lines3d.csv");
        assert!(lines3d.starts_with("id,X1,Y1,Z1,X2,Y2,Z2,n_points,n_images,rms_m"), "{lines3d}");
        assert!(out.join("lines3d.ply").is_file());
        // The live eval's figures for the 3-D lines (thesis, A55 at full size: 53 % success, 13-28 cm endpoints).
        let success = figure_after(&report, "### all edges", "success rate ");
        let endpoint_mm = figure_after(&report, "| endpoint perpendicular distance (mm) |", "");
        assert!(success > 50.0, "success rate {success} %:\n{report}");
        assert!(endpoint_mm < 2.0 * gsd * 1e3, "endpoint distance {endpoint_mm} mm:\n{report}");
        // Every line is classed, and the structure lines are the edges: on this brick façade (2026-11-27) 26 % of
        // them lie within 2 GSD of a true edge against 10 % of all lines, and 0.1 % of the texture lines do.
        assert!(lines3d.lines().next().unwrap().ends_with(",rms_m,class"), "{lines3d}");
        assert!(
            lines3d
                .lines()
                .skip(1)
                .all(|l| l.ends_with(",structure") || l.ends_with(",texture")),
            "unclassed lines"
        );
        let metrics: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("eval/metrics.json")).unwrap()).unwrap();
        let precision = |class: &str| {
            let c = metrics["lines3d"]["classes"]
                .as_array()
                .unwrap()
                .iter()
                .find(|c| c["class"] == class)
                .unwrap();
            let at = c["at"].as_array().unwrap().iter().find(|a| a["label"] == "2 GSD").unwrap();
            at["segment_precision"].as_f64().unwrap()
        };
        let (all, structure, texture) = (precision("all"), precision("structure lines"), precision("texture lines"));
        assert!(
            structure > 2.0 * all && texture < 0.01,
            "precision at 2 GSD: all {all}, structure {structure}, texture {texture}"
        );
        lines.push(lines3d);
        // The model stage closes the graph: a wire-frame from those lines, scored by the live eval.
        let obj = std::fs::read_to_string(out.join("model.obj")).expect("no model.obj");
        assert!(
            obj.lines().any(|l| l.starts_with("v ")) && obj.lines().any(|l| l.starts_with("l ")),
            "{obj}"
        );
        let city = std::fs::read_to_string(out.join("model.city.json")).expect("no model.city.json");
        assert!(
            city.contains("\"type\":\"CityJSON\"") && city.contains("\"version\":\"2.0\""),
            "{city}"
        );
        assert!(
            report.contains("| true vertices | model vertices |"),
            "the live eval saw no wire-frame:\n{report}"
        );
        assert!(obj.lines().any(|l| l.starts_with("f ")), "the demo model has faces:\n{obj}");
        // The model-image fit is not in the default graph (it makes façade models worse): nothing fitted.
        assert!(!out.join("model_fitted.obj").exists());
        // The live eval got the model's faces too (the `faces` topic): the openings are scored.
        assert!(
            report.contains("Openings of the CSR model:") && report.contains("of 40 true windows and doors found"),
            "{report}"
        );
        models.push(obj);
    }
    assert_eq!(poses[0], poses[1], "two runs oriented differently");
    assert!(lines[0] == lines[1], "two runs gave different 3-D lines");
    assert!(models[0] == models[1], "two runs gave different models");

    // Refine offline: the same lines with the images' 2-D lines, the camera they were measured with and the poses
    // (the 2-D lines alone confirm openings; Refine is asked for).
    let out = sb.path().join("out0");
    let camera = sb.path().join("camera.toml");
    let scene = lineflow_synthetic::Synthetic::new("a55-two-strips", 0.3, 1).unwrap();
    std::fs::write(&camera, toml_camera(&scene)).unwrap();
    let refined = sb.path().join("refined");
    let arg = |name: &str| out.join(name).to_str().unwrap().to_owned();
    let r = sb.run(&[
        "model",
        &arg("lines3d.csv"),
        "--poses",
        &arg("poses.csv"),
        "--lines2d",
        &arg("lines2d.csv"),
        "--camera",
        camera.to_str().unwrap(),
        "--out",
        refined.to_str().unwrap(),
        "--set",
        "refine=true",
    ]);
    let said = String::from_utf8_lossy(&r.stdout).into_owned();
    assert!(r.status.success(), "{said}{}", String::from_utf8_lossy(&r.stderr));
    let refined_edges = figure_after(&said, "median sigma0", ", ");
    assert!(refined_edges > 0.0, "no edge refined: {said}");
    assert!(refined.join("model.obj").is_file() && refined.join("model.city.json").is_file());
    // Without poses the images cannot be used: a clear refusal, nothing written.
    let r = sb.run(&[
        "model",
        &arg("lines3d.csv"),
        "--lines2d",
        &arg("lines2d.csv"),
        "--camera",
        camera.to_str().unwrap(),
    ]);
    assert!(!r.status.success());
}

/// The camera of a synthetic scene as `camera.toml` text.
fn toml_camera(scene: &lineflow_synthetic::Synthetic) -> String {
    toml::to_string(&lineflow_formats::project::CameraFile::of(scene.camera())).expect("camera.toml")
}

/// The first number after `marker` (then `lead`) in `text`.
fn figure_after(text: &str, marker: &str, lead: &str) -> f64 {
    let rest = &text[text.find(marker).unwrap_or_else(|| panic!("no '{marker}' in:\n{text}")) + marker.len()..];
    let rest = &rest[rest.find(lead).unwrap_or_else(|| panic!("no '{lead}' after '{marker}'")) + lead.len()..];
    let number: String = rest.trim_start().chars().take_while(|c| c.is_ascii_digit() || *c == '.').collect();
    number
        .parse()
        .unwrap_or_else(|_| panic!("no number after '{marker}' '{lead}': {}", &rest[..rest.len().min(40)]))
}

/// A node in another language that forgets its end-of-stream: it exits cleanly, its topic is left without a
/// publisher and without an end, and the node downstream must not wait for it forever (the orphan rule of
/// `docs/nodes.md`). The Python `sobel` node with its end-of-stream removed plays that node.
#[test]
fn an_input_whose_publisher_leaves_without_end_of_stream_is_ended_and_the_run_finishes() {
    let sb = Sandbox::new();
    let folder = sb.project(6, 48, 32);
    let script = std::fs::read_to_string(repo_file("nodes/python/sobel_node.py")).unwrap();
    let eos = "    publish(eos, np.zeros(0, dtype=pixel_dtype))\n";
    assert!(script.contains(eos), "the sobel node's end-of-stream line moved");
    let forgetful = sb.path().join("forgetful_sobel.py");
    std::fs::write(&forgetful, script.replace(eos, "")).unwrap();
    std::fs::set_permissions(&forgetful, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let graph = executable_edges_graph(&sb, "g.toml", &folder, &forgetful);
    let out = sb.path().join("out");
    // Without the rule the run would wait forever: bounded here so that the test fails instead of hanging.
    // The log goes to a file: a pipe nobody reads while we wait could fill up and stall the run.
    let log = sb.path().join("run.log");
    let mut child = sb
        .run_command(&graph, &out)
        .stderr(std::fs::File::create(&log).unwrap())
        .spawn()
        .unwrap();
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > Duration::from_secs(300) {
            child.kill().unwrap();
            panic!("the run did not finish: the orphaned input was never ended");
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let stderr = std::fs::read_to_string(&log).unwrap();
    eprintln!("{stderr}");
    assert!(
        status.success(),
        "the Python node failed or the run hung (CI installs numpy and iceoryx2 for Python)"
    );
    assert!(
        stderr.contains("left without end-of-stream"),
        "the orphaned input is named in the log"
    );
    // Nothing already received is lost: stats wrote every frame's edge map.
    let edges = std::fs::read_to_string(out.join("edges.csv")).unwrap();
    assert_eq!(edges.lines().count(), 1 + 6, "{edges}");
    assert_nothing_left(&sb, &out);
}

/// Poses from elsewhere (`poses.csv` in the project folder) replace the orientation stage: every frame gets the
/// given pose, the 3-D stages run on them, and the check points are intersected from them.
/// A node that never becomes ready, whether it hangs before describing its ports or after: the run ends after the
/// launch file's `connect_timeout_s`, naming the node, and leaves no process behind; what the recorder has is a
/// readable file.
#[test]
fn a_node_that_never_becomes_ready_ends_the_run_naming_it() {
    let sb = Sandbox::new();
    let folder = sb.project(3, 48, 32);
    let ports = r#"{"inputs":[{"port":"images","message":"Image","required":true}],"outputs":[]}"#;
    for (case, script) in [
        ("mute", "#!/bin/sh\nexec sleep 6011\n".to_owned()),
        (
            "stuck",
            format!("#!/bin/sh\nif [ \"$LINEFLOW_DESCRIBE\" = 1 ]; then echo '{ports}'; exit 0; fi\nexec sleep 6012\n"),
        ),
    ] {
        let exe = sb.path().join(format!("{case}.sh"));
        std::fs::write(&exe, script).unwrap();
        std::fs::set_permissions(&exe, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
        let graph = sb.graph(
            &format!("{case}.toml"),
            &format!(
                "[graph]\nconnect_timeout_s = 3\n\n[[node]]\nname = \"capture\"\nstage = \"capture\"\nimpl = \"folder\"\n\
                 params = {{ folder = \"{}\" }}\n\n[[node]]\nname = \"{case}\"\nexecutable = \"{}\"\n\n[[edge]]\n\
                 topic = \"images\"\ntype = \"Image\"\nfrom = \"capture\"\nto = [\"{case}\"]\n",
                folder.display(),
                exe.display()
            ),
        );
        let out = sb.path().join(case);
        let start = Instant::now();
        let r = sb.run(&["run", graph.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success(), "{err}");
        assert!(start.elapsed() < Duration::from_secs(60), "the timeout held: {:?}", start.elapsed());
        let why = if case == "mute" {
            "did not describe its ports"
        } else {
            "not connected after"
        };
        assert!(err.contains(case) && err.contains(why), "{err}");
        let left: Vec<String> = std::fs::read_dir("/proc")
            .unwrap()
            .flatten()
            .filter_map(|e| std::fs::read(e.path().join("cmdline")).ok())
            .map(|c| String::from_utf8_lossy(&c).replace('\0', " "))
            .filter(|c| c.starts_with("sleep 601"))
            .collect();
        assert!(left.is_empty(), "a node was left running: {left:?}");
        if case == "stuck" {
            let info = sb.run(&["info", out.join("recording.mcap").to_str().unwrap()]);
            assert!(info.status.code().is_some_and(|c| c == 0 || c == 2), "the recording opens");
        }
    }
    let bad = sb.graph(
        "bad.toml",
        "[graph]\nconnect_timeout_s = -1\n[[node]]\nname = \"a\"\nstage = \"stats\"\n",
    );
    let err = String::from_utf8_lossy(&sb.run(&["run", bad.to_str().unwrap()]).stderr).into_owned();
    assert!(
        err.contains("connect_timeout_s") && err.contains("positive number of seconds"),
        "{err}"
    );
}

/// Too few open files (every port holds shared-memory and event files; the recorder subscribes to every topic): a
/// soft limit below what the demo graph needs is raised to the hard one and the run completes; a hard limit that
/// low ends the run with the failing node's own error and the limit named.
#[test]
fn a_low_limit_of_open_files_is_raised_or_named() {
    let sb = Sandbox::new();
    let demo = repo_file("launch/demo.toml");
    let run = |soft_only: bool, out: &str| {
        let mut cmd = sb.lineflow(&["run", demo.to_str().unwrap(), "--set", "capture.scale=0.06", "--out", out, "-q"]);
        // SAFETY: only setrlimit, which is async-signal-safe, between fork and exec.
        unsafe {
            std::os::unix::process::CommandExt::pre_exec(&mut cmd, move || {
                let mut r = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
                libc::getrlimit(libc::RLIMIT_NOFILE, &mut r);
                r.rlim_cur = 100;
                if !soft_only {
                    r.rlim_max = 100;
                }
                libc::setrlimit(libc::RLIMIT_NOFILE, &r);
                Ok(())
            });
        }
        cmd.output().unwrap()
    };
    let raised = run(true, sb.path().join("soft").to_str().unwrap());
    assert!(raised.status.success(), "{}", String::from_utf8_lossy(&raised.stderr));
    let capped = run(false, sb.path().join("hard").to_str().unwrap());
    let err = String::from_utf8_lossy(&capped.stderr);
    assert!(!capped.status.success(), "{err}");
    assert!(err.contains("open files are limited to 100") && err.contains("] error: "), "{err}");
}

#[test]
fn poses_supplied_with_the_project_replace_the_orientation() {
    let sb = Sandbox::new();
    let scene = small_convergent_scene(&sb);
    std::fs::copy(scene.join("gt/poses.csv"), scene.join("poses.csv")).unwrap();
    let r = sb.run(&["process", scene.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{stderr}");
    assert!(stderr.contains("in place of the orientation stage"), "{stderr}");
    let out = scene.join("out");
    // The poses written are the ones given: the truth scores perfectly.
    let r = sb.run(&["eval", out.to_str().unwrap(), "--gt", scene.to_str().unwrap()]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success() && stdout.contains("centre RMS 0.0 mm"), "{stdout}");
    // The same figures as one JSON object, and in the report folder.
    let r = sb.run(&["eval", out.to_str().unwrap(), "--gt", scene.to_str().unwrap(), "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert!(json["orientation"]["rms_center_m"].as_f64().unwrap() < 1e-4, "{json}");
    assert!(json["lines3d"]["classes"][0]["success_rate"].is_number(), "{json}");
    let kept: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(out.join("eval/metrics.json")).unwrap()).unwrap();
    assert_eq!(kept, json);
    let checks = std::fs::read_to_string(out.join("checkpoints.csv")).unwrap();
    assert!(checks.lines().count() > 1, "{checks}");
    assert!(out.join("lines3d.csv").is_file());

    // A malformed poses file: one clear line naming it, a non-zero exit.
    std::fs::write(scene.join("poses.csv"), "image,X\nIMG_0001.png,abc\n").unwrap();
    let r = sb.run(&[
        "process",
        scene.to_str().unwrap(),
        "--out",
        sb.path().join("out2").to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success());
    assert!(stderr.contains("poses.csv"), "{stderr}");
}

/// Root-mean-square per axis of the deltas in a `checkpoints.csv`, and their number.
fn checkpoint_rmse(text: &str) -> ([f64; 3], usize) {
    let deltas: Vec<Vec<f64>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').skip(1).take(3).map(|x| x.parse().unwrap()).collect())
        .collect();
    let n = deltas.len().max(1) as f64;
    let rmse = std::array::from_fn(|k| (deltas.iter().map(|d| d[k] * d[k]).sum::<f64>() / n).sqrt());
    (rmse, deltas.len())
}

#[test]
fn the_second_detector_and_the_essential_matrix_orientation_swap_in_from_the_command_line() {
    let sb = Sandbox::new();
    let graph = sb.graph(
        "orient.toml",
        r#"
[[node]]
name = "capture"
stage = "capture"
impl = "synthetic"
params = { preset = "d2x-strip", scale = 0.25, seed = 1, fps = 0 }

[[node]]
name = "gray"
stage = "convert"
impl = "gray"

[[node]]
name = "features"
stage = "features"
impl = "surf"
remap = { images = "gray" }

[[node]]
name = "matcher"
stage = "matcher"
impl = "ratio"
remap = { images = "gray" }

[[node]]
name = "orientation"
stage = "orientation"
impl = "bundle"

[[edge]]
topic = "images"
type = "Image"
from = "capture"
to = ["gray", "orientation"]

[[edge]]
topic = "gray"
type = "Image"
from = "gray"
to = ["features", "matcher"]

[[edge]]
topic = "camera"
type = "CameraModel"
from = "capture"
to = ["matcher", "orientation"]

[[edge]]
topic = "keypoints"
type = "Keypoints"
from = "features"
to = ["matcher"]

[[edge]]
topic = "tiepoints"
type = "TiePoints"
from = "matcher"
to = ["orientation"]

[[edge]]
topic = "control_points"
type = "ControlPoints"
from = "capture"
to = ["orientation"]

[[edge]]
topic = "observations"
type = "Observations"
from = "capture"
to = ["orientation"]

[[edge]]
topic = "poses"
type = "Poses"
from = "orientation"
to = []
"#,
    );
    let out = sb.path().join("out");
    let r = sb.run(&[
        "run",
        graph.to_str().unwrap(),
        "--set",
        "features.impl=orb",
        "--set",
        "orientation.impl=essential",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "run failed");
    let log = String::from_utf8_lossy(&r.stderr);
    assert!(log.contains("final transformation"), "the essential impl did not run:\n{log}");
    let poses = std::fs::read_to_string(out.join("poses.csv")).expect("no poses.csv");
    assert_eq!(poses.lines().count(), 34, "every frame of the strip oriented:\n{poses}");
    let (rmse, n) = checkpoint_rmse(&std::fs::read_to_string(out.join("checkpoints.csv")).expect("no checkpoints.csv"));
    // GSD of the d2x-strip preset at scale 0.25: 6.3 mm / 0.25. The chain without adjustment stays within 2 GSD.
    let gsd = 0.0063 / 0.25;
    eprintln!("orb + essential: check-point RMSE {rmse:?} m over {n} points (GSD {gsd} m)");
    assert!(n >= 10 && rmse.iter().all(|&r| r < 2.0 * gsd), "check-point RMSE {rmse:?} m");
    let info = String::from_utf8_lossy(&sb.run(&["info", out.join("recording.mcap").to_str().unwrap()]).stdout).into_owned();
    assert!(info.lines().any(|l| l.starts_with("keypoints ")), "{info}");
    // An unknown implementation names the available ones.
    let bad = sb.run(&[
        "run",
        graph.to_str().unwrap(),
        "--set",
        "features.impl=sift",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("available: surf, orb"));
}

/// `lineflow run` started on a project of `frames` small images with a watching capture, which keeps the run alive
/// until it is stopped or killed; its output folder.
fn start_watching_run(sb: &Sandbox, frames: usize) -> (std::process::Child, PathBuf) {
    let folder = sb.project(frames, 16, 16);
    let graph = sb.graph("g.toml", &direct_graph(&folder, ", watch = true, idle_timeout_s = 120.0", ""));
    let out = sb.path().join("out");
    let child = sb.run_command(&graph, &out).stderr(Stdio::null()).spawn().unwrap();
    (child, out)
}

/// A process has ended: gone from /proc, or a zombie waiting for whoever adopted it.
fn ended(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .map(|stat| stat.rfind(')').is_some_and(|b| stat[b + 2..].starts_with('Z')))
        .unwrap_or(true)
}

#[test]
fn nodes_whose_supervisor_is_killed_stop_within_seconds_and_the_recording_stays_readable() {
    let sb = Sandbox::new();
    let (mut child, out) = start_watching_run(&sb, 3);
    let start = Instant::now();
    let nodes = loop {
        let up = ["lineflow-stats", "lineflow-captur", "lineflow-record"]
            .iter()
            .all(|n| !children_of(child.id(), n).is_empty());
        if up {
            // Past the `--describe` runs, connected, and the three frames through.
            std::thread::sleep(Duration::from_millis(1500));
            break children_of(child.id(), "lineflow");
        }
        assert!(start.elapsed() < Duration::from_secs(60), "the run never got going");
        std::thread::sleep(Duration::from_millis(50));
    };
    // Only the supervisor dies (a closed terminal, an out-of-memory kill): its nodes are left without anyone to
    // stop them.
    // SAFETY: signalling a process this test started.
    unsafe { libc::kill(child.id() as i32, libc::SIGKILL) };
    let _ = child.wait();
    let killed = Instant::now();
    while !nodes.iter().all(|&pid| ended(pid)) {
        assert!(
            killed.elapsed() < Duration::from_secs(15),
            "nodes still running 15 s after their supervisor was killed: {:?}",
            nodes.iter().filter(|&&pid| !ended(pid)).collect::<Vec<_>>()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    // The recorder closed its file as on SIGTERM: every frame is in it, and the independent reader agrees.
    let info = sb.run(&["info", out.join("recording.mcap").to_str().unwrap()]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(info.status.success(), "{text}{}", String::from_utf8_lossy(&info.stderr));
    let images = text
        .lines()
        .find(|l| l.starts_with("images "))
        .unwrap_or_else(|| panic!("no images topic:\n{text}"));
    assert_eq!(images.split_whitespace().nth(1), Some("3"), "{text}");
    let _ = sb.run(&["doctor", "--fix"]);
}

#[test]
fn doctor_finds_what_a_killed_run_left_and_fix_removes_it() {
    let sb = Sandbox::new();
    let (mut child, _out) = start_watching_run(&sb, 2);
    let runs = sb.path().join("state/runs");
    let start = Instant::now();
    let id = loop {
        let id = std::fs::read_dir(&runs)
            .into_iter()
            .flatten()
            .flatten()
            .find_map(|e| e.file_name().to_str().map(str::to_owned));
        let nodes_up = !children_of(child.id(), "lineflow-stats").is_empty() && !children_of(child.id(), "lineflow-captur").is_empty();
        if let Some(id) = id.filter(|id| nodes_up && !shm_files(id).is_empty()) {
            // Past the `--describe` runs: the nodes proper are connected.
            std::thread::sleep(Duration::from_millis(500));
            break id;
        }
        assert!(start.elapsed() < Duration::from_secs(30), "the run never got going");
        std::thread::sleep(Duration::from_millis(50));
    };
    // The supervisor and every node die at once, as in a power cut or `kill -9` of the process group.
    let nodes = children_of(child.id(), "lineflow");
    for pid in nodes.iter().copied().chain([child.id()]) {
        // SAFETY: signalling processes this test started.
        unsafe { libc::kill(pid as i32, libc::SIGKILL) };
    }
    let _ = child.wait();
    std::thread::sleep(Duration::from_millis(200));
    assert!(!shm_files(&id).is_empty(), "the killed run left nothing to clean up");

    let report = sb.run(&["doctor"]);
    let text = String::from_utf8_lossy(&report.stdout);
    assert_eq!(report.status.code(), Some(2), "stale runs are a finding:\n{text}");
    assert!(
        text.contains(&format!("run {id}: stale")) && text.contains("supervisor died"),
        "{text}"
    );
    assert!(text.contains("free"), "{text}");

    let fixed = sb.run(&["doctor", "--fix"]);
    assert!(fixed.status.success(), "{}", String::from_utf8_lossy(&fixed.stdout));
    assert!(String::from_utf8_lossy(&fixed.stdout).contains("removed"));
    assert!(shm_files(&id).is_empty(), "doctor --fix left files of run {id} in /dev/shm");
    assert!(!runs.join(&id).exists(), "doctor --fix left the run's folder");
    let again = sb.run(&["doctor"]);
    assert!(again.status.success() && String::from_utf8_lossy(&again.stdout).contains("no stale runs"));
}

/// Without a site model the walls come from the tie points. The orientation works in a frame of its own until it
/// has seen three control points, then georeferences the block: the walls fitted before, and the masters matched
/// against them, are redone in the survey's frame, so every master is matched and the lines are in place.
#[test]
fn without_a_site_model_the_walls_are_fitted_to_the_tie_points_in_the_surveys_frame() {
    let sb = Sandbox::new();
    let scene = sb.synth("scene", "d2x-strip", "0.3");
    std::fs::remove_file(scene.join("site.toml")).unwrap();
    let r = sb.run(&["process", scene.to_str().unwrap()]);
    let log = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{log}");
    assert!(log.contains("walls fitted to the tie points"), "{log}");
    let matched = log
        .lines()
        .find(|l| l.contains("masters matched"))
        .expect("no summary of linematch");
    let masters: usize = matched.split_whitespace().nth(2).and_then(|n| n.parse().ok()).expect("a count");
    // Frame 0 matches no neighbour at this scale and stays unoriented (docs/orientation.md); the other 32 are
    // masters. Walls fitted in the orientation's own frame left 10 of them matched, in the wrong place.
    assert!(masters >= 30, "every oriented frame a master: {matched}\n{log}");
    let r = sb.run(&["eval", scene.join("out").to_str().unwrap(), "--gt", scene.to_str().unwrap()]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{stdout}");
    // 69.9 % with the site model, 69.3 % without (release build, 2026-11-25).
    let success = figure_after(&stdout, "3-D lines:", "success rate ");
    assert!(success > 60.0, "{stdout}");
}

/// Runs `graph` with the capture at scale 0.15 into `out`. The run must succeed, each of `nodes` finish ok with no
/// frame missed, and nothing be left in shared memory.
fn run_small(sb: &Sandbox, graph: &Path, out: &Path, nodes: &[&str]) {
    let r = sb.run(&[
        "run",
        graph.to_str().unwrap(),
        "--set",
        "capture.scale=0.15",
        "--out",
        out.to_str().unwrap(),
    ]);
    let log = String::from_utf8_lossy(&r.stderr).into_owned();
    assert!(r.status.success(), "{} failed:\n{log}", graph.display());
    for node in nodes {
        let row = summary_row(out, node);
        assert_eq!(row[1], "ok", "{node}: {row:?}");
        assert_eq!(row[9], "-", "{node} missed frames: {row:?}");
    }
    assert_nothing_left(sb, out);
}

#[test]
fn the_modelfit_graph_fits_the_model_to_the_images_the_same_way_twice() {
    let sb = Sandbox::new();
    let graph = repo_file("launch/demo-modelfit.toml");
    let mut fits = Vec::new();
    for k in 0..2 {
        let out = sb.path().join(format!("out{k}"));
        run_small(&sb, &graph, &out, &["model", "modelfit", "eval"]);
        let obj = std::fs::read_to_string(out.join("model.obj")).expect("no model.obj");
        // The modelfit stage fits the wire-frame to every image's edge pixels (seed 004), scored too.
        let fitted = std::fs::read_to_string(out.join("model_fitted.obj")).expect("no model_fitted.obj");
        assert_eq!(
            fitted.lines().filter(|l| l.starts_with("v ")).count(),
            obj.lines().filter(|l| l.starts_with("v ")).count(),
            "the fitted model keeps the model's vertices"
        );
        // ... and its faces (the `faces` topic), written by the same code: each face group and its faces. (The
        // edges' groups differ: the `wireframe` topic tells hidden edges from seen ones, not inferred from
        // observed, so the fitted model writes its inferred edges with the observed.)
        let faces = |text: &str| {
            let lines: Vec<&str> = text.lines().collect();
            lines
                .iter()
                .enumerate()
                .filter(|(k, l)| l.starts_with("f ") || (l.starts_with("g ") && lines.get(k + 1).is_some_and(|n| n.starts_with("f "))))
                .map(|(_, l)| l.to_string())
                .collect::<Vec<_>>()
        };
        assert!(obj.lines().any(|l| l.starts_with("f ")), "the model has faces to keep:\n{obj}");
        assert_eq!(faces(&fitted), faces(&obj), "the fitted model's faces");
        assert!(out.join("model_fitted.city.json").is_file());
        let report = std::fs::read_to_string(out.join("eval/report.md")).unwrap();
        assert!(report.contains("| fitted to the images (`model_fitted.obj`) |"), "{report}");
        fits.push(fitted);
    }
    assert!(fits[0] == fits[1], "two runs gave different fitted models");
}

#[test]
fn the_linemap_graph_maps_3d_lines_from_every_image_the_same_way_twice() {
    let sb = Sandbox::new();
    let graph = repo_file("launch/demo-linemap.toml");
    let mut lines = Vec::new();
    for k in 0..2 {
        let out = sb.path().join(format!("out{k}"));
        // Every frame gets a set: the stage publishes once a frame's 2-D lines are in, and the final set.
        run_small(&sb, &graph, &out, &["linemap", "model", "eval"]);
        let lines3d = std::fs::read_to_string(out.join("lines3d.csv")).expect("no lines3d.csv");
        assert!(lines3d.starts_with("id,X1,Y1,Z1,X2,Y2,Z2,n_points,n_images,rms_m"), "{lines3d}");
        assert!(lines3d.lines().count() > 20, "few lines:\n{lines3d}");
        assert!(lines3d.lines().next().unwrap().ends_with(",class"), "linemap classes its lines");
        assert!(out.join("lines3d.ply").is_file());
        let report = std::fs::read_to_string(out.join("eval/report.md")).unwrap();
        // At this scale (about 640 px wide, GSD 4.5 cm) the stage found 26 % of the edges on 2026-11-26 (24 %
        // before the appearance test); a broken stage finds none.
        let success = figure_after(&report, "### all edges", "success rate ");
        assert!(success > 20.0, "success rate {success} %:\n{report}");
        assert!(
            out.join("model.obj").is_file(),
            "the model stage built nothing from linemap's lines"
        );
        lines.push(lines3d);
    }
    assert_eq!(lines[0], lines[1], "two runs of the linemap graph differ");
}

#[test]
fn completions_and_man_pages_cover_every_command() {
    let sb = Sandbox::new();
    let r = sb.run(&["completions", "bash"]);
    assert!(r.status.success());
    let script = String::from_utf8_lossy(&r.stdout);
    for command in ["run", "process", "replay", "echo", "logs", "ps", "stop", "eval"] {
        assert!(script.contains(command), "bash completion lacks '{command}'");
    }
    assert!(!sb.run(&["completions", "tcsh"]).status.success(), "an unknown shell is refused");
    let man = sb.path().join("man");
    assert!(sb.run(&["man", "--out", man.to_str().unwrap()]).status.success());
    let page = std::fs::read_to_string(man.join("lineflow-run.1")).unwrap();
    assert!(page.contains(r"\-\-json") && page.contains(".TH lineflow-run"), "{page}");
    assert!(man.join("lineflow.1").is_file() && man.join("lineflow-bench-linemap.1").is_file());
}

#[test]
fn a_dev_shm_too_small_for_the_graph_is_named_before_anything_starts() {
    // A private mount namespace with a 2 MiB /dev/shm (needs the right to mount; where it is missing, the test says
    // so and passes: the check itself is the same code either way).
    let sb = Sandbox::new();
    let out = sb.path().join("small-shm");
    let lineflow = sb.lineflow(&[
        "run",
        repo_file("launch/demo.toml").to_str().unwrap(),
        "--set",
        "capture.scale=0.06",
        "--out",
        out.to_str().unwrap(),
    ]);
    let mut cmd = std::process::Command::new("unshare");
    cmd.args(["-m", "sh", "-c", "mount -t tmpfs -o size=2m tmpfs /dev/shm && exec \"$0\" \"$@\""])
        .arg(lineflow.get_program())
        .args(lineflow.get_args())
        .stdin(Stdio::null());
    for (k, v) in lineflow.get_envs() {
        if let Some(v) = v {
            cmd.env(k, v);
        }
    }
    let probe = std::process::Command::new("unshare")
        .args(["-m", "sh", "-c", "mount -t tmpfs -o size=2m tmpfs /dev/shm"])
        .status();
    if !probe.is_ok_and(|s| s.success()) {
        eprintln!("SKIPPED: no private mount namespace here");
        return;
    }
    let r = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(
        err.contains("of shared memory but /dev/shm has only") && err.contains("free"),
        "the error names /dev/shm and the sizes: {err}"
    );
    assert!(!out.join("recording.mcap").exists(), "nothing started");
}
