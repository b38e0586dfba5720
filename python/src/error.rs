//! How Rust errors reach Python: bad input as `ValueError`, a failed run as `RiskTwinError`,
//! both with the Rust message.

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyValueError};
use pyo3::prelude::*;

create_exception!(risktwin._native, RiskTwinError, PyException, "A RiskTwin run failed (the message says why).");

/// Bad input: `ValueError` with the message.
pub fn bad_input(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// A failure of the run: `RiskTwinError` with the message.
pub fn failed(e: impl std::fmt::Display) -> PyErr {
    RiskTwinError::new_err(e.to_string())
}
