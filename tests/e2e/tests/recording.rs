//! End-to-end tests of recording and replay on the demo graph (the default pipeline, at test scale):
//! record, replay and `diff` equal, swap a stage on replay, decode with Python's `mcap`, and the faults
//! (Ctrl-C, a killed recorder, truncated and foreign files, a full disk).
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::{Duration, Instant};

use lineflow_e2e::*;

const SCALE: &str = "capture.scale=0.06";

fn demo() -> PathBuf {
    repo_file("launch/demo.toml")
}

fn stdout(o: &std::process::Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Runs the demo graph into `out` with extra `--set`s; returns its recording.
fn record_demo(sb: &Sandbox, out: &Path, sets: &[&str]) -> PathBuf {
    let graph = demo();
    let mut args = vec!["run", graph.to_str().unwrap(), "--set", SCALE];
    for s in sets {
        args.extend(["--set", s]);
    }
    args.extend(["--out", out.to_str().unwrap()]);
    let r = sb.run(&args);
    assert!(r.status.success(), "demo run failed");
    out.join("recording.mcap")
}

/// `lineflow replay REC --rerun` with `--set`s into `out`; whether it succeeded.
fn rerun(sb: &Sandbox, rec: &Path, sets: &[&str], out: &Path) -> bool {
    let mut args = vec!["replay", rec.to_str().unwrap(), "--rerun"];
    for s in sets {
        args.extend(["--set", s]);
    }
    args.extend(["--out", out.to_str().unwrap()]);
    sb.run(&args).status.success()
}

/// The topics `lineflow diff` reports as differing, and its whole output.
fn differing(sb: &Sandbox, a: &Path, b: &Path) -> (Vec<String>, String) {
    let text = stdout(&sb.run(&["diff", a.to_str().unwrap(), b.to_str().unwrap()]));
    let topics = text
        .lines()
        .filter_map(|l| l.strip_prefix("DIFFERS  "))
        .map(|l| l.split(':').next().unwrap().to_owned())
        .collect();
    (topics, text)
}

#[test]
fn a_demo_recording_replays_byte_for_byte_swaps_a_stage_and_decodes_in_python() {
    let sb = Sandbox::new();
    let rec = record_demo(&sb, &sb.path().join("live"), &[]);
    let info = sb.run(&["info", rec.to_str().unwrap()]);
    assert!(info.status.success());
    let text = stdout(&info);
    assert!(text.contains("status:    complete"), "{text}");
    for topic in [
        "images",
        "gray",
        "edges",
        "lines2d",
        "camera",
        "gt/poses",
        "gt/lines3d",
        "images/preview",
    ] {
        assert!(
            text.lines().any(|l| l.starts_with(&format!("{topic} "))),
            "{topic} missing:\n{text}"
        );
    }
    // The same as one JSON object.
    let json: serde_json::Value = serde_json::from_str(&stdout(&sb.run(&["info", "--json", rec.to_str().unwrap()]))).unwrap();
    assert_eq!(json["complete"], true, "{json}");
    let topics = json["topics"].as_array().unwrap();
    let gray = topics.iter().find(|t| t["topic"] == "gray").expect("gray in the JSON");
    let line = text.lines().find(|l| l.starts_with("gray ")).unwrap();
    assert_eq!(
        gray["messages"].as_u64().unwrap().to_string(),
        line.split_whitespace().nth(1).unwrap(),
        "{line}"
    );
    assert_eq!(gray["schema"], "lineflow_msgs/msg/Image");

    // The same graph on the recorded source topics: every derived topic byte for byte the same. The re-run records
    // its images as PNG, which `diff` compares as the images they restore.
    let again = sb.path().join("again");
    assert!(rerun(&sb, &rec, &["record.images=\"png\""], &again), "rerun failed");
    let png_rec = again.join("recording.mcap");
    let d = sb.run(&["diff", rec.to_str().unwrap(), png_rec.to_str().unwrap()]);
    assert!(d.status.success(), "replay differs:\n{}", stdout(&d));
    assert!(stdout(&d).contains("recordings are equal on all 17 topics"), "{}", stdout(&d));
    assert_eq!(
        std::fs::read(sb.path().join("live/lines2d.csv")).unwrap(),
        std::fs::read(again.join("lines2d.csv")).unwrap()
    );
    let info = stdout(&sb.run(&["info", png_rec.to_str().unwrap()]));
    assert!(
        info.contains("lineflow_msgs/msg/CompressedImage") && info.contains("status:    complete"),
        "{info}"
    );
    let size = |p: &Path| std::fs::metadata(p).unwrap().len();
    assert!(
        size(&png_rec) < size(&rec),
        "a PNG recording is smaller: {} vs {}",
        size(&png_rec),
        size(&rec)
    );
    // A PNG recording replays as the raw one did.
    let third = sb.path().join("third");
    assert!(rerun(&sb, &png_rec, &[], &third), "rerun of the PNG recording failed");
    let d = sb.run(&["diff", rec.to_str().unwrap(), third.join("recording.mcap").to_str().unwrap()]);
    assert!(d.status.success(), "a PNG recording's replay differs:\n{}", stdout(&d));

    // Sobel instead of Canny on replay: only the edge topic and what follows from it differ.
    let swapped = sb.path().join("sobel");
    assert!(rerun(&sb, &rec, &["edges.impl=sobel"], &swapped), "swapped rerun failed");
    let d = sb.run(&["diff", rec.to_str().unwrap(), swapped.join("recording.mcap").to_str().unwrap()]);
    assert_eq!(d.status.code(), Some(1), "a swapped detector must differ");
    let (topics, text) = differing(&sb, &rec, &swapped.join("recording.mcap"));
    assert_eq!(topics, ["edges", "lines2d"], "{text}");
    assert!(text.contains("field 'detector' differs"), "{text}");

    // An independent reader: Python's mcap decodes every channel from the embedded schemas and checks the
    // messages against the run's CSV files and the PNG files of the same scene.
    let scene = sb.synth("scene", "a55-two-strips", "0.06");
    // The same for the re-run that recorded its images as PNG files.
    for (recording, out) in [(&rec, sb.path().join("live")), (&png_rec, again.clone())] {
        let py = std::process::Command::new(lineflow_e2e::python())
            .arg(repo_file("tests/e2e/check_recording.py"))
            .args([recording, &out, &scene.join("images")])
            .output()
            .expect("python3");
        eprintln!("{}{}", stdout(&py), String::from_utf8_lossy(&py.stderr));
        assert!(py.status.success(), "the Python check failed on {}", recording.display());
    }

    // Export gives the formats of conventions.md back.
    let exported = sb.path().join("exported");
    let r = sb.run(&[
        "export",
        rec.to_str().unwrap(),
        "--topic",
        "lines2d",
        "--out",
        exported.to_str().unwrap(),
    ]);
    assert!(r.status.success());
    let mut a: Vec<String> = std::fs::read_to_string(exported.join("lines2d.csv"))
        .unwrap()
        .lines()
        .map(str::to_owned)
        .collect();
    let mut b: Vec<String> = std::fs::read_to_string(sb.path().join("live/lines2d.csv"))
        .unwrap()
        .lines()
        .map(str::to_owned)
        .collect();
    a.sort();
    b.sort();
    assert_eq!(a, b);
    let r = sb.run(&[
        "export",
        rec.to_str().unwrap(),
        "--topic",
        "images",
        "--out",
        exported.to_str().unwrap(),
    ]);
    assert!(r.status.success());
    let png = image::open(exported.join("IMG_0001.png")).unwrap().to_rgb8();
    assert_eq!(png, image::open(scene.join("images/IMG_0001.png")).unwrap().to_rgb8());
}

fn wait_for_child(pid: u32, prefix: &str) -> u32 {
    let start = Instant::now();
    loop {
        let found = children_of(pid, prefix);
        if let Some(&p) = found.first() {
            return p;
        }
        assert!(start.elapsed() < Duration::from_secs(30), "{prefix} never started");
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn ctrl_c_finishes_a_valid_recording_and_a_killed_recorder_leaves_a_recoverable_one() {
    let sb = Sandbox::new();
    // Slow enough (5 frames/s) to be caught mid-run.
    for (signal, name) in [(libc::SIGINT, "sigint"), (libc::SIGKILL, "sigkill")] {
        let out = sb.path().join(name);
        let child = sb
            .lineflow(&[
                "run",
                demo().to_str().unwrap(),
                "--set",
                "capture.scale=0.15",
                "--set",
                "capture.fps=5",
                "--out",
                out.to_str().unwrap(),
            ])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        wait_for_child(child.id(), "lineflow-record");
        // Mid-run with a few complete chunks (4 MiB each) written, however slow the machine is today.
        let start = Instant::now();
        let written = || std::fs::metadata(out.join("recording.mcap")).map_or(0, |m| m.len());
        while written() < 12 << 20 && start.elapsed() < Duration::from_secs(60) {
            std::thread::sleep(Duration::from_millis(50));
        }
        // The first recorder process seen may have been the short `--describe` run; ask again.
        let target = if signal == libc::SIGINT {
            child.id()
        } else {
            wait_for_child(child.id(), "lineflow-record")
        };
        // SAFETY: signalling processes this test started.
        unsafe { libc::kill(target as i32, signal) };
        let r = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&r.stderr);
        eprintln!("{err}");
        assert!(!r.status.success(), "{name}: an interrupted run is not a success");
        let rec = out.join("recording.mcap");
        let info = sb.run(&["info", rec.to_str().unwrap()]);
        let text = stdout(&info);
        if signal == libc::SIGINT {
            assert!(info.status.success(), "after Ctrl-C the recording is finished:\n{text}");
            assert!(text.contains("incomplete: interrupted"), "{text}");
        } else {
            assert!(err.contains("recorder"), "the run names the dead recorder: {err}");
            assert_eq!(info.status.code(), Some(2), "{text}");
            assert!(text.contains("recorder did not finish"), "{text}");
            let fixed = out.join("fixed.mcap");
            let r = sb.run(&["recover", rec.to_str().unwrap(), "--out", fixed.to_str().unwrap()]);
            assert!(r.status.success());
            let text = stdout(&sb.run(&["info", fixed.to_str().unwrap()]));
            assert!(text.contains("incomplete: recovered"), "{text}");
            let images: u64 = text
                .lines()
                .find(|l| l.starts_with("images "))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|n| n.parse().ok())
                .unwrap_or(0);
            assert!(images >= 2, "the complete chunks before the kill hold frames:\n{text}");
            // The recovered file replays through the graph.
            let again = out.join("again");
            let r = sb.run(&["replay", fixed.to_str().unwrap(), "--rerun", "--out", again.to_str().unwrap()]);
            assert!(r.status.success(), "a recovered recording replays");
            let frames = std::fs::read_to_string(again.join("frames.csv")).unwrap();
            assert_eq!(frames.lines().count() as u64, images + 1);
        }
    }
}

#[test]
fn foreign_truncated_and_unwritable_recordings_get_clear_errors() {
    let sb = Sandbox::new();
    let junk = sb.path().join("junk.mcap");
    std::fs::write(&junk, b"PK\x03\x04 certainly not an MCAP file").unwrap();
    for cmd in [
        &["info"][..],
        &["replay", "--max"][..],
        &["export", "--topic", "images", "--out", "x"][..],
    ] {
        let mut args = vec![cmd[0], junk.to_str().unwrap()];
        args.extend(&cmd[1..]);
        let r = sb.run(&args);
        assert_eq!(r.status.code(), Some(1));
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(err.contains("not an MCAP file") && !err.contains("panicked"), "{err}");
    }
    let rec = record_demo(&sb, &sb.path().join("live"), &[]);
    let bytes = std::fs::read(&rec).unwrap();
    let cut = sb.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let r = sb.run(&["diff", rec.to_str().unwrap(), cut.to_str().unwrap()]);
    assert_eq!(r.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&r.stderr).contains("the recording was not finished"));
    // `info` trusts a finished file's summary; `--verify` reads every chunk and finds a flipped byte in one.
    let mut flipped = bytes.clone();
    flipped[bytes.len() / 2] ^= 0x5a;
    let bad = sb.path().join("flipped.mcap");
    std::fs::write(&bad, &flipped).unwrap();
    let r = sb.run(&["info", bad.to_str().unwrap()]);
    assert!(r.status.success() && stdout(&r).contains("chunks:    not read"), "{}", stdout(&r));
    let r = sb.run(&["info", bad.to_str().unwrap(), "--verify"]);
    assert_eq!(r.status.code(), Some(2), "{}", stdout(&r));
    assert!(stdout(&r).contains("CORRUPT"), "{}", stdout(&r));
    let r = sb.run(&["export", rec.to_str().unwrap(), "--topic", "nope", "--out", "x"]);
    assert!(String::from_utf8_lossy(&r.stderr).contains("no topic 'nope' (topics: "));
    // A disk that is full from the start (the recording's name linked to /dev/full): the run stops before any
    // frame flows, naming the file and the cause.
    let full = sb.path().join("full");
    std::fs::create_dir_all(&full).unwrap();
    std::os::unix::fs::symlink("/dev/full", full.join("full.mcap")).unwrap();
    let run_with = |set: &str, out: &Path| {
        sb.run(&[
            "run",
            demo().to_str().unwrap(),
            "--set",
            SCALE,
            "--set",
            set,
            "--out",
            out.to_str().unwrap(),
        ])
    };
    let r = run_with("record.file=\"full.mcap\"", &full);
    assert!(!r.status.success());
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(err.contains("full.mcap") && err.contains("No space left on device"), "{err}");
    // A launch file cannot have the recorder write outside the run's output folder.
    for outside in ["../outside.mcap", "/tmp/outside.mcap"] {
        let r = run_with(&format!("record.file=\"{outside}\""), &sb.path().join("confined"));
        let err = String::from_utf8_lossy(&r.stderr);
        assert!(!r.status.success() && err.contains("a file name without a folder"), "{err}");
    }
    assert!(!sb.path().join("outside.mcap").exists());
}

#[test]
fn recordings_larger_than_the_reader_holds_are_read_in_bounded_memory() {
    // The benchmark's own measurement at a size a test can afford: 17 frames of 12 MP (620 MB). Reading the whole
    // file into memory, as the reader once did, would peak above the file's size.
    let sb = Sandbox::new();
    let r = sb.run(&["bench", "reader", "--gb", "0.6", "--json", "--dir", sb.path().to_str().unwrap()]);
    let out = stdout(&r);
    let v: serde_json::Value = serde_json::from_str(out.trim()).unwrap_or_else(|e| panic!("{e}: {out}"));
    let file_mb = v["file_mb"].as_f64().unwrap();
    assert!(file_mb > 600.0, "{v}");
    assert_eq!(v["exported_files"], v["frames"], "one PNG per thumbnail: {v}");
    for case in v["cases"].as_array().unwrap() {
        let peak = case["peak_rss_mb"].as_f64().unwrap();
        assert!(case["success"].as_bool().unwrap(), "{case}");
        // The largest message is a 37 MB frame: a streaming reader holds it about twice, never the file.
        assert!(peak > 1.0 && peak < file_mb / 4.0, "{case}");
    }
    assert!(
        v["cases"][0]["peak_rss_mb"].as_f64().unwrap() < 40.0,
        "`info` reads only the summary: {v}"
    );
}

/// A 6 MiB tmpfs (room for one 4 MiB chunk and a part of the next) at a fresh folder, unmounted on drop; `None`
/// where mounting is not permitted.
struct SmallDisk(PathBuf);

impl SmallDisk {
    fn mount(at: PathBuf) -> Option<Self> {
        std::fs::create_dir_all(&at).ok()?;
        let ok = std::process::Command::new("mount")
            .args(["-t", "tmpfs", "-o", "size=6m", "tmpfs"])
            .arg(&at)
            .stderr(Stdio::null())
            .status()
            .is_ok_and(|s| s.success());
        ok.then_some(Self(at))
    }
}

impl Drop for SmallDisk {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount").arg(&self.0).status();
    }
}

#[test]
fn a_disk_that_fills_mid_run_stops_the_run_and_keeps_what_was_written() {
    let sb = Sandbox::new();
    let Some(disk) = SmallDisk::mount(sb.path().join("small-disk")) else {
        // Mounting needs CAP_SYS_ADMIN; the case of a disk full from the start runs everywhere (above).
        eprintln!("SKIPPED: cannot mount a tmpfs here");
        return;
    };
    // The recording's name links to a file on a 6 MiB disk; the run writes 10 MB.
    let out = sb.path().join("full-mid-run");
    std::fs::create_dir_all(&out).unwrap();
    std::os::unix::fs::symlink(disk.0.join("recording.mcap"), out.join("recording.mcap")).unwrap();
    let r = sb.run(&["run", demo().to_str().unwrap(), "--set", SCALE, "--out", out.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success(), "a full disk ends the run: {err}");
    assert!(err.contains("recording.mcap") && err.contains("No space left on device"), "{err}");
    // What reached the disk is readable and recoverable.
    let cut = disk.0.join("recording.mcap");
    let info = sb.run(&["info", cut.to_str().unwrap()]);
    assert_eq!(info.status.code(), Some(2), "{}", stdout(&info));
    let fixed = sb.path().join("fixed.mcap");
    let r = sb.run(&["recover", cut.to_str().unwrap(), "--out", fixed.to_str().unwrap()]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let text = stdout(&sb.run(&["info", fixed.to_str().unwrap()]));
    let messages: u64 = text
        .lines()
        .find_map(|l| l.strip_prefix("duration:"))
        .and_then(|l| l.split(", ").nth(1))
        .and_then(|m| m.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or(0);
    assert!(messages > 0, "the chunks written before the disk filled are kept:\n{text}");
}

#[test]
fn a_recording_split_into_files_reads_and_replays_as_one() {
    let sb = Sandbox::new();
    let rec = record_demo(&sb, &sb.path().join("split"), &["record.max_file_mb=1"]);
    let second = sb.path().join("split/recording.001.mcap");
    assert!(second.exists(), "the recorder moved on to a second file");
    let info = stdout(&sb.run(&["info", rec.to_str().unwrap()]));
    assert!(info.contains(" files)") && info.contains("status:    complete"), "{info}");
    // Re-run on the set: the player reads every file in order.
    let again = sb.path().join("again");
    assert!(
        rerun(&sb, &rec, &["record.max_file_mb=0"], &again),
        "rerun of a split recording failed"
    );
    let d = sb.run(&["diff", rec.to_str().unwrap(), again.join("recording.mcap").to_str().unwrap()]);
    assert!(d.status.success(), "{}", stdout(&d));
    // A file missing from the middle of the set is named; `info` exits with status 2.
    std::fs::remove_file(&second).unwrap();
    let r = sb.run(&["info", rec.to_str().unwrap()]);
    assert_eq!(r.status.code(), Some(2), "{}", stdout(&r));
    assert!(
        stdout(&r).contains("recording.001.mcap of the split recording is missing"),
        "{}",
        stdout(&r)
    );
}

#[test]
fn a_recording_plays_back_for_viewers_until_ctrl_c() {
    let sb = Sandbox::new();
    let rec = record_demo(&sb, &sb.path().join("live"), &[]);
    let player = sb
        .lineflow(&["replay", rec.to_str().unwrap(), "--loop", "--rate", "4"])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // `echo` attaches to the newest running run of the sandbox: the playback.
    let start = Instant::now();
    let lines = loop {
        let r = sb.run(&["echo", "lines2d", "-n", "3"]);
        if r.status.success() {
            break stdout(&r);
        }
        assert!(start.elapsed() < Duration::from_secs(30), "the playback never became attachable");
        std::thread::sleep(Duration::from_millis(200));
    };
    assert_eq!(lines.lines().filter(|l| l.starts_with("lines2d: frame")).count(), 3, "{lines}");
    // The fields by name, from the schema: the header's stamp, and the segments' count with the first ones.
    assert!(lines.contains("\"stamp\": {") && lines.contains("\"count\": "), "{lines}");
    let json = stdout(&sb.run(&["echo", "lines2d", "-n", "1", "--json", "--elements", "2"]));
    let v: serde_json::Value = serde_json::from_str(json.trim()).unwrap_or_else(|e| panic!("{e}: {json}"));
    assert_eq!(v["topic"], "lines2d");
    assert!(v["stamp"]["frame"].is_u64(), "{v}");
    let segments = v
        .as_object()
        .unwrap()
        .values()
        .find(|x| x.get("count").is_some())
        .expect("a sequence");
    assert!(
        segments["count"].as_u64().unwrap() > 0 && segments["first"].as_array().unwrap().len() == 2,
        "{v}"
    );
    // `topics` lists what the player publishes; `hz` measures a topic's rate (its value is not asserted: timing).
    let topics = stdout(&sb.run(&["topics"]));
    for t in ["images", "lines2d", "tiepoints", "camera"] {
        assert!(topics.lines().any(|l| l.starts_with(&format!("{t} "))), "{t} missing:\n{topics}");
    }
    let hz = sb.run(&["hz", "lines2d", "--seconds", "2"]);
    assert!(
        hz.status.success() && stdout(&hz).contains("lines2d:") && stdout(&hz).contains("Hz"),
        "{}",
        stdout(&hz)
    );
    // `record` attaches to the running playback and records two topics, the images as PNG, until the run ends.
    let attached = sb.path().join("attached.mcap");
    let recorder = sb
        .lineflow(&[
            "record",
            "--topic",
            "lines2d",
            "--topic",
            "images",
            "--images",
            "png",
            "--out",
            attached.to_str().unwrap(),
        ])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_secs(3));
    // `ps` lists the playback; `stop` ends it as Ctrl-C would.
    let ps = stdout(&sb.run(&["ps", "--json"]));
    let runs: Vec<serde_json::Value> = ps.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(runs.len(), 1, "{ps}");
    assert_eq!(runs[0]["pid"], player.id(), "{ps}");
    let id = runs[0]["id"].as_str().unwrap().to_owned();
    assert!(stdout(&sb.run(&["ps"])).lines().any(|l| l.starts_with(&id)));
    let stopped = sb.run(&["stop", &id]);
    assert!(stopped.status.success(), "{}", String::from_utf8_lossy(&stopped.stderr));
    let r = player.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(
        err.contains("player") && !err.contains("[player] error"),
        "the player stops cleanly on Ctrl-C: {err}"
    );
    assert!(stdout(&sb.run(&["ps"])).contains("no lineflow run is running"));
    let r = recorder.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    // The stopped player ends its topics, which ends the attached recording.
    assert!(r.status.success() && err.contains("messages of 2 topics"), "{err}");
    let info = stdout(&sb.run(&["info", attached.to_str().unwrap(), "--json"]));
    let v: serde_json::Value = serde_json::from_str(info.trim()).unwrap_or_else(|e| panic!("{e}: {info}"));
    let topic = |name: &str| v["topics"].as_array().unwrap().iter().find(|t| t["topic"] == name).cloned();
    assert!(topic("lines2d").unwrap()["messages"].as_u64().unwrap() > 0, "{v}");
    assert_eq!(topic("images").unwrap()["schema"], "lineflow_msgs/msg/CompressedImage", "{v}");
    assert!(topic("tiepoints").is_none(), "only the chosen topics: {v}");
    assert!(v["status"].as_str().unwrap().contains("attached to a running run"), "{v}");
    assert!(!sb.run(&["stop", &id]).status.success(), "a run that ended cannot be stopped");
}

#[test]
fn a_recorded_launch_file_that_starts_programs_is_not_rerun_without_consent() {
    let sb = Sandbox::new();
    let folder = sb.project(4, 48, 32);
    let graph = executable_edges_graph(&sb, "g.toml", &folder, &repo_file("nodes/python/sobel_node.py"));
    let live = sb.path().join("live");
    let r = sb.run(&["run", graph.to_str().unwrap(), "--out", live.to_str().unwrap()]);
    assert!(r.status.success(), "the Python node's run failed");
    let rec = live.join("recording.mcap");
    // A recording from someone else can name any program in its launch file. Without a terminal to ask on, the
    // re-run refuses, names the program and starts nothing.
    let refused = sb.path().join("refused");
    let r = sb.run(&["replay", rec.to_str().unwrap(), "--rerun", "--out", refused.to_str().unwrap()]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success(), "{err}");
    assert!(err.contains("sobel_node.py") && err.contains("--yes"), "{err}");
    assert!(!refused.join("recording.mcap").exists(), "nothing was started");
    // With consent it runs; a launch file of the user's own (--graph) needs none.
    let again = sb.path().join("again");
    let r = sb.run(&[
        "replay",
        rec.to_str().unwrap(),
        "--rerun",
        "--yes",
        "--out",
        again.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let own = sb.path().join("own");
    let args = [
        "replay",
        rec.to_str().unwrap(),
        "--rerun",
        "--graph",
        graph.to_str().unwrap(),
        "--out",
        own.to_str().unwrap(),
    ];
    assert!(sb.run(&args).status.success());
    assert_eq!(
        std::fs::read(again.join("edges.csv")).unwrap(),
        std::fs::read(own.join("edges.csv")).unwrap(),
        "the same graph on the same frames"
    );
}

#[test]
fn the_python_sobel_node_swaps_in_on_replay_and_matches_the_rust_sobel() {
    let sb = Sandbox::new();
    let rec = record_demo(&sb, &sb.path().join("live"), &[]);
    let py = sb.path().join("python");
    let rs = sb.path().join("rust");
    // Relative executables are taken from the launch file's folder (launch/).
    let python = ["edges.executable=\"../nodes/python/sobel_node.py\"", "edges.threshold=100.0"];
    assert!(rerun(&sb, &rec, &python, &py), "the Python node failed");
    // The Python node takes the grey image's gradient, not the colour channels'.
    assert!(rerun(&sb, &rec, &["edges.impl=sobel", "edges.color=\"off\""], &rs));
    // The same edge pixels frame by frame, hence the same 2-D lines downstream.
    let counts = |dir: &Path| -> Vec<String> {
        std::fs::read_to_string(dir.join("edges.csv"))
            .unwrap()
            .lines()
            .map(|l| {
                let f: Vec<&str> = l.split(',').collect();
                format!("{},{}", f[0], f[2])
            })
            .collect()
    };
    assert_eq!(counts(&py), counts(&rs));
    assert_eq!(
        std::fs::read(py.join("lines2d.csv")).unwrap(),
        std::fs::read(rs.join("lines2d.csv")).unwrap()
    );
    // Against the recorded Canny run, only the swapped stage's topic and what follows from it differ.
    let (topics, text) = differing(&sb, &rec, &py.join("recording.mcap"));
    assert_eq!(topics, ["edges", "lines2d"], "{text}");
}

#[test]
fn lsd_swaps_in_for_the_line_tracing_on_replay() {
    let sb = Sandbox::new();
    let rec = record_demo(&sb, &sb.path().join("live"), &[]);
    let out = sb.path().join("lsd");
    assert!(rerun(&sb, &rec, &["lines2d.impl=lsd"], &out), "lsd rerun failed");
    let (topics, text) = differing(&sb, &rec, &out.join("recording.mcap"));
    assert_eq!(topics, ["lines2d"], "{text}");
    let rows = std::fs::read_to_string(out.join("lines2d.csv")).unwrap();
    assert!(rows.lines().count() > 18 * 5, "LSD found few segments:\n{rows}");
    let report = std::fs::read_to_string(out.join("eval/report.md")).unwrap();
    assert!(report.contains("Length recall"), "{report}");
}
