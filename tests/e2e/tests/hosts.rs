//! End-to-end tests of one graph on two hosts (`docs/hosts.md`), on one machine: two supervisors with their own
//! iceoryx2 roots, their bridges talking Zenoh over 127.0.0.1. The demo graph split in two gives the bytes of a
//! run on one host, its recording replays on one host, and a host whose supervisor dies ends the other's run with
//! an error naming it.
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use lineflow_e2e::*;

const SCALE: &str = "capture.scale=0.06";
/// The capture and the 2-D stages run on the camera's host; orientation, the 3-D stages, eval and the recorder on
/// the main one.
const ON_CAMERA: [&str; 5] = ["capture", "gray", "stats", "edges", "lines2d"];

/// A port nobody listens on now.
fn free_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// The demo graph on one host, into `one`: what a split run must give.
fn one_host_demo(sb: &Sandbox, one: &Path, extra: &[&str]) {
    let graph = repo_file("launch/demo.toml");
    let mut args = vec!["run", graph.to_str().unwrap(), "--set", SCALE, "--out", one.to_str().unwrap()];
    for s in extra {
        args.extend(["--set", s]);
    }
    let r = sb.run(&args);
    assert!(r.status.success(), "the one-host run failed");
}

/// The demo graph with two hosts: `main` listening on `port`, `camera` connecting to it.
fn two_host_demo(sb: &Sandbox, port: u16) -> PathBuf {
    let demo = std::fs::read_to_string(repo_file("launch/demo.toml")).unwrap();
    let hosts = format!("\n[hosts.main]\nlisten = [\"tcp/127.0.0.1:{port}\"]\n\n[hosts.camera]\n");
    sb.graph("demo-two-hosts.toml", &(demo + &hosts))
}

/// `lineflow run GRAPH --host HOST` with the split's `--set`s and `extra`, into `out`.
fn start_host(sb: &Sandbox, graph: &Path, host: &str, out: &Path, extra: &[&str]) -> Child {
    start_host_with(sb, graph, host, out, extra, &[])
}

/// As [`start_host`], with more arguments of `lineflow run` (`--chaos`).
fn start_host_with(sb: &Sandbox, graph: &Path, host: &str, out: &Path, extra: &[&str], more: &[&str]) -> Child {
    let mut args = vec![
        "run",
        graph.to_str().unwrap(),
        "--host",
        host,
        "--out",
        out.to_str().unwrap(),
        "--set",
        SCALE,
    ];
    let sets: Vec<String> = ON_CAMERA.iter().map(|n| format!("{n}.host=camera")).collect();
    for s in sets.iter().map(String::as_str).chain(extra.iter().copied()) {
        args.extend(["--set", s]);
    }
    args.extend(more);
    // To a file, not a pipe: a pipe nobody reads while the other host runs would fill and stall this one.
    let log = std::fs::File::create(log_of(out)).unwrap();
    sb.lineflow(&args)
        .env("LINEFLOW_STATE_DIR", state_of(sb, host))
        .stdout(Stdio::null())
        .stderr(log)
        .spawn()
        .unwrap()
}

/// Each host's supervisor keeps its runs in a state folder of its own, as on two machines.
fn state_of(sb: &Sandbox, host: &str) -> PathBuf {
    sb.path().join(format!("state-{host}"))
}

/// Where a host's terminal output goes.
fn log_of(out: &Path) -> PathBuf {
    out.with_extension("stderr")
}

/// The split demo at one frame a second, both hosts started and the camera's host past `n` images (lines2d.csv
/// grows as the frames come, a row per segment, the image first): the run is mid-stream. The two supervisors and
/// their output folders.
fn both_hosts_mid_stream(sb: &Sandbox, n: usize) -> (Child, Child, PathBuf, PathBuf) {
    let graph = two_host_demo(sb, free_port());
    let (main_out, camera_out) = (sb.path().join("main"), sb.path().join("camera"));
    let slow = ["capture.fps=1"];
    let main = start_host(sb, &graph, "main", &main_out, &slow);
    let camera = start_host(sb, &graph, "camera", &camera_out, &slow);
    let start = Instant::now();
    let images = |f: String| {
        f.lines()
            .skip(1)
            .filter_map(|l| l.split(',').next().map(str::to_owned))
            .collect::<BTreeSet<_>>()
            .len()
    };
    while std::fs::read_to_string(camera_out.join("lines2d.csv")).map_or(0, images) < n {
        assert!(start.elapsed() < Duration::from_secs(120), "the two hosts never got going");
        std::thread::sleep(Duration::from_millis(100));
    }
    (main, camera, main_out, camera_out)
}

/// Waits for a host's supervisor: whether it succeeded, and what it printed.
fn finish(mut child: Child, out: &Path) -> (bool, String) {
    let ok = child.wait().unwrap().success();
    let err = std::fs::read_to_string(log_of(out)).unwrap_or_default();
    eprintln!("--- {}\n{err}", out.display());
    (ok, err)
}

#[test]
fn the_demo_split_over_two_hosts_gives_the_bytes_of_one_host_and_its_recording_replays_on_one() {
    let sb = Sandbox::new();
    let graph = two_host_demo(&sb, free_port());
    let (main_out, camera_out) = (sb.path().join("main"), sb.path().join("camera"));
    // The camera's host first: its bridge waits for the main host to appear. Images cross as PNG, lossless.
    let png = ["bridge.images=png"];
    let camera = start_host(&sb, &graph, "camera", &camera_out, &png);
    std::thread::sleep(Duration::from_millis(500));
    let main = start_host(&sb, &graph, "main", &main_out, &png);
    let (main_ok, main_err) = finish(main, &main_out);
    let (camera_ok, camera_err) = finish(camera, &camera_out);
    assert!(main_ok && camera_ok, "a host failed:\n{main_err}\n{camera_err}");
    for (host, out) in [("main", &main_out), ("camera", &camera_out)] {
        assert_nothing_left_in(&state_of(&sb, host), out);
    }
    // Each host ran its own part, with a bridge.
    let summary = |out: &Path| std::fs::read_to_string(out.join("summary.txt")).unwrap();
    let (m, c) = (summary(&main_out), summary(&camera_out));
    assert!(c.contains("capture") && c.contains("bridge") && !c.contains("orientation"), "{c}");
    assert!(
        m.contains("orientation") && m.contains("recorder") && !m.lines().any(|l| l.starts_with("capture ")),
        "{m}"
    );
    // The main host's summary has the camera's nodes too, as its bridge reported them.
    for node in ON_CAMERA {
        assert!(m.contains(&format!("camera/{node} ")), "no row of camera/{node}:\n{m}");
    }
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(main_out.join("summary.json")).unwrap()).unwrap();
    let capture = &json["hosts"][0]["nodes"][0];
    assert_eq!(
        (&json["hosts"][0]["host"], &capture["name"]),
        (&"camera".into(), &"capture".into()),
        "{json}"
    );
    assert_eq!(capture["finished"], true, "{json}");
    assert!(capture["msgs_out"].as_u64().unwrap() > 0, "{json}");
    for (text, host) in [(&m, "main"), (&c, "camera")] {
        for row in text
            .lines()
            .skip_while(|l| !l.starts_with("node "))
            .skip(1)
            .take_while(|l| !l.trim().is_empty() && !l.starts_with('('))
        {
            let cols: Vec<&str> = row.split_whitespace().collect();
            assert_eq!((cols[4], cols[6]), ("0", "0"), "a drop or a missed frame on host {host}: {row}");
        }
    }

    // The same graph on one host.
    let one = sb.path().join("one");
    one_host_demo(&sb, &one, &[]);
    let (rec_one, rec_two) = (one.join("recording.mcap"), main_out.join("recording.mcap"));
    let d = sb.run(&["diff", rec_one.to_str().unwrap(), rec_two.to_str().unwrap()]);
    assert!(
        d.status.success(),
        "two hosts differ from one:\n{}",
        String::from_utf8_lossy(&d.stdout)
    );
    // The stage outputs written on each host are those of the one-host run.
    for (file, out) in [
        ("lines3d.csv", &main_out),
        ("poses.csv", &main_out),
        ("frames.csv", &camera_out),
        ("lines2d.csv", &camera_out),
    ] {
        let a = std::fs::read(one.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        let b = std::fs::read(out.join(file)).unwrap_or_else(|e| panic!("{file} on the split: {e}"));
        assert!(a == b, "{file} differs between one host and two");
    }

    // The two-host recording replays on one machine with the same bytes out.
    let again = sb.path().join("again");
    // Images crossed as PNG: lossless, hence the bytes above.
    let camera_log = std::fs::read_to_string(camera_out.join("logs/bridge.log")).unwrap_or_default();
    assert!(camera_log.contains("images as png"), "{camera_log}");
    let r = sb.run(&[
        "replay",
        rec_two.to_str().unwrap(),
        "--rerun",
        "--set",
        SCALE,
        "--out",
        again.to_str().unwrap(),
    ]);
    assert!(r.status.success(), "the replay on one host failed");
    let d = sb.run(&["diff", rec_two.to_str().unwrap(), again.join("recording.mcap").to_str().unwrap()]);
    assert!(d.status.success(), "the replay differs:\n{}", String::from_utf8_lossy(&d.stdout));

    // As JPEG, when asked: the run goes through, and the images (with what the main host derives from them) are
    // no longer those of one host.
    let port = free_port();
    let graph = two_host_demo(&sb, port);
    let (main_out, camera_out) = (sb.path().join("main-jpeg"), sb.path().join("camera-jpeg"));
    let jpeg = ["bridge.images=jpeg", "bridge.jpeg_quality=80"];
    let camera = start_host(&sb, &graph, "camera", &camera_out, &jpeg);
    let main = start_host(&sb, &graph, "main", &main_out, &jpeg);
    let (main_ok, main_err) = finish(main, &main_out);
    let (camera_ok, camera_err) = finish(camera, &camera_out);
    assert!(main_ok && camera_ok, "a host failed with JPEG images:\n{main_err}\n{camera_err}");
    let d = sb.run(&["diff", rec_one.to_str().unwrap(), main_out.join("recording.mcap").to_str().unwrap()]);
    let text = String::from_utf8_lossy(&d.stdout);
    assert!(!d.status.success() && text.contains("images"), "JPEG images must differ:\n{text}");
    let a = std::fs::read(one.join("frames.csv")).unwrap();
    assert!(
        a == std::fs::read(camera_out.join("frames.csv")).unwrap(),
        "the camera's own stages see its own images"
    );
}

#[test]
fn a_host_whose_supervisor_dies_ends_the_other_hosts_run_with_an_error_naming_it() {
    let sb = Sandbox::new();
    let (main, mut camera, main_out, _) = both_hosts_mid_stream(&sb, 4);
    // SAFETY: signalling a process this test started.
    unsafe { libc::kill(camera.id() as i32, libc::SIGKILL) };
    let _ = camera.wait();
    let killed = Instant::now();
    let (ok, err) = finish(main, &main_out);
    let took = killed.elapsed();
    assert!(!ok, "the main host's run must fail when the camera's host dies:\n{err}");
    assert!(err.contains("host 'camera'"), "the error names the host:\n{err}");
    assert!(took < Duration::from_secs(20), "the main host took {took:?} to end");
    assert_nothing_left_in(&state_of(&sb, "main"), &main_out);
    // The recorder kept what it had received, readable to its end.
    let info = sb.run(&["info", main_out.join("recording.mcap").to_str().unwrap()]);
    assert!(info.status.success(), "{}", String::from_utf8_lossy(&info.stdout));
    // The killed supervisor's leftovers are for `doctor` on its host.
    let fix = sb
        .lineflow(&["doctor", "--fix"])
        .env("LINEFLOW_STATE_DIR", state_of(&sb, "camera"))
        .output()
        .unwrap();
    assert!(fix.status.success(), "{}", String::from_utf8_lossy(&fix.stderr));
}

#[test]
fn a_host_with_other_settings_is_refused_by_name() {
    let sb = Sandbox::new();
    let graph = two_host_demo(&sb, free_port());
    let (main_out, camera_out) = (sb.path().join("main"), sb.path().join("camera"));
    let main = start_host(&sb, &graph, "main", &main_out, &[]);
    let camera = start_host(&sb, &graph, "camera", &camera_out, &["capture.seed=2"]);
    let (main_ok, main_err) = finish(main, &main_out);
    let (camera_ok, camera_err) = finish(camera, &camera_out);
    assert!(!main_ok && !camera_ok, "hosts of different graphs must not run together");
    let both = format!("{main_err}{camera_err}");
    assert!(both.contains("runs another version of graph 'demo'"), "{both}");
    assert!(both.contains("same launch file with the same --set options"), "{both}");
}

#[test]
fn ctrl_c_on_one_host_ends_the_others_with_the_reason() {
    let sb = Sandbox::new();
    let (main, camera, main_out, camera_out) = both_hosts_mid_stream(&sb, 3);
    // SAFETY: signalling a process this test started.
    unsafe { libc::kill(main.id() as i32, libc::SIGINT) };
    let interrupted = Instant::now();
    let (camera_ok, err) = finish(camera, &camera_out);
    let took = interrupted.elapsed();
    let (main_ok, _) = finish(main, &main_out);
    assert!(!main_ok && !camera_ok, "an interrupted run is not a finished one");
    assert!(
        err.contains("host 'main' was interrupted"),
        "the camera's host names the reason:\n{err}"
    );
    assert!(took < Duration::from_secs(20), "the camera's host took {took:?} to end");
    for (host, out) in [("main", &main_out), ("camera", &camera_out)] {
        assert_nothing_left_in(&state_of(&sb, host), out);
    }
}

/// The demo graph on two hosts over mutual TLS, each host's certificate and key in `dir` as `HOST.pem` and
/// `HOST.key` beside the authority's `ca.pem`, and the launch file there too (its paths are relative to it).
fn two_host_demo_tls(dir: &Path, port: u16) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    let demo = std::fs::read_to_string(repo_file("launch/demo.toml")).unwrap();
    let tls = format!(
        "\n[bridge.tls]\nca = \"ca.pem\"\n\n[hosts.main]\nlisten = [\"tls/127.0.0.1:{port}\"]\ncertificate = \"main.pem\"\nkey = \"main.key\"\n\n[hosts.camera]\ncertificate = \"camera.pem\"\nkey = \"camera.key\"\n"
    );
    // A short wait for a host that never shows: the refusal below is then quick.
    let text = demo.replacen("[graph]", "[graph]\nconnect_timeout_s = 8", 1) + &tls;
    let graph = dir.join("demo-tls.toml");
    std::fs::write(&graph, text).unwrap();
    graph
}

/// Puts the test authority's certificate and `who`'s certificate and key into `dir`, named as host `host`'s.
fn certificates(dir: &Path, host: &str, who: &str) {
    let fixtures = repo_file("tests/e2e/fixtures/tls");
    std::fs::copy(fixtures.join("ca.pem"), dir.join("ca.pem")).unwrap();
    for ext in ["pem", "key"] {
        std::fs::copy(fixtures.join(format!("{who}.{ext}")), dir.join(format!("{host}.{ext}"))).unwrap();
    }
}

/// Both hosts of the TLS demo, each from its own folder as on two machines; the camera's host shows `camera_cert`.
fn tls_run(sb: &Sandbox, camera_cert: &str) -> ((bool, String), (bool, String)) {
    let port = free_port();
    let (main_dir, camera_dir) = (sb.path().join("main-host"), sb.path().join("camera-host"));
    let main_graph = two_host_demo_tls(&main_dir, port);
    let camera_graph = two_host_demo_tls(&camera_dir, port);
    certificates(&main_dir, "main", "main");
    certificates(&camera_dir, "camera", camera_cert);
    let (main_out, camera_out) = (sb.path().join("main"), sb.path().join("camera"));
    let main = start_host(sb, &main_graph, "main", &main_out, &[]);
    let camera = start_host(sb, &camera_graph, "camera", &camera_out, &[]);
    (finish(main, &main_out), finish(camera, &camera_out))
}

#[test]
fn over_mutual_tls_the_split_runs_and_a_certificate_of_another_name_is_refused() {
    let sb = Sandbox::new();
    let ((main_ok, main_err), (camera_ok, camera_err)) = tls_run(&sb, "camera");
    assert!(main_ok && camera_ok, "a host failed over TLS:\n{main_err}\n{camera_err}");
    // Every frame crossed: the main host's bridge published the camera's 10 topics, the images once a frame.
    let summary = std::fs::read_to_string(sb.path().join("main/summary.txt")).unwrap();
    let bridge: Vec<&str> = summary
        .lines()
        .find(|l| l.starts_with("bridge "))
        .unwrap()
        .split_whitespace()
        .collect();
    let frames = std::fs::read_to_string(sb.path().join("camera/frames.csv"))
        .unwrap()
        .lines()
        .count()
        - 1;
    assert!(frames > 0 && bridge[3].parse::<usize>().unwrap() >= frames, "{summary}");

    // A certificate the authority signed, but for a name that is no host of the graph: access control keeps it out.
    let sb = Sandbox::new();
    let ((main_ok, main_err), (camera_ok, _)) = tls_run(&sb, "intruder");
    assert!(!main_ok && !camera_ok, "a host with another name's certificate must not join");
    assert!(
        main_err.contains("host camera did not appear") && main_err.contains("[bridge.tls]"),
        "{main_err}"
    );
}

/// The split demo with its bridges restarted on failure (`[bridge] restart = "on-failure"`) and the bridge of host
/// `victim` SIGKILLed after frame 4: the lossless edges between the hosts resume with nothing lost and nothing
/// published twice, so the recording and the 3-D lines are those of one host.
fn bridge_killed_on(victim: &str) {
    let sb = Sandbox::new();
    let one = sb.path().join("one");
    // A camera's pace, not as fast as the renderer goes: the history a restarted bridge re-reads is a window and two
    // frames deep, and at `fps = 0` the camera's host published more than that while its bridge restarted (2026-12-02:
    // frame 5 missed on every try on a 2-core machine, at this commit and at the one before it).
    let pace = "capture.fps=3";
    one_host_demo(&sb, &one, &[pace]);
    let graph = two_host_demo(&sb, free_port());
    let (main_out, camera_out) = (sb.path().join("main"), sb.path().join("camera"));
    let sets = ["bridge.restart=on-failure", pace];
    let chaos = ["--chaos", "bridge@4"];
    let on = |host: &str| if host == victim { &chaos[..] } else { &[][..] };
    let camera = start_host_with(&sb, &graph, "camera", &camera_out, &sets, on("camera"));
    let main = start_host_with(&sb, &graph, "main", &main_out, &sets, on("main"));
    let (main_ok, main_err) = finish(main, &main_out);
    let (camera_ok, camera_err) = finish(camera, &camera_out);
    assert!(
        main_ok && camera_ok,
        "the {victim} host's bridge killed: a host failed:\n{main_err}\n{camera_err}"
    );
    let summary_of =
        |out: &Path| -> serde_json::Value { serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap() };
    let summary = summary_of(if victim == "main" { &main_out } else { &camera_out });
    assert_eq!(summary["chaos"][0]["struck"], true, "the {victim} bridge was not killed: {summary}");
    let bridge = summary["nodes"].as_array().unwrap().iter().find(|n| n["name"] == "bridge").unwrap();
    assert_eq!(bridge["restarts"], 1, "{bridge}");
    for (host, out) in [("main", &main_out), ("camera", &camera_out)] {
        for node in summary_of(out)["nodes"].as_array().unwrap() {
            assert_eq!(node["missed"], 0, "the {victim} bridge killed, on {host}: {node}");
            // What the killed bridge did not take counts as a drop at its publishers (history re-sends it).
            if host != victim {
                assert_eq!(node["drops"], 0, "the {victim} bridge killed, on {host}: {node}");
            }
        }
    }
    let d = sb.run(&[
        "diff",
        one.join("recording.mcap").to_str().unwrap(),
        main_out.join("recording.mcap").to_str().unwrap(),
    ]);
    assert!(
        d.status.success(),
        "the {victim} host's bridge restarted: two hosts differ from one:\n{}",
        String::from_utf8_lossy(&d.stdout)
    );
    let lines = |dir: &Path| std::fs::read(dir.join("lines3d.csv")).unwrap();
    assert!(
        lines(&one) == lines(&main_out),
        "lines3d.csv differs after the {victim} bridge's restart"
    );
}

/// The sending bridge (the camera's) killed: it re-reads its inputs' history and the main host drops what it had.
#[test]
fn a_sending_bridge_killed_mid_run_is_restarted_and_the_edges_between_hosts_lose_nothing() {
    bridge_killed_on("camera");
}

/// The receiving bridge (the main host's) killed: the camera's bridge re-sends what it kept.
#[test]
#[ignore = "passed 69 of 70 runs here: in the other, nodes of the main host that publish for the first time after its bridge restarted reach none of their subscribers (docs/hosts.md, Limits); run with --ignored"]
fn a_receiving_bridge_killed_mid_run_is_restarted_and_the_edges_between_hosts_lose_nothing() {
    bridge_killed_on("main");
}
