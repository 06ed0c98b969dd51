//! `lineflow bench view`: the live view's cost and latency (#32). The 2-D part of the pipeline (synthetic capture
//! at full size, grey conversion, Canny edges, line tracing, a sink) runs on the same frames flat out without the
//! viewer, then with it and a WebSocket client of our own (tungstenite) subscribed to every channel: the ratio of
//! their wall times is the viewer's throughput cost. A third run, with the viewer, paces the camera at half the
//! rate the first run reached, so that each frame's stamp is the moment it was taken: per channel, the latency from
//! a frame's capture to the client's receipt of its preview and of its 2-D lines, and the viewer's own share (from
//! the moment it took the message out of shared memory, the log time it sends, to the receipt).
use std::collections::BTreeMap;
use std::net::TcpListener;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use anyhow::{bail, Context, Result};
use tungstenite::client::IntoClientRequest;
use tungstenite::Message;

fn graph(preset: &str, scale: f64, frames: u64, fps: f64) -> String {
    format!(
        r#"[graph]
name = "bench-view"

[[node]]
name = "capture"
stage = "capture"
impl = "synthetic"
params = {{ preset = "{preset}", scale = {scale}, seed = 1, fps = {fps}, frames = {frames}, use_clock = true }}

[[node]]
name = "gray"
stage = "convert"
impl = "gray"

[[node]]
name = "edges"
stage = "edges"
impl = "canny"

[[node]]
name = "lines2d"
stage = "lines2d"
impl = "trace"
remap = {{ images = "gray" }}

[[node]]
name = "stats"
stage = "stats"
remap = {{ images = "gray" }}

[[edge]]
topic = "images"
type = "Image"
from = "capture"
to = ["gray", "edges"]

[[edge]]
topic = "gray"
type = "Image"
from = "gray"
to = ["stats", "lines2d"]

[[edge]]
topic = "edges"
type = "EdgeMap"
from = "edges"
to = ["stats", "lines2d"]
max_payload_bytes = 16777216

[[edge]]
topic = "camera"
type = "CameraModel"
from = "capture"
to = ["lines2d"]

[[edge]]
topic = "lines2d"
type = "Lines2D"
from = "lines2d"
to = ["stats"]
max_payload_bytes = 16777216

[record]
enabled = false
"#
    )
}

fn now_ns() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos() as u64)
}

/// What the client measured per channel: (capture → receipt, log time → receipt) in ms.
type Latencies = BTreeMap<String, Vec<(f64, f64)>>;

/// The capture stamp inside a preview (CDR `RawImage`: the time first) or an annotation (JSON), ns.
fn capture_stamp(topic: &str, payload: &[u8]) -> Option<u64> {
    if topic.ends_with("/preview") {
        let sec = u32::from_le_bytes(payload.get(4..8)?.try_into().ok()?) as u64;
        let nsec = u32::from_le_bytes(payload.get(8..12)?.try_into().ok()?) as u64;
        return Some(sec * 1_000_000_000 + nsec);
    }
    let v: serde_json::Value = serde_json::from_slice(payload).ok()?;
    let t = v.pointer("/points/0/timestamp").or_else(|| v.pointer("/timestamp"))?;
    Some(t["sec"].as_u64()? * 1_000_000_000 + t["nsec"].as_u64()?)
}

/// Connects (retrying until `deadline`), subscribes to every channel and measures until the server closes.
fn client(port: u16, deadline: Instant) -> Result<Latencies> {
    let ws_url = format!("ws://127.0.0.1:{port}");
    let mut ws = loop {
        let mut req = ws_url.as_str().into_client_request()?;
        req.headers_mut().insert("Sec-WebSocket-Protocol", "foxglove.sdk.v1".parse()?);
        match tungstenite::connect(req) {
            Ok((ws, _)) => break ws,
            Err(_) if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(20)),
            Err(e) => return Err(e).context("the viewer never listened"),
        }
    };
    let mut topics: BTreeMap<u32, String> = BTreeMap::new();
    let mut out = Latencies::new();
    loop {
        let msg = match ws.read() {
            Ok(m) => m,
            Err(_) => return Ok(out), // the viewer stopped at the run's end
        };
        let received = now_ns();
        match msg {
            Message::Text(text) => {
                let v: serde_json::Value = serde_json::from_str(text.as_str())?;
                if v["op"] == "advertise" {
                    let mut subs = Vec::new();
                    for c in v["channels"].as_array().into_iter().flatten() {
                        let id = c["id"].as_u64().unwrap_or(0) as u32;
                        topics.insert(id, c["topic"].as_str().unwrap_or("").to_owned());
                        subs.push(serde_json::json!({ "id": id, "channelId": id }));
                    }
                    ws.send(Message::text(
                        serde_json::json!({ "op": "subscribe", "subscriptions": subs }).to_string(),
                    ))?;
                }
            }
            Message::Binary(data) if data.first() == Some(&1) && data.len() >= 13 => {
                let sub = u32::from_le_bytes(data[1..5].try_into()?);
                let log_time = u64::from_le_bytes(data[5..13].try_into()?);
                let Some(topic) = topics.get(&sub) else { continue };
                let Some(captured) = capture_stamp(topic, &data[13..]) else {
                    continue;
                };
                let ms = |t: u64| received.saturating_sub(t) as f64 / 1e6;
                out.entry(topic.clone()).or_default().push((ms(captured), ms(log_time)));
            }
            _ => {}
        }
    }
}

fn run(graph: &Path, out: &Path, view_port: Option<u16>) -> Result<(f64, Option<Latencies>)> {
    let exe = std::env::current_exe().context("cannot find the lineflow executable")?;
    let mut c = Command::new(exe);
    c.arg("run").arg(graph).arg("-q").arg("--out").arg(out);
    if let Some(p) = view_port {
        // No lingering for the client after the end: the client measures until the viewer closes.
        c.args(["--view-port", &p.to_string(), "--set", "view.linger_s=0"]);
    }
    let start = Instant::now();
    let mut child = c
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .spawn()
        .context("cannot start the run")?;
    let latencies = view_port
        .map(|p| client(p, Instant::now() + Duration::from_secs(120)))
        .transpose()?;
    let status = child.wait()?;
    if !status.success() {
        bail!("the run failed ({status}); its logs are in {}", out.join("logs").display());
    }
    Ok((start.elapsed().as_secs_f64(), latencies))
}

fn percentile(v: &mut [f64], q: f64) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(((v.len() as f64 - 1.0) * q).round() as usize).copied().unwrap_or(f64::NAN)
}

/// Runs the benchmark.
pub fn bench_view(preset: &str, scale: f64, frames: u64, pairs: usize) -> Result<std::process::ExitCode> {
    let dir = tempfile::Builder::new().prefix("lineflow-bench-view").tempdir()?;
    let flat_out = dir.path().join("flat-out.toml");
    std::fs::write(&flat_out, graph(preset, scale, frames, 0.0))?;
    let port = || -> Result<u16> { Ok(TcpListener::bind("127.0.0.1:0")?.local_addr()?.port()) };
    println!("{preset} at scale {scale}, {frames} frames: capture -> gray, edges -> lines2d -> stats\n");
    // Runs without and with the viewer alternate, and their medians are compared: on two cores the same run
    // varies by ±10 % from one to the next, more than the cost measured.
    let (mut withouts, mut withs) = (Vec::new(), Vec::new());
    for k in 0..pairs.max(1) {
        withouts.push(run(&flat_out, &dir.path().join(format!("without-{k}")), None)?.0);
        withs.push(run(&flat_out, &dir.path().join(format!("with-{k}")), Some(port()?))?.0);
    }
    let list = |v: &[f64]| v.iter().map(|s| format!("{s:.2}")).collect::<Vec<_>>().join(", ");
    let (runs_without, runs_with) = (list(&withouts), list(&withs));
    let (without, with) = (percentile(&mut withouts, 0.5), percentile(&mut withs, 0.5));
    let fps = 0.5 * frames as f64 / without;
    let paced = dir.path().join("paced.toml");
    std::fs::write(&paced, graph(preset, scale, frames, fps))?;
    let (paced_s, latencies) = run(&paced, &dir.path().join("paced"), Some(port()?))?;
    let latencies = latencies.unwrap_or_default();
    println!("| run | wall s |\n|---|---|");
    println!("| flat out, without the viewer (reference), median of {runs_without} | {without:.2} |");
    println!("| flat out, with the viewer and one client, median of {runs_with} | {with:.2} |");
    println!("| paced at {fps:.2} frames/s, with the viewer and one client | {paced_s:.2} |");
    let cost = (with / without - 1.0) * 100.0;
    println!(
        "\nthroughput cost of the live view: {cost:+.1} % (ratio {:.3}; target ≤ 5 %)\n",
        with / without
    );
    println!("paced run, per channel:\n");
    println!("| channel | messages | stamp → client ms, median | max | viewer's own ms, median | max |");
    println!("|---|---|---|---|---|---|");
    let mut worst = BTreeMap::new();
    for (topic, v) in &latencies {
        let (mut total, mut own): (Vec<f64>, Vec<f64>) = v.iter().copied().unzip();
        let max = percentile(&mut total, 1.0);
        worst.insert(topic.as_str(), max);
        println!(
            "| {topic} | {} | {:.0} | {max:.0} | {:.1} | {:.1} |",
            v.len(),
            percentile(&mut total, 0.5),
            percentile(&mut own, 0.5),
            percentile(&mut own, 1.0)
        );
    }
    let shown = |t: &str| worst.get(t).map_or("-".to_owned(), |ms| format!("{ms:.0} ms"));
    println!(
        "\nslowest stamp to client: preview {}, 2-D lines {} (target ≤ 300 ms from the frame's capture). The \
         synthetic camera stamps a frame when it is due and renders it after, so these include its rendering, which \
         a real camera does not have; the lines include the edge and line stages' own time. The viewer's own share \
         runs from taking the message out of shared memory to the client's receipt.",
        shown("images/preview"),
        shown("lines2d/annotations")
    );
    Ok(std::process::ExitCode::SUCCESS)
}
