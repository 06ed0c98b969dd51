//! `lineflow bench transport`: latency and throughput of iceoryx2 between two processes, against a Unix-domain
//! socket that copies the same payloads, measured in the same run.
//!
//! Latency is taken from just before `send()` (or the socket `write`) of a filled sample to the moment the
//! subscriber holds it (or the socket reader has read the last byte), on `CLOCK_MONOTONIC`, which both processes
//! share.
use std::io::{Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::process::{Command, ExitCode, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use lineflow_runtime::transport;

#[derive(Debug, Default, Clone, Copy, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/BenchHeader/v1")]
struct BenchHeader {
    sent_ns: u64,
    seq: u64,
}

fn mono_ns() -> u64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: valid out-pointer.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// What the receiving side reports.
#[derive(Debug, Clone, Copy)]
struct Stats {
    p50_us: f64,
    p99_us: f64,
    msgs_per_s: f64,
}

fn summarize(mut lat_ns: Vec<u64>, first: Instant, last: Instant) -> String {
    lat_ns.sort_unstable();
    let q = |p: f64| lat_ns.get(((lat_ns.len() as f64 - 1.0) * p).round() as usize).copied().unwrap_or(0) as f64 / 1e3;
    let secs = last.duration_since(first).as_secs_f64();
    let rate = if secs > 0.0 { (lat_ns.len() as f64 - 1.0) / secs } else { 0.0 };
    format!("RESULT {} {} {}", q(0.5), q(0.99), rate)
}

fn parse_result(stdout: &str) -> Result<Stats> {
    let line = stdout
        .lines()
        .find(|l| l.starts_with("RESULT "))
        .context("benchmark child printed no result")?;
    let v: Vec<f64> = line[7..].split(' ').map(|s| s.parse().unwrap_or(f64::NAN)).collect();
    Ok(Stats {
        p50_us: v[0],
        p99_us: v[1],
        msgs_per_s: v[2],
    })
}

fn pace(start: Instant, i: u64, hz: Option<f64>) {
    if let Some(hz) = hz {
        let due = start + Duration::from_secs_f64(i as f64 / hz);
        if let Some(d) = due.checked_duration_since(Instant::now()) {
            std::thread::sleep(d);
        }
    }
}

type BenchService = iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, [u8], BenchHeader>;

/// The node and the lossless, one-to-one service both sides of the iceoryx2 benchmark open identically.
fn bench_service(prefix: &str, root: &std::path::Path, size: usize, node_name: &str) -> Result<(Node<ipc::Service>, String, BenchService)> {
    let cfg = transport::config(prefix, root)?;
    let node = transport::create_node(&cfg, node_name)?;
    let name = format!("bench/{size}");
    let svc = node
        .service_builder(&name.as_str().try_into()?)
        .publish_subscribe::<[u8]>()
        .user_header::<BenchHeader>()
        .enable_safe_overflow(false)
        .subscriber_max_buffer_size(4)
        .max_publishers(1)
        .max_subscribers(1)
        .open_or_create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    Ok((node, name, svc))
}

fn iox_case(prefix: &str, root: &std::path::Path, size: usize, count: u64, hz: Option<f64>) -> Result<Stats> {
    let (node, name, svc) = bench_service(prefix, root, size, "bench-pub")?;
    let event = transport::open_event(&node, &name)?;
    let publisher = svc
        .publisher_builder()
        .initial_max_slice_len(size)
        .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let notifier = event.notifier_builder().create().map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let exe = std::env::current_exe()?;
    let child = Command::new(exe)
        .args([
            "bench",
            "iox-sub",
            prefix,
            &root.display().to_string(),
            &size.to_string(),
            &count.to_string(),
        ])
        .stdout(Stdio::piped())
        .spawn()?;
    if !transport::wait_until(Duration::from_secs(20), || svc.dynamic_config().number_of_subscribers() > 0) {
        bail!("benchmark subscriber did not connect");
    }
    // Give the subscriber time to call update_connections() after it saw us (P1 in the iceoryx2 notes).
    std::thread::sleep(Duration::from_millis(200));
    publisher.update_connections().map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let start = Instant::now();
    for i in 0..count {
        pace(start, i, hz);
        let mut sample = publisher.loan_slice_uninit(size).map_err(|e| anyhow::anyhow!("{e:?}"))?;
        for b in sample.payload_mut().iter_mut() {
            b.write(i as u8);
        }
        // SAFETY: every element was written above.
        let mut sample = unsafe { sample.assume_init() };
        *sample.user_header_mut() = BenchHeader {
            sent_ns: mono_ns(),
            seq: i,
        };
        sample.send().map_err(|e| anyhow::anyhow!("{e:?}"))?;
        notifier.notify().map_err(|e| anyhow::anyhow!("{e:?}"))?;
    }
    let out = child.wait_with_output()?;
    parse_result(&String::from_utf8_lossy(&out.stdout))
}

pub(crate) fn iox_sub(prefix: &str, root: &str, size: usize, count: u64) -> Result<()> {
    let (node, name, svc) = bench_service(prefix, std::path::Path::new(root), size, "bench-sub")?;
    let listener = transport::open_event(&node, &name)?
        .listener_builder()
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let sub = svc
        .subscriber_builder()
        .buffer_size(4)
        .create()
        .map_err(|e| anyhow::anyhow!("{e:?}"))?;
    transport::wait_until(Duration::from_secs(20), || svc.dynamic_config().number_of_publishers() > 0);
    sub.update_connections().map_err(|e| anyhow::anyhow!("{e:?}"))?;
    let mut lat = Vec::with_capacity(count as usize);
    let (mut first, mut last) = (Instant::now(), Instant::now());
    while (lat.len() as u64) < count {
        listener.blocking_wait(|_| {}).map_err(|e| anyhow::anyhow!("{e:?}"))?;
        while let Some(s) = sub.receive().map_err(|e| anyhow::anyhow!("{e:?}"))? {
            let now = mono_ns();
            lat.push(now.saturating_sub(s.user_header().sent_ns));
            last = Instant::now();
            if lat.len() == 1 {
                first = last;
            }
        }
    }
    println!("{}", summarize(lat, first, last));
    Ok(())
}

fn uds_case(dir: &std::path::Path, size: usize, count: u64, hz: Option<f64>) -> Result<Stats> {
    let path = dir.join(format!("uds-{size}.sock"));
    let _ = std::fs::remove_file(&path);
    let listener = UnixListener::bind(&path)?;
    let child = Command::new(std::env::current_exe()?)
        .args([
            "bench",
            "uds-sub",
            &path.display().to_string(),
            &size.to_string(),
            &count.to_string(),
        ])
        .stdout(Stdio::piped())
        .spawn()?;
    let (mut sock, _) = listener.accept()?;
    let mut buf = vec![0u8; size];
    let start = Instant::now();
    for i in 0..count {
        pace(start, i, hz);
        buf.fill(i as u8);
        sock.write_all(&mono_ns().to_le_bytes())?;
        sock.write_all(&buf)?;
    }
    let out = child.wait_with_output()?;
    let _ = std::fs::remove_file(&path);
    parse_result(&String::from_utf8_lossy(&out.stdout))
}

pub(crate) fn uds_sub(path: &str, size: usize, count: u64) -> Result<()> {
    let mut sock = UnixStream::connect(path)?;
    let mut buf = vec![0u8; size];
    let mut stamp = [0u8; 8];
    let mut lat = Vec::with_capacity(count as usize);
    let (mut first, mut last) = (Instant::now(), Instant::now());
    for i in 0..count {
        sock.read_exact(&mut stamp)?;
        sock.read_exact(&mut buf)?;
        lat.push(mono_ns().saturating_sub(u64::from_le_bytes(stamp)));
        last = Instant::now();
        if i == 0 {
            first = last;
        }
    }
    println!("{}", summarize(lat, first, last));
    Ok(())
}

pub(crate) fn transport_bench(paced: u64, flat_scale: f64) -> Result<ExitCode> {
    let dir = tempfile_dir()?;
    let prefix = format!("lfb{:x}_", std::process::id());
    let sizes: [(usize, &str, u64); 4] = [
        (64, "64 B", 20_000),
        (1 << 20, "1 MB", 2_000),
        (1920 * 1080 * 3, "6 MB", 500),
        (4912 * 3264 * 3, "48 MB", 60),
    ];
    println!("transport benchmark: 2 processes, lossless, buffer 4, WaitSet/blocking wake-ups; latency = send() of a filled sample -> subscriber holds it");
    println!(
        "{:<6} {:<8} {:>12} {:>12} {:>12} | {:>12} {:>12} {:>12} | {:>9}",
        "size", "mode", "iox p50 us", "iox p99 us", "iox msg/s", "uds p50 us", "uds p99 us", "uds msg/s", "uds/iox"
    );
    let mut paced_p50 = Vec::new();
    let mut ratio_48 = 0.0;
    for (size, label, flat) in sizes {
        for (mode, hz, count) in [
            ("30 Hz", Some(30.0), paced),
            ("flat", None, ((flat as f64 * flat_scale) as u64).max(10)),
        ] {
            let iox = iox_case(&prefix, &dir, size, count, hz)?;
            let uds = uds_case(&dir, size, count, hz)?;
            let ratio = uds.p50_us / iox.p50_us.max(1e-9);
            println!(
                "{label:<6} {mode:<8} {:>12.1} {:>12.1} {:>12.0} | {:>12.1} {:>12.1} {:>12.0} | {:>8.1}x",
                iox.p50_us, iox.p99_us, iox.msgs_per_s, uds.p50_us, uds.p99_us, uds.msgs_per_s, ratio
            );
            if hz.is_some() {
                paced_p50.push((label, iox.p50_us));
                if size == sizes[3].0 {
                    ratio_48 = ratio;
                }
            }
        }
    }
    let worst = paced_p50.iter().map(|p| p.1).fold(0.0, f64::max);
    let spread = paced_p50.last().map(|l| l.1).unwrap_or(0.0) / paced_p50.first().map(|f| f.1).unwrap_or(1.0).max(1e-9);
    println!(
        "targets: p50 at 30 Hz <= 100 us for every size: worst {worst:.1} us [{}]",
        if worst <= 100.0 { "met" } else { "MISSED" }
    );
    println!(
        "         48 MB / 64 B p50 at 30 Hz <= 2x: {spread:.2}x [{}]",
        if spread <= 2.0 { "met" } else { "MISSED" }
    );
    println!(
        "         socket / iceoryx2 p50 at 48 MB >= 50x: {ratio_48:.1}x [{}]",
        if ratio_48 >= 50.0 { "met" } else { "MISSED" }
    );
    cleanup_prefix(&prefix, &dir);
    Ok(ExitCode::SUCCESS)
}

fn tempfile_dir() -> Result<std::path::PathBuf> {
    let dir = std::env::temp_dir().join(format!("lineflow-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    Ok(dir)
}

fn cleanup_prefix(prefix: &str, dir: &std::path::Path) {
    lineflow_runtime::shm::remove_prefixed(prefix);
    let _ = std::fs::remove_dir_all(dir);
}
