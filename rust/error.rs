//! The one error type of the core: an argument that is out of its documented
//! domain. It names the argument so the Python binding can raise a `ValueError`
//! that tells the user exactly what to fix.

use std::fmt;

#[derive(Clone, Debug, PartialEq)]
pub struct InvalidArgument {
    /// The argument's name as the public API spells it (`"params.intensity"`, `"grid"`).
    pub name: String,
    /// What was expected and what was given.
    pub message: String,
}

impl InvalidArgument {
    pub fn new(name: impl Into<String>, message: impl Into<String>) -> Self {
        Self { name: name.into(), message: message.into() }
    }
}

impl fmt::Display for InvalidArgument {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.name, self.message)
    }
}

impl std::error::Error for InvalidArgument {}

pub type Result<T> = std::result::Result<T, InvalidArgument>;

/// `value` must be finite.
pub fn finite(name: &str, value: f64) -> Result<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(InvalidArgument::new(name, format!("expected a finite number, got {value}")))
    }
}

/// `value` must be finite and within `[lo, hi]`.
pub fn in_range(name: &str, value: f64, lo: f64, hi: f64) -> Result<f64> {
    finite(name, value)?;
    if (lo..=hi).contains(&value) {
        Ok(value)
    } else {
        Err(InvalidArgument::new(name, format!("expected a value in [{lo}, {hi}], got {value}")))
    }
}

/// An integer size within `[lo, hi]`.
pub fn size_in(name: &str, value: i64, lo: i64, hi: i64) -> Result<usize> {
    if (lo..=hi).contains(&value) {
        Ok(value as usize)
    } else {
        Err(InvalidArgument::new(name, format!("expected an integer in [{lo}, {hi}], got {value}")))
    }
}
