//! `skelform.Mesh`: a mesh as NumPy arrays, with skelform's writers and topology checker.

use std::path::PathBuf;

use numpy::{PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use skelform::mesh::io::{Format, WriteOptions, read_mesh, write_mesh};

use crate::errors::io_error;

/// A triangle mesh: vertices, faces, normals, region labels and intersection curves.
///
/// The arrays are copies (changing them does not change the mesh): `vertices` (N×3
/// float32), `faces` (M×3 int32, counter-clockwise seen from outside), `normals` (N×3
/// float32, or 0×3 when the mesh has none), `labels` (M×2 int32: the two regions each face
/// separates, or 0×2), `curves` (K×2 int32 vertex indices of the intersection curves'
/// segments) and `curve_labels` (K×3 int32: the three regions along each segment).
#[pyclass(module = "skelform", name = "Mesh", frozen)]
pub(crate) struct PyMesh {
    pub(crate) mesh: skelform::Mesh,
    /// The run's statistics as JSON, when the mesh came from a polygonizer.
    pub(crate) stats: Option<String>,
    /// The method that made it.
    pub(crate) method: Option<String>,
}

fn index(i: u32) -> PyResult<i32> {
    i32::try_from(i).map_err(|_| PyValueError::new_err(format!("index {i} does not fit int32")))
}

fn rows<'py, T: numpy::Element + Copy, const N: usize>(
    py: Python<'py>,
    items: impl ExactSizeIterator<Item = PyResult<[T; N]>>,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let n = items.len();
    let mut flat = Vec::with_capacity(n * N);
    for row in items {
        flat.extend_from_slice(&row?);
    }
    PyArray1::from_vec(py, flat).reshape([n, N])
}

fn json_to_py<'py>(py: Python<'py>, json: &str) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (json,))
}

#[pymethods]
impl PyMesh {
    /// A mesh from arrays (vertices N×3, faces M×3, optional normals N×3), e.g. to check or
    /// write a mesh made elsewhere.
    #[new]
    #[pyo3(signature = (vertices, faces, normals=None))]
    fn new(
        vertices: &Bound<'_, PyAny>,
        faces: &Bound<'_, PyAny>,
        normals: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyMesh> {
        let np = vertices.py().import("numpy")?;
        let vertices: PyReadonlyArray2<'_, f32> =
            np.call_method1("ascontiguousarray", (vertices, "float32"))?.extract()?;
        let faces: PyReadonlyArray2<'_, i64> =
            np.call_method1("ascontiguousarray", (faces, "int64"))?.extract()?;
        let normals: Option<PyReadonlyArray2<'_, f32>> = normals
            .map(|n| np.call_method1("ascontiguousarray", (n, "float32"))?.extract())
            .transpose()?;
        let triple = |shape: &[usize], what: &str| {
            if shape.len() == 2 && shape[1] == 3 {
                Ok(())
            } else {
                Err(PyValueError::new_err(format!("{what} must have shape (n, 3), not {shape:?}")))
            }
        };
        let (v, f) = (vertices.as_array(), faces.as_array());
        triple(v.shape(), "vertices")?;
        triple(f.shape(), "faces")?;
        let positions: Vec<[f32; 3]> = v.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect();
        let mut triangles = Vec::with_capacity(f.nrows());
        for r in f.rows() {
            let mut t = [0u32; 3];
            for (o, &i) in t.iter_mut().zip(r.iter()) {
                *o = u32::try_from(i).ok().filter(|&i| (i as usize) < positions.len()).ok_or_else(
                    || {
                        PyValueError::new_err(format!(
                            "face index {i} is outside the {} vertices",
                            positions.len()
                        ))
                    },
                )?;
            }
            triangles.push(t);
        }
        let normals = match normals {
            Some(n) => {
                let n = n.as_array();
                triple(n.shape(), "normals")?;
                if n.nrows() != positions.len() {
                    return Err(PyValueError::new_err("normals must have one row per vertex"));
                }
                n.rows().into_iter().map(|r| [r[0], r[1], r[2]]).collect()
            }
            None => Vec::new(),
        };
        let mesh = skelform::Mesh { positions, triangles, normals, ..skelform::Mesh::default() };
        Ok(PyMesh { mesh, stats: None, method: None })
    }

    /// Reads a PLY, OBJ, STL or glTF binary (.glb) file.
    #[staticmethod]
    fn read(path: PathBuf) -> PyResult<PyMesh> {
        let mesh = read_mesh(&path).map_err(io_error)?;
        Ok(PyMesh { mesh, stats: None, method: None })
    }

    /// Vertex positions, N×3 float32.
    #[getter]
    fn vertices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        rows(py, self.mesh.positions.iter().map(|p| Ok(*p)))
    }

    /// Triangles as vertex indices, M×3 int32.
    #[getter]
    fn faces<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i32>>> {
        rows(py, self.mesh.triangles.iter().map(|t| Ok([index(t[0])?, index(t[1])?, index(t[2])?])))
    }

    /// Unit vertex normals, N×3 float32 (0×3 when the mesh has none).
    #[getter]
    fn normals<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f32>>> {
        rows(py, self.mesh.normals.iter().map(|n| Ok(*n)))
    }

    /// The two regions each face separates, M×2 int32 (0×2 for an unlabelled mesh).
    #[getter]
    fn labels<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i32>>> {
        rows(py, self.mesh.labels.iter().map(|l| Ok([index(l.0)?, index(l.1)?])))
    }

    /// Segments of the intersection curves as vertex indices, K×2 int32.
    #[getter]
    fn curves<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i32>>> {
        rows(py, self.mesh.curves.iter().map(|c| Ok([index(c.v[0])?, index(c.v[1])?])))
    }

    /// The three regions along each curve segment, K×3 int32.
    #[getter]
    fn curve_labels<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i32>>> {
        rows(
            py,
            self.mesh.curves.iter().map(|c| {
                let [a, b, d] = c.label.0;
                Ok([index(a)?, index(b)?, index(d)?])
            }),
        )
    }

    /// The polygonizer's statistics (a dict), or None for a mesh not made by one.
    #[getter]
    fn stats<'py>(&self, py: Python<'py>) -> PyResult<Option<Bound<'py, PyAny>>> {
        self.stats.as_deref().map(|s| json_to_py(py, s)).transpose()
    }

    /// The method that made the mesh (`"grid"`, `"continuation"`, …), or None.
    #[getter]
    fn method(&self) -> Option<String> {
        self.method.clone()
    }

    /// Writes the mesh, in the format of the file's extension (.ply, .obj, .stl, .glb),
    /// atomically (the file appears whole or not at all). `ascii` for text PLY/STL,
    /// `curves=False` to leave the intersection curves out.
    #[pyo3(signature = (path, *, ascii=false, curves=true, normals=true))]
    fn write(&self, path: PathBuf, ascii: bool, curves: bool, normals: bool) -> PyResult<()> {
        let format = Format::from_path(&path).ok_or_else(|| {
            PyValueError::new_err(format!(
                "{}: the extension names no mesh format (use .ply, .obj, .stl or .glb)",
                path.display()
            ))
        })?;
        let options = WriteOptions { ascii, curves, normals, ..WriteOptions::default() };
        write_mesh(&path, &self.mesh, format, &options).map_err(io_error)
    }

    /// skelform's topology report (what `skelform check --json` prints) as a dict:
    /// components with their Euler characteristic, genus, closedness and orientation,
    /// boundary and non-manifold edges, labels and curves.
    fn check<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let report = py.detach(|| skelform::mesh::check::check(&self.mesh));
        let json = serde_json::to_string(&report)
            .map_err(|e| PyValueError::new_err(format!("cannot serialise the report: {e}")))?;
        json_to_py(py, &json)
    }

    /// The mesh as a `trimesh.Trimesh` (needs trimesh), vertices and faces as they are.
    fn to_trimesh<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        slf.py().import("skelform._convert")?.call_method1("to_trimesh", (slf,))
    }

    /// The mesh as a `pyvista.PolyData` (needs pyvista), with the labels as cell data.
    fn to_pyvista<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyAny>> {
        slf.py().import("skelform._convert")?.call_method1("to_pyvista", (slf,))
    }

    fn __repr__(&self) -> String {
        let m = &self.mesh;
        let mut s = format!("Mesh({} vertices, {} faces", m.positions.len(), m.triangles.len());
        if !m.labels.is_empty() {
            s.push_str(", labelled");
        }
        if !m.curves.is_empty() {
            s.push_str(&format!(", {} curve segments", m.curves.len()));
        }
        if let Some(method) = &self.method {
            s.push_str(&format!(", by {method}"));
        }
        s.push(')');
        s
    }
}
