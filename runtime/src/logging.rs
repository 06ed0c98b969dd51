//! Logging: `tracing` to stderr, the node name in every line, level from `LINEFLOW_LOG` (default `info`; Zenoh's
//! at `warn`).
use tracing_subscriber::EnvFilter;

/// Installs the subscriber once; later calls do nothing. iceoryx2's own log is limited to errors (its warnings
/// about missing config files are noise here: every run is configured programmatically).
pub fn init(node: &str) {
    iceoryx2::prelude::set_log_level_from_env_or(iceoryx2::prelude::LogLevel::Error);
    // Zenoh's own info lines (its session id, its endpoints, each session closed) are noise in a run's log; its
    // warnings stay. An explicit `LINEFLOW_LOG` may still ask for them (`info,zenoh=info`).
    let level = std::env::var("LINEFLOW_LOG").unwrap_or_else(|_| "info".into());
    let filter = EnvFilter::try_new(format!("zenoh=warn,{level}")).unwrap_or_else(|_| EnvFilter::new("info,zenoh=warn"));
    let node = node.to_owned();
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .without_time()
        // The lines go through the supervisor into log files as well as to a terminal: no escape codes.
        .with_ansi(false)
        .event_format(NodeFormat { node })
        .try_init();
}

struct NodeFormat {
    node: String,
}

impl<S, N> tracing_subscriber::fmt::FormatEvent<S, N> for NodeFormat
where
    S: tracing::Subscriber + for<'a> tracing_subscriber::registry::LookupSpan<'a>,
    N: for<'a> tracing_subscriber::fmt::FormatFields<'a> + 'static,
{
    fn format_event(
        &self,
        ctx: &tracing_subscriber::fmt::FmtContext<'_, S, N>,
        mut w: tracing_subscriber::fmt::format::Writer<'_>,
        event: &tracing::Event<'_>,
    ) -> std::fmt::Result {
        let level = *event.metadata().level();
        write!(w, "[{}] {:5} ", self.node, level)?;
        ctx.field_format().format_fields(w.by_ref(), event)?;
        writeln!(w)
    }
}
