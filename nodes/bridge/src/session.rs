//! The Zenoh session of a host's bridge, configured from its plan.
use anyhow::{Context, Result};
use lineflow_runtime::hosts::{BridgePlan, TlsPlan};

/// The Zenoh configuration of a bridge: a peer that listens only where the launch file says (Zenoh's own default
/// would listen on every interface, on a random port), connects to the other hosts' endpoints (retried in the
/// background until they are up), and scouts by multicast only when asked.
///
/// # Errors
/// An endpoint Zenoh does not accept.
pub fn config(plan: &BridgePlan) -> Result<zenoh::Config> {
    let mut c = zenoh::Config::default();
    let set = |c: &mut zenoh::Config, key: &str, value: String| {
        c.insert_json5(key, &value)
            .map_err(|e| anyhow::anyhow!("{e}"))
            .with_context(|| format!("Zenoh setting {key} = {value}"))
    };
    set(&mut c, "mode", json("peer"))?;
    set(&mut c, "listen/endpoints", json(&plan.listen))?;
    set(&mut c, "connect/endpoints", json(&plan.connect))?;
    set(&mut c, "scouting/multicast/enabled", json(&plan.scouting))?;
    // The bridges' own window (credit.rs) keeps puts from waiting on a busy host; a put may still wait while a
    // large image crosses a slow link, which Zenoh's default (5 s) would take for a dead session.
    set(
        &mut c,
        "transport/link/tx/queue/congestion_control/block/wait_before_close",
        json(&60_000_000u64),
    )?;
    // Images of tens of MB cross in 64 KB fragments: a larger receive buffer and more batches in flight per
    // priority let the link stream them (measured: `lineflow bench transport --zenoh`, docs/hosts.md).
    set(&mut c, "transport/link/rx/buffer_size", json(&(16u64 << 20)))?;
    set(&mut c, "transport/link/tx/queue/size/data", json(&16u64))?;
    if let Some(tls) = &plan.tls {
        secure(&mut c, plan, tls, set)?;
    }
    Ok(c)
}

/// Mutual TLS (each host shows its certificate, signed by the graph's authority, and checks the other's, names
/// included) and access control: only certificates with the common name of one of the graph's hosts may put,
/// subscribe or declare a token, and only on the graph's own keys; everything else is denied.
fn secure(
    c: &mut zenoh::Config,
    plan: &BridgePlan,
    tls: &TlsPlan,
    set: impl Fn(&mut zenoh::Config, &str, String) -> Result<()>,
) -> Result<()> {
    let path = |p: &std::path::Path| json(&p.to_string_lossy());
    set(c, "transport/link/tls/root_ca_certificate", path(&tls.ca))?;
    for side in ["listen", "connect"] {
        set(c, &format!("transport/link/tls/{side}_certificate"), path(&tls.certificate))?;
        set(c, &format!("transport/link/tls/{side}_private_key"), path(&tls.key))?;
    }
    set(c, "transport/link/tls/enable_mtls", json(&true))?;
    set(c, "transport/link/tls/verify_name_on_connect", json(&true))?;
    let graph_keys = format!("{}/**", crate::wire::Keys::new(&plan.graph, &plan.hash).graph_prefix());
    let acl = serde_json::json!({
        "enabled": true,
        "default_permission": "deny",
        "rules": [{
            "id": "graph",
            "key_exprs": [graph_keys],
            "messages": ["put", "delete", "declare_subscriber", "query", "declare_queryable", "reply",
                         "liveliness_token", "declare_liveliness_subscriber", "liveliness_query"],
            "flows": ["ingress", "egress"],
            "permission": "allow",
        }],
        "subjects": [{ "id": "hosts", "cert_common_names": tls.common_names }],
        "policies": [{ "rules": ["graph"], "subjects": ["hosts"] }],
    });
    set(c, "access_control", acl.to_string())
}

/// A setting's value as JSON5 (JSON is JSON5).
fn json<T: serde::Serialize + ?Sized>(value: &T) -> String {
    serde_json::to_string(value).expect("plain data serializes")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(listen: &[&str], connect: &[&str]) -> BridgePlan {
        BridgePlan {
            graph: "g".into(),
            hash: "0".into(),
            host: "main".into(),
            listen: listen.iter().map(|s| s.to_string()).collect(),
            connect: connect.iter().map(|s| s.to_string()).collect(),
            peers: vec!["camera".into()],
            ..Default::default()
        }
    }

    #[test]
    fn the_session_listens_only_where_the_launch_file_says() {
        let c = config(&plan(&["tcp/127.0.0.1:7447"], &[])).unwrap();
        let listen = c.get_json("listen/endpoints").unwrap();
        assert!(listen.contains("tcp/127.0.0.1:7447"), "{listen}");
        let none = config(&plan(&[], &["tcp/127.0.0.1:7447"])).unwrap();
        let listen = none.get_json("listen/endpoints").unwrap();
        assert!(!listen.contains("tcp/"), "a host without `listen` listens nowhere: {listen}");
        assert!(none.get_json("connect/endpoints").unwrap().contains("tcp/127.0.0.1:7447"));
        assert_eq!(none.get_json("scouting/multicast/enabled").unwrap(), "false");
    }

    #[test]
    fn an_endpoint_zenoh_refuses_is_named() {
        let e = format!("{:#}", config(&plan(&["nonsense"], &[])).unwrap_err());
        assert!(e.contains("listen/endpoints") && e.contains("nonsense"), "{e}");
    }
}
