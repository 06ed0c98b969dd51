//! Graphs across machines (`docs/hosts.md`): the `[hosts]` of a launch file, the part of a graph each host runs,
//! and the bridge the loader adds to a host's part where an edge has its publisher on one host and subscribers on
//! another. Inside a host the edges stay iceoryx2 shared memory; between hosts the bridges carry them over Zenoh.
//!
//! Every host loads the whole launch file and checks the whole graph (types, the `gt/*` rule, every edge with a
//! publisher); [`part`] then keeps its own nodes. A graph's [`hash`](crate::launch::Graph::hash) covers every node
//! and edge of every host, so that two hosts running different launch files, or the same one with other `--set`s,
//! refuse each other instead of exchanging messages of another graph.
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::launch::{added_node, Graph, LaunchError, NodeSpec, Resolver, RestartPolicy};
pub use crate::launch::{BridgeSettings, HostSpec, TlsSettings, BRIDGE, DEFAULT_HOST};
use lineflow_messages::image::{ImageFormat, DEFAULT_JPEG_QUALITY};

/// Stage of the bridge node.
pub const BRIDGE_STAGE: &str = "bridge";

/// One edge that crosses between hosts, as one host's bridge sees it.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Crossing {
    /// The topic.
    pub topic: String,
    /// Sending: the hosts that subscribe. Receiving: the host that publishes.
    pub hosts: Vec<String>,
    /// Sending: how many messages may be put ahead of a receiving host's credit ([`window`]).
    #[serde(default)]
    pub window: u64,
    /// Sending, when the bridges restart: how many of the last messages are kept to re-send to a restarted
    /// receiving bridge (its window, and the receiving edge's buffer, which dies with the bridge's shared memory).
    #[serde(default)]
    pub keep: usize,
}

/// How many messages of an edge of buffer `depth` a sending bridge puts ahead of a receiving host's credit: the
/// edge's depth, at least 4, so that a frame stream keeps moving over a link's latency.
pub fn window(depth: usize) -> u64 {
    depth.max(4) as u64
}

/// What a host's bridge carries: its parameters, written by [`part`].
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BridgePlan {
    /// The graph's name: the first level of every key expression.
    pub graph: String,
    /// The graph's hash: a peer with another one is refused.
    pub hash: String,
    /// The host this bridge runs on.
    pub host: String,
    /// Endpoints to listen on.
    pub listen: Vec<String>,
    /// Endpoints to connect to.
    pub connect: Vec<String>,
    /// The hosts this one exchanges topics with.
    pub peers: Vec<String>,
    /// Topics published here and read on other hosts.
    pub send: Vec<Crossing>,
    /// Topics published on another host and read here.
    pub receive: Vec<Crossing>,
    /// Zenoh multicast scouting, besides the explicit endpoints (`[bridge] scouting = true`).
    #[serde(default)]
    pub scouting: bool,
    /// How images cross (`[bridge] images`) and the JPEG quality.
    #[serde(default)]
    pub images: ImageFormat,
    /// JPEG quality of `images = "jpeg"`.
    #[serde(default = "default_jpeg_quality")]
    pub jpeg_quality: u8,
    /// Mutual TLS and access control (`[bridge.tls]`).
    #[serde(default)]
    pub tls: Option<TlsPlan>,
    /// With `[bridge] restart = "on-failure"`: the longest wait before a bridge is restarted (ms). A peer that
    /// leaves is then given that long, and a start's, to come back before the run ends.
    #[serde(default)]
    pub restart_wait_ms: Option<u64>,
}

/// A bridge's TLS: the files of this host (absolute, checked to exist) and the certificates' common names that
/// access control admits.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TlsPlan {
    /// The authority's certificate.
    pub ca: PathBuf,
    /// This host's certificate.
    pub certificate: PathBuf,
    /// Its private key.
    pub key: PathBuf,
    /// The common names of the graph's hosts, this one's included.
    pub common_names: Vec<String>,
}

fn default_jpeg_quality() -> u8 {
    DEFAULT_JPEG_QUALITY
}

/// The part of `graph` that `host` runs: its own nodes, the edges with an end on it, and a bridge node for the
/// edges that cross to or from other hosts. The other hosts' nodes are kept in `replaced`, where a stage that needs
/// a source's parameters (eval regenerating the synthetic scene) finds them. A graph on one host is returned as it
/// is.
///
/// # Errors
/// A host the graph does not declare, or a missing bridge binary.
pub fn part(graph: &Graph, host: &str, resolver: &Resolver) -> Result<Graph, LaunchError> {
    let invalid = |entry: String, message: String| LaunchError::Invalid {
        path: graph.source.clone(),
        entry,
        message,
    };
    let mut names: BTreeSet<&str> = graph.nodes.iter().map(|n| n.host.as_str()).collect();
    names.extend(graph.hosts.iter().map(|h| h.name.as_str()));
    if !names.contains(host) {
        let known: Vec<&str> = names.into_iter().collect();
        return Err(invalid(
            format!("--host {host}"),
            format!("the graph has no host '{host}' (its hosts: {})", known.join(", ")),
        ));
    }
    if names.len() == 1 {
        return Ok(graph.clone());
    }
    let host_of: BTreeMap<&str, &str> = graph.nodes.iter().map(|n| (n.name.as_str(), n.host.as_str())).collect();
    let here = |node: &str| host_of.get(node).copied() == Some(host);
    let mut part = graph.clone();
    part.host = host.to_owned();
    let (mine, others): (Vec<NodeSpec>, Vec<NodeSpec>) = graph.nodes.iter().cloned().partition(|n| n.host == host);
    part.nodes = mine;
    part.replaced.extend(others);
    let (mut send, mut receive) = (Vec::new(), Vec::new());
    let settings = &graph.bridge;
    let restarts = settings.restart == RestartPolicy::OnFailure;
    part.edges = graph
        .edges
        .iter()
        .filter_map(|e| {
            let local: Vec<String> = e.to.iter().filter(|t| here(t)).cloned().collect();
            let remote: BTreeSet<String> = e.to.iter().filter(|t| !here(t)).map(|t| host_of[t.as_str()].to_owned()).collect();
            let mut e = e.clone();
            if here(&e.from) {
                if !remote.is_empty() {
                    let window = window(e.depth);
                    send.push(Crossing {
                        topic: e.topic.clone(),
                        hosts: remote.into_iter().collect(),
                        window,
                        keep: if restarts { window as usize + e.depth + 2 } else { 0 },
                    });
                    e.to = local.into_iter().chain([BRIDGE.to_owned()]).collect();
                    if restarts {
                        // A restarted bridge re-reads what it had taken but not yet delivered: at most a window.
                        e.history = e.history.max(window as usize + 2);
                        e.depth = e.depth.max(e.history);
                    }
                }
                Some(e)
            } else if !local.is_empty() {
                receive.push(Crossing {
                    topic: e.topic.clone(),
                    hosts: vec![host_of[e.from.as_str()].to_owned()],
                    window: 0,
                    keep: 0,
                });
                e.from = BRIDGE.to_owned();
                e.to = local;
                Some(e)
            } else {
                None
            }
        })
        .collect();
    for (i, n) in part.nodes.iter_mut().enumerate() {
        n.index = i as u32;
    }
    if send.is_empty() && receive.is_empty() {
        return Ok(part);
    }
    let me = graph.hosts.iter().find(|h| h.name == host);
    let listen = me.map(|h| h.listen.clone()).unwrap_or_default();
    let connect = match me.map(|h| h.connect.clone()).unwrap_or_default() {
        c if !c.is_empty() => c,
        _ => graph
            .hosts
            .iter()
            .filter(|h| h.name != host)
            .flat_map(|h| h.listen.iter().cloned())
            .collect(),
    };
    let peers: BTreeSet<String> = send.iter().chain(&receive).flat_map(|c| c.hosts.iter().cloned()).collect();
    let tls = graph
        .bridge
        .tls
        .as_ref()
        .map(|t| tls_plan(graph, host, &t.ca))
        .transpose()
        .map_err(|(entry, message)| invalid(entry, message))?;
    let plan = BridgePlan {
        graph: graph.name.clone(),
        hash: graph.hash.clone(),
        host: host.to_owned(),
        listen,
        connect,
        peers: peers.into_iter().collect(),
        send,
        receive,
        scouting: graph.bridge.scouting,
        images: graph.bridge.images,
        jpeg_quality: graph.bridge.jpeg_quality,
        tls,
        restart_wait_ms: restarts.then(|| {
            let doublings = settings.max_restarts.saturating_sub(1).min(10);
            settings.backoff_ms.saturating_mul(1 << doublings)
        }),
    };
    let serde_json::Value::Object(params) = serde_json::to_value(&plan).expect("plain data serializes") else {
        unreachable!("a struct serializes to an object")
    };
    let mut bridge =
        added_node(BRIDGE, BRIDGE_STAGE, params, part.nodes.len(), resolver).map_err(|m| invalid(format!("node '{BRIDGE}'"), m))?;
    bridge.host = host.to_owned();
    if restarts {
        bridge.restart = RestartPolicy::OnFailure;
        bridge.max_restarts = settings.max_restarts;
        bridge.backoff_ms = settings.backoff_ms;
    }
    part.nodes.push(bridge);
    Ok(part)
}

/// This host's TLS files, relative to the launch file's folder, checked to exist.
fn tls_plan(graph: &Graph, host: &str, ca: &str) -> Result<TlsPlan, (String, String)> {
    let base = graph.source.parent().unwrap_or(Path::new("."));
    let entry = format!("[hosts.{host}]");
    let me = graph.hosts.iter().find(|h| h.name == host).ok_or_else(|| {
        (
            entry.clone(),
            "with [bridge.tls] every host needs its `certificate` and `key`".to_owned(),
        )
    })?;
    let file = |entry: &str, key: &str, name: Option<&str>| -> Result<PathBuf, (String, String)> {
        let name = name.ok_or_else(|| (entry.to_owned(), format!("`{key}` is missing")))?;
        let path = base.join(name);
        if !path.is_file() {
            return Err((entry.to_owned(), format!("`{key}`: no file {}", path.display())));
        }
        Ok(path)
    };
    Ok(TlsPlan {
        ca: file("[bridge.tls]", "ca", Some(ca))?,
        certificate: file(&entry, "certificate", me.certificate.as_deref())?,
        key: file(&entry, "key", me.key.as_deref())?,
        common_names: graph.hosts.iter().map(|h| h.common_name.clone()).collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::launch::parse;
    use std::path::Path;

    fn resolver(dir: &Path) -> Resolver {
        for s in ["capture", "stats", "record", "view", "bridge"] {
            std::fs::write(dir.join(format!("lineflow-{s}")), "").unwrap();
        }
        Resolver { bin_dir: dir.to_owned() }
    }

    /// A camera host with the source and a filter, the main host with the sink and the recorder.
    const TWO_HOSTS: &str = r#"
        [hosts.main]
        listen = ["tcp/127.0.0.1:7447"]
        [hosts.camera]
        [[node]]
        name = "cap"
        stage = "capture"
        host = "camera"
        [[node]]
        name = "filter"
        stage = "stats"
        host = "camera"
        [[node]]
        name = "sink"
        stage = "stats"
        [[edge]]
        topic = "images"
        type = "Image"
        from = "cap"
        to = ["filter", "sink"]
        max_payload_bytes = 1000
        [[edge]]
        topic = "camera"
        type = "CameraModel"
        from = "cap"
        to = ["filter"]
    "#;

    fn plan(g: &Graph) -> BridgePlan {
        let bridge = g.node(BRIDGE).expect("a bridge");
        serde_json::from_value(serde_json::Value::Object(bridge.params.clone())).unwrap()
    }

    #[test]
    fn restarting_bridges_keep_a_window_to_resend_and_the_edges_into_them_a_history() {
        let dir = tempfile::tempdir().unwrap();
        let r = resolver(dir.path());
        let g = |sets: &[String]| {
            let whole = parse(&dir.path().join("g.toml"), TWO_HOSTS, sets, &r).unwrap();
            part(&whole, "camera", &r).unwrap()
        };
        let plain = g(&[]);
        let p = plan(&plain);
        assert_eq!(plain.node(BRIDGE).unwrap().restart, RestartPolicy::Never);
        assert_eq!((p.send[0].window, p.send[0].keep, p.restart_wait_ms), (4, 0, None));
        let images = plain.edges.iter().find(|e| e.topic == "images").unwrap();
        assert_eq!(images.history, 0);

        let sets = ["bridge.restart=on-failure".to_owned(), "bridge.backoff_ms=100".to_owned()];
        let restarting = g(&sets);
        let bridge = restarting.node(BRIDGE).unwrap();
        assert_eq!(
            (bridge.restart, bridge.max_restarts, bridge.backoff_ms),
            (RestartPolicy::OnFailure, 3, 100)
        );
        let p = plan(&restarting);
        assert_eq!(p.restart_wait_ms, Some(400), "the third restart waits 4 back-offs");
        assert_eq!((p.send[0].window, p.send[0].keep), (4, 4 + 4 + 2));
        let images = restarting.edges.iter().find(|e| e.topic == "images").unwrap();
        assert_eq!((images.history, images.depth), (6, 6), "a window and two re-read after a restart");
    }

    #[test]
    fn each_host_runs_its_nodes_and_a_bridge_carries_the_edges_that_cross() {
        let dir = tempfile::tempdir().unwrap();
        let r = resolver(dir.path());
        let whole = parse(&dir.path().join("g.toml"), TWO_HOSTS, &[], &r).unwrap();
        let camera = part(&whole, "camera", &r).unwrap();
        let names: Vec<&str> = camera.nodes.iter().map(|n| n.name.as_str()).collect();
        assert_eq!(names, ["cap", "filter", BRIDGE]);
        assert_eq!(
            camera.nodes.iter().map(|n| n.index).collect::<Vec<_>>(),
            [0, 1, 2],
            "indices within the part"
        );
        let images = camera.edges.iter().find(|e| e.topic == "images").unwrap();
        assert_eq!(images.to, ["filter", BRIDGE], "the sink and the recorder are on main");
        let cam = camera.edges.iter().find(|e| e.topic == "camera").unwrap();
        assert_eq!(cam.to, ["filter", BRIDGE], "the recorder on main records it");
        let p = plan(&camera);
        assert_eq!(
            p.connect,
            ["tcp/127.0.0.1:7447"],
            "a host without endpoints connects to the listeners"
        );
        assert!(p.listen.is_empty());
        assert_eq!(p.peers, ["main"]);
        assert_eq!(p.send.iter().map(|c| c.topic.as_str()).collect::<Vec<_>>(), ["images", "camera"]);
        assert!(p.receive.is_empty());

        let main = part(&whole, DEFAULT_HOST, &r).unwrap();
        let names: Vec<&str> = main.nodes.iter().map(|n| n.name.as_str()).collect();
        assert_eq!(names, ["sink", crate::launch::RECORDER, BRIDGE]);
        let images = main.edges.iter().find(|e| e.topic == "images").unwrap();
        assert_eq!(
            (images.from.as_str(), images.to.clone()),
            (BRIDGE, vec!["sink".into(), crate::launch::RECORDER.into()])
        );
        assert!(main.replaced.iter().any(|n| n.name == "cap"), "eval finds the source's parameters");
        let p = plan(&main);
        assert_eq!(p.receive.len(), 2);
        assert_eq!(p.receive[0].hosts, ["camera"]);
        assert_eq!(p.hash, whole.hash);
        assert_eq!(p.listen, ["tcp/127.0.0.1:7447"]);

        // The recorder may sit on any host: it records every topic there.
        let elsewhere = parse(&dir.path().join("g.toml"), TWO_HOSTS, &["record.on_host=\"camera\"".into()], &r).unwrap();
        let camera = part(&elsewhere, "camera", &r).unwrap();
        let images = camera.edges.iter().find(|e| e.topic == "images").unwrap();
        assert_eq!(images.to, ["filter", crate::launch::RECORDER, BRIDGE]);
        assert!(part(&elsewhere, DEFAULT_HOST, &r).unwrap().node(crate::launch::RECORDER).is_none());
    }

    #[test]
    fn the_hash_covers_every_host_and_setting() {
        let dir = tempfile::tempdir().unwrap();
        let r = resolver(dir.path());
        let p = dir.path().join("g.toml");
        let a = parse(&p, TWO_HOSTS, &[], &r).unwrap();
        assert_eq!(a.hash, parse(&p, TWO_HOSTS, &[], &r).unwrap().hash, "stable");
        assert_ne!(a.hash, parse(&p, TWO_HOSTS, &["cap.fps=3".into()], &r).unwrap().hash);
        assert_ne!(a.hash, parse(&p, TWO_HOSTS, &["filter.host=main".into()], &r).unwrap().hash);
    }

    #[test]
    fn a_graph_on_one_host_is_unchanged_and_unknown_hosts_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let r = resolver(dir.path());
        let p = dir.path().join("g.toml");
        let one = TWO_HOSTS.replace("host = \"camera\"", "");
        let g = parse(&p, &one, &[], &r).unwrap();
        let same = part(&g, DEFAULT_HOST, &r).unwrap();
        assert_eq!(same.nodes.len(), g.nodes.len());
        assert!(same.node(BRIDGE).is_none());
        let e = part(&g, "nowhere", &r).unwrap_err().to_string();
        assert!(e.contains("no host 'nowhere'") && e.contains("camera"), "{e}");

        let cases = [
            (TWO_HOSTS.replace("[hosts.camera]", ""), "host 'camera': not declared"),
            (
                TWO_HOSTS.replace("listen = [\"tcp/127.0.0.1:7447\"]", ""),
                "needs `listen` on at least one host",
            ),
            (TWO_HOSTS.replace("tcp/127.0.0.1:7447", "udp/127.0.0.1"), "endpoint 'udp/127.0.0.1'"),
            (
                TWO_HOSTS
                    .replace("name = \"sink\"", "name = \"bridge\"")
                    .replace("\"sink\"]", "\"bridge\"]"),
                "'bridge' is reserved",
            ),
        ];
        for (text, expected) in cases {
            let e = parse(&p, &text, &[], &r).unwrap_err().to_string();
            assert!(e.contains(expected), "{e}");
        }
    }

    /// [`TWO_HOSTS`] over TLS, with certificates `main.pem`, `camera.pem` and their keys beside the launch file.
    fn tls_hosts() -> String {
        TWO_HOSTS
            .replace("tcp/", "tls/")
            .replace(
                "[hosts.main]",
                "[bridge.tls]\nca = \"ca.pem\"\n[hosts.main]\ncertificate = \"main.pem\"\nkey = \"main.key\"",
            )
            .replace(
                "[hosts.camera]",
                "[hosts.camera]\ncertificate = \"camera.pem\"\nkey = \"camera.key\"\ncommon_name = \"cam-7\"",
            )
    }

    #[test]
    fn tls_plans_carry_this_hosts_files_and_every_hosts_name_and_refuse_what_is_missing() {
        let dir = tempfile::tempdir().unwrap();
        let r = resolver(dir.path());
        let p = dir.path().join("g.toml");
        for f in ["ca.pem", "main.pem", "main.key", "camera.pem", "camera.key"] {
            std::fs::write(dir.path().join(f), "").unwrap();
        }
        let g = parse(&p, &tls_hosts(), &[], &r).unwrap();
        let tls = plan(&part(&g, "camera", &r).unwrap()).tls.expect("a TLS plan");
        assert_eq!(tls.certificate, dir.path().join("camera.pem"));
        assert_eq!(tls.ca, dir.path().join("ca.pem"));
        assert_eq!(tls.common_names, ["cam-7", "main"]);
        std::fs::remove_file(dir.path().join("camera.key")).unwrap();
        let e = part(&g, "camera", &r).unwrap_err().to_string();
        assert!(e.contains("[hosts.camera]") && e.contains("`key`: no file"), "{e}");
        assert!(part(&g, DEFAULT_HOST, &r).is_ok(), "the main host has its files");

        let cases = [
            (tls_hosts().replace("tls/", "tcp/"), "with [bridge.tls] every endpoint is tls/"),
            (TWO_HOSTS.replace("tcp/", "tls/"), "tls/ endpoints need [bridge.tls]"),
            (
                tls_hosts().replace("certificate = \"camera.pem\"", ""),
                "every host needs `certificate` and `key`",
            ),
            (tls_hosts().replace("cam-7", "main"), "common name 'main' is another host's too"),
            (
                TWO_HOSTS.replace("[hosts.main]", "[hosts.main]\ncertificate = \"main.pem\""),
                "need [bridge.tls]",
            ),
        ];
        for (text, expected) in cases {
            let e = parse(&p, &text, &[], &r).unwrap_err().to_string();
            assert!(e.contains(expected), "{expected}: {e}");
        }
    }
}
