//! The Foxglove WebSocket server of the live view (the Foxglove SDK's), serving a fixed set of channels, each
//! sent again to a client that subscribes late as its last message.
use std::collections::BTreeMap;
use std::sync::Arc;

use anyhow::{Context as _, Result};
use foxglove::websocket::{ChannelView, Client, ServerListener};
use foxglove::{ChannelId, Context, PartialMetadata, RawChannel, Schema, WebSocketServer, WebSocketServerHandle};
use lineflow_recordings::views::ViewSchema;

use crate::latest::Latest;

/// What the subscribe callback needs: every channel by id, and its last message.
struct Replay {
    channels: BTreeMap<u64, Arc<RawChannel>>,
    latest: Arc<Latest<u64>>,
}

/// Messages queued per client.
const BACKLOG: usize = 32;

fn key(id: ChannelId) -> u64 {
    u64::from(id)
}

impl ServerListener for Replay {
    fn on_subscribe(&self, client: Client, channel: ChannelView) {
        let k = key(channel.id());
        if let (Some(ch), Some(last)) = (self.channels.get(&k), self.latest.get(&k)) {
            ch.log_with_meta_to_sink(&last.bytes, PartialMetadata::with_log_time(last.log_time), client.sink_id());
        }
    }
}

/// The running server.
pub struct LiveServer {
    handle: Option<WebSocketServerHandle>,
    /// Owns the channels: they close when their context is dropped.
    _context: Arc<Context>,
    by_topic: BTreeMap<String, Arc<RawChannel>>,
    latest: Arc<Latest<u64>>,
    port: u16,
}

impl LiveServer {
    /// Listens on `host:port` (0: any free port) and advertises `channels` (topic, schema).
    ///
    /// # Errors
    /// When the address cannot be bound (a port in use names itself), or a channel is refused.
    pub fn start(host: &str, port: u16, channels: &[(String, &'static ViewSchema)]) -> Result<Self> {
        // A context of its own: nothing else in the process logs to the server.
        let context = Context::new();
        let mut by_topic = BTreeMap::new();
        for (topic, view) in channels {
            let schema = Schema::new(view.name, view.schema_encoding, view.data.as_bytes());
            let channel = context
                .channel_builder(topic.as_str())
                .message_encoding(view.message_encoding)
                .schema(schema)
                .build_raw()
                .with_context(|| format!("viewer channel '{topic}'"))?;
            by_topic.insert(topic.clone(), channel);
        }
        let latest = Arc::new(Latest::default());
        let replay = Replay {
            channels: by_topic.values().map(|c| (key(c.id()), c.clone())).collect(),
            latest: latest.clone(),
        };
        let handle = WebSocketServer::new()
            .name("lineflow")
            .context(&context)
            // Per client; the oldest go first when a client reads slower than the run sends. The SDK's 1024 would
            // hold 2 GB of 960-px previews for one stalled client.
            .message_backlog_size(BACKLOG)
            .bind(host, port)
            .listener(Arc::new(replay))
            .start_blocking()
            .with_context(|| format!("the live view cannot listen on {host}:{port}"))?;
        let port = handle.port();
        Ok(Self {
            handle: Some(handle),
            _context: context,
            by_topic,
            latest,
            port,
        })
    }

    /// The port it listens on.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// How many clients are connected.
    pub fn clients(&self) -> usize {
        self.handle.as_ref().map_or(0, WebSocketServerHandle::client_count)
    }

    /// Sends a message on `topic` to the clients subscribed to it and keeps it for those that subscribe later;
    /// a topic that was not advertised is ignored.
    pub fn publish(&self, topic: &str, bytes: &[u8], log_time: u64) {
        if let Some(ch) = self.by_topic.get(topic) {
            self.latest.keep(&key(ch.id()), bytes, log_time);
            ch.log_with_meta(bytes, PartialMetadata::with_log_time(log_time));
        }
    }

    /// Closes the connections and waits for the server's tasks.
    pub fn stop(mut self) {
        if let Some(h) = self.handle.take() {
            h.stop().wait_blocking();
        }
    }
}
