//! The live viewer: every topic of a run rendered into the recorder's viewer channels (`lineflow_recordings::views`)
//! and served over the Foxglove WebSocket protocol while the photos arrive.
pub mod latest;
pub mod live;
pub mod server;
