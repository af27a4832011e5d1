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
use numpy::{Element, PyArray1, PyArray2, PyReadonlyArray3};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use rayon::prelude::*;
use skelform::DVec3;
use skelform::volume::{
    Assembly, Grid, GridVertex, Level, MAX_SAMPLES_PER_AXIS, Near, Place, SlabVertex, VertexSink,
    Volume, VolumeView, extract_view_records_into, extract_view_sunk, extract_volume_records_into,
    extract_volume_sunk, sanitize_sample, stream_rows,
};
use std::sync::{Mutex, PoisonError};

use crate::errors::polygonize_error;
use crate::pooled;
use crate::run::{Run, pool};

/// Element types read straight from the array, without a conversion copy in NumPy.
trait Sample: Element + Copy + Sync + PartialOrd {
    fn to_f64(self) -> f64;
    /// The values as `f32`s when they are, to be read in place.
    fn as_f32(values: &[Self]) -> Option<&[f32]> {
        let _ = values;
        None
    }
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
sample!(f64, i8, i16, i32, i64, u8, u16, u32, u64);

impl Sample for f32 {
    fn to_f64(self) -> f64 {
        f64::from(self)
    }
    fn as_f32(values: &[f32]) -> Option<&[f32]> {
        Some(values)
    }
}

/// The lattice the extractor sees and which array axis each of its axes is.
#[derive(Clone, Copy)]
struct Layout {
    grid: Grid,
    /// `axis_of[m]`: the array axis of the extractor's axis `m` (x, y, z).
    axis_of: [usize; 3],
}

/// The samples of every `step`-th element along each axis, in the extractor's layout (x
/// fastest): the array itself when it is `f32`, contiguous (C or Fortran order) and taken
/// whole, else a converted copy.
enum Samples<'a> {
    InPlace(VolumeView<'a>),
    Converted(Volume),
}

/// The extractor's layout of every `step`-th sample of `a`, in the order of memory where
/// it can (C or Fortran order: no strided walk); refuses lattices too small or too large.
fn layout<T>(a: ArrayView3<'_, T>, step: usize) -> PyResult<(ArrayView3<'_, T>, Layout)> {
    let shape = a.shape().to_vec();
    let sub = a.slice_move(s![..;step, ..;step, ..;step]);
    let strides = sub.strides();
    let fortran = strides[0].unsigned_abs() < strides[2].unsigned_abs();
    let (v, axis_of) = if fortran { (sub.reversed_axes(), [0, 1, 2]) } else { (sub, [2, 1, 0]) };
    let (na, nb, nc) = v.dim();
    let dims = [nc, nb, na];
    if dims.iter().any(|&d| d < 2) {
        return Err(PyValueError::new_err(format!(
            "step_size {step} leaves fewer than 2 samples along an axis of a volume of shape {:?}",
            shape
        )));
    }
    if dims.iter().any(|&d| d > MAX_SAMPLES_PER_AXIS) {
        return Err(PyValueError::new_err(format!(
            "the volume has more than {MAX_SAMPLES_PER_AXIS} samples along an axis (shape {:?})",
            shape
        )));
    }
    let grid = Grid { origin: DVec3::ZERO, cell: step as f64, dims };
    Ok((v, Layout { grid, axis_of }))
}

/// The samples of `v` (already in the extractor's axis order) at `level`: read in place
/// when they can be, else converted.
fn samples<'a, T: Sample>(
    v: ArrayView3<'a, T>,
    layout: &Layout,
    level: f64,
) -> PyResult<Samples<'a>> {
    if let Some(values) = v.to_slice().and_then(T::as_f32) {
        return VolumeView::new(layout.grid, values, level)
            .map(Samples::InPlace)
            .ok_or_else(|| PyValueError::new_err("the volume's samples do not fill its shape"));
    }
    let (na, nb, nc) = v.dim();
    let slab = nb * nc;
    let count = slab.checked_mul(na).ok_or_else(|| PyValueError::new_err("volume too large"))?;
    let mut values = take_buffer(count);
    let non_finite: u64 = values.spare_capacity_mut()[..count]
        .par_chunks_mut(slab)
        .enumerate()
        .map(|(k, out)| {
            let layer = v.index_axis(Axis(0), k);
            let mut bad = 0;
            let mut put = |o: &mut std::mem::MaybeUninit<f32>, x: &T| {
                let (f, replaced) = sanitize_sample((x.to_f64() - level) as f32);
                bad += u64::from(replaced);
                o.write(f);
            };
            // A contiguous layer is read as a slice, which the compiler vectorises;
            // ndarray's general iterator is several times slower.
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
    Ok(Samples::Converted(Volume { grid: layout.grid, values, non_finite }))
}

/// The smallest and largest element as floats, NaN when there is a NaN (as NumPy's
/// `min()` and `max()`), in parallel.
fn value_range<T: Sample>(a: &ArrayView3<'_, T>) -> (f64, f64) {
    fn fold<'x, T: Sample + 'x>(it: impl Iterator<Item = &'x T> + Clone) -> Option<(T, T, bool)> {
        let first = *it.clone().next()?;
        let (mut lo, mut hi, mut nan) = (first, first, false);
        for &x in it {
            // `x != x` only for NaN; the compares pass NaN over, which `nan` reports.
            #[allow(clippy::eq_op)]
            let is_nan = x != x;
            nan |= is_nan;
            lo = if x < lo { x } else { lo };
            hi = if x > hi { x } else { hi };
        }
        Some((lo, hi, nan))
    }
    let parts: Vec<(T, T, bool)> = match a.as_slice_memory_order() {
        Some(values) => values.par_chunks(1 << 16).filter_map(|c| fold(c.iter())).collect(),
        None => (0..a.len_of(Axis(0)))
            .into_par_iter()
            .filter_map(|k| fold(a.index_axis(Axis(0), k).iter()))
            .collect(),
    };
    let mut nan = false;
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (l, h, n) in parts {
        // A chunk that starts with NaN keeps it as its extreme: the flag covers it.
        nan |= n || l.to_f64().is_nan();
        lo = lo.min(l.to_f64());
        hi = hi.max(h.to_f64());
    }
    if nan { (f64::NAN, f64::NAN) } else { (lo, hi) }
}

/// Whether some element is at or above `level`, or NaN: with one below it (which a
/// non-empty mesh shows), `level` is in the data's range as scikit-image checks it. Stops at
/// the first such element; most volumes have one in their first row.
fn reaches<T: Sample>(a: &ArrayView3<'_, T>, level: f64) -> bool {
    let hit = |x: &T| {
        let f = x.to_f64();
        f >= level || f.is_nan()
    };
    match a.as_slice_memory_order() {
        Some(values) => values.chunks(1 << 12).any(|c| c.iter().fold(false, |h, x| h | hit(x))),
        None => a.iter().any(hit),
    }
}

/// The buffer of converted samples of the last call, kept for the next: fresh memory costs
/// a page fault a page, and callers extract volume after volume.
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

/// The vertex records of the last call that dropped triangles (a mask, or degenerate ones
/// removed), kept for the next (emptied): written again without a page fault a page, where
/// fresh memory for them costs as much as a tenth of an extraction. Such calls need the
/// whole mesh of records before the arrays are made ([`conventions`]); the others hand
/// each slab's records to the arrays as the slab is done ([`Columns`]). The faces are the
/// extractor's triangles themselves, wound as the conventions want them ([`Record`]) and
/// written into the faces of an earlier call (`pooled::take_triangles`).
static RECORDS: Mutex<Vec<Vertex>> = Mutex::new(Vec::new());

/// The most vertex records kept between calls (about 0.9 GiB).
const KEEP_RECORDS: usize = 1 << 25;

/// A vertex as the conventions need it, made by the extractor while the samples around it
/// are in the cache: its position and, from the gradient there, its unit normal (down the
/// gradient) and the gradient's size; in the extractor's axes.
#[derive(Clone, Copy, Default)]
struct Vertex {
    position: [f32; 3],
    normal: [f32; 3],
    value: f32,
}

/// A [`Vertex`] as the extractor makes it, over triangles wound the other way round when
/// `REWOUND`: the faces come out of the extractor wound as scikit-image's conventions want
/// them, and go to NumPy without a pass over them.
#[derive(Clone, Copy, Default)]
#[repr(transparent)]
struct Record<const REWOUND: bool>(Vertex);

impl<const REWOUND: bool> SlabVertex for Record<REWOUND> {
    const READS_NEAR: bool = true;
    const REWOUND: bool = REWOUND;

    #[inline(always)]
    fn make<L: Level>(grid: &Grid, v: GridVertex, ends: [f32; 2], near: &Near<'_, L>) -> Self {
        Record(Vertex::make(grid, v, ends, near))
    }
}

/// `v` as a vector of `B`, which has the layout of `A`: the records as [`Vertex`]es and
/// back, without a copy.
fn retype<A, B>(v: Vec<A>) -> Vec<B> {
    assert!(size_of::<A>() == size_of::<B>() && align_of::<A>() == align_of::<B>());
    let mut v = std::mem::ManuallyDrop::new(v);
    // SAFETY: only called between `Vertex` and `Record<_>`, a `repr(transparent)` wrapper of
    // it (the same layout, checked above, and every bit pattern of one is one of the other);
    // the memory came from the global allocator for `capacity` elements of that layout; the
    // ManuallyDrop hands the ownership over.
    unsafe { Vec::from_raw_parts(v.as_mut_ptr().cast::<B>(), v.len(), v.capacity()) }
}

impl Vertex {
    #[inline(always)]
    fn make<L: Level>(grid: &Grid, v: GridVertex, ends: [f32; 2], near: &Near<'_, L>) -> Self {
        // Whether the position across an edge vertex's axis is its base exactly (below).
        let on_base = grid.cell == 1.0 && grid.origin == DVec3::ZERO;
        let position = match v.place {
            // On this crate's lattices (at the origin; with a cell of 1 at a step of 1, the
            // usual call) an edge vertex's position is its base, plus the fraction along the
            // edge's axis: the bits `GridVertex::position` computes (`0 + b·1` is `b`, and
            // `0·t` adds `+0`), without its products and sums in three coordinates.
            Place::Edge { dir, t } if on_base => {
                let b = v.base.map(f64::from);
                let along = |m: usize| if dir >> m & 1 == 1 { b[m] + t } else { b[m] };
                [along(0) as f32, along(1) as f32, along(2) as f32]
            }
            _ => v.position(grid).as_vec3().to_array(),
        };
        // A cell of 1 (a step of 1, the usual call) is a path of its own, where the stored
        // coordinates are read without the division by the cell that the general path makes
        // (three a vertex, computed and discarded when the choice is made per coordinate,
        // on the divider that the vertex's crossing and normal need too). The branch goes
        // the same way for the whole call.
        let edge = if on_base {
            edge_gradient::<true, true, L>(grid, &v, position, ends, near)
        } else if grid.cell == 1.0 {
            edge_gradient::<true, false, L>(grid, &v, position, ends, near)
        } else {
            edge_gradient::<false, false, L>(grid, &v, position, ends, near)
        };
        let g = match edge {
            Some(g) => g,
            None => {
                // From the stored position, so that a vertex at a node is treated as one.
                let q = [0, 1, 2].map(|m| f64::from(position[m]) / grid.cell);
                gradient_at(near, q)
            }
        };
        let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
        // (Spelled out, not `map`ped: an array `map` can stay a call, and this runs for
        // every vertex.) One division and three products, not three divisions: the
        // divider is the slowest unit a record uses. In `f64` the two differ in the last
        // bit or so, which rounding to `f32` nearly always removes (on the benchmark fields
        // every component of every normal is the same).
        let normal = if len > 0.0 {
            let inv = -1.0 / len;
            [(g[0] * inv) as f32, (g[1] * inv) as f32, (g[2] * inv) as f32]
        } else {
            [0.0; 3]
        };
        Vertex { position, normal, value: (g[0].abs() + g[1].abs() + g[2].abs()) as f32 }
    }
}

/// The gradient of the samples at lattice node `n`: central differences inside, one-sided
/// ones at the border; per lattice step.
#[inline(always)]
fn node_gradient<L: Level>(near: &Near<'_, L>, n: [usize; 3]) -> [f64; 3] {
    let dims = near.dims();
    let [i, j, k] = n;
    let value = |i: usize, j: usize, k: usize| f64::from(near.sample(i, j, k));
    let span = |c: usize, d: usize| (c.saturating_sub(1), (c + 1).min(d - 1));
    let (x0, x1) = span(i, dims[0]);
    let (y0, y1) = span(j, dims[1]);
    let (z0, z1) = span(k, dims[2]);
    [
        (value(x1, j, k) - value(x0, j, k)) / (x1 - x0) as f64,
        (value(i, y1, k) - value(i, y0, k)) / (y1 - y0) as f64,
        (value(i, j, z1) - value(i, j, z0)) / (z1 - z0) as f64,
    ]
}

/// [`gradient_at`] of an edge vertex strictly between the ends of its lattice edge, when
/// both ends are a step or more from the lattice's border on every axis and the whole
/// volume is at hand (`None` otherwise): nearly every vertex, and most of the cost of the
/// vertices' normals. The same bits as [`gradient_at`] (the same fraction, from the stored
/// position; a difference halved is the difference divided by 2), without its general
/// cases: central differences from flat indices. `ends` are the samples at the edge's two
/// ends (as the extractor passes them): each end's difference along the edge reaches the
/// other end, so those two of its twelve samples are not read again.
#[inline(always)]
fn edge_gradient<const UNIT_CELL: bool, const ON_BASE: bool, L: Level>(
    grid: &Grid,
    v: &GridVertex,
    position: [f32; 3],
    ends: [f32; 2],
    near: &Near<'_, L>,
) -> Option<[f64; 3]> {
    let Place::Edge { dir, .. } = v.place else { return None };
    let axis = match dir {
        1 => 0,
        2 => 1,
        4 => 2,
        _ => return None,
    };
    let (values, level) = near.whole()?;
    let dims = near.dims();
    let b = [v.base[0] as usize, v.base[1] as usize, v.base[2] as usize];
    // What `gradient_at` finds from the stored position: on the other two axes the node's
    // own coordinate (not between nodes), along the edge a fraction strictly inside it.
    let cell = grid.cell;
    let q = |m: usize| {
        let p = f64::from(position[m]);
        // Dividing by a cell of 1 changes nothing (`UNIT_CELL`: the cell is 1).
        if UNIT_CELL { p } else { p / cell }
    };
    // (`ON_BASE`: the position was made from the base on a lattice at the origin with a
    // cell of 1, so across the edge it is the base, below 2¹⁵ and exact in `f32`.)
    for (m, &bm) in b.iter().enumerate() {
        if !ON_BASE && m != axis && q(m) != bm as f64 {
            return None;
        }
    }
    debug_assert!((0..3).all(|m| m == axis || q(m) == b[m] as f64));
    // Along it, `gradient_at` finds the cube of `floor(qa)` and the fraction `qa − c`: the
    // edge's own base and a fraction strictly inside exactly when `qa − b` is strictly
    // between 0 and 1 (a rounded difference is monotone in `qa`, and `b + 1 − b` is 1), so
    // that one subtraction is the whole test, and the fraction too.
    let t = q(axis) - b[axis] as f64;
    if !(t > 0.0 && t < 1.0) {
        return None;
    }
    // Both ends a step or more from the border: 1 <= b[m] <= dims[m] - 2 on the axes
    // across the edge, and to dims[m] - 3 along it (its tip is one further).
    let within = |m: usize| {
        let top = dims[m].saturating_sub(2 + usize::from(m == axis));
        b[m].wrapping_sub(1) < top
    };
    let stride = [1, dims[0], dims[0] * dims[1]];
    let at = b[0] + stride[1] * b[1] + stride[2] * b[2];
    let tip = at + stride[axis];
    // The highest sample read is the tip plus a step along z; the lowest, `at` less a
    // step along z, is in the lattice when the ends are within it.
    if !(within(0) && within(1) && within(2)) || tip + stride[2] >= values.len() {
        return None;
    }
    // (Spelled out: closures called six times each are left as calls. `axis` is a constant
    // where this is inlined into the extractor's loop over one axis's edges, so the
    // indexing by it is resolved there.)
    let mut g0 = [0.0; 3];
    let mut g1 = [0.0; 3];
    for m in 0..3 {
        if m != axis {
            g0[m] = central(values, level, at, stride[m]);
            g1[m] = central(values, level, tip, stride[m]);
        }
    }
    // Along the edge: `at + stride` is the tip and `tip − stride` is `at`, samples in hand.
    debug_assert_eq!(ends.map(f32::to_bits), [at, tip].map(|n| level.sample(values[n]).to_bits()));
    let s = stride[axis];
    // SAFETY: `at − s` and `tip + s` are lattice samples below `values.len()`: checked above
    // (`within` on the edge's axis, and `tip + stride[2]` bounds every `tip + stride[m]`).
    let (below, beyond) =
        unsafe { (*values.get_unchecked(at - s), *values.get_unchecked(tip + s)) };
    g0[axis] = (f64::from(ends[1]) - f64::from(level.sample(below))) * 0.5;
    g1[axis] = (f64::from(level.sample(beyond)) - f64::from(ends[0])) * 0.5;
    let (w0, w1) = (1.0 - t, t);
    let mut g = [0.0; 3];
    for m in 0..3 {
        g[m] += w0 * g0[m];
        g[m] += w1 * g1[m];
    }
    Some(g)
}

/// The central difference, per lattice step, of the samples a stride `s` either side of
/// flat index `n`, as [`node_gradient`] computes it inside the lattice.
#[inline(always)]
fn central<L: Level>(values: &[f32], level: L, n: usize, s: usize) -> f64 {
    debug_assert!(s <= n && n + s < values.len());
    // SAFETY: called by `edge_gradient` only, for the two ends of an edge with every
    // coordinate between 1 and dims − 2 and a stride of one lattice step: `n ± s` is a
    // lattice sample, below `values.len()` as checked there.
    let (hi, lo) = unsafe { (*values.get_unchecked(n + s), *values.get_unchecked(n - s)) };
    (f64::from(level.sample(hi)) - f64::from(level.sample(lo))) * 0.5
}

/// The gradient at a point of the lattice (in lattice steps): node gradients interpolated
/// trilinearly, which on a lattice edge, where every vertex lies, is linear along the edge.
#[inline(always)]
fn gradient_at<L: Level>(near: &Near<'_, L>, q: [f64; 3]) -> [f64; 3] {
    let dims = near.dims();
    let mut base = [0usize; 3];
    let mut t = [0.0; 3];
    // The axes along which the point lies between nodes: one for a vertex on an edge.
    let mut free = [0usize; 3];
    let mut nfree = 0;
    for m in 0..3 {
        let last = dims[m] - 2;
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
    if nfree == 1 {
        // A vertex on an edge, nearly all of them: the two ends' gradients, weighted as the
        // general loop below weighs them (and so to the same bits).
        let m = free[0];
        let mut tip = base;
        tip[m] += 1;
        let (g0, g1) = (node_gradient(near, base), node_gradient(near, tip));
        let (w0, w1) = (1.0 - t[m], t[m]);
        for c in 0..3 {
            g[c] += w0 * g0[c];
            g[c] += w1 * g1[c];
        }
        return g;
    }
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
        let gn = node_gradient(near, n);
        for m in 0..3 {
            g[m] += w * gn[m];
        }
    }
    g
}

/// What the extractor made, before the conventions are applied.
struct Extracted {
    vertices: Vec<Vertex>,
    triangles: Vec<[u32; 3]>,
}

impl Extracted {
    /// Keeps the triangles whose flag in `keep` is set and the vertices they use,
    /// renumbered in their original order (so the result is the same on any thread count).
    fn retain(&mut self, keep: &[bool]) {
        let mut flags = keep.iter();
        self.triangles.retain(|_| flags.next().copied().unwrap_or(false));
        let mut used = vec![u32::MAX; self.vertices.len()];
        for t in &self.triangles {
            for &i in t {
                used[i as usize] = 0;
            }
        }
        let mut next = 0u32;
        let mut vertices = Vec::new();
        for (i, u) in used.iter_mut().enumerate() {
            if *u == 0 {
                *u = next;
                next += 1;
                vertices.push(self.vertices[i]);
            }
        }
        for t in &mut self.triangles {
            *t = t.map(|i| used[i as usize]);
        }
        self.vertices = vertices;
    }

    /// Merges vertices at bitwise-equal positions (samples equal to the level put several
    /// edge vertices on one lattice node) and drops the triangles that then repeat a vertex.
    fn remove_degenerate(&mut self) {
        let mut first = std::collections::HashMap::with_capacity(self.vertices.len());
        let same: Vec<u32> = self
            .vertices
            .iter()
            .enumerate()
            .map(|(i, v)| *first.entry(v.position.map(f32::to_bits)).or_insert(i as u32))
            .collect();
        for t in &mut self.triangles {
            *t = t.map(|i| same[i as usize]);
        }
        let keep: Vec<bool> =
            self.triangles.iter().map(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]).collect();
        self.retain(&keep);
    }
}

/// The cube (lowest corner, in lattice steps) a triangle came from: the one holding its
/// centroid, every vertex of a marching-cubes triangle lying on one cube's edges.
fn cube_of(grid: &Grid, v: &[Vertex], t: &[u32; 3]) -> [usize; 3] {
    let mut c = [0usize; 3];
    for (m, cm) in c.iter_mut().enumerate() {
        let centroid = t.iter().map(|&i| f64::from(v[i as usize].position[m])).sum::<f64>() / 3.0;
        let q = centroid / grid.cell;
        *cm = (q.floor().max(0.0) as usize).min(grid.dims[m] - 2);
    }
    c
}

type Arrays<'py> = (
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<i32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray1<f32>>,
);

/// What a call asks for besides the volume.
struct Options<'a> {
    level: Option<f64>,
    step: usize,
    ascent: bool,
    allow_degenerate: bool,
    mask: Option<ArrayView3<'a, bool>>,
}

/// Vertices, faces (the extractor's triangles, wound for the conventions), normals and
/// values.
type Flat = (Vec<[f32; 3]>, Vec<[u32; 3]>, Vec<[f32; 3]>, Vec<f32>);

/// The Rust half of `skelform.marching_cubes` (arguments already checked by the Python
/// half, but for the level): vertices in array index units (spacing not applied), faces,
/// normals, values. With `level` `None`, the middle of the data range; a given level
/// outside the range raises ValueError, as in scikit-image.
#[pyfunction]
#[pyo3(signature = (volume, level, step, ascent, allow_degenerate, mask, threads, progress))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn marching_cubes_core<'py>(
    py: Python<'py>,
    volume: &Bound<'py, PyAny>,
    level: Option<f64>,
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
    let mask_view = mask.as_ref().map(|m| m.as_array());
    let options = Options { level, step, ascent, allow_degenerate, mask: mask_view };
    macro_rules! read {
        ($($t:ty),*) => {
            'read: {
                $(if let Ok(a) = volume.extract::<PyReadonlyArray3<'py, $t>>() {
                    let view = a.as_array();
                    if options.mask.as_ref().is_some_and(|m| m.shape() != view.shape()) {
                        return Err(PyValueError::new_err("volume and mask must have the same shape."));
                    }
                    break 'read run.run(py, pool.as_ref(), || extract(view, &options, &run))?;
                })*
                return Err(PyTypeError::new_err(
                    "the volume must be a 3-D array of floats or integers",
                ));
            }
        };
    }
    let (positions, faces, normals, values) =
        read!(f32, f64, i8, i16, i32, i64, u8, u16, u32, u64)?;
    // Over the vectors' own memory, which goes back to the pool for the next call when
    // NumPy lets go of it.
    Ok((
        pooled::rows(py, positions)?,
        pooled::faces(py, faces)?,
        pooled::rows(py, normals)?,
        pooled::values(py, values)?,
    ))
}

/// The work of a call, off the GIL: the level, the samples, extraction, scikit-image's
/// options and conventions.
fn extract<T: Sample>(a: ArrayView3<'_, T>, o: &Options<'_>, run: &Run) -> PyResult<Flat> {
    let level = match o.level {
        Some(l) => l,
        None => {
            let (lo, hi) = value_range(&a);
            0.5 * (lo + hi)
        }
    };
    let (v, layout) = layout(a, o.step)?;
    let samples = samples(v, &layout, level)?;
    // The extractor winds counter-clockwise seen from the higher values in its own axes;
    // the array's axis order is a reflection of them when it is (2, 1, 0).
    let reflected = layout.axis_of == [2, 1, 0];
    let rewound = reflected != o.ascent;
    // scikit-image's check that a given level lies in the data's range (no error when the
    // data has NaN, whose comparisons are false). A mesh has a sample below the level (the
    // shifted sample is negative only then), so only the other end needs looking at; with
    // no mesh, both do.
    let check_level = |no_mesh: bool| {
        if o.level.is_none() {
            return Ok(());
        }
        let in_range = if no_mesh {
            let (lo, hi) = value_range(&a);
            !(level < lo || level > hi)
        } else {
            reaches(&a, level)
        };
        if in_range {
            Ok(())
        } else {
            Err(PyValueError::new_err("Surface level must be within volume data range."))
        }
    };
    let fits = |n: usize| {
        if i32::try_from(n).is_err() {
            return Err(PyValueError::new_err(format!(
                "{n} vertices do not fit the int32 face indices of scikit-image's convention"
            )));
        }
        Ok(())
    };
    // With nothing to drop from the mesh, each slab's records go straight into the arrays
    // as the slab is done, on any number of threads.
    if o.mask.is_none() && o.allow_degenerate {
        let reversed = layout.axis_of == [2, 1, 0];
        debug_assert!(reversed || layout.axis_of == [0, 1, 2]);
        let got = match (rewound, reversed) {
            (false, false) => extract_columns::<false, false>(&samples, &run.control),
            (false, true) => extract_columns::<false, true>(&samples, &run.control),
            (true, false) => extract_columns::<true, false>(&samples, &run.control),
            (true, true) => extract_columns::<true, true>(&samples, &run.control),
        };
        if let Samples::Converted(volume) = samples {
            keep_buffer(volume.values);
        }
        let flat = got.map_err(|cancelled| polygonize_error(cancelled.into()))?;
        check_level(flat.1.is_empty())?;
        fits(flat.0.len())?;
        return Ok(flat);
    }
    let kept = std::mem::take(&mut *RECORDS.lock().unwrap_or_else(PoisonError::into_inner));
    let kept = (kept, pooled::take_triangles());
    let records = if rewound {
        extract_records::<true>(&samples, &run.control, kept)
    } else {
        extract_records::<false>(&samples, &run.control, kept)
    };
    // The samples are done with once extracted: a converted buffer goes back for the next
    // call whatever happens now.
    if let Samples::Converted(volume) = samples {
        keep_buffer(volume.values);
    }
    let (vertices, triangles) = records.map_err(|cancelled| polygonize_error(cancelled.into()))?;
    check_level(triangles.is_empty())?;
    let mut ex = Extracted { vertices, triangles };
    if let Some(m) = &o.mask {
        let keep: Vec<bool> = ex
            .triangles
            .par_iter()
            .map(|t| {
                let c = cube_of(&layout.grid, &ex.vertices, t);
                let mut at = [0usize; 3];
                for (k, &axis) in layout.axis_of.iter().enumerate() {
                    // scikit-image looks the cube up by its last corner.
                    at[axis] = (c[k] + 1) * o.step;
                }
                m[at]
            })
            .collect();
        ex.retain(&keep);
    }
    if !o.allow_degenerate {
        ex.remove_degenerate();
    }
    fits(ex.vertices.len())?;
    let (flat, mut vertices) = conventions(&layout, ex);
    vertices.clear();
    if vertices.capacity() <= KEEP_RECORDS {
        *RECORDS.lock().unwrap_or_else(PoisonError::into_inner) = vertices;
    }
    Ok(flat)
}

/// The extraction itself, over triangles wound the other way round when `REWOUND`, into
/// the memory of `kept` (vertex records and triangles of earlier calls).
fn extract_records<const REWOUND: bool>(
    samples: &Samples<'_>,
    control: &skelform::Control,
    kept: (Vec<Vertex>, Vec<[u32; 3]>),
) -> Result<(Vec<Vertex>, Vec<[u32; 3]>), skelform::volume::Cancelled> {
    let kept = (retype::<Vertex, Record<REWOUND>>(kept.0), kept.1);
    let (records, triangles) = match samples {
        Samples::InPlace(view) => extract_view_records_into(view, control, kept),
        Samples::Converted(volume) => extract_volume_records_into(volume, control, kept),
    }?;
    Ok((retype(records), triangles))
}

/// The arrays of a call in scikit-image's conventions, made as the slabs are done: the
/// extractor hands each slab's records over ([`VertexSink`]) while they are in the cache,
/// and they go straight into their rows, in the array axis order (reversed when `REVERSED`:
/// a C-ordered volume); no mesh of records is written to memory and read back. Each array
/// grows in place as the slabs come (see [`Assembly`]), from the memory of an earlier
/// call's arrays that NumPy let go of.
struct Columns<const REVERSED: bool> {
    positions: Assembly<[f32; 3]>,
    normals: Assembly<[f32; 3]>,
    values: Assembly<f32>,
    /// Which arrays started from kept memory (kept whole for the next call), and which
    /// from nothing (trimmed to their size at the end).
    reused: [bool; 3],
}

impl<const REVERSED: bool> Columns<REVERSED> {
    fn new() -> Self {
        let (positions, normals) = (pooled::take_largest(), pooled::take_largest());
        let values = pooled::take_largest();
        let reused = [positions.capacity() > 0, normals.capacity() > 0, values.capacity() > 0];
        Columns {
            positions: Assembly::from_vec(positions),
            normals: Assembly::from_vec(normals),
            values: Assembly::from_vec(values),
            reused,
        }
    }

    /// The arrays of the mesh's `n` vertices.
    ///
    /// # Safety
    /// The extractor placed vertices `0..n`.
    unsafe fn into_arrays(self, n: usize) -> (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<f32>) {
        let [p, q, v] = self.reused;
        // SAFETY: every vertex placed writes its element of each array (`place`).
        let (positions, normals, values) = unsafe {
            (self.positions.into_vec(n, p), self.normals.into_vec(n, q), self.values.into_vec(n, v))
        };
        (trimmed(positions), trimmed(normals), trimmed(values))
    }
}

/// `v`, its memory cut to its length when it holds more than twice that: kept memory of a
/// much larger earlier call would otherwise stay with arrays a caller may keep.
fn trimmed<T>(mut v: Vec<T>) -> Vec<T> {
    if v.capacity() / 2 > v.len() {
        v.shrink_to_fit();
    }
    v
}

impl<const REWOUND: bool, const REVERSED: bool> VertexSink<Record<REWOUND>> for Columns<REVERSED> {
    fn reserve(&self, needed: usize, wanted: usize) {
        self.positions.reserve(needed, wanted);
        self.normals.reserve(needed, wanted);
        self.values.reserve(needed, wanted);
    }

    unsafe fn place(&self, first: usize, vertices: &[Record<REWOUND>]) {
        // The order fixed per instance: looked up per coordinate it costs about twice the
        // copy.
        let order = |a: [f32; 3]| if REVERSED { [a[2], a[1], a[0]] } else { a };
        let n = vertices.len();
        // In one pass over the records (each array's lock is taken for reading, which
        // growth waits for, one at a time, so that the three cannot wait on each other).
        // SAFETY: the extractor gives each range once (`VertexSink::place`'s contract,
        // which is `Assembly::write`'s); the loop writes every element of the three ranges.
        unsafe {
            self.positions.write(first, n, |pos| {
                self.normals.write(first, n, |normal| {
                    self.values.write(first, n, |value| {
                        let rows = vertices
                            .iter()
                            .map(|r| (order(r.0.position), order(r.0.normal), r.0.value));
                        stream_rows(pos, normal, value, rows);
                    })
                })
            });
        }
    }
}

/// The extraction straight into the arrays ([`Columns`]), over triangles wound the other way
/// round when `REWOUND`, the vertices' axes reversed when `REVERSED`.
fn extract_columns<const REWOUND: bool, const REVERSED: bool>(
    samples: &Samples<'_>,
    control: &skelform::Control,
) -> Result<Flat, skelform::volume::Cancelled> {
    let columns = Columns::<REVERSED>::new();
    let faces = pooled::take_triangles();
    let (n, triangles) = match samples {
        Samples::InPlace(view) => {
            extract_view_sunk::<Record<REWOUND>>(view, control, &columns, faces)
        }
        Samples::Converted(volume) => {
            extract_volume_sunk::<Record<REWOUND>>(volume, control, &columns, faces)
        }
    }?;
    // SAFETY: the extractor placed every vertex of the mesh, `0..n`.
    let (positions, normals, values) = unsafe { columns.into_arrays(n) };
    Ok((positions, triangles, normals, values))
}

/// The vertices of a block into their rows of the arrays, every row written; with the axes
/// in reverse order when `REVERSED` (the array's axis order is z, y, x: a C-ordered volume).
#[inline(always)]
fn copy_block<const REVERSED: bool>(
    pos: &mut [std::mem::MaybeUninit<[f32; 3]>],
    normal: &mut [std::mem::MaybeUninit<[f32; 3]>],
    value: &mut [std::mem::MaybeUninit<f32>],
    vertices: &[Vertex],
) {
    let order = |a: [f32; 3]| if REVERSED { [a[2], a[1], a[0]] } else { a };
    let outs = pos.iter_mut().zip(normal.iter_mut()).zip(value);
    for (((pos, normal), value), v) in outs.zip(vertices) {
        pos.write(order(v.position));
        normal.write(order(v.normal));
        value.write(v.value);
    }
}

/// Flat arrays in scikit-image's conventions: vertices and normals in array axis order,
/// the gradient size as the value, and the faces, which the extractor wound already. The
/// vertex arrays are written once, in blocks on the pool's threads, into memory that is not
/// zeroed first. Gives the vertex records back, for the next call.
fn conventions(layout: &Layout, ex: Extracted) -> (Flat, Vec<Vertex>) {
    /// Vertices per parallel task: enough to make a task's start-up cost nothing.
    const BLOCK: usize = 1 << 13;
    let n = ex.vertices.len();
    let mut positions = pooled::take::<[f32; 3]>(n);
    let mut normals = pooled::take::<[f32; 3]>(n);
    let mut values = pooled::take::<f32>(n);
    positions.spare_capacity_mut()[..n]
        .par_chunks_mut(BLOCK)
        .zip(normals.spare_capacity_mut()[..n].par_chunks_mut(BLOCK))
        .zip(values.spare_capacity_mut()[..n].par_chunks_mut(BLOCK))
        .zip(ex.vertices.par_chunks(BLOCK))
        .for_each(|(((pos, normal), value), vertices)| {
            // The two layouts there are, each a loop of its own with the order fixed (an
            // order looked up per coordinate costs about twice the copy).
            if layout.axis_of == [2, 1, 0] {
                copy_block::<true>(pos, normal, value, vertices);
            } else {
                debug_assert_eq!(layout.axis_of, [0, 1, 2]);
                copy_block::<false>(pos, normal, value, vertices);
            }
        });
    // SAFETY: the blocks above cover the first n elements of each array, block `b` of
    // each with vertices `b·BLOCK..` of the n, and every vertex writes its element of each
    // (`copy_block`).
    unsafe {
        positions.set_len(n);
        normals.set_len(n);
        values.set_len(n);
    }
    ((positions, ex.triangles, normals, values), ex.vertices)
}
