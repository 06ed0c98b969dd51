//! The graphs `lineflow replay` runs: the player alone (playback for viewers), or a launch graph whose capture
//! sources are replaced by the player (`--rerun`), so the rest of the graph runs live on recorded input.
use std::collections::BTreeMap;
use std::path::Path;

use anyhow::{bail, Context, Result};
use lineflow_messages::MessageKind;

use super::Recording;
use lineflow_runtime::launch::{self, EdgePolicy, EdgeSpec, Graph, NodeSpec, Resolver, RestartPolicy};

/// Stage of the player node.
pub const PLAYER_STAGE: &str = "play";

/// How the player plays.
#[derive(Debug, Clone, Copy)]
pub struct Pace {
    /// Speed relative to the recorded timing; 0 = as fast as the graph goes (lossless).
    pub rate: f64,
    /// Start again at the end.
    pub repeat: bool,
}

/// Per recorded topic (viewer channels excepted): its kind and largest message in bytes.
fn recorded_topics(rec: &Recording) -> Result<BTreeMap<String, (MessageKind, u64)>> {
    let mut topics = BTreeMap::new();
    for c in rec.channels().into_iter().filter(|c| !c.view) {
        if let Some(kind) = c.kind {
            topics.insert(c.topic, (kind, 0u64));
        }
    }
    // A finished file's totals record says how large each topic's messages are; otherwise read them.
    let (largest, read) = match rec.topic_totals() {
        Some(totals) => (totals, Ok(())),
        None => rec.scan_totals(),
    };
    if let Err(e) = read {
        if rec.is_finished() {
            return Err(e);
        }
        tracing::warn!("{e:#}");
    }
    for (topic, t) in &mut topics {
        t.1 = largest.get(topic).map_or(0, |l| l.largest);
    }
    Ok(topics)
}

fn player(name: &str, rec: &Recording, resolver: &Resolver, pace: Pace) -> Result<NodeSpec> {
    let path = std::fs::canonicalize(&rec.path).with_context(|| format!("{}", rec.path.display()))?;
    let mut params = serde_json::Map::new();
    params.insert("recording".into(), path.display().to_string().into());
    params.insert("rate".into(), pace.rate.into());
    params.insert("loop".into(), pace.repeat.into());
    Ok(NodeSpec {
        name: name.into(),
        index: 0,
        stage: Some(PLAYER_STAGE.into()),
        implementation: None,
        command: vec![resolver.stage(PLAYER_STAGE).map_err(anyhow::Error::msg)?],
        params,
        restart: RestartPolicy::Never,
        max_restarts: 0,
        backoff_ms: 0,
        remap: BTreeMap::new(),
        host: lineflow_runtime::hosts::DEFAULT_HOST.into(),
    })
}

/// The player publishing `topics` (default: every recorded topic) with no subscribers: `lineflow echo`, `hz` and
/// nodes in other languages attach to it.
///
/// # Errors
/// When a requested topic is not in the recording or the player binary is missing.
pub fn playback_graph(rec: &Recording, topics: &[String], resolver: &Resolver, pace: Pace) -> Result<Graph> {
    let recorded = recorded_topics(rec)?;
    for t in topics {
        if !recorded.contains_key(t) {
            bail!(
                "{}: no topic '{t}' (recorded: {})",
                rec.path.display(),
                recorded.keys().cloned().collect::<Vec<_>>().join(", ")
            );
        }
    }
    let node = player("player", rec, resolver, pace)?;
    let edges = recorded
        .iter()
        .filter(|(t, _)| topics.is_empty() || topics.contains(t))
        .map(|(topic, (kind, bytes))| EdgeSpec {
            topic: topic.clone(),
            message: kind.name().into(),
            from: node.name.clone(),
            to: Vec::new(),
            policy: EdgePolicy::Lossless,
            max_payload_bytes: (*bytes).max(1),
            depth: 4,
            history: usize::from(kind.latched()),
            timeout_ms: lineflow_runtime::launch::DEFAULT_TIMEOUT_MS,
        })
        .collect();
    Ok(Graph {
        name: format!("replay of {}", rec.path.display()),
        description: String::new(),
        source: rec.path.clone(),
        text: String::new(),
        nodes: vec![node],
        edges,
        connect_timeout_s: None,
        replaced: Vec::new(),
        hosts: Vec::new(),
        host: lineflow_runtime::hosts::DEFAULT_HOST.into(),
        bridge: Default::default(),
        hash: String::new(),
    })
}

/// The programs a re-run of the recorded launch file would start that are not lineflow's own stages and that the
/// recording, not the user, names: the nodes of `g` with an `executable` that `set` does not replace, as (node,
/// command line). A recording from someone else may name any program there.
pub fn recorded_programs(g: &Graph, set: &[String]) -> Vec<(String, String)> {
    g.nodes
        .iter()
        .filter(|n| n.stage.is_none())
        .filter(|n| !set.iter().any(|s| s.starts_with(&format!("{}.executable=", n.name))))
        .map(|n| (n.name.clone(), n.command.join(" ")))
        .collect()
}

/// A launch graph with its sources (nodes without inputs: capture) replaced by the player of `rec`. The graph is
/// `graph` when given, else the launch file stored in the recording; `set` overrides parameters as in `run`.
///
/// # Errors
/// When the graph does not load, has no source, or a source publishes a topic the recording lacks.
pub fn rerun_graph(rec: &Recording, graph: Option<&Path>, set: &[String], resolver: &Resolver, pace: Pace) -> Result<Graph> {
    let mut g = match graph {
        Some(path) => launch::load(path, set, resolver)?,
        None => {
            let text = rec
                .run_meta("launch_text")
                .with_context(|| format!("{}: no launch graph in the metadata; pass --graph", rec.path.display()))?;
            let path = rec.run_meta("launch_path").unwrap_or("recorded.toml");
            launch::parse(Path::new(path), text, set, resolver)?
        }
    };
    let recorded = recorded_topics(rec)?;
    let sources: Vec<String> = g
        .nodes
        .iter()
        .filter(|n| g.is_source(&n.name) && !launch::is_observer(&n.name))
        .map(|n| n.name.clone())
        .collect();
    if sources.is_empty() {
        bail!("graph '{}' has no source node to replace with the recording", g.name);
    }
    for e in g.edges.iter().filter(|e| sources.contains(&e.from)) {
        match recorded.get(&e.topic) {
            Some((kind, _)) if kind.name() == e.message => {}
            Some((kind, _)) => bail!(
                "{}: topic '{}' was recorded as {} but graph '{}' carries {} on it",
                rec.path.display(),
                e.topic,
                kind.name(),
                g.name,
                e.message
            ),
            None => bail!(
                "{}: source '{}' publishes '{}', which the recording lacks",
                rec.path.display(),
                e.from,
                e.topic
            ),
        }
    }
    let mut name = "player".to_owned();
    while g.node(&name).is_some() {
        name.push('_');
    }
    let node = player(&name, rec, resolver, pace)?;
    let (replaced, kept) = std::mem::take(&mut g.nodes).into_iter().partition(|n| sources.contains(&n.name));
    g.replaced = replaced;
    g.nodes = kept;
    g.nodes.insert(0, node);
    for (i, n) in g.nodes.iter_mut().enumerate() {
        n.index = i as u32;
    }
    for e in g.edges.iter_mut().filter(|e| sources.contains(&e.from)) {
        e.from = name.clone();
        e.max_payload_bytes = e.max_payload_bytes.max(recorded[&e.topic].1);
    }
    Ok(g)
}
