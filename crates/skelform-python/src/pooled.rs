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
use numpy::{Element, PyArray1, PyArray2};
use pyo3::prelude::*;

/// A vector of one of the element types handed out.
pub(crate) enum Memory {
    F32(Vec<f32>),
    I32(Vec<i32>),
    /// The extractor's triangles, handed to NumPy as the faces themselves.
    Triangles(Vec<[u32; 3]>),
}

impl Memory {
    fn bytes(&self) -> usize {
        match self {
            Memory::F32(v) => 4 * v.capacity(),
            Memory::I32(v) => 4 * v.capacity(),
            Memory::Triangles(v) => 12 * v.capacity(),
        }
    }
}

/// Element types the pool holds.
pub(crate) trait PoolElement: Element + Copy + Sized {
    fn wrap(v: Vec<Self>) -> Memory;
    fn unwrap(m: &mut Memory) -> Option<&mut Vec<Self>>;
}

impl PoolElement for f32 {
    fn wrap(v: Vec<f32>) -> Memory {
        Memory::F32(v)
    }
    fn unwrap(m: &mut Memory) -> Option<&mut Vec<f32>> {
        if let Memory::F32(v) = m { Some(v) } else { None }
    }
}

impl PoolElement for i32 {
    fn wrap(v: Vec<i32>) -> Memory {
        Memory::I32(v)
    }
    fn unwrap(m: &mut Memory) -> Option<&mut Vec<i32>> {
        if let Memory::I32(v) = m { Some(v) } else { None }
    }
}

/// Memory back from NumPy, for the next calls.
static POOL: Mutex<Vec<Memory>> = Mutex::new(Vec::new());

/// The most vectors kept (two calls' arrays), and the most bytes in all.
const MOST: usize = 8;
const MOST_BYTES: usize = 1 << 30;

/// An empty vector with room for `n` elements: the smallest kept one that has it, else
/// fresh memory (in huge pages where the system allows, a fault per 2 MiB instead of per
/// 4 KiB).
pub(crate) fn take<T: PoolElement>(n: usize) -> Vec<T> {
    {
        let mut pool = POOL.lock().unwrap_or_else(PoisonError::into_inner);
        let best = pool
            .iter_mut()
            .enumerate()
            .filter_map(|(at, m)| T::unwrap(m).map(|v| (at, v.capacity())))
            .filter(|&(_, capacity)| capacity >= n)
            .min_by_key(|&(_, capacity)| capacity);
        if let Some((at, _)) = best {
            let mut m = pool.swap_remove(at);
            if let Some(v) = T::unwrap(&mut m) {
                let mut v = std::mem::take(v);
                v.clear();
                return v;
            }
        }
    }
    let v = Vec::with_capacity(n);
    skelform::field::pages::advise_huge(v.as_ptr(), n);
    v
}

/// An empty vector of triangles for the extractor to write the faces into: the largest
/// kept one (the faces of an earlier call that NumPy let go of), else a new one, which the
/// extractor grows in huge pages.
pub(crate) fn take_triangles() -> Vec<[u32; 3]> {
    let mut pool = POOL.lock().unwrap_or_else(PoisonError::into_inner);
    let largest = pool
        .iter()
        .enumerate()
        .filter_map(|(at, m)| match m {
            Memory::Triangles(v) => Some((at, v.capacity())),
            _ => None,
        })
        .max_by_key(|&(_, capacity)| capacity);
    match largest.map(|(at, _)| pool.swap_remove(at)) {
        Some(Memory::Triangles(mut v)) => {
            v.clear();
            v
        }
        _ => Vec::new(),
    }
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

/// `v` as a NumPy array of `rows` rows of `cols` (C order), over `v`'s own memory.
pub(crate) fn array2<'py, T: PoolElement>(
    py: Python<'py>,
    v: Vec<T>,
    cols: usize,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    let rows = v.len() / cols;
    assert_eq!(rows * cols, v.len(), "a partial row");
    let start = v.as_ptr();
    let owner = Bound::new(py, Pooled { memory: Mutex::new(Some(T::wrap(v))) })?;
    // SAFETY: `start` is the vector's first element of `rows · cols`, aligned and
    // initialised; the vector now lives in `owner`, untouched (never grown, so never moved)
    // until `owner` drops, which the array's base reference holds off while the array lives.
    let view = unsafe { ArrayView2::from_shape_ptr((rows, cols), start) };
    Ok(unsafe { PyArray2::borrow_from_array(&view, owner.into_any()) })
}

/// `v` as a one-dimensional NumPy array over `v`'s own memory.
pub(crate) fn array1<'py, T: PoolElement>(
    py: Python<'py>,
    v: Vec<T>,
) -> PyResult<Bound<'py, PyArray1<T>>> {
    let (start, n) = (v.as_ptr(), v.len());
    let owner = Bound::new(py, Pooled { memory: Mutex::new(Some(T::wrap(v))) })?;
    // SAFETY: as in `array2`.
    let view = unsafe { ArrayView1::from_shape_ptr(n, start) };
    Ok(unsafe { PyArray1::borrow_from_array(&view, owner.into_any()) })
}

/// Triangles as NumPy's `int32` faces (F×3, C order), over the vector's own memory, with no
/// copy. Every index must be below 2³¹ (the caller checks the vertex count), so that it
/// reads as the same `int32`.
pub(crate) fn faces<'py>(py: Python<'py>, v: Vec<[u32; 3]>) -> PyResult<Bound<'py, PyArray2<i32>>> {
    let (start, rows) = (v.as_ptr().cast::<i32>(), v.len());
    let owner = Bound::new(py, Pooled { memory: Mutex::new(Some(Memory::Triangles(v))) })?;
    // SAFETY: as in `array2`; a `[u32; 3]` is three `u32`s in a row with the alignment of
    // one, and a `u32` below 2³¹ has the bits of the `i32` of the same value.
    let view = unsafe { ArrayView2::from_shape_ptr((rows, 3), start) };
    Ok(unsafe { PyArray2::borrow_from_array(&view, owner.into_any()) })
}
