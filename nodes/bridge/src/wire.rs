//! What crosses between hosts (`docs/hosts.md`): the Zenoh key expressions of a graph, the attachment that names
//! each message's type and version, and what a receiving bridge sends back to the sending one.
use lineflow_messages::checksum::fnv1a64;
use lineflow_messages::image::ImageFormat;
use lineflow_messages::MessageKind;
use serde::{Deserialize, Serialize};

/// The key expressions of one graph. Data and replies carry the graph's hash, so that two runs of different
/// graphs (or of one graph with other settings) never exchange a message; the hosts' liveliness tokens do not,
/// so that such a peer is seen and refused by name.
#[derive(Debug, Clone)]
pub struct Keys {
    graph: String,
    hash: String,
}

impl Keys {
    /// The keys of the graph `name` with hash `hash`.
    pub fn new(name: &str, hash: &str) -> Self {
        Self {
            graph: key_level(name),
            hash: key_level(hash),
        }
    }
    /// The first level of every key of the graph, whatever its hash: `lineflow/GRAPH`.
    pub fn graph_prefix(&self) -> String {
        format!("lineflow/{}", self.graph)
    }
    /// Where a topic's messages are put.
    pub fn data(&self, topic: &str) -> String {
        format!("lineflow/{}/{}/data/{topic}", self.graph, self.hash)
    }
    /// Where the hosts that receive from `host` answer it (credits, ends taken).
    pub fn back(&self, host: &str) -> String {
        format!("lineflow/{}/{}/back/{}", self.graph, self.hash, key_level(host))
    }
    /// Where a host that was interrupted says so.
    pub fn stop(&self) -> String {
        format!("lineflow/{}/{}/stop", self.graph, self.hash)
    }
    /// Where `host` puts its nodes' counters at the end of a run.
    pub fn report(&self, host: &str) -> String {
        format!("lineflow/{}/{}/report/{}", self.graph, self.hash, key_level(host))
    }
    /// Every host's report.
    pub fn reports(&self) -> String {
        format!("lineflow/{}/{}/report/*", self.graph, self.hash)
    }
    /// The liveliness token of `host`.
    pub fn token(&self, host: &str) -> String {
        format!("lineflow/{}/host/{}/{}", self.graph, key_level(host), self.hash)
    }
    /// Every host's token.
    pub fn tokens(&self) -> String {
        format!("lineflow/{}/host/**", self.graph)
    }
    /// The host and graph hash of a token's key.
    pub fn parse_token<'a>(&self, key: &'a str) -> Option<(&'a str, &'a str)> {
        let rest = key
            .strip_prefix("lineflow/")?
            .strip_prefix(self.graph.as_str())?
            .strip_prefix("/host/")?;
        rest.split_once('/')
    }
}

/// A name as one level of a key expression: letters, digits, `_` and `-` kept, anything else `_`.
fn key_level(name: &str) -> String {
    let level: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if level.is_empty() {
        "_".into()
    } else {
        level
    }
}

/// Whether a topic can be the tail of a key expression: Zenoh reserves `*`, `$`, `?` and `#`, and a key has no
/// empty level.
///
/// # Errors
/// What is wrong, naming the topic.
pub fn check_topic(topic: &str) -> Result<(), String> {
    if topic.contains(['*', '$', '?', '#']) || topic.split('/').any(str::is_empty) {
        return Err(format!(
            "topic '{topic}' cannot cross between hosts: a Zenoh key holds no '*', '$', '?' or '#' and no empty level ('//', a leading or trailing '/')"
        ));
    }
    Ok(())
}

/// The version of a message type as it crosses: a hash of its recorded definition (every field, nested types
/// included), so that two builds whose messages differ refuse each other's instead of misreading them.
pub fn version(kind: MessageKind) -> String {
    format!("{:016x}", fnv1a64(kind.schema().ros2msg().as_bytes()))
}

/// How a message of `kind` crosses when images go as `images`: only images are packed, every other kind raw.
pub fn packing(kind: MessageKind, images: ImageFormat) -> ImageFormat {
    if kind == MessageKind::Image {
        images
    } else {
        ImageFormat::Raw
    }
}

/// The attachment of a put on a data key.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Tag {
    /// A message: its type (MCAP schema name) and [`version`].
    Message {
        /// The schema name, e.g. `lineflow_msgs/msg/Image`.
        schema: String,
        /// Its [`version`].
        version: String,
        /// How an image's pixels are packed (`[bridge] images`): raw, or a PNG or JPEG file in their place.
        packed: ImageFormat,
    },
    /// The topic has ended on the sending host: no message follows.
    End,
    /// What follows is what the sending host kept of the topic, re-sent for a restarted bridge on host `to`, which
    /// takes the topic from here on (and nothing before).
    Resend {
        /// The restarted host.
        to: String,
    },
}

impl Tag {
    /// The tag of a message of `kind`, its pixels unpacked.
    pub fn of(kind: MessageKind) -> Self {
        Self::packed(kind, ImageFormat::Raw)
    }
    /// The tag of a message of `kind` whose images go as `images` ([`packing`]).
    pub fn packed(kind: MessageKind, images: ImageFormat) -> Self {
        Tag::Message {
            schema: kind.schema().name(),
            version: version(kind),
            packed: packing(kind, images),
        }
    }
    /// The attachment's bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        match self {
            Tag::Message { schema, version, packed } => match packed.name() {
                None => format!("msg {schema} {version}").into_bytes(),
                Some(format) => format!("msg {schema} {version} {format}").into_bytes(),
            },
            Tag::End => b"end".to_vec(),
            Tag::Resend { to } => format!("resend {to}").into_bytes(),
        }
    }
    /// Reads an attachment.
    ///
    /// # Errors
    /// An attachment that is not a bridge's.
    pub fn parse(bytes: &[u8]) -> Result<Self, String> {
        let text = std::str::from_utf8(bytes).map_err(|_| "attachment is not UTF-8".to_owned())?;
        let not_ours = || {
            format!(
                "attachment '{}' is not a lineflow bridge's",
                text.chars().take(80).collect::<String>()
            )
        };
        let mut words = text.split(' ');
        match (words.next(), words.next(), words.next(), words.next(), words.next()) {
            (Some("end"), None, None, None, None) => Ok(Tag::End),
            (Some("resend"), Some(to), None, None, None) => Ok(Tag::Resend { to: to.into() }),
            (Some("msg"), Some(schema), Some(version), packed, None) => Ok(Tag::Message {
                schema: schema.into(),
                version: version.into(),
                packed: match packed {
                    None => ImageFormat::Raw,
                    Some("raw") => return Err(not_ours()),
                    Some(p) => p.parse().map_err(|e| format!("{}: {e}", not_ours()))?,
                },
            }),
            _ => Err(not_ours()),
        }
    }
    /// Checks that a message tagged so can be read on `topic`, whose messages this host tags `want`
    /// ([`Tag::of`] its type, computed once: it hashes the type's definition).
    ///
    /// # Errors
    /// The type or version that differs, naming both; pixels packed in a message that is no image.
    pub fn check(&self, want: &Tag, topic: &str) -> Result<(), String> {
        match (self, want) {
            (Tag::End | Tag::Resend { .. }, _) => Ok(()),
            (Tag::Message { schema, .. }, Tag::Message { schema: s, .. }) if schema != s => Err(format!(
                "topic '{topic}': a message of type {schema} arrived where this graph carries {s}"
            )),
            (Tag::Message { version, .. }, Tag::Message { schema, version: v, .. }) if version != v => Err(format!(
                "topic '{topic}': the sending host's {schema} is version {version}, this host's {v}: run the same lineflow on every host"
            )),
            (Tag::Message { packed, schema, .. }, _) if *packed != ImageFormat::Raw && *schema != MessageKind::Image.schema().name() => {
                Err(format!(
                    "topic '{topic}': a {schema} arrived packed as {packed:?}, which only images are"
                ))
            }
            _ => Ok(()),
        }
    }
}

/// What a receiving host tells the sending one about a topic.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Reply {
    /// The receiving host.
    pub from: String,
    /// The topic.
    pub topic: String,
    /// Messages it has published into its own graph since its last reply: room for as many more.
    pub credit: u64,
    /// It has taken the topic's end: nothing more is owed to it.
    pub ended: bool,
    /// It was restarted and asks for what the sending host kept of every topic it receives from it (`topic` is
    /// then empty).
    #[serde(default)]
    pub resend: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_keep_graphs_apart_and_tokens_name_their_host() {
        let k = Keys::new("demo two hosts", "00ff");
        assert_eq!(k.data("gt/poses"), "lineflow/demo_two_hosts/00ff/data/gt/poses");
        assert_ne!(Keys::new("demo", "01").data("images"), Keys::new("demo", "02").data("images"));
        assert_eq!(k.parse_token(&k.token("camera")), Some(("camera", "00ff")));
        assert_eq!(k.parse_token("lineflow/other/host/camera/00ff"), None);
    }

    #[test]
    fn topics_that_are_no_key_are_refused_by_name() {
        assert!(check_topic("gt/lines3d").is_ok());
        for bad in ["a*", "a//b", "/a", "a/", "x$y"] {
            let e = check_topic(bad).unwrap_err();
            assert!(e.contains(&format!("'{bad}'")), "{e}");
        }
    }

    #[test]
    fn tags_round_trip_and_a_type_or_version_mismatch_is_named() {
        let tag = Tag::of(MessageKind::Image);
        assert_eq!(Tag::parse(&tag.to_bytes()).unwrap(), tag);
        assert_eq!(Tag::parse(b"end").unwrap(), Tag::End);
        let resend = Tag::Resend { to: "main".into() };
        assert_eq!(Tag::parse(&resend.to_bytes()).unwrap(), resend);
        assert!(Tag::parse(b"resend").is_err() && Tag::parse(b"resend a b").is_err());
        assert!(Tag::parse(b"hello").is_err());
        assert!(tag.check(&Tag::of(MessageKind::Image), "images").is_ok());
        let e = tag.check(&Tag::of(MessageKind::Lines2D), "lines2d").unwrap_err();
        assert!(e.contains("lineflow_msgs/msg/Image") && e.contains("lines2d"), "{e}");
        let old = Tag::Message {
            schema: MessageKind::Image.schema().name(),
            version: "0000000000000000".into(),
            packed: ImageFormat::Raw,
        };
        let e = old.check(&tag, "images").unwrap_err();
        assert!(e.contains("version 0000000000000000"), "{e}");
        assert_ne!(version(MessageKind::Image), version(MessageKind::Lines2D));
    }

    #[test]
    fn packed_images_are_tagged_and_nothing_else_may_be() {
        for format in [ImageFormat::Png, ImageFormat::Jpeg] {
            let tag = Tag::packed(MessageKind::Image, format);
            assert_eq!(Tag::parse(&tag.to_bytes()).unwrap(), tag);
            assert!(tag.check(&Tag::of(MessageKind::Image), "images").is_ok());
        }
        assert_eq!(Tag::packed(MessageKind::Lines2D, ImageFormat::Png), Tag::of(MessageKind::Lines2D));
        let forged = [
            b"msg ".as_slice(),
            MessageKind::Lines2D.schema().name().as_bytes(),
            b" ",
            version(MessageKind::Lines2D).as_bytes(),
            b" png",
        ]
        .concat();
        let e = Tag::parse(&forged)
            .unwrap()
            .check(&Tag::of(MessageKind::Lines2D), "lines2d")
            .unwrap_err();
        assert!(e.contains("only images"), "{e}");
        for bad in ["msg a b raw", "msg a b gif", "msg a b png x"] {
            assert!(Tag::parse(bad.as_bytes()).is_err(), "{bad}");
        }
    }
}
