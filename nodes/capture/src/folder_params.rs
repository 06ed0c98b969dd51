//! The `folder` implementation's launch-file parameters.
use std::path::PathBuf;

use lineflow_runtime::params::{self, ParamError};
use serde::Deserialize;

/// Where the project is and how its images are streamed.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FolderParams {
    /// Project folder (relative paths from the launch file's folder).
    pub folder: PathBuf,
    /// Frames per second; 0 = as fast as the graph accepts.
    #[serde(default)]
    pub fps: f64,
    /// Keep watching images/ for new files.
    #[serde(default)]
    pub watch: bool,
    /// Watch mode ends after this long without a new file (0 = never).
    #[serde(default = "default_idle")]
    pub idle_timeout_s: f64,
    /// Watch mode ends when this file appears in the project folder.
    #[serde(default = "default_stop_file")]
    pub stop_file: String,
    /// A file must keep its size this long before it is read.
    #[serde(default = "default_settle")]
    pub settle_ms: u64,
    /// Stamp frames from the system clock instead of the fixed start.
    #[serde(default)]
    pub use_clock: bool,
}

fn default_idle() -> f64 {
    30.0
}
fn default_stop_file() -> String {
    "STOP".into()
}
fn default_settle() -> u64 {
    300
}

impl lineflow_runtime::StageParams for FolderParams {
    fn validate(&self) -> Result<(), ParamError> {
        params::non_negative("fps", self.fps)?;
        let idle = self.idle_timeout_s;
        params::check(idle >= 0.0 && !idle.is_nan(), "idle_timeout_s", ">= 0", idle)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_runtime::StageParams;

    #[test]
    fn defaults_fill_in_and_bad_values_are_named() {
        let p: FolderParams = serde_json::from_str(r#"{"folder": "site"}"#).unwrap();
        assert_eq!(
            (p.fps, p.idle_timeout_s, p.stop_file.as_str(), p.settle_ms),
            (0.0, 30.0, "STOP", 300)
        );
        assert!(p.validate().is_ok());
        let never = FolderParams {
            idle_timeout_s: f64::INFINITY,
            ..p.clone()
        };
        assert!(never.validate().is_ok(), "an endless watch is allowed");
        let bad = FolderParams { fps: f64::NAN, ..p };
        assert!(bad.validate().unwrap_err().to_string().starts_with("fps must be >= 0"));
    }
}
