//! skelform's errors as Python exceptions: what the caller gave is wrong (`ValueError`,
//! `FileNotFoundError` for a missing file), the run failed (`RuntimeError`), or it was
//! cancelled ([`Cancelled`]; Ctrl-C raises `KeyboardInterrupt` as usual).

use pyo3::exceptions::{PyFileNotFoundError, PyRuntimeError, PyValueError};
use pyo3::{PyErr, create_exception};

create_exception!(
    skelform,
    Cancelled,
    PyRuntimeError,
    "The work was cancelled: the progress callback returned False."
);

/// An error of the front door as the exception a Python caller expects.
pub(crate) fn error(e: skelform::Error) -> PyErr {
    if e.is_cancelled() {
        return Cancelled::new_err("cancelled");
    }
    if let skelform::Error::Scene(skelform::SceneError::Io { source, .. }) = &e
        && source.kind() == std::io::ErrorKind::NotFound
    {
        return PyFileNotFoundError::new_err(e.to_string());
    }
    if e.is_input() {
        PyValueError::new_err(e.to_string())
    } else {
        PyRuntimeError::new_err(e.to_string())
    }
}

/// A polygonizer's error (from the extraction-only path, which has no scene).
pub(crate) fn polygonize_error(e: skelform::polygonize::Error) -> PyErr {
    match e {
        skelform::polygonize::Error::Cancelled => Cancelled::new_err("cancelled"),
        e => PyRuntimeError::new_err(e.to_string()),
    }
}

/// A mesh file that cannot be read or written.
pub(crate) fn io_error(e: skelform::mesh::io::IoError) -> PyErr {
    PyValueError::new_err(e.to_string())
}
