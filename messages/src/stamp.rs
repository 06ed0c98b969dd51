//! The stamp at the start of every message header.
use iceoryx2::prelude::ZeroCopySend;

/// Identity and timing of a message; the first field of every header.
///
/// Capture sources set `frame`, `capture_time_ns` and `seq`; every derived message copies the stamp of the input
/// it was computed from (`conventions.md`, "Time and determinism"), so a live run and its replay carry the same
/// stamps.
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq, ZeroCopySend)]
#[repr(C)]
#[type_name("lineflow/Stamp/v1")]
pub struct Stamp {
    /// Frame number, counted from 0 by the capture source; one-shot messages (camera, site) use 0.
    pub frame: u64,
    /// Capture time, nanoseconds since the Unix epoch.
    pub capture_time_ns: u64,
    /// Sequence number of the message on its topic, counted from 0 by the publisher.
    pub seq: u64,
    /// Bit set of [`StampFlags`].
    pub flags: u32,
    /// Revision of the content (0 = first); a result that improves later is republished with a higher one.
    pub revision: u32,
}

/// Flags of a [`Stamp`].
pub struct StampFlags;

impl StampFlags {
    /// Nothing follows on this topic; the payload is empty.
    pub const END_OF_STREAM: u32 = 1;
    /// The stage could not compute a result for this frame; the payload is empty. Keeps frame numbers contiguous.
    pub const NO_RESULT: u32 = 2;
    /// The result is final (after the end-of-stream adjustment).
    pub const FINAL: u32 = 4;
}

impl Stamp {
    /// Whether this stamp marks the end of the stream.
    pub fn is_end_of_stream(&self) -> bool {
        self.flags & StampFlags::END_OF_STREAM != 0
    }
}
