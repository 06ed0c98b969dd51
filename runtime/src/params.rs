//! Stage parameters: one error type for a value out of its range, the checks every stage's `validate` is made of,
//! and the trait the process shell reads them through. A launch-file typo or a value out of range stops the node
//! at startup with the parameter, its range and the value given, never halfway through a run.
use std::fmt::Display;

use serde::de::DeserializeOwned;

/// A parameter out of its range: its name, what it must be, and the value given.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{name} must be {requirement}, got {value}")]
pub struct ParamError {
    /// The parameter, as spelled in the launch file.
    pub name: String,
    /// What it must be ("> 0", "in [0, 90)", "at most max_slaves").
    pub requirement: String,
    /// What was given.
    pub value: String,
}

impl ParamError {
    /// The error for `name`, which must be `requirement` and is `value`.
    pub fn new(name: impl Into<String>, requirement: impl Into<String>, value: impl Display) -> Self {
        ParamError {
            name: name.into(),
            requirement: requirement.into(),
            value: value.to_string(),
        }
    }
}

/// `Ok` when `ok`, else the error naming the parameter, its requirement and its value.
///
/// # Errors
/// When `ok` is false.
pub fn check(ok: bool, name: &str, requirement: &str, value: impl Display) -> Result<(), ParamError> {
    if ok {
        Ok(())
    } else {
        Err(ParamError::new(name, requirement, value))
    }
}

/// A file's name in the run's output folder: not empty and without a folder, so that no launch file (`..`, an
/// absolute path) can have a node write outside the run's output folder.
///
/// # Errors
/// When `value` is empty, `.` or `..`, or holds a path separator.
pub fn file_name(name: &str, value: &str) -> Result<(), ParamError> {
    let plain = !value.is_empty() && !value.contains(['/', '\\']) && value != "." && value != "..";
    check(
        plain,
        name,
        "a file name without a folder (files go into the run's output folder)",
        value,
    )
}

/// A finite number above zero.
///
/// # Errors
/// When `value` is not.
pub fn positive(name: &str, value: f64) -> Result<(), ParamError> {
    check(value.is_finite() && value > 0.0, name, "> 0", value)
}

/// A finite number of at least zero.
///
/// # Errors
/// When `value` is not.
pub fn non_negative(name: &str, value: f64) -> Result<(), ParamError> {
    check(value.is_finite() && value >= 0.0, name, ">= 0", value)
}

/// A count of at least `min`.
///
/// # Errors
/// When `value` is below `min`.
pub fn at_least(name: &str, value: usize, min: usize) -> Result<(), ParamError> {
    check(value >= min, name, &format!(">= {min}"), value)
}

/// A number in `[lo, hi)`.
///
/// # Errors
/// When `value` is outside (NaN included).
pub fn in_half_open(name: &str, value: f64, lo: f64, hi: f64) -> Result<(), ParamError> {
    check((lo..hi).contains(&value), name, &format!("in [{lo}, {hi})"), value)
}

/// A number in `[lo, hi]`.
///
/// # Errors
/// When `value` is outside (NaN included).
pub fn in_closed(name: &str, value: f64, lo: f64, hi: f64) -> Result<(), ParamError> {
    check((lo..=hi).contains(&value), name, &format!("in [{lo}, {hi}]"), value)
}

/// The parameters of one stage implementation: read from its launch-file entry (`#[serde(deny_unknown_fields)]`,
/// so that a typo is an error) and checked before the node connects.
pub trait StageParams: DeserializeOwned {
    /// Checks every value against its range.
    ///
    /// # Errors
    /// The first parameter out of range.
    fn validate(&self) -> Result<(), ParamError>;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_message_names_the_parameter_its_range_and_the_value() {
        assert_eq!(positive("sigma_m", -1.5).unwrap_err().to_string(), "sigma_m must be > 0, got -1.5");
        assert_eq!(
            in_half_open("angle_deg", 90.0, 0.0, 90.0).unwrap_err().to_string(),
            "angle_deg must be in [0, 90), got 90"
        );
        assert_eq!(at_least("window", 1, 2).unwrap_err().to_string(), "window must be >= 2, got 1");
    }

    #[test]
    fn nan_and_infinity_are_out_of_every_range() {
        assert!(positive("a", f64::NAN).is_err());
        assert!(non_negative("a", f64::INFINITY).is_err());
        assert!(in_closed("a", f64::NAN, 0.0, 1.0).is_err());
        assert!(in_closed("a", 1.0, 0.0, 1.0).is_ok());
        assert!(non_negative("a", 0.0).is_ok());
    }
}
