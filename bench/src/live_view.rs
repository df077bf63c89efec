//! Live view: a run's or a replay's streams served to Foxglove over its WebSocket protocol
//! (the `foxglove` crate's server), bound to 127.0.0.1 unless asked otherwise.
//!
//! Channels carry the recording's topics, schemas (JSON Schema) and JSON bodies, so a Foxglove
//! layout made for a recording works live. Open Foxglove → "Open connection" →
//! `ws://127.0.0.1:8765`.
//!
//! ```no_run
//! # async fn demo() -> Result<(), bench::live_view::LiveError> {
//! let live = bench::live_view::LiveView::start("127.0.0.1", 8765).await?;
//! live.publish("/gyro/rate", 1_700_000_000_000_000_000, br#"{"rate":0.1,"temperature":null,"seq":0,"status":0}"#);
//! # Ok(()) }
//! ```

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use foxglove::{ChannelBuilder, Context, PartialMetadata, RawChannel, Schema, WebSocketServer};
use serde_json::json;

use crate::run::{Event, EventSink};
use bench_recording::schema::{
    CHAMBER_SCHEMA_JSON, GYRO_SCHEMA_JSON, LOG_SCHEMA_JSON, MESSAGE_ENCODING, SCHEMA_CHAMBER,
    SCHEMA_ENCODING, SCHEMA_GYRO, SCHEMA_LOG, SCHEMA_STEP, SCHEMA_TABLE, STEP_SCHEMA_JSON,
    TABLE_SCHEMA_JSON, TOPIC_CHAMBER, TOPIC_GYRO, TOPIC_LOG, TOPIC_STEP, TOPIC_TABLE,
};

/// Default port of Foxglove's WebSocket connection.
pub const DEFAULT_PORT: u16 = 8765;

/// The live view could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The server or a channel could not be made.
    #[error("live view on {host}:{port}: {source}")]
    Start {
        /// Host asked for.
        host: String,
        /// Port asked for.
        port: u16,
        /// The foxglove crate's error.
        #[source]
        source: foxglove::FoxgloveError,
    },
}

/// A running Foxglove WebSocket server with the bench's channels. The server stops when the
/// view is dropped.
pub struct LiveView {
    ctx: Arc<Context>,
    handle: Option<foxglove::WebSocketServerHandle>,
    port: u16,
    channels: Mutex<HashMap<String, Arc<RawChannel>>>,
}

impl std::fmt::Debug for LiveView {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveView").field("port", &self.port).finish_non_exhaustive()
    }
}

/// The contract's channels: topic, schema name, schema.
const CONTRACT: [(&str, &str, &str); 5] = [
    (TOPIC_GYRO, SCHEMA_GYRO, GYRO_SCHEMA_JSON),
    (TOPIC_TABLE, SCHEMA_TABLE, TABLE_SCHEMA_JSON),
    (TOPIC_CHAMBER, SCHEMA_CHAMBER, CHAMBER_SCHEMA_JSON),
    (TOPIC_STEP, SCHEMA_STEP, STEP_SCHEMA_JSON),
    (TOPIC_LOG, SCHEMA_LOG, LOG_SCHEMA_JSON),
];

impl LiveView {
    /// Start the server on `host:port` (port 0: any free port) on the current tokio runtime,
    /// with the contract's five channels advertised.
    pub async fn start(host: &str, port: u16) -> Result<Self, LiveError> {
        let err = |source| LiveError::Start { host: host.to_string(), port, source };
        let ctx = Context::new();
        let handle = WebSocketServer::new()
            .name(format!("bench {}", env!("CARGO_PKG_VERSION")))
            .bind(host, port)
            .context(&ctx)
            .start()
            .await
            .map_err(err)?;
        let view = Self {
            ctx,
            port: handle.port(),
            handle: Some(handle),
            channels: Mutex::new(HashMap::new()),
        };
        for (topic, name, schema) in CONTRACT {
            view.channel(topic, Some((name, SCHEMA_ENCODING, schema.as_bytes())), MESSAGE_ENCODING)
                .map_err(err)?;
        }
        Ok(view)
    }

    /// The port the server listens on.
    pub fn port(&self) -> u16 {
        self.port
    }

    /// The channel of `topic`, created with `schema` (name, encoding, data) and
    /// `message_encoding` on first use.
    pub fn channel(
        &self,
        topic: &str,
        schema: Option<(&str, &str, &[u8])>,
        message_encoding: &str,
    ) -> Result<Arc<RawChannel>, foxglove::FoxgloveError> {
        let mut map = self.channels.lock().unwrap_or_else(|p| p.into_inner());
        if let Some(c) = map.get(topic) {
            return Ok(c.clone());
        }
        let schema = schema.map(|(n, e, d)| Schema::new(n, e, d.to_vec()));
        let c = ChannelBuilder::new(topic)
            .message_encoding(message_encoding)
            .schema(schema)
            .context(&self.ctx)
            .build_raw()?;
        map.insert(topic.to_string(), c.clone());
        Ok(c)
    }

    /// Publish a JSON body on one of the contract's topics (other topics are ignored unless
    /// made with [`LiveView::channel`]), stamped `log_time_ns`.
    pub fn publish(&self, topic: &str, log_time_ns: u64, body: &[u8]) {
        let c = self.channels.lock().unwrap_or_else(|p| p.into_inner()).get(topic).cloned();
        if let Some(c) = c {
            c.log_with_meta(body, PartialMetadata { log_time: Some(log_time_ns) });
        }
    }

    /// Publish one orchestrator event of a run whose bench time zero is `epoch_ns`.
    pub fn publish_event(&self, epoch_ns: u64, event: &Event) {
        let at = |t: &std::time::Duration| epoch_ns.saturating_add(t.as_nanos() as u64);
        let (topic, t, body) = match event {
            Event::Gyro(t, s) => (
                TOPIC_GYRO,
                at(t),
                json!({"rate": s.rate_rad_s, "temperature": s.temperature_c, "seq": s.seq,
                       "status": s.status}),
            ),
            Event::Table(t, r) => (
                TOPIC_TABLE,
                at(t),
                json!({"angle": r.angle_rad, "rate": r.rate_rad_s,
                       "rate_command": r.rate_command_rad_s, "status": r.status}),
            ),
            Event::Chamber(t, r) => (
                TOPIC_CHAMBER,
                at(t),
                json!({"temperature": r.temperature_c, "setpoint": r.setpoint_c,
                       "status": r.status}),
            ),
            Event::Step { t, index, name, event, label } => (
                TOPIC_STEP,
                at(t),
                json!({"index": index, "name": name, "event": event.as_str(), "label": label}),
            ),
            Event::Log { t, level, message, name, file, line } => {
                let ns = at(t);
                (
                    TOPIC_LOG,
                    ns,
                    json!({"timestamp": {"sec": ns / 1_000_000_000, "nsec": ns % 1_000_000_000},
                           "level": *level as u8, "message": message, "name": name,
                           "file": file, "line": line}),
                )
            }
        };
        // Non-finite numbers become null in JSON text: the view shows a gap.
        if let Ok(bytes) = serde_json::to_vec(&body) {
            self.publish(topic, t, &bytes);
        }
    }
}

impl Drop for LiveView {
    fn drop(&mut self) {
        if let Some(h) = self.handle.take() {
            // The shutdown runs on the server's runtime; nothing to wait for here.
            drop(h.stop());
        }
    }
}

/// An [`EventSink`] that records into `inner` and shows every event in a [`LiveView`].
pub struct LiveTee<S> {
    inner: S,
    live: Option<Arc<LiveView>>,
    epoch_ns: u64,
}

impl<S> LiveTee<S> {
    /// Record into `inner`; also publish to `live` if given (bench time zero at `epoch_ns`).
    pub fn new(inner: S, live: Option<Arc<LiveView>>, epoch_ns: u64) -> Self {
        Self { inner, live, epoch_ns }
    }

    /// The inner sink.
    pub fn into_inner(self) -> S {
        self.inner
    }
}

impl<S: EventSink> EventSink for LiveTee<S> {
    fn record(&mut self, event: &Event) -> anyhow::Result<()> {
        if let Some(live) = &self.live {
            live.publish_event(self.epoch_ns, event);
        }
        self.inner.record(event)
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use futures::{SinkExt, StreamExt};
    use tokio_tungstenite::tungstenite::client::IntoClientRequest;
    use tokio_tungstenite::tungstenite::Message;

    use super::*;

    /// A WebSocket client connects, is told about the five channels, subscribes to the gyro's
    /// and receives a published sample.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_client_sees_the_channels_and_the_data() {
        let live = LiveView::start("127.0.0.1", 0).await.expect("starts");
        assert_ne!(live.port(), 0);
        let mut req =
            format!("ws://127.0.0.1:{}", live.port()).into_client_request().expect("request");
        req.headers_mut()
            .insert("sec-websocket-protocol", "foxglove.sdk.v1".parse().expect("header value"));
        let (mut ws, _) = tokio_tungstenite::connect_async(req).await.expect("connects");
        let mut topics: HashMap<String, u64> = HashMap::new();
        let deadline = tokio::time::Instant::now() + Duration::from_secs(10);
        while topics.len() < 5 {
            let msg = tokio::time::timeout_at(deadline, ws.next())
                .await
                .expect("advertised in time")
                .expect("open")
                .expect("message");
            if let Message::Text(text) = msg {
                let v: serde_json::Value = serde_json::from_str(&text).expect("JSON");
                if v["op"] == "advertise" {
                    for c in v["channels"].as_array().expect("channels") {
                        let topic = c["topic"].as_str().expect("topic").to_string();
                        assert_eq!(c["encoding"], "json");
                        topics.insert(topic, c["id"].as_u64().expect("id"));
                    }
                }
            }
        }
        let mut names: Vec<&str> = topics.keys().map(String::as_str).collect();
        names.sort();
        assert_eq!(names, ["/bench/step", "/chamber/state", "/gyro/rate", "/log", "/table/state"]);
        let sub = json!({"op": "subscribe",
                         "subscriptions": [{"id": 7, "channelId": topics["/gyro/rate"]}]});
        ws.send(Message::Text(sub.to_string().into())).await.expect("subscribe");
        // Publish until the subscription is in place and a message arrives.
        let sample = crate::run::Event::Gyro(
            Duration::from_millis(50),
            bench_drivers::GyroSample {
                rate_rad_s: 0.25,
                temperature_c: None,
                seq: 9,
                status: 0,
                device_time: None,
            },
        );
        loop {
            live.publish_event(1_000_000_000, &sample);
            let msg = tokio::time::timeout(Duration::from_millis(100), ws.next()).await;
            let Ok(Some(Ok(Message::Binary(bin)))) = msg else {
                assert!(tokio::time::Instant::now() < deadline, "no message data");
                continue;
            };
            // opcode 1 (message data), subscription id u32, log time u64, then the body.
            assert_eq!(bin.first(), Some(&1));
            assert_eq!(bin.get(1..5), Some(&7u32.to_le_bytes()[..]));
            assert_eq!(bin.get(5..13), Some(&1_050_000_000u64.to_le_bytes()[..]));
            let body: serde_json::Value =
                serde_json::from_slice(bin.get(13..).expect("body")).expect("JSON body");
            assert_eq!(body, json!({"rate": 0.25, "temperature": null, "seq": 9, "status": 0}));
            break;
        }
    }
}
