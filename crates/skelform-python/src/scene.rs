//! Scenes from Python: a scene file or text meshed with overrides, and `skelform.mesh` for a
//! field given as a formula, a scene or a Python callable.

use std::path::PathBuf;
use std::sync::Arc;

use numpy::PyArrayDyn;
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use skelform::{Aabb, DVec3, LoadOptions, Method, Overrides, Resolution, Threads};

use crate::errors::error;
use crate::field::{CallableField, PyFormula, eval_on};
use crate::mesh::PyMesh;
use crate::run::{Run, pool};

/// A checked scene (a TOML file of skelform's scene language), ready to mesh.
#[pyclass(module = "skelform", name = "Scene", frozen)]
pub(crate) struct PyScene {
    pub(crate) scene: skelform::Scene,
}

/// What a mesh call may change, as keyword arguments.
#[derive(Default)]
pub(crate) struct Choices {
    resolution: Option<usize>,
    cell: Option<f64>,
    method: Option<String>,
    pose: Option<String>,
    threads: Option<usize>,
    refine: Option<bool>,
    normals: Option<bool>,
    max_memory: Option<u64>,
    seeds: Option<Vec<[f64; 3]>>,
}

impl Choices {
    fn overrides(&self, run: &Run) -> PyResult<Overrides> {
        let resolution = match (self.resolution, self.cell) {
            (Some(_), Some(_)) => {
                return Err(PyValueError::new_err("give resolution or cell, not both"));
            }
            (Some(n), None) => Some(Resolution::Samples(n)),
            (None, Some(c)) => Some(Resolution::Cell(c)),
            (None, None) => None,
        };
        let method = self
            .method
            .as_deref()
            .map(str::parse::<Method>)
            .transpose()
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        Ok(Overrides {
            resolution,
            method,
            seeds: self.seeds.as_ref().map(|s| s.iter().map(|&p| DVec3::from_array(p)).collect()),
            pose: self.pose.clone(),
            threads: pool(self.threads)?.map(|p| Threads::Pool(p.threads)),
            refine: self.refine,
            normals: self.normals,
            max_memory: self.max_memory,
            control: run.control.clone(),
            ..Overrides::default()
        })
    }
}

/// Meshes `scene` off the GIL; `callable`, when the field is a Python function, is asked
/// for its exception first.
fn mesh_scene(
    py: Python<'_>,
    scene: &skelform::Scene,
    choices: Choices,
    callable: Option<&CallableField>,
    run: &Run,
) -> PyResult<PyMesh> {
    let overrides = choices.overrides(run)?;
    let result = run.run(py, None, || scene.mesh(&overrides));
    if let Some(e) = callable.and_then(CallableField::take_failure) {
        return Err(e);
    }
    let meshed = result?.map_err(error)?;
    let stats = serde_json::to_string(&meshed.stats)
        .map_err(|e| PyValueError::new_err(format!("cannot serialise the statistics: {e}")))?;
    Ok(PyMesh { mesh: meshed.mesh, stats: Some(stats), method: Some(meshed.method.name().into()) })
}

#[pymethods]
impl PyScene {
    /// A scene from TOML text; `name` stands for the file in messages.
    #[staticmethod]
    #[pyo3(signature = (text, name="<string>"))]
    fn from_toml(text: &str, name: &str) -> PyResult<PyScene> {
        Ok(PyScene { scene: skelform::Scene::parse(text, name).map_err(error)? })
    }

    /// Meshes the scene with its own settings, changed by the keywords: `resolution`
    /// (samples along the longest side) or `cell`, `method` ("grid", "continuation",
    /// "tetra", "healed", "nonmanifold"), `pose` (a pose of an articulated skeleton),
    /// `threads`, `refine`, `normals`, `max_memory` (bytes), `seeds` (start points), and
    /// `progress(phase, done, total)`, which may return False to cancel. The same scene
    /// gives the same mesh on any number of threads.
    #[pyo3(signature = (*, resolution=None, cell=None, method=None, pose=None, threads=None,
        refine=None, normals=None, max_memory=None, seeds=None, progress=None))]
    #[allow(clippy::too_many_arguments)]
    fn mesh(
        &self,
        py: Python<'_>,
        resolution: Option<usize>,
        cell: Option<f64>,
        method: Option<String>,
        pose: Option<String>,
        threads: Option<usize>,
        refine: Option<bool>,
        normals: Option<bool>,
        max_memory: Option<u64>,
        seeds: Option<Vec<[f64; 3]>>,
        progress: Option<Py<PyAny>>,
    ) -> PyResult<PyMesh> {
        let run = Run::new(progress);
        let choices =
            Choices { resolution, cell, method, pose, threads, refine, normals, max_memory, seeds };
        mesh_scene(py, &self.scene, choices, None, &run)
    }

    /// The scene's field (the iso value subtracted: the surface is where it is 0) at the
    /// broadcast points.
    fn eval<'py>(
        &self,
        py: Python<'py>,
        x: &Bound<'py, PyAny>,
        y: &Bound<'py, PyAny>,
        z: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        eval_on(py, self.scene.field.as_ref(), x, y, z)
    }

    /// `(min, max)` corners of the domain.
    #[getter]
    fn domain(&self) -> ([f64; 3], [f64; 3]) {
        (self.scene.domain.min.to_array(), self.scene.domain.max.to_array())
    }

    /// The scene's own method.
    #[getter]
    fn method(&self) -> &'static str {
        self.scene.method.name()
    }

    /// `[scene] name`, if the file gives one.
    #[getter]
    fn name(&self) -> Option<String> {
        self.scene.name.clone()
    }

    /// The poses an articulated skeleton defines (empty without one).
    #[getter]
    fn poses(&self) -> Vec<String> {
        self.scene.articulation.as_ref().map(|a| a.poses.clone()).unwrap_or_default()
    }

    fn __repr__(&self) -> String {
        format!("Scene({:?}, method={:?})", self.scene.origin, self.scene.method.name())
    }
}

/// Reads and checks a scene file; a mistake raises ValueError naming the file, line and
/// column.
#[pyfunction]
#[pyo3(signature = (path, *, pose=None))]
pub(crate) fn load_scene(path: PathBuf, pose: Option<String>) -> PyResult<PyScene> {
    let scene = skelform::Scene::load_with(&path, &LoadOptions { pose, ..Default::default() })
        .map_err(error)?;
    Ok(PyScene { scene })
}

fn domain_of(domain: Option<([f64; 3], [f64; 3])>) -> PyResult<Aabb> {
    let (lo, hi) = domain.ok_or_else(|| {
        PyValueError::new_err("a domain ((xmin, ymin, zmin), (xmax, ymax, zmax)) is needed")
    })?;
    Ok(Aabb::new(DVec3::from_array(lo), DVec3::from_array(hi)))
}

/// Meshes a field: a `Formula`, formula text, a `Scene` or a Python callable (given an
/// (N, 3) float64 array of points, returning N values; the surface is where it is 0,
/// inside negative), over `domain`, with the keywords of `Scene.mesh`.
#[pyfunction]
#[pyo3(signature = (field, domain=None, *, resolution=None, cell=None, method=None,
    pose=None, threads=None, refine=None, normals=None, max_memory=None, seeds=None,
    progress=None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn mesh(
    py: Python<'_>,
    field: &Bound<'_, PyAny>,
    domain: Option<([f64; 3], [f64; 3])>,
    resolution: Option<usize>,
    cell: Option<f64>,
    method: Option<String>,
    pose: Option<String>,
    threads: Option<usize>,
    refine: Option<bool>,
    normals: Option<bool>,
    max_memory: Option<u64>,
    seeds: Option<Vec<[f64; 3]>>,
    progress: Option<Py<PyAny>>,
) -> PyResult<PyMesh> {
    let run = Run::new(progress);
    let choices =
        Choices { resolution, cell, method, pose, threads, refine, normals, max_memory, seeds };
    if let Ok(scene) = field.cast::<PyScene>() {
        if domain.is_some() {
            return Err(PyValueError::new_err(
                "a Scene has its own domain: mesh it without one (or change [domain] in its text)",
            ));
        }
        let scene = scene.get().scene.clone();
        return mesh_scene(py, &scene, choices, None, &run);
    }
    let domain = domain_of(domain)?;
    let formula = if let Ok(f) = field.cast::<PyFormula>() {
        Some(f.get().formula.clone())
    } else if let Ok(text) = field.extract::<String>() {
        Some(PyFormula::new(&text)?.formula)
    } else {
        None
    };
    if let Some(f) = formula {
        let scene = skelform::Scene::from_field(f, domain, "<formula>").map_err(error)?;
        return mesh_scene(py, &scene, choices, None, &run);
    }
    if !field.is_callable() {
        return Err(PyTypeError::new_err(
            "the field must be a Formula, formula text, a Scene or a callable",
        ));
    }
    let callable = Arc::new(CallableField::new(field.clone().unbind(), run.control.clone()));
    let scene =
        skelform::Scene::from_field(callable.clone(), domain, "<callable>").map_err(error)?;
    mesh_scene(py, &scene, choices, Some(&callable), &run)
}
