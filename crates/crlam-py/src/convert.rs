//! Error mapping and array helpers.

use crlam_core::CrlamError;
use numpy::{PyReadonlyArray1, PyReadonlyArray2, PyUntypedArrayMethods};
use pyo3::prelude::*;

/// Raises the `crlam.errors` class matching a core error (the Python module is the single
/// definition of the hierarchy).
pub fn to_py(err: CrlamError) -> PyErr {
    Python::with_gil(|py| {
        let class = match &err {
            CrlamError::Config { .. } | CrlamError::Shape(_) => "ConfigError",
            CrlamError::OutOfBounds(_) => "MapBoundsError",
            CrlamError::NonFinite { .. } => "NumericalError",
            CrlamError::Limit { .. } | CrlamError::Alloc(_) => "ResourceLimitError",
        };
        let msg = err.to_string();
        match py
            .import("crlam.errors")
            .and_then(|m| m.getattr(class))
            .and_then(|c| c.call1((msg.clone(),)))
        {
            Ok(obj) => PyErr::from_value(obj),
            Err(_) => pyo3::exceptions::PyValueError::new_err(msg),
        }
    })
}

/// Runs the body of a Python-facing function, turning a panic (a bug: the core returns errors
/// for every bad input) into `crlam.errors.InternalError`, a `CrlamError`, instead of PyO3's
/// `PanicException`, which derives from `BaseException` and escapes `except Exception`.
pub fn guard<T>(what: &str, body: impl FnOnce() -> PyResult<T>) -> PyResult<T> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(body)) {
        Ok(result) => result,
        Err(payload) => {
            let reason = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            let msg = format!(
                "internal error in {what}: {reason} (a bug in crlam; please report it with the call that caused it)"
            );
            Err(Python::with_gil(|py| {
                match py
                    .import("crlam.errors")
                    .and_then(|m| m.getattr("InternalError"))
                    .and_then(|c| c.call1((msg.clone(),)))
                {
                    Ok(obj) => PyErr::from_value(obj),
                    Err(_) => pyo3::exceptions::PyRuntimeError::new_err(msg),
                }
            }))
        }
    }
}

/// Shorthand for mapping a core `Result` into a `PyResult`.
pub trait IntoPy<T> {
    fn py_err(self) -> PyResult<T>;
}

impl<T> IntoPy<T> for crlam_core::Result<T> {
    fn py_err(self) -> PyResult<T> {
        self.map_err(to_py)
    }
}

/// A `ConfigError` from the glue itself (argument shapes).
pub fn shape_err(msg: impl Into<String>) -> PyErr {
    to_py(CrlamError::Shape(msg.into()))
}

/// Contiguous slice of a 1-D array argument.
pub fn slice1<'a>(a: &'a PyReadonlyArray1<'_, f64>, name: &str) -> PyResult<&'a [f64]> {
    a.as_slice()
        .map_err(|_| shape_err(format!("{name} must be a contiguous float64 array")))
}

/// A pose argument of length 3.
pub fn pose3(a: &PyReadonlyArray1<'_, f64>) -> PyResult<[f64; 3]> {
    let s = slice1(a, "pose")?;
    if s.len() != 3 {
        return Err(shape_err(format!(
            "pose must have 3 values (x, y, theta), got {}",
            s.len()
        )));
    }
    Ok([s[0], s[1], s[2]])
}

/// An (n, 3) pose array as a vector of poses.
pub fn poses_n3(a: &PyReadonlyArray2<'_, f64>) -> PyResult<Vec<[f64; 3]>> {
    let shape = a.shape();
    if shape[1] != 3 {
        return Err(shape_err(format!(
            "poses must have shape (n, 3), got {shape:?}"
        )));
    }
    let s = a
        .as_slice()
        .map_err(|_| shape_err("poses must be a contiguous float64 array"))?;
    Ok(s.chunks(3).map(|c| [c[0], c[1], c[2]]).collect())
}
