//! End-to-end tests of the live view (`lineflow run --view`): the demo graph served over the Foxglove WebSocket
//! protocol to an independent client (Python's `websockets`) that subscribes and decodes what it receives, beside
//! clients that connect and leave in a loop or stop reading; and a port already in use refused before the graph
//! starts.
use std::net::TcpListener;
use std::process::{Command, Stdio};

use lineflow_e2e::*;

const SCALE: &str = "capture.scale=0.06";
/// Frames at 5 a second: the run lasts long enough for the client to connect while it goes.
const PACE: &str = "capture.fps=5";

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

#[test]
fn a_foxglove_client_receives_the_run_live_and_the_recording_stays_complete() {
    let sb = Sandbox::new();
    let out = sb.path().join("live");
    let port = free_port();
    let demo = repo_file("launch/demo.toml");
    let run = sb
        .lineflow(&[
            "run",
            demo.to_str().unwrap(),
            "--set",
            SCALE,
            "--set",
            PACE,
            "--view-port",
            &port.to_string(),
            "--out",
            out.to_str().unwrap(),
            "-q",
        ])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Misbehaving clients beside the good one, for as long as the run goes.
    let hostile = Command::new(python())
        .arg(repo_file("tests/e2e/hostile_view_clients.py"))
        .arg(format!("ws://127.0.0.1:{port}"))
        .arg("8")
        .stdout(Stdio::piped())
        .spawn()
        .expect("python3");
    let client = Command::new(python())
        .arg(repo_file("tests/e2e/live_view_client.py"))
        .arg(format!("ws://127.0.0.1:{port}"))
        .arg("300")
        .args([
            "images/preview",
            "images/calibration",
            "lines2d/annotations",
            "keypoints/annotations",
            "poses/scene",
            "poses/transforms",
            "lines3d/scene",
            "wireframe/scene",
        ])
        .output()
        .expect("python3");
    let report = String::from_utf8_lossy(&client.stdout).into_owned();
    eprintln!("{report}{}", String::from_utf8_lossy(&client.stderr));
    // The client has closed: the viewer does not hold the run open.
    let finished = run.wait_with_output().unwrap();
    let log = String::from_utf8_lossy(&finished.stderr);
    eprintln!("{log}");
    assert!(client.status.success(), "the client did not get every channel: {report}");
    assert!(finished.status.success(), "the run failed with the viewer on");
    let received: serde_json::Value = serde_json::from_str(report.trim()).unwrap();
    assert!(received["channels"].as_u64().unwrap() >= 8, "{report}");
    let hostile = hostile.wait_with_output().unwrap();
    let misbehaved: serde_json::Value = serde_json::from_slice(&hostile.stdout).unwrap();
    assert!(
        misbehaved["churn"].as_u64().unwrap() >= 3 && misbehaved["stalled"] == true,
        "{misbehaved}"
    );

    // The viewer is a subscriber like the recorder, never a cause of drops: the recording is complete.
    let info = sb.run(&["info", "--json", out.join("recording.mcap").to_str().unwrap()]);
    let json: serde_json::Value = serde_json::from_slice(&info.stdout).unwrap();
    assert_eq!(json["complete"], true, "{json}");
}

#[test]
fn a_port_in_use_fails_the_run_before_the_graph_starts_naming_the_address() {
    let sb = Sandbox::new();
    let taken = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = taken.local_addr().unwrap().port();
    let out = sb.path().join("busy");
    let demo = repo_file("launch/demo.toml");
    let r = sb.run(&[
        "run",
        demo.to_str().unwrap(),
        "--set",
        SCALE,
        "--view-port",
        &port.to_string(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success(), "the run went on without its viewer");
    assert!(err.contains(&format!("cannot listen on 127.0.0.1:{port}")), "{err}");
    drop(taken);
}
