//! `marching_cubes` on NumPy volumes: skelform's extractor (the topology of the trilinear
//! interpolant, no holes at samples equal to the level) behind scikit-image's conventions.
//!
//! The conventions, as `skimage.measure.marching_cubes` has them: vertices in array index
//! coordinates, axis 0 first; faces wound so that, with `gradient_direction="descent"`,
//! their normals (right-hand rule) point towards higher values; vertex normals pointing
//! down the gradient (towards lower values) whatever the direction; `values` the size of
//! the gradient at each vertex (the sum of its components' magnitudes). The Python layer
//! (`skelform/__init__.py`) checks the arguments and applies the spacing, as scikit-image
//! does, so that dtypes and errors match too.

use numpy::ndarray::{ArrayView3, Axis, s};
use numpy::{Element, PyArray1, PyArray2, PyArrayMethods, PyReadonlyArray3};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use rayon::prelude::*;
use skelform::DVec3;
use skelform::volume::{Grid, MAX_SAMPLES_PER_AXIS, Volume, extract_mesh};
use std::sync::{Mutex, PoisonError};

use crate::errors::polygonize_error;
use crate::run::{Run, pool};

/// The samples relative to the level, in the layout the extractor reads (x fastest), and
/// which array axis each of the extractor's axes is.
struct Samples {
    volume: Volume,
    /// `axis_of[m]`: the array axis of the extractor's axis `m` (x, y, z).
    axis_of: [usize; 3],
}

/// Element types read straight from the array, without a conversion copy in NumPy.
trait Sample: Element + Copy + Sync {
    fn to_f64(self) -> f64;
}

macro_rules! sample {
    ($($t:ty),*) => {$(
        impl Sample for $t {
            #[allow(clippy::cast_lossless, clippy::cast_precision_loss)]
            fn to_f64(self) -> f64 {
                self as f64
            }
        }
    )*};
}
sample!(f32, f64, i8, i16, i32, i64, u8, u16, u32, u64);

/// Reads every `step`-th sample along each axis, minus `level`, in the order of memory
/// where it can (C or Fortran order: no strided walk, no copy of the array in NumPy).
fn samples<T: Sample>(a: ArrayView3<'_, T>, level: f64, step: usize) -> PyResult<Samples> {
    let sub = a.slice(s![..;step, ..;step, ..;step]);
    let strides = sub.strides();
    let fortran = strides[0].unsigned_abs() < strides[2].unsigned_abs();
    let (v, axis_of) = if fortran { (sub.reversed_axes(), [0, 1, 2]) } else { (sub, [2, 1, 0]) };
    let (na, nb, nc) = v.dim();
    let dims = [nc, nb, na];
    if dims.iter().any(|&d| d < 2) {
        return Err(PyValueError::new_err(format!(
            "step_size {step} leaves fewer than 2 samples along an axis of a volume of shape {:?}",
            a.shape()
        )));
    }
    if dims.iter().any(|&d| d > MAX_SAMPLES_PER_AXIS) {
        return Err(PyValueError::new_err(format!(
            "the volume has more than {MAX_SAMPLES_PER_AXIS} samples along an axis (shape {:?})",
            a.shape()
        )));
    }
    let slab = nb * nc;
    let count = slab.checked_mul(na).ok_or_else(|| PyValueError::new_err("volume too large"))?;
    let mut values = take_buffer(count);
    let non_finite: u64 = values.spare_capacity_mut()[..count]
        .par_chunks_mut(slab)
        .enumerate()
        .map(|(k, out)| {
            let layer = v.index_axis(Axis(0), k);
            let mut bad = 0;
            // NaN and ±∞ become ±f32::MAX, as `skelform::volume::sanitize` has them; without
            // branches, so that it vectorises.
            let mut put = |o: &mut std::mem::MaybeUninit<f32>, x: &T| {
                let f = (x.to_f64() - level) as f32;
                let finite = f.is_finite();
                bad += u64::from(!finite);
                let far = if f == f32::NEG_INFINITY { -f32::MAX } else { f32::MAX };
                o.write(if finite { f } else { far });
            };
            // A contiguous layer (C or Fortran order, step 1) is read as a slice, which the
            // compiler vectorises; ndarray's general iterator is several times slower.
            match layer.as_slice() {
                Some(row) => out.iter_mut().zip(row).for_each(|(o, x)| put(o, x)),
                None => out.iter_mut().zip(layer.iter()).for_each(|(o, x)| put(o, x)),
            }
            bad
        })
        .sum();
    // SAFETY: the loop above wrote all `count` elements: `slab`-sized chunks of the first
    // `count`, one per layer `k < na`, each zipped with a layer of exactly `slab` samples.
    unsafe { values.set_len(count) };
    let grid = Grid { origin: DVec3::ZERO, cell: step as f64, dims };
    Ok(Samples { volume: Volume { grid, values, non_finite }, axis_of })
}

/// The samples' buffer of the last call, kept for the next: fresh memory costs a page fault
/// a page (a sixth of a 256³ call's time), and callers extract volume after volume.
static BUFFER: Mutex<Vec<f32>> = Mutex::new(Vec::new());

/// The largest buffer kept between calls (1 GiB of samples).
const KEEP: usize = 1 << 28;

/// An empty buffer with room for `count` samples: the kept one when it is large enough,
/// else a new one in huge pages where the system allows.
fn take_buffer(count: usize) -> Vec<f32> {
    let mut kept = std::mem::take(&mut *BUFFER.lock().unwrap_or_else(PoisonError::into_inner));
    kept.clear();
    if kept.capacity() >= count {
        return kept;
    }
    drop(kept);
    let values = Vec::with_capacity(count);
    skelform::field::pages::advise_huge(values.as_ptr(), count);
    values
}

/// Gives a buffer back for the next call.
fn keep_buffer(values: Vec<f32>) {
    if values.capacity() <= KEEP {
        *BUFFER.lock().unwrap_or_else(PoisonError::into_inner) = values;
    }
}

/// The gradient of the samples at lattice node `(i, j, k)`: central differences inside,
/// one-sided ones at the border; per lattice step.
fn node_gradient(v: &Volume, n: [usize; 3]) -> [f64; 3] {
    let mut g = [0.0; 3];
    for (m, gm) in g.iter_mut().enumerate() {
        let d = v.grid.dims[m];
        let at = |i: usize| {
            let mut p = n;
            p[m] = i;
            f64::from(v.get(p[0], p[1], p[2]))
        };
        let (lo, hi) = (n[m].saturating_sub(1), (n[m] + 1).min(d - 1));
        *gm = (at(hi) - at(lo)) / (hi - lo) as f64;
    }
    g
}

/// The gradient at a point of the lattice (in lattice steps): node gradients interpolated
/// trilinearly, which on a lattice edge, where every vertex lies, is linear along the edge.
fn gradient_at(v: &Volume, q: [f64; 3]) -> [f64; 3] {
    let mut base = [0usize; 3];
    let mut t = [0.0; 3];
    // The axes along which the point lies between nodes: one for a vertex on an edge.
    let mut free = [0usize; 3];
    let mut nfree = 0;
    for m in 0..3 {
        let last = v.grid.dims[m] - 2;
        let c = (q[m].floor().max(0.0) as usize).min(last);
        base[m] = c;
        t[m] = (q[m] - c as f64).clamp(0.0, 1.0);
        if t[m] == 1.0 {
            base[m] += 1;
            t[m] = 0.0;
        }
        if t[m] > 0.0 {
            free[nfree] = m;
            nfree += 1;
        }
    }
    let mut g = [0.0; 3];
    for corner in 0..1usize << nfree {
        let mut w = 1.0;
        let mut n = base;
        for (bit, &m) in free[..nfree].iter().enumerate() {
            if corner >> bit & 1 == 1 {
                w *= t[m];
                n[m] += 1;
            } else {
                w *= 1.0 - t[m];
            }
        }
        let gn = node_gradient(v, n);
        for m in 0..3 {
            g[m] += w * gn[m];
        }
    }
    g
}

/// What the extractor made, before the conventions are applied.
struct Extracted {
    positions: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
}

impl Extracted {
    /// Keeps the triangles `keep` says yes to and the vertices they use, renumbered in
    /// their original order (so the result is the same on any thread count).
    fn retain(&mut self, keep: impl Fn(&[u32; 3]) -> bool) {
        self.triangles.retain(|t| keep(t));
        let mut used = vec![u32::MAX; self.positions.len()];
        for t in &self.triangles {
            for &i in t {
                used[i as usize] = 0;
            }
        }
        let mut next = 0u32;
        let mut positions = Vec::new();
        for (i, u) in used.iter_mut().enumerate() {
            if *u == 0 {
                *u = next;
                next += 1;
                positions.push(self.positions[i]);
            }
        }
        for t in &mut self.triangles {
            *t = t.map(|i| used[i as usize]);
        }
        self.positions = positions;
    }

    /// Merges vertices at bitwise-equal positions (samples equal to the level put several
    /// edge vertices on one lattice node) and drops the triangles that then repeat a vertex.
    fn remove_degenerate(&mut self) {
        let mut first = std::collections::HashMap::with_capacity(self.positions.len());
        let same: Vec<u32> = self
            .positions
            .iter()
            .enumerate()
            .map(|(i, p)| *first.entry(p.map(f32::to_bits)).or_insert(i as u32))
            .collect();
        for t in &mut self.triangles {
            *t = t.map(|i| same[i as usize]);
        }
        self.retain(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
    }
}

/// The cube (lowest corner, in lattice steps) a triangle came from: the one holding its
/// centroid, every vertex of a marching-cubes triangle lying on one cube's edges.
fn cube_of(v: &Volume, p: &[[f32; 3]], t: &[u32; 3]) -> [usize; 3] {
    let mut c = [0usize; 3];
    for (m, cm) in c.iter_mut().enumerate() {
        let centroid = t.iter().map(|&i| f64::from(p[i as usize][m])).sum::<f64>() / 3.0;
        let q = centroid / v.grid.cell;
        *cm = (q.floor().max(0.0) as usize).min(v.grid.dims[m] - 2);
    }
    c
}

type Arrays<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<i32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f32>>,
);

/// The Rust half of `skelform.marching_cubes` (arguments already checked by the Python
/// half): vertices in array index units (spacing not applied), faces, normals, values.
#[pyfunction]
#[pyo3(signature = (volume, level, step, ascent, allow_degenerate, mask, threads, progress))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn marching_cubes_core<'py>(
    py: Python<'py>,
    volume: &Bound<'py, PyAny>,
    level: f64,
    step: usize,
    ascent: bool,
    allow_degenerate: bool,
    mask: Option<PyReadonlyArray3<'py, bool>>,
    threads: Option<usize>,
    progress: Option<Py<PyAny>>,
) -> PyResult<Arrays<'py>> {
    if step == 0 {
        return Err(PyValueError::new_err("step_size must be at least one."));
    }
    let run = Run::new(progress);
    let pool = pool(threads)?;
    macro_rules! read {
        ($($t:ty),*) => {
            'read: {
                $(if let Ok(a) = volume.extract::<PyReadonlyArray3<'py, $t>>() {
                    let view = a.as_array();
                    let shape = view.shape().to_vec();
                    let samples = run.run(py, || install(&pool, || samples(view, level, step)))?;
                    break 'read (samples?, shape);
                })*
                return Err(PyTypeError::new_err(
                    "the volume must be a 3-D array of floats or integers",
                ));
            }
        };
    }
    let (s, shape) = read!(f32, f64, i8, i16, i32, i64, u8, u16, u32, u64);
    let mask_view = mask.as_ref().map(|m| m.as_array());
    if mask_view.as_ref().is_some_and(|m| m.shape() != shape.as_slice()) {
        return Err(PyValueError::new_err("volume and mask must have the same shape."));
    }
    let control = run.control.clone();
    let result = run.run(py, || {
        install(&pool, || {
            let mesh = extract_mesh(&s.volume, &control).map_err(polygonize_error)?;
            let mut ex = Extracted { positions: mesh.positions, triangles: mesh.triangles };
            if let Some(m) = &mask_view {
                let v = &s.volume;
                let p = ex.positions.clone();
                ex.retain(|t| {
                    let c = cube_of(v, &p, t);
                    let mut at = [0usize; 3];
                    for (m, &axis) in s.axis_of.iter().enumerate() {
                        // scikit-image looks the cube up by its last corner.
                        at[axis] = (c[m] + 1) * step;
                    }
                    m[at]
                });
            }
            if !allow_degenerate {
                ex.remove_degenerate();
            }
            if i32::try_from(ex.positions.len()).is_err() {
                return Err(PyValueError::new_err(format!(
                    "{} vertices do not fit the int32 face indices of scikit-image's convention",
                    ex.positions.len()
                )));
            }
            Ok(conventions(&s, &ex, ascent))
        })
    });
    keep_buffer(s.volume.values);
    let (positions, faces, normals, values) = result??;
    let n = positions.len() / 3;
    let f = faces.len() / 3;
    Ok((
        PyArray1::from_vec(py, positions).reshape([n, 3])?,
        PyArray1::from_vec(py, faces).reshape([f, 3])?,
        PyArray1::from_vec(py, normals).reshape([n, 3])?,
        PyArray1::from_vec(py, values),
    ))
}

/// Runs `op` on `pool`, or on the current (global) pool.
fn install<R: Send>(
    pool: &Option<std::sync::Arc<rayon::ThreadPool>>,
    op: impl FnOnce() -> R + Send,
) -> R {
    match pool {
        Some(p) => p.install(op),
        None => op(),
    }
}

/// Flat arrays in scikit-image's conventions: vertices and normals in array axis order,
/// faces wound for the gradient direction, the gradient size as the value.
fn conventions(
    s: &Samples,
    ex: &Extracted,
    ascent: bool,
) -> (Vec<f32>, Vec<i32>, Vec<f32>, Vec<f32>) {
    let v = &s.volume;
    let n = ex.positions.len();
    let mut positions = vec![0f32; 3 * n];
    let mut normals = vec![0f32; 3 * n];
    let mut values = vec![0f32; n];
    positions
        .par_chunks_mut(3)
        .zip(normals.par_chunks_mut(3))
        .zip(values.par_iter_mut())
        .zip(ex.positions.par_iter())
        .for_each(|(((pos, normal), value), p)| {
            let q = p.map(|c| f64::from(c) / v.grid.cell);
            let g = gradient_at(v, q);
            let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
            for (m, &axis) in s.axis_of.iter().enumerate() {
                pos[axis] = p[m];
                normal[axis] = if len > 0.0 { (-g[m] / len) as f32 } else { 0.0 };
            }
            *value = (g[0].abs() + g[1].abs() + g[2].abs()) as f32;
        });
    // The extractor winds counter-clockwise seen from the higher values in its own axes;
    // the array's axis order is a reflection of them when it is (2, 1, 0).
    let reflected = s.axis_of == [2, 1, 0];
    let flip = reflected != ascent;
    let mut faces = Vec::with_capacity(3 * ex.triangles.len());
    for t in &ex.triangles {
        let t = if flip { [t[0], t[2], t[1]] } else { *t };
        faces.extend(t.map(|i| i as i32));
    }
    (positions, faces, normals, values)
}
