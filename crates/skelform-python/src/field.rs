//! Fields from Python: formulas evaluated on broadcasting NumPy arrays, and Python
//! callables as fields that skelform's polygonizers sample.

use std::sync::{Arc, Mutex, PoisonError};

use numpy::{PyArray1, PyArrayDyn, PyArrayMethods, PyReadonlyArrayDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rayon::prelude::*;
use skelform::{Control, DVec3, Field, Formula};

/// Points per task when a formula is evaluated in parallel.
const CHUNK: usize = 4096;

/// `x`, `y`, `z` broadcast against each other as contiguous float64 arrays.
fn broadcast<'py>(
    py: Python<'py>,
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    z: &Bound<'py, PyAny>,
) -> PyResult<(Vec<usize>, [PyReadonlyArrayDyn<'py, f64>; 3])> {
    let np = py.import("numpy")?;
    let arrays = np.call_method1("broadcast_arrays", (x, y, z))?;
    let get = |i: usize| -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
        let a = arrays.get_item(i)?;
        np.call_method1("ascontiguousarray", (a, "float64"))?.extract()
    };
    let (ax, ay, az) = (get(0)?, get(1)?, get(2)?);
    // Taken before `ascontiguousarray`, which makes numbers 1-D.
    let shape: Vec<usize> = arrays.get_item(0)?.getattr("shape")?.extract()?;
    Ok((shape, [ax, ay, az]))
}

/// The points of broadcast coordinate arrays.
fn points(c: &[PyReadonlyArrayDyn<'_, f64>; 3]) -> PyResult<Vec<DVec3>> {
    fn s<'a>(a: &'a PyReadonlyArrayDyn<'_, f64>) -> PyResult<&'a [f64]> {
        a.as_slice().map_err(|e| PyValueError::new_err(e.to_string()))
    }
    let (x, y, z) = (s(&c[0])?, s(&c[1])?, s(&c[2])?);
    Ok(x.iter().zip(y).zip(z).map(|((&x, &y), &z)| DVec3::new(x, y, z)).collect())
}

/// `field` at the broadcast points, shaped like them; the GIL is released while it runs.
pub(crate) fn eval_on<'py>(
    py: Python<'py>,
    field: &(dyn Field + 'static),
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    z: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let (shape, c) = broadcast(py, x, y, z)?;
    let p = points(&c)?;
    let out = py.detach(|| {
        let mut out = vec![0.0; p.len()];
        out.par_chunks_mut(CHUNK).zip(p.par_chunks(CHUNK)).for_each(|(o, p)| field.eval_many(p, o));
        out
    });
    PyArray1::from_vec(py, out).reshape(shape)
}

/// The gradient of `field` at the broadcast points, shaped like them with a last axis of 3.
pub(crate) fn gradient_on<'py>(
    py: Python<'py>,
    field: &(dyn Field + 'static),
    x: &Bound<'py, PyAny>,
    y: &Bound<'py, PyAny>,
    z: &Bound<'py, PyAny>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let (mut shape, c) = broadcast(py, x, y, z)?;
    let p = points(&c)?;
    let out = py.detach(|| {
        p.par_iter().flat_map_iter(|&q| field.gradient(q).to_array()).collect::<Vec<f64>>()
    });
    shape.push(3);
    PyArray1::from_vec(py, out).reshape(shape)
}

/// A formula in skelform's language (`sqrt(x^2 + y^2 + z^2) - 0.8`, definitions, CSG and
/// smooth CSG; see SCENES.md), compiled once and evaluated on NumPy arrays.
#[pyclass(module = "skelform", name = "Formula", frozen)]
pub(crate) struct PyFormula {
    pub(crate) formula: Arc<Formula>,
}

#[pymethods]
impl PyFormula {
    /// Compiles `text`; a mistake raises ValueError with its line and column.
    #[new]
    pub(crate) fn new(text: &str) -> PyResult<PyFormula> {
        let formula = Formula::parse(text).map_err(|e| {
            PyValueError::new_err(format!(
                "formula, line {}, column {}: {}",
                e.line(),
                e.column(),
                e.message()
            ))
        })?;
        Ok(PyFormula { formula: Arc::new(formula) })
    }

    /// The value at the points (x, y, z), arrays (or numbers) broadcast against each other.
    fn eval<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        y: &Bound<'py, PyAny>,
        z: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        eval_on(py, self.formula.as_ref(), x, y, z)
    }

    /// Same as `eval`.
    fn __call__<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        y: &Bound<'py, PyAny>,
        z: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        eval_on(py, self.formula.as_ref(), x, y, z)
    }

    /// The gradient at the points, with a last axis of 3 (∂/∂x, ∂/∂y, ∂/∂z).
    fn gradient<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        y: &Bound<'py, PyAny>,
        z: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        gradient_on(py, self.formula.as_ref(), x, y, z)
    }

    /// The formula's text.
    #[getter]
    fn source(&self) -> String {
        self.formula.source().to_string()
    }

    fn __repr__(&self) -> String {
        format!("Formula({:?})", self.formula.source())
    }
}

/// A Python callable as a field: called with an (N, 3) float64 array of points, it returns
/// N values. It is called in batches (a lattice layer at a time when sampling), holding the
/// GIL; its first exception stops the run and is raised when the run returns.
pub(crate) struct CallableField {
    func: Py<PyAny>,
    control: Control,
    failure: Mutex<Option<PyErr>>,
}

impl CallableField {
    pub(crate) fn new(func: Py<PyAny>, control: Control) -> CallableField {
        CallableField { func, control, failure: Mutex::new(None) }
    }

    /// The callable's first exception, if it raised.
    pub(crate) fn take_failure(&self) -> Option<PyErr> {
        self.failure.lock().unwrap_or_else(PoisonError::into_inner).take()
    }

    fn call(&self, py: Python<'_>, points: &[DVec3], out: &mut [f64]) -> PyResult<()> {
        let flat: Vec<f64> = points.iter().flat_map(|p| p.to_array()).collect();
        let arg = PyArray1::from_vec(py, flat).reshape([points.len(), 3])?;
        let result = self.func.call1(py, (arg,))?;
        let np = py.import("numpy")?;
        let values = np.call_method1("asarray", (result, "float64"))?;
        let values = values.call_method1("reshape", (-1,))?;
        let values: PyReadonlyArrayDyn<'_, f64> =
            np.call_method1("ascontiguousarray", (values,))?.extract()?;
        let values = values.as_slice().map_err(|e| PyValueError::new_err(e.to_string()))?;
        if values.len() != out.len() {
            return Err(PyValueError::new_err(format!(
                "the field returned {} values for {} points (it is given an (N, 3) array and \
                 must return N values)",
                values.len(),
                out.len()
            )));
        }
        out.copy_from_slice(values);
        Ok(())
    }
}

impl Field for CallableField {
    fn eval(&self, p: DVec3) -> f64 {
        let mut out = [0.0];
        self.eval_many(&[p], &mut out);
        out[0]
    }

    fn eval_many(&self, points: &[DVec3], out: &mut [f64]) {
        if self.control.is_cancelled() || points.is_empty() {
            out.fill(f64::NAN);
            return;
        }
        Python::attach(|py| {
            if let Err(e) = self.call(py, points, out) {
                let mut failure = self.failure.lock().unwrap_or_else(PoisonError::into_inner);
                failure.get_or_insert(e);
                self.control.cancel();
                out.fill(f64::NAN);
            }
        });
    }

    /// One call for the whole layer, not one a row.
    fn eval_layer(&self, xs: &[f64], ys: &[f64], z: f64, out: &mut [f64]) {
        let points: Vec<DVec3> =
            ys.iter().flat_map(|&y| xs.iter().map(move |&x| DVec3::new(x, y, z))).collect();
        self.eval_many(&points, out);
    }

    /// Central differences, all points in one call.
    fn gradient(&self, p: DVec3) -> DVec3 {
        let mut g = [DVec3::ZERO];
        let mut v = [0.0];
        self.eval_grad_many(&[p], &mut v, &mut g);
        g[0]
    }

    fn eval_grad_many(&self, points: &[DVec3], values: &mut [f64], grads: &mut [DVec3]) {
        let h = self.gradient_step();
        let axes = [DVec3::X, DVec3::Y, DVec3::Z];
        let mut all = Vec::with_capacity(points.len() * 7);
        for &p in points {
            all.push(p);
            for e in axes {
                all.push(p + e * h);
                all.push(p - e * h);
            }
        }
        let mut out = vec![0.0; all.len()];
        self.eval_many(&all, &mut out);
        for ((chunk, v), g) in out.chunks_exact(7).zip(values.iter_mut()).zip(grads.iter_mut()) {
            *v = chunk[0];
            let d = |a: usize| (chunk[1 + 2 * a] - chunk[2 + 2 * a]) / (2.0 * h);
            *g = DVec3::new(d(0), d(1), d(2));
        }
    }
}
