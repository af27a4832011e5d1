//! Memory for the arrays `marching_cubes` hands to NumPy, taken back when NumPy lets go of
//! it and handed out again by the next call.
//!
//! Fresh memory costs a page fault a page, and the kernel zeroes every page first: for the
//! four arrays of a 256³ extraction, megabytes a call and a tenth of its time. A caller that
//! extracts again and again (frames, sweeps, a benchmark) drops the arrays of one call
//! before the next, so their memory comes back here through the arrays' base object
//! ([`Pooled`]) and is written again without faults. Arrays that a caller keeps are simply
//! not back; the next call then takes fresh memory, as it would without the pool.

use std::sync::{Mutex, PoisonError};

use numpy::ndarray::{ArrayView1, ArrayView2};
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;

/// A vector of one of the element types handed out.
pub(crate) enum Memory {
    /// Values (one `f32` a vertex).
    Values(Vec<f32>),
    /// Positions or normals (three `f32`s a vertex), handed to NumPy as N×3 arrays.
    Rows(Vec<[f32; 3]>),
    /// The extractor's triangles, handed to NumPy as the faces themselves.
    Triangles(Vec<[u32; 3]>),
}

impl Memory {
    fn bytes(&self) -> usize {
        match self {
            Memory::Values(v) => 4 * v.capacity(),
            Memory::Rows(v) => 12 * v.capacity(),
            Memory::Triangles(v) => 12 * v.capacity(),
        }
    }
}

/// Element types the pool holds, each in a [`Memory`] of its own.
pub(crate) trait PoolElement: Copy + Sized {
    fn unwrap(m: &mut Memory) -> Option<&mut Vec<Self>>;
}

impl PoolElement for f32 {
    fn unwrap(m: &mut Memory) -> Option<&mut Vec<f32>> {
        if let Memory::Values(v) = m { Some(v) } else { None }
    }
}

impl PoolElement for [f32; 3] {
    fn unwrap(m: &mut Memory) -> Option<&mut Vec<[f32; 3]>> {
        if let Memory::Rows(v) = m { Some(v) } else { None }
    }
}

impl PoolElement for [u32; 3] {
    fn unwrap(m: &mut Memory) -> Option<&mut Vec<[u32; 3]>> {
        if let Memory::Triangles(v) = m { Some(v) } else { None }
    }
}

/// Memory back from NumPy, for the next calls.
static POOL: Mutex<Vec<Memory>> = Mutex::new(Vec::new());

/// The most vectors kept (two calls' arrays), and the most bytes in all.
const MOST: usize = 8;
const MOST_BYTES: usize = 1 << 30;

/// The kept vector of `T` that `better` prefers (by capacity) among those of `least`
/// elements or more, emptied.
fn pick<T: PoolElement>(least: usize, better: impl Fn(usize, usize) -> bool) -> Option<Vec<T>> {
    let mut pool = POOL.lock().unwrap_or_else(PoisonError::into_inner);
    let mut best: Option<(usize, usize)> = None;
    for (at, m) in pool.iter_mut().enumerate() {
        let Some(capacity) = T::unwrap(m).map(|v| v.capacity()) else { continue };
        if capacity >= least && best.is_none_or(|(_, c)| better(capacity, c)) {
            best = Some((at, capacity));
        }
    }
    let mut m = pool.swap_remove(best?.0);
    let mut v = std::mem::take(T::unwrap(&mut m)?);
    v.clear();
    Some(v)
}

/// An empty vector with room for `n` elements: the smallest kept one that has it, else
/// fresh memory (in huge pages where the system allows, a fault per 2 MiB instead of per
/// 4 KiB).
pub(crate) fn take<T: PoolElement>(n: usize) -> Vec<T> {
    pick(n, |a, b| a < b).unwrap_or_else(|| {
        let v = Vec::with_capacity(n);
        skelform::field::pages::advise_huge(v.as_ptr(), n);
        v
    })
}

/// The largest kept vector of `T` (emptied), else an empty one: for arrays written before
/// their size is known (the faces, and the vertex arrays slab by slab), which grow from
/// there, usually not at all when the calls are alike.
pub(crate) fn take_largest<T: PoolElement>() -> Vec<T> {
    pick(0, |a, b| a > b).unwrap_or_default()
}

/// An empty vector of triangles for the extractor to write the faces into: the largest
/// kept one (the faces of an earlier call that NumPy let go of), else a new one, which the
/// extractor grows in huge pages.
pub(crate) fn take_triangles() -> Vec<[u32; 3]> {
    take_largest()
}

/// The base object of the arrays handed to NumPy: owns their memory, and gives it back to
/// the pool when NumPy drops the last array on it.
#[pyclass(frozen, module = "skelform._skelform")]
pub(crate) struct Pooled {
    memory: Mutex<Option<Memory>>,
}

impl Drop for Pooled {
    fn drop(&mut self) {
        let memory = self.memory.get_mut().unwrap_or_else(PoisonError::into_inner).take();
        let Some(memory) = memory else { return };
        let mut pool = POOL.lock().unwrap_or_else(PoisonError::into_inner);
        let held: usize = pool.iter().map(Memory::bytes).sum();
        if pool.len() < MOST && held + memory.bytes() <= MOST_BYTES {
            pool.push(memory);
        }
    }
}

/// Rows of three as a NumPy array (N×3, C order), over `v`'s own memory.
pub(crate) fn rows<'py>(py: Python<'py>, v: Vec<[f32; 3]>) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let (start, rows) = (v.as_ptr().cast::<f32>(), v.len());
    let owner = Bound::new(py, Pooled { memory: Mutex::new(Some(Memory::Rows(v))) })?;
    // SAFETY: `start` is the vector's first element of `rows`, each three `f32`s in a row
    // with the alignment of one, initialised; the vector now lives in `owner`, untouched
    // (never grown, so never moved) until `owner` drops, which the array's base reference
    // holds off while the array lives.
    let view = unsafe { ArrayView2::from_shape_ptr((rows, 3), start) };
    Ok(unsafe { PyArray2::borrow_from_array(&view, owner.into_any()) })
}

/// Values as a one-dimensional NumPy array over `v`'s own memory.
pub(crate) fn values<'py>(py: Python<'py>, v: Vec<f32>) -> PyResult<Bound<'py, PyArray1<f32>>> {
    let (start, n) = (v.as_ptr(), v.len());
    let owner = Bound::new(py, Pooled { memory: Mutex::new(Some(Memory::Values(v))) })?;
    // SAFETY: as in `rows`.
    let view = unsafe { ArrayView1::from_shape_ptr(n, start) };
    Ok(unsafe { PyArray1::borrow_from_array(&view, owner.into_any()) })
}

/// Triangles as NumPy's `int32` faces (F×3, C order), over the vector's own memory, with no
/// copy. Every index must be below 2³¹ (the caller checks the vertex count), so that it
/// reads as the same `int32`.
pub(crate) fn faces<'py>(py: Python<'py>, v: Vec<[u32; 3]>) -> PyResult<Bound<'py, PyArray2<i32>>> {
    let (start, rows) = (v.as_ptr().cast::<i32>(), v.len());
    let owner = Bound::new(py, Pooled { memory: Mutex::new(Some(Memory::Triangles(v))) })?;
    // SAFETY: as in `rows`; a `[u32; 3]` is three `u32`s in a row with the alignment of
    // one, and a `u32` below 2³¹ has the bits of the `i32` of the same value.
    let view = unsafe { ArrayView2::from_shape_ptr((rows, 3), start) };
    Ok(unsafe { PyArray2::borrow_from_array(&view, owner.into_any()) })
}
