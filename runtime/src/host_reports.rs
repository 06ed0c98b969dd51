//! One summary for a graph on several hosts: at the end of a run each host's bridge sends the others its nodes'
//! counters, each bridge keeps what it receives in `OUT/hosts/HOST.json`, and the supervisor adds those rows to its
//! own summary (`summary.txt`, `summary.json`). CPU time and restarts are counted by each host's supervisor, which
//! ends after its bridge: they stay in that host's own summary.
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::supervisor::Row;

/// A host's nodes as its bridge saw them at the end.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct HostReport {
    /// The host.
    pub host: String,
    /// Its nodes, in graph order, its bridge left out.
    pub nodes: Vec<RemoteNode>,
}

/// One node of another host: the counters it last reported.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct RemoteNode {
    /// Its name.
    pub name: String,
    /// Whether it had reported finishing.
    pub finished: bool,
    /// Messages received.
    pub msgs_in: u64,
    /// Messages published.
    pub msgs_out: u64,
    /// Deliveries that missed an expected subscriber.
    pub drops: u64,
    /// Messages discarded as already seen.
    pub duplicates: u64,
    /// Frames missed on its inputs.
    pub missed: u64,
}

/// Where the report of `host` is kept in a run's output folder.
pub fn report_path(out: &Path, host: &str) -> PathBuf {
    out.join("hosts").join(format!("{host}.json"))
}

/// Forgets the reports of an earlier run in `out`.
pub fn clear_reports(out: &Path) {
    let _ = std::fs::remove_dir_all(out.join("hosts"));
}

/// The reports kept in `out`, by host name; a file that does not read is left out with a warning.
pub fn read_reports(out: &Path) -> Vec<HostReport> {
    let Ok(dir) = std::fs::read_dir(out.join("hosts")) else {
        return Vec::new();
    };
    let mut reports: Vec<HostReport> = dir
        .flatten()
        .filter(|e| e.path().extension().is_some_and(|x| x == "json"))
        .filter_map(|e| {
            let text = std::fs::read_to_string(e.path()).ok()?;
            serde_json::from_str(&text)
                .map_err(|err| tracing::warn!("{}: not a host's report ({err}); left out of the summary", e.path().display()))
                .ok()
        })
        .collect();
    reports.sort_by(|a, b| a.host.cmp(&b.host));
    reports
}

/// The reports as rows under the summary's own table (`HOST/NODE`, cpu and restarts left to that host).
pub fn table(reports: &[HostReport]) -> String {
    let mut s = String::new();
    for r in reports {
        for n in &r.nodes {
            s += &Row {
                name: &format!("{}/{}", r.host, n.name),
                status: if n.finished { "ok" } else { "unfinished" },
                msgs_in: n.msgs_in,
                msgs_out: n.msgs_out,
                drops: n.drops,
                duplicates: n.duplicates,
                missed: n.missed,
                cpu_s: None,
                restarts: None,
                missed_ranges: &[],
            }
            .line();
        }
    }
    if !s.is_empty() {
        s += "(other hosts' nodes as their bridges reported them at the end; cpu and restarts in each host's own summary)\n";
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn report(host: &str) -> HostReport {
        HostReport {
            host: host.into(),
            nodes: vec![RemoteNode {
                name: "capture".into(),
                finished: true,
                msgs_in: 0,
                msgs_out: 27,
                drops: 0,
                duplicates: 0,
                missed: 0,
            }],
        }
    }

    #[test]
    fn reports_are_kept_read_in_host_order_and_tabled() {
        let dir = tempfile::tempdir().unwrap();
        assert!(read_reports(dir.path()).is_empty());
        for host in ["drone", "camera"] {
            let p = report_path(dir.path(), host);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, serde_json::to_string(&report(host)).unwrap()).unwrap();
        }
        std::fs::write(dir.path().join("hosts/broken.json"), "{").unwrap();
        let got = read_reports(dir.path());
        assert_eq!(got, [report("camera"), report("drone")], "the broken file is left out");
        let t = table(&got);
        assert!(
            t.contains("camera/capture") && t.contains("drone/capture") && t.contains("27"),
            "{t}"
        );
        clear_reports(dir.path());
        assert!(read_reports(dir.path()).is_empty());
        assert_eq!(table(&[]), "");
    }
}
