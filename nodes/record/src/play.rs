//! `lineflow-play`: publishes the recorded messages of a recording on the topics it is wired to, in file order, as
//! fast as the graph takes them (lossless) or paced by the recorded receipt times. It stands in for the nodes that
//! produced those topics (`lineflow replay`), so the rest of a graph runs live on recorded input.
use std::collections::HashMap;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use lineflow_messages::schema::{decode_view, Decoded};
use lineflow_messages::MessageKind;
use lineflow_recordings::Recording;
use lineflow_runtime::tap::{emitter, Emit};
use lineflow_runtime::NodeContext;

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    /// The recording (absolute, or relative to the working directory of `lineflow`).
    recording: String,
    /// Playback speed relative to the recorded timing; 0 = as fast as possible.
    #[serde(default)]
    rate: f64,
    /// Play the recording again and again (for viewers; frames repeat).
    #[serde(default, rename = "loop")]
    repeat: bool,
}

fn main() -> std::process::ExitCode {
    lineflow_runtime::run_node(body)
}

fn body() -> Result<()> {
    let ctx = NodeContext::from_env()?;
    let p: Params = ctx.params()?;
    if !(p.rate >= 0.0 && p.rate.is_finite()) {
        bail!(
            "node '{}': rate must be 0 (as fast as possible) or positive, got {}",
            ctx.name(),
            p.rate
        );
    }
    let mut outputs: HashMap<String, (MessageKind, Box<dyn Emit>)> = HashMap::new();
    for e in ctx.graph().edges.iter().filter(|e| e.from == ctx.name()) {
        let kind = e.kind();
        outputs.insert(e.topic.clone(), (kind, emitter(&ctx, &e.topic, kind, false)?));
    }
    // Fail before the graph starts when the recording cannot feed the topics.
    let recording = (!lineflow_runtime::env::RunEnv::describe_requested())
        .then(|| Recording::open(std::path::Path::new(&p.recording)))
        .transpose()?;
    if let Some(rec) = &recording {
        let channels = rec.channels();
        for (topic, (kind, _)) in &outputs {
            match channels.iter().find(|c| &c.topic == topic && !c.view) {
                Some(c) if c.kind == Some(*kind) => {}
                Some(c) => bail!(
                    "{}: topic '{topic}' holds {} but the graph wants {}",
                    rec.path.display(),
                    c.schema,
                    kind.name()
                ),
                None => bail!("{}: no topic '{topic}' in the recording", rec.path.display()),
            }
        }
        if let Some(damage) = &rec.damage {
            tracing::warn!("{}: {damage}; replaying what is readable", rec.path.display());
        }
    }
    ctx.connect()?;
    let rec = recording.context("no recording")?;
    let mut sent = 0u64;
    // Image pixels go from the recorded bytes straight into shared memory; other payloads reuse these buffers.
    let mut scratch = Decoded::default();
    // iceoryx2 reports a signal once: remember it.
    let mut stopped = false;
    loop {
        let (start, mut first_log) = (Instant::now(), None);
        let result = rec.for_each_message(|mut m| {
            let Some((kind, out)) = outputs.get(&m.topic) else {
                return Ok(());
            };
            if ctx.should_stop() {
                stopped = true;
                bail!("interrupted");
            }
            if p.rate > 0.0 {
                let t0 = *first_log.get_or_insert(m.log_time);
                let due = start + Duration::from_nanos((m.log_time.saturating_sub(t0) as f64 / p.rate) as u64);
                if let Some(wait) = due.checked_duration_since(Instant::now()) {
                    std::thread::sleep(wait);
                }
            }
            // An image recorded compressed is published as the graph carried it.
            m.restore(&mut scratch)?;
            let (header, payload) =
                decode_view(*kind, &m.data, &mut scratch).with_context(|| format!("topic '{}' message {}", m.topic, m.sequence))?;
            out.emit(header, payload)?;
            sent += 1;
            Ok(())
        });
        match result {
            Ok(()) => {}
            Err(e) if stopped => {
                tracing::info!("stopped after {sent} messages: {e:#}");
                break;
            }
            // A recording cut short (recorder killed, disk full) replays up to its last complete chunk.
            Err(e) if !rec.is_finished() => tracing::warn!("{e:#}"),
            Err(e) => return Err(e),
        }
        if !p.repeat || stopped || ctx.should_stop() {
            break;
        }
    }
    for (_, out) in outputs.values() {
        out.end()?;
    }
    tracing::info!("replayed {sent} messages from {}", rec.path.display());
    ctx.finish();
    Ok(())
}
