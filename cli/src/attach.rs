//! `lineflow topics`, `echo` and `hz`: attaching to a running graph as one more subscriber.
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use lineflow_messages::{with_kind, Encoding, ImageHeader, Message, MessageKind};
use lineflow_runtime::launch::{EdgeSpec, Graph};
use lineflow_runtime::runs::RunRecord;
use lineflow_runtime::transport;

fn attach(run: Option<&str>) -> Result<(RunRecord, Graph, Node<ipc::Service>)> {
    let rec = RunRecord::find(run)?;
    let graph = rec.load_graph()?;
    let cfg = transport::config(&rec.prefix, &rec.root)?;
    let node = transport::create_node(&cfg, &format!("cli-{}", std::process::id()))?;
    Ok((rec, graph, node))
}

fn edge<'a>(graph: &'a Graph, topic: &str) -> Result<&'a EdgeSpec> {
    graph.edges.iter().find(|e| e.topic == topic).with_context(|| {
        let names: Vec<_> = graph.edges.iter().map(|e| e.topic.as_str()).collect();
        format!("no topic '{topic}' in this run (topics: {})", names.join(", "))
    })
}

/// Lists the run's topics with their types and live port counts.
pub fn topics(run: Option<&str>) -> Result<ExitCode> {
    let (rec, graph, node) = attach(run)?;
    println!("run {} ({})", rec.id, graph.name);
    println!(
        "{:<20} {:<14} {:<9} {:>4} {:>4}  from -> to",
        "topic", "type", "policy", "pubs", "subs"
    );
    for e in &graph.edges {
        let (pubs, subs) = with_kind!(e.kind(), M => {
            let s = transport::open_pubsub::<M>(&node, e, 0)?;
            (s.dynamic_config().number_of_publishers(), s.dynamic_config().number_of_subscribers().saturating_sub(1))
        });
        println!(
            "{:<20} {:<14} {:<9} {:>4} {:>4}  {} -> {}",
            e.topic,
            e.message,
            format!("{:?}", e.policy).to_lowercase(),
            pubs,
            subs,
            e.from,
            e.to.join(",")
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// How `lineflow echo` prints a message.
#[derive(Debug, Clone, Copy)]
pub enum EchoForm {
    /// The stamp line, then the fields by name (indented JSON), with the first N elements of each sequence.
    Fields(usize),
    /// One JSON object a line (the topic added), with the first N elements of each sequence.
    Json(usize),
    /// The stamp line, then the header's bytes and the payload's first [`RAW_BYTES`] in hex.
    Raw,
}

/// Payload bytes `echo --raw` shows.
const RAW_BYTES: usize = 256;

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect::<Vec<_>>().join(" ")
}

/// One line per message: stamp and payload size (and the image geometry for images).
fn describe<M: Message>(header: &M::Header, elements: usize) -> String {
    let s = M::stamp(header);
    let mut line = format!(
        "frame {:>6}  seq {:>6}  t {}.{:09}  rev {}  flags {:#x}  {} elements ({} B)",
        s.frame,
        s.seq,
        s.capture_time_ns / 1_000_000_000,
        s.capture_time_ns % 1_000_000_000,
        s.revision,
        s.flags,
        elements,
        elements * size_of::<M::Element>()
    );
    if M::KIND == MessageKind::Image {
        // SAFETY: M::Header is ImageHeader when the kind is Image (one registry entry each).
        let h = unsafe { &*(header as *const M::Header as *const ImageHeader) };
        line += &format!(
            "  {}x{} {} {}",
            h.width,
            h.height,
            Encoding::from_u32(h.encoding).map(Encoding::name).unwrap_or("?"),
            h.name()
        );
    }
    if s.is_end_of_stream() {
        line += "  END-OF-STREAM";
    }
    line
}

fn subscribe_loop<M: Message>(
    node: &Node<ipc::Service>,
    e: &EdgeSpec,
    mut on_msg: impl FnMut(Option<(&M::Header, &[M::Element])>) -> bool,
) -> Result<()> {
    let svc = transport::open_pubsub::<M>(node, e, 0)?;
    let sub = svc.subscriber_builder().buffer_size(e.depth).create().map_err(|err| {
        anyhow::anyhow!(
            "cannot subscribe to '{}': {err:?} (the edge has room for one tool at a time)",
            e.topic
        )
    })?;
    let listener = transport::open_event(node, &e.topic)?
        .listener_builder()
        .create()
        .map_err(|err| anyhow::anyhow!("{err:?}"))?;
    let _ = sub.update_connections();
    loop {
        if node.wait(Duration::ZERO).is_err() {
            return Ok(());
        }
        let _ = listener.timed_wait(|_| {}, Duration::from_millis(200));
        let _ = sub.update_connections();
        while let Some(sample) = sub.receive().map_err(|err| anyhow::anyhow!("{err:?}"))? {
            if !on_msg(Some((sample.user_header(), sample.payload()))) {
                return Ok(());
            }
        }
        if !on_msg(None) {
            return Ok(());
        }
    }
}

/// Prints each message of a topic until end-of-stream, `count`, or Ctrl-C.
pub fn echo(topic: &str, run: Option<&str>, count: Option<u64>, form: EchoForm) -> Result<ExitCode> {
    let (_rec, graph, node) = attach(run)?;
    let e = edge(&graph, topic)?.clone();
    let mut n = 0u64;
    with_kind!(e.kind(), M => subscribe_loop::<M>(&node, &e, |m| {
        let Some((h, elements)) = m else { return true };
        let header = lineflow_messages::schema::bytes_of(h);
        let payload = lineflow_messages::schema::slice_bytes(elements);
        match form {
            EchoForm::Fields(shown) => {
                println!("{topic}: {}", describe::<M>(h, elements.len()));
                let fields = lineflow_recordings::fields::message_json(M::KIND, header, payload, shown);
                println!("{}", serde_json::to_string_pretty(&fields).unwrap_or_default());
            }
            EchoForm::Json(shown) => {
                let mut fields = lineflow_recordings::fields::message_json(M::KIND, header, payload, shown);
                if let Some(o) = fields.as_object_mut() {
                    o.insert("topic".into(), topic.into());
                }
                println!("{fields}");
            }
            EchoForm::Raw => {
                println!("{topic}: {}", describe::<M>(h, elements.len()));
                println!("header  {}", hex(header));
                let more = if payload.len() > RAW_BYTES { " ..." } else { "" };
                println!("payload {}{more}", hex(&payload[..payload.len().min(RAW_BYTES)]));
            }
        }
        n += 1;
        !M::stamp(h).is_end_of_stream() && count.is_none_or(|c| n < c)
    }))?;
    Ok(ExitCode::SUCCESS)
}

/// One second of a topic's messages: their arrival times and sizes.
struct RateWindow {
    start: Instant,
    arrivals: Vec<Instant>,
    bytes: usize,
}

impl RateWindow {
    fn new() -> Self {
        Self {
            start: Instant::now(),
            arrivals: Vec::new(),
            bytes: 0,
        }
    }

    /// Rate, the period's min / max / standard deviation between arrivals, and bandwidth, as `ros2 topic hz`
    /// and `bw` print them.
    fn line(&self, topic: &str) -> String {
        let dt = self.start.elapsed().as_secs_f64().max(1e-9);
        let n = self.arrivals.len();
        let mut line = format!("{topic}: {:.2} Hz ({n} messages in {dt:.2} s)", n as f64 / dt);
        let periods: Vec<f64> = self.arrivals.windows(2).map(|w| (w[1] - w[0]).as_secs_f64()).collect();
        if !periods.is_empty() {
            let mean = periods.iter().sum::<f64>() / periods.len() as f64;
            let std = (periods.iter().map(|p| (p - mean).powi(2)).sum::<f64>() / periods.len() as f64).sqrt();
            let (min, max) = periods.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &p| (a.min(p), b.max(p)));
            line += &format!("  period min {min:.3} s max {max:.3} s std {std:.3} s");
        }
        line + &format!("  {:.2} MB/s", self.bytes as f64 / dt / 1e6)
    }
}

/// Prints a topic's message rate, period statistics and bandwidth once a second.
pub fn hz(topic: &str, run: Option<&str>, seconds: Option<u64>) -> Result<ExitCode> {
    let (_rec, graph, node) = attach(run)?;
    let e = edge(&graph, topic)?.clone();
    let start = Instant::now();
    let mut window = RateWindow::new();
    with_kind!(e.kind(), M => subscribe_loop::<M>(&node, &e, |m| {
        let mut ended = false;
        if let Some((h, elements)) = m {
            ended = M::stamp(h).is_end_of_stream();
            if !ended {
                window.arrivals.push(Instant::now());
                window.bytes += size_of_val(h) + size_of_val(elements);
            }
        }
        if window.start.elapsed() >= Duration::from_secs(1) || ended {
            println!("{}", window.line(topic));
            window = RateWindow::new();
        }
        !ended && seconds.is_none_or(|s| start.elapsed().as_secs() < s)
    }))?;
    Ok(ExitCode::SUCCESS)
}
