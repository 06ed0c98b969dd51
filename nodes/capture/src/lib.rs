//! The capture stage: sources of images. `folder` reads a project folder (`conventions.md`), once or watching it
//! fill up as a tethered camera writes files.
#![warn(missing_docs)]

pub mod decode;
pub mod folder_params;
pub mod pacer;
pub mod synthetic_source;
pub mod watch;

pub use decode::{decode_file, decode_file_for, DecodedImage};
