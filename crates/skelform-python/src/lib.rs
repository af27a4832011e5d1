//! The `skelform` Python module's native half (`skelform._skelform`): NumPy in and out over
//! skelform's library.
//!
//! What it guarantees: `marching_cubes` gives scikit-image's conventions (axis order,
//! coordinates, winding, dtypes, errors) with skelform's topology: ambiguous cubes resolved
//! by the trilinear interpolant, no holes where samples equal the level, closed surfaces
//! wherever the surface stays inside the volume. Meshes of scenes and fields keep the
//! guarantees of their method (see the `skelform` crate). Every long call releases the GIL,
//! answers Ctrl-C (`KeyboardInterrupt`) and a progress callback, and gives the same result
//! on any number of threads.
//!
//! What it does not: vertices are not welded across the faces of a volume's cubes other
//! than through shared edges (as scikit-image's are), triangles are not of good shape, and
//! a Python callable field runs one batch at a time (it holds the GIL).
//!
//! The Python half (`python/skelform/__init__.py`) checks `marching_cubes`' arguments
//! exactly as scikit-image does and applies the spacing; the tests are the pytest suite
//! in `tests/`, run on the installed wheel.

mod errors;
mod field;
mod mesh;
mod pooled;
mod run;
mod scene;
mod volume;

use pyo3::prelude::*;

#[pymodule]
fn _skelform(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add("Cancelled", m.py().get_type::<errors::Cancelled>())?;
    m.add_class::<mesh::PyMesh>()?;
    m.add_class::<field::PyFormula>()?;
    m.add_class::<scene::PyScene>()?;
    m.add_function(wrap_pyfunction!(volume::marching_cubes_core, m)?)?;
    m.add_function(wrap_pyfunction!(scene::load_scene, m)?)?;
    m.add_function(wrap_pyfunction!(scene::mesh, m)?)?;
    Ok(())
}
