//! The viewer node's body: takes every topic's messages as they arrive, renders them on a thread of its own into
//! the recorder's viewer channels and publishes them. The graph never waits for the viewer: images it cannot
//! keep up with are skipped (the previews show the newest frame), everything else is rendered in order.
use std::time::{Duration, Instant};

use anyhow::{bail, Context as _, Result};
use crossbeam::channel::{Receiver, Sender, TrySendError};
use lineflow_messages::schema::encode;
use lineflow_messages::MessageKind;
use lineflow_recordings::now_ns;
use lineflow_recordings::views::{ViewRenderer, ViewSchema};
use lineflow_runtime::tap::{all_ended, subscribe_all, update_ended, Topic};
use lineflow_runtime::{Flow, NodeContext, RunEnd};

use crate::server::LiveServer;

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Params {
    /// Address to listen on: loopback unless the launch file names another.
    #[serde(default = "default_host")]
    host: String,
    /// Port (0: any free port, logged).
    #[serde(default = "default_port")]
    port: u16,
    /// Longest side of the image previews, pixels.
    #[serde(default = "default_preview")]
    preview_max_px: u32,
    /// Pixels averaged per side of each preview pixel's box (0: the whole box, as the recorder's previews).
    #[serde(default = "default_preview_samples")]
    preview_samples: usize,
    /// After the graph has ended, seconds to keep serving while a client is connected (Ctrl-C ends sooner).
    #[serde(default = "default_linger")]
    linger_s: f64,
    /// Image topics served as previews; by default those a source publishes (the camera's frames).
    #[serde(default)]
    previews: Option<Vec<String>>,
}
fn default_host() -> String {
    "127.0.0.1".into()
}
/// Foxglove's default for a WebSocket connection.
fn default_port() -> u16 {
    8765
}
fn default_preview() -> u32 {
    960
}
/// A 12 MP frame's preview then reads two rows in five (a tenth of a second of a core less per frame).
fn default_preview_samples() -> usize {
    2
}
fn default_linger() -> f64 {
    60.0
}

/// Messages waiting to be rendered; images beyond are skipped.
const QUEUE: usize = 8;

/// One message on its way to the renderer.
struct Item {
    topic: usize,
    /// When the viewer took it from shared memory, ns since the epoch: the log time its views are sent with (as
    /// the recorder's), so that a client can tell the viewer's own latency from the pipeline's.
    taken_ns: u64,
    cdr: Vec<u8>,
}

/// The viewer channels of the subscribed topics, as the recorder names them (`<topic>/<view>`).
pub fn channels(topics: &[(String, MessageKind)], renderer: &ViewRenderer) -> Vec<(String, &'static ViewSchema)> {
    topics
        .iter()
        .flat_map(|(name, kind)| renderer.views(*kind).map(move |(suffix, view)| (format!("{name}/{suffix}"), view)))
        .collect()
}

/// Whether an image topic is served as previews: the ones `previews` names, or by default those a source publishes
/// (the camera's frames): a grey copy or another derived image would double the viewer's work, a 12 MP frame's
/// preview costing a tenth of a second, and show nothing new.
pub fn previewed(name: &str, from_source: bool, previews: Option<&[String]>) -> bool {
    previews.map_or(from_source, |list| list.iter().any(|t| t == name))
}

/// Whether a message may be skipped when the renderer is behind: an image is followed by a newer one, while a
/// skipped model or set of lines would leave the view stale until the next.
pub fn skippable(kind: MessageKind) -> bool {
    kind == MessageKind::Image
}

/// The node's body.
///
/// # Errors
/// Bad parameters, a port that cannot be bound, a transport error.
pub fn run(ctx: NodeContext) -> Result<()> {
    let p: Params = ctx.params()?;
    let Ok(linger_for) = Duration::try_from_secs_f64(p.linger_s) else {
        bail!("view.linger_s must be 0 or a positive number of seconds, got {:?}", p.linger_s);
    };
    if p.preview_max_px == 0 {
        bail!("view.preview_max_px must be positive (the viewer's images are its previews)");
    }
    let mut topics = subscribe_all(&ctx)?;
    for name in p.previews.iter().flatten() {
        if !topics.iter().any(|t| &t.name == name && t.kind == MessageKind::Image) {
            bail!("view.previews: '{name}' is not an image topic of the graph");
        }
    }
    let mut status = ctx.watch_status()?;
    if lineflow_runtime::env::RunEnv::describe_requested() {
        return ctx.connect();
    }
    let graph = ctx.graph();
    let shown: Vec<bool> = topics
        .iter()
        .map(|t| {
            let from_source = graph.nodes.iter().any(|n| n.index == t.from && graph.is_source(&n.name));
            t.kind != MessageKind::Image || previewed(&t.name, from_source, p.previews.as_deref())
        })
        .collect();
    let names: Vec<(String, MessageKind)> = topics.iter().map(|t| (t.name.clone(), t.kind)).collect();
    let served: Vec<(String, MessageKind)> = names.iter().zip(&shown).filter(|(_, s)| **s).map(|(n, _)| n.clone()).collect();
    let mut renderer = ViewRenderer::new(p.preview_max_px);
    if p.preview_samples > 0 {
        renderer = renderer.with_sampled_previews(p.preview_samples);
    }
    // Bound before the graph starts: a port in use fails the run before any frame is lost.
    let server = LiveServer::start(&p.host, p.port, &channels(&served, &renderer))?;
    tracing::info!(
        "live view on ws://{}:{} (Foxglove: Open connection → Foxglove WebSocket; layout docs/foxglove-layout.json)",
        p.host,
        server.port()
    );
    let (to_render, queue) = crossbeam::channel::bounded::<Item>(QUEUE);
    // Buffers come back from the render thread, as in the recorder: a 12 MP frame's copy reuses memory already
    // faulted in instead of 36 MB fresh each frame.
    let (give_back, pool) = crossbeam::channel::bounded::<Vec<u8>>(QUEUE + 1);
    let renderer = std::thread::Builder::new()
        .name("view-render".into())
        .spawn(move || render_loop(&queue, &give_back, &names, renderer, &server).map(|()| server))
        .context("cannot start the viewer's render thread")?;
    ctx.connect()?;
    let mut skipped = 0u64;
    let ended = ctx.run(|| {
        update_ended(&mut topics, status.as_mut());
        take(&mut topics, &shown, &to_render, &pool, &mut skipped)?;
        Ok(if all_ended(&topics) { Flow::Stop } else { Flow::Continue })
    });
    drop(to_render);
    let server = renderer
        .join()
        .map_err(|_| anyhow::anyhow!("the viewer's render thread panicked"))??;
    if skipped > 0 {
        tracing::info!("{skipped} images skipped while the view caught up (the previews show the newest)");
    }
    if matches!(ended, Ok(RunEnd::Finished)) {
        linger(&ctx, &server, linger_for);
    }
    server.stop();
    ctx.finish();
    ended.map(|_| ())
}

/// Takes every waiting message; a skippable one is dropped when the renderer is behind, and of several waiting on
/// one topic only the newest is kept; any other waits for room. Topics not `shown` are drained without a copy.
fn take(topics: &mut [Topic], shown: &[bool], to_render: &Sender<Item>, pool: &Receiver<Vec<u8>>, skipped: &mut u64) -> Result<()> {
    let mut taken: Vec<Item> = Vec::new();
    for (i, t) in topics.iter_mut().enumerate() {
        let kind = t.kind;
        if !shown[i] {
            t.messages += t.tap.drain(&mut |_, _, _| Ok(()))? as u64;
            continue;
        }
        let full = to_render.is_full();
        t.messages += t.tap.drain(&mut |_capture_time, header, payload| {
            if skippable(kind) && full {
                *skipped += 1;
                return Ok(());
            }
            // An older image of this topic taken in the same drain would only be shown to be replaced at once.
            let older = if skippable(kind) { taken.pop() } else { None };
            *skipped += u64::from(older.is_some());
            let mut cdr = older.map_or_else(|| pool.try_recv().unwrap_or_default(), |o| o.cdr);
            encode(kind, header, payload, &mut cdr);
            taken.push(Item {
                topic: i,
                taken_ns: now_ns(),
                cdr,
            });
            Ok(())
        })? as u64;
        // Handed on once the samples are released: a full queue never holds shared memory.
        for item in taken.drain(..) {
            match to_render.try_send(item) {
                Ok(()) => {}
                Err(TrySendError::Full(item)) if skippable(kind) => {
                    drop(item);
                    *skipped += 1;
                }
                Err(TrySendError::Full(item)) => to_render
                    .send(item)
                    .map_err(|_| anyhow::anyhow!("the viewer's render thread stopped"))?,
                Err(TrySendError::Disconnected(_)) => bail!("the viewer's render thread stopped"),
            }
        }
    }
    Ok(())
}

fn render_loop(
    queue: &Receiver<Item>,
    give_back: &Sender<Vec<u8>>,
    topics: &[(String, MessageKind)],
    mut renderer: ViewRenderer,
    server: &LiveServer,
) -> Result<()> {
    for item in queue {
        let (name, kind) = &topics[item.topic];
        for (suffix, bytes) in renderer.render(*kind, &item.cdr) {
            server.publish(&format!("{name}/{suffix}"), &bytes, item.taken_ns);
        }
        let _ = give_back.try_send(item.cdr);
    }
    Ok(())
}

/// After the graph's end, serves the last view while a client is connected, up to `limit`.
fn linger(ctx: &NodeContext, server: &LiveServer, limit: Duration) {
    if server.clients() == 0 || limit.is_zero() {
        return;
    }
    tracing::info!(
        "the graph has ended; serving the last view to {} client(s) for up to {} s (Ctrl-C ends it)",
        server.clients(),
        limit.as_secs()
    );
    let until = Instant::now() + limit;
    while server.clients() > 0 && Instant::now() < until && !ctx.should_stop() {
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_channels_are_the_recorders_and_only_images_may_be_skipped() {
        let topics = vec![
            ("images".to_owned(), MessageKind::Image),
            ("lines2d".to_owned(), MessageKind::Lines2D),
            ("poses".to_owned(), MessageKind::Poses),
            ("edges".to_owned(), MessageKind::EdgeMap),
        ];
        let renderer = ViewRenderer::new(960);
        let names: Vec<String> = channels(&topics, &renderer).into_iter().map(|(n, _)| n).collect();
        assert_eq!(
            names,
            [
                "images/preview",
                "images/calibration",
                "lines2d/annotations",
                "poses/scene",
                "poses/transforms"
            ]
        );
        assert!(skippable(MessageKind::Image));
        // The camera's frames by default, not their grey copies; a list names them.
        assert!(previewed("images", true, None) && !previewed("gray", false, None));
        let chosen = ["gray".to_owned()];
        assert!(previewed("gray", false, Some(&chosen)) && !previewed("images", true, Some(&chosen)));
        for kind in [
            MessageKind::Lines3D,
            MessageKind::Wireframe,
            MessageKind::Poses,
            MessageKind::Lines2D,
        ] {
            assert!(!skippable(kind), "{kind:?}");
        }
    }
}
