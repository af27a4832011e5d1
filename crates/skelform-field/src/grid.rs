//! Regular lattices over a box, and sampling a field on them.

use std::mem::MaybeUninit;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;
use thiserror::Error;

use crate::control::{Control, Progress};
use crate::{Aabb, Field, LayerSampler};

/// The most samples along one axis (indices must fit `u32` edge numbering downstream).
pub const MAX_SAMPLES_PER_AXIS: usize = 1 << 15;

/// Why a grid could not be made or sampled.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum GridError {
    /// The domain box is empty, inverted or not finite on some axis ([`Aabb::is_valid`]).
    #[error(
        "the domain box must have positive, finite size on every axis and lie within ±3.4e38 (mesh coordinates are 32-bit floats); got min {min:?}, max {max:?}"
    )]
    BadDomain {
        /// The box's `min` corner, as given.
        min: [f64; 3],
        /// Its `max` corner.
        max: [f64; 3],
    },
    /// Fewer than 2 samples along the longest side: there would be no cell.
    #[error("the resolution must be at least 2 samples along the longest side (got {0})")]
    BadResolution(usize),
    /// A cell size that is zero, negative or not finite.
    #[error("the cell size must be positive and finite (got {0})")]
    BadCell(f64),
    /// More than [`MAX_SAMPLES_PER_AXIS`] samples along an axis: refused before anything is
    /// allocated, since the volume (or the edge numbering) would not fit.
    #[error(
        "the grid would have {} × {} × {} samples; at most {max} are allowed along one axis",
        count(dims[0]), count(dims[1]), count(dims[2])
    )]
    TooLarge {
        /// The samples along x, y, z the domain and cell would need (as floats: a tiny cell
        /// asks for counts past any integer type).
        dims: [f64; 3],
        /// The limit, [`MAX_SAMPLES_PER_AXIS`].
        max: usize,
    },
    /// The [`Control`] asked the sampling to stop.
    #[error("cancelled")]
    Cancelled,
}

/// A lattice of `dims[0] × dims[1] × dims[2]` samples spaced `cell` apart, from `origin`.
///
/// Cells are cubes. When a domain's sides are not whole multiples of the cell, the lattice is
/// grown to the next whole cell and centred on the domain, so it always covers the domain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    /// The position of sample `(0, 0, 0)`, the lattice's lowest corner: the domain's `min`,
    /// moved out by half of what rounding the sides up to whole cells adds.
    pub origin: DVec3,
    /// The side of every cell; samples are `cell` apart along each axis.
    pub cell: f64,
    /// Samples (not cells) along x, y, z; each at least 2.
    pub dims: [usize; 3],
}

impl Grid {
    /// `samples` samples along the domain's longest side (so `samples − 1` cells).
    pub fn with_resolution(domain: &Aabb, samples: usize) -> Result<Grid, GridError> {
        check_domain(domain)?;
        if samples < 2 {
            return Err(GridError::BadResolution(samples));
        }
        let longest = domain.size().max_element();
        Grid::with_cell(domain, longest / (samples - 1) as f64)
    }

    /// Cells of side `cell` covering the domain.
    pub fn with_cell(domain: &Aabb, cell: f64) -> Result<Grid, GridError> {
        check_domain(domain)?;
        if !(cell.is_finite() && cell > 0.0) {
            return Err(GridError::BadCell(cell));
        }
        let size = domain.size();
        // A relative slack keeps 2.0 / (2.0 / 100) from becoming 101 cells.
        let cells = |len: f64| ((len / cell) * (1.0 - 1e-12)).ceil().max(1.0);
        let n = [cells(size.x), cells(size.y), cells(size.z)];
        // Compared as floats: a tiny cell makes counts past u64 (`as` would saturate them and
        // the `+ 1` overflow), and the message shows them saturated.
        if n.iter().any(|&c| c >= MAX_SAMPLES_PER_AXIS as f64) {
            return Err(GridError::TooLarge {
                dims: n.map(|c| c + 1.0),
                max: MAX_SAMPLES_PER_AXIS,
            });
        }
        let dims64 = n.map(|c| c as u64 + 1);
        let extent = DVec3::new(n[0], n[1], n[2]) * cell;
        let origin = domain.center() - extent * 0.5;
        Ok(Grid { origin, cell, dims: dims64.map(|d| d as usize) })
    }

    /// The position of sample `(i, j, k)`.
    #[inline]
    pub fn point(&self, i: usize, j: usize, k: usize) -> DVec3 {
        self.origin + DVec3::new(i as f64, j as f64, k as f64) * self.cell
    }

    /// Total number of samples.
    pub fn sample_count(&self) -> u64 {
        self.dims.iter().map(|&d| d as u64).product()
    }

    /// Number of cells (cubes between samples).
    pub fn cell_count(&self) -> u64 {
        self.dims.iter().map(|&d| d as u64 - 1).product()
    }

    /// The box the lattice spans.
    pub fn bounds(&self) -> Aabb {
        let n = DVec3::new(
            (self.dims[0] - 1) as f64,
            (self.dims[1] - 1) as f64,
            (self.dims[2] - 1) as f64,
        );
        Aabb { min: self.origin, max: self.origin + n * self.cell }
    }

    /// Linear index of sample `(i, j, k)`: x varies fastest, then y, then z.
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        i + self.dims[0] * (j + self.dims[1] * k)
    }
}

/// A sample count as a person reads it: whole below a billion, else in powers of ten.
fn count(n: f64) -> String {
    if n < 1e9 { format!("{n}") } else { format!("{n:.2e}") }
}

/// Mesh positions are stored as `f32`: a lattice past its range would write infinite
/// coordinates.
const LARGEST_COORDINATE: f64 = f32::MAX as f64;

fn check_domain(domain: &Aabb) -> Result<(), GridError> {
    let size = domain.size();
    let in_range = (domain.min.abs().max_element() <= LARGEST_COORDINATE)
        && (domain.max.abs().max_element() <= LARGEST_COORDINATE)
        && size.is_finite();
    if domain.is_valid() && in_range {
        Ok(())
    } else {
        Err(GridError::BadDomain { min: domain.min.to_array(), max: domain.max.to_array() })
    }
}

/// Field values on a [`Grid`], stored as `f32` after subtracting nothing: the field itself is
/// expected to be zero on the surface (wrap it in [`crate::Iso`] for another level).
///
/// Non-finite values are replaced when sampling (NaN and +∞ by `f32::MAX`, −∞ by `-f32::MAX`)
/// so that extraction never interpolates towards NaN; [`Volume::non_finite`] says how many.
#[derive(Clone, Debug)]
pub struct Volume {
    /// The lattice the values were sampled on.
    pub grid: Grid,
    /// `values[grid.index(i, j, k)]`.
    pub values: Vec<f32>,
    /// How many samples were NaN or infinite (and replaced).
    pub non_finite: u64,
}

impl Volume {
    /// A volume from values already computed elsewhere (e.g. read from a raw file).
    ///
    /// # Panics
    /// If `values.len()` is not `grid.sample_count()`.
    pub fn from_values(grid: Grid, mut values: Vec<f32>) -> Volume {
        assert_eq!(values.len() as u64, grid.sample_count(), "values do not fill the grid");
        let non_finite = sanitize(&mut values);
        Volume { grid, values, non_finite }
    }

    /// The (sanitised) value at sample `(i, j, k)`, which must be inside the grid: the
    /// indices are not checked axis by axis, only the resulting position in `values`.
    #[inline]
    pub fn get(&self, i: usize, j: usize, k: usize) -> f32 {
        self.values[self.grid.index(i, j, k)]
    }

    /// The smallest and largest sample: a surface needs one of each sign.
    pub fn value_range(&self) -> (f32, f32) {
        self.values
            .par_chunks(1 << 16)
            .map(value_range)
            .reduce(|| value_range(&[]), |a, b| (a.0.min(b.0), a.1.max(b.1)))
    }

    /// Bytes a volume of this grid takes.
    pub fn bytes_for(grid: &Grid) -> u64 {
        grid.sample_count() * std::mem::size_of::<f32>() as u64
    }
}

/// The smallest and largest of `values` (`(∞, −∞)` for none; NaNs are passed over).
pub fn value_range(values: &[f32]) -> (f32, f32) {
    // Sixteen running minima and maxima, so that the loop vectorises.
    const W: usize = 16;
    let (mut lo, mut hi) = ([f32::INFINITY; W], [f32::NEG_INFINITY; W]);
    let chunks = values.chunks_exact(W);
    let rest = chunks.remainder();
    for c in chunks {
        for i in 0..W {
            lo[i] = if c[i] < lo[i] { c[i] } else { lo[i] };
            hi[i] = if c[i] > hi[i] { c[i] } else { hi[i] };
        }
    }
    lo.iter()
        .chain(rest)
        .zip(hi.iter().chain(rest))
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(l, h), (&a, &b)| {
            (if a < l { a } else { l }, if b > h { b } else { h })
        })
}

/// Replaces non-finite samples so that extraction can compare them: NaN and +∞ become the
/// largest finite value (far outside), −∞ the most negative (far inside). Returns how many
/// were replaced.
pub fn sanitize(values: &mut [f32]) -> u64 {
    let mut bad = 0;
    // Without branches, so that it vectorises: most volumes have no bad value at all.
    for v in values {
        let (s, replaced) = sanitize_sample(*v);
        bad += u64::from(replaced);
        *v = s;
    }
    bad
}

/// One sample as [`sanitize`] has it: NaN and +∞ become `f32::MAX`, −∞ `-f32::MAX`, finite
/// values stay; and whether it was replaced. Without branches, so that loops over it
/// vectorise.
#[inline(always)]
pub fn sanitize_sample(v: f32) -> (f32, bool) {
    (finite_sample(v), !v.is_finite())
}

/// The sample [`sanitize_sample`] makes of `v`, in two instructions: extraction reads
/// samples through it (every cube corner and, for vertex normals, a dozen around each
/// vertex), where the test for finiteness and the choice of replacement cost about ten.
/// A comparison with NaN is false, so NaN takes the first arm's replacement, as `minss`
/// and `maxss` (what these compile to) do.
#[inline(always)]
fn finite_sample(v: f32) -> f32 {
    let below = if v < f32::MAX { v } else { f32::MAX };
    if below > -f32::MAX { below } else { -f32::MAX }
}

/// How stored values are read as samples relative to the iso level (inside negative):
/// the extractor compares and interpolates `sample(raw)`, and finds the inside by comparing
/// raw values with `threshold()` (so that the pass over every value needs no arithmetic).
pub trait Level: Copy + Send + Sync {
    /// The sample that raw value `raw` stands for: finite, relative to the level.
    fn sample(self, raw: f32) -> f32;
    /// A raw value is inside (`sample(raw) < 0`) exactly when `raw < threshold()`; NaN never
    /// is.
    fn threshold(self) -> f32;
}

/// Values that are already samples: relative to the level and finite (a [`Volume`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Relative;

impl Level for Relative {
    #[inline(always)]
    fn sample(self, raw: f32) -> f32 {
        raw
    }
    #[inline(always)]
    fn threshold(self) -> f32 {
        0.0
    }
}

/// Raw values (a caller's array, read in place) and the level of the surface: a value `x`
/// is the sample `(x − level)`, computed in `f64`, rounded to `f32` and sanitised as
/// [`sanitize`] does, exactly what converting the array into a [`Volume`] would store.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shifted {
    level: f64,
    threshold: f32,
}

impl Shifted {
    /// The reading of raw values at iso level `level` (any `f64`: a NaN level leaves every
    /// sample outside, as converting would).
    pub fn new(level: f64) -> Shifted {
        let level = Shifted { level, threshold: 0.0 };
        // `sample` never decreases as the raw value grows (a subtraction, a rounding and a
        // clamp of ±∞ to ±f32::MAX, all monotone), so the inside is the raw values below the
        // smallest one that is not inside: found by bisection over the ordered f32 values
        // from −∞ to +∞ (keys that order floats as their values, −0 just below +0).
        let key = |x: f32| {
            let b = x.to_bits();
            if b >> 31 == 1 { !b } else { b | 1 << 31 }
        };
        let value = |k: u32| f32::from_bits(if k >> 31 == 1 { k & !(1 << 31) } else { !k });
        let inside = |k: u32| level.sample(value(k)) < 0.0;
        let (mut lo, mut hi) = (key(f32::NEG_INFINITY), key(f32::INFINITY));
        // +∞ is never inside (+∞ − level is +∞ or NaN, both stored as f32::MAX).
        let threshold = if !inside(lo) {
            f32::NEG_INFINITY
        } else {
            // inside(lo), !inside(hi): narrow to adjacent keys.
            while hi - lo > 1 {
                let mid = lo + (hi - lo) / 2;
                if inside(mid) { lo = mid } else { hi = mid }
            }
            value(hi)
        };
        Shifted { threshold, ..level }
    }

    /// The level.
    pub fn level(&self) -> f64 {
        self.level
    }

    /// This reading without its arithmetic when the level is +0 (a caller's usual level):
    /// `x − 0` is `x`, exactly, in `f64` and back in `f32`, so a sample is the raw value
    /// sanitised. (Not at −0, where `−0 − (−0)` is +0.)
    pub fn at_zero(&self) -> Option<AtZero> {
        (self.level.to_bits() == 0).then_some(AtZero { threshold: self.threshold })
    }
}

/// [`Shifted`] at level +0, read without the subtraction ([`Shifted::at_zero`]): the same
/// samples bit for bit, with three fewer conversions and subtractions a read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtZero {
    threshold: f32,
}

impl Level for AtZero {
    #[inline(always)]
    fn sample(self, raw: f32) -> f32 {
        finite_sample(raw)
    }
    #[inline(always)]
    fn threshold(self) -> f32 {
        self.threshold
    }
}

impl Level for Shifted {
    #[inline(always)]
    fn sample(self, raw: f32) -> f32 {
        finite_sample((f64::from(raw) - self.level) as f32)
    }
    #[inline(always)]
    fn threshold(self) -> f32 {
        self.threshold
    }
}

/// Raw values held elsewhere (a caller's array), read in place at a level: what a
/// [`Volume`] of `Shifted::sample` of each value would be, without the copy.
#[derive(Clone, Copy, Debug)]
pub struct VolumeView<'a> {
    /// The lattice.
    pub grid: Grid,
    /// `values[grid.index(i, j, k)]`, raw.
    pub values: &'a [f32],
    /// How they are read.
    pub level: Shifted,
}

impl<'a> VolumeView<'a> {
    /// A view of `values` on `grid` at `level`; `None` unless `values` fills the grid
    /// exactly.
    pub fn new(grid: Grid, values: &'a [f32], level: f64) -> Option<VolumeView<'a>> {
        (values.len() as u64 == grid.sample_count()).then(|| VolumeView {
            grid,
            values,
            level: Shifted::new(level),
        })
    }

    /// The sample (relative to the level, sanitised) at `(i, j, k)`, which must be inside
    /// the grid (only the position in `values` is checked).
    #[inline]
    pub fn get(&self, i: usize, j: usize, k: usize) -> f32 {
        self.level.sample(self.values[self.grid.index(i, j, k)])
    }
}

/// Field values as samples: clamped into `f32`'s finite range (huge finite values stay
/// finite, ±∞ become ±`f32::MAX`), NaN replaced as [`sanitize`] does. Returns how many were
/// NaN.
fn store_samples(values: &[f64], out: &mut [MaybeUninit<f32>]) -> u64 {
    let mut bad = 0;
    for (o, &v) in out.iter_mut().zip(values) {
        let (sample, nan) = to_sample(v);
        bad += u64::from(nan);
        o.write(sample);
    }
    bad
}

/// One field value as a sample (see [`store_samples`]), and whether it was NaN.
#[inline(always)]
fn to_sample(v: f64) -> (f32, bool) {
    let nan = v.is_nan();
    let clamped = v.clamp(-f32::MAX as f64, f32::MAX as f64) as f32;
    (if nan { f32::MAX } else { clamped }, nan)
}

/// Samples a field on the layers of one lattice, in any order and from any thread, exactly
/// as [`sample`] does: for callers that stream a volume layer by layer. Work that is the same
/// on every layer is done once, when it is made ([`Field::sampler`]).
pub struct LayerSampling<'a> {
    grid: Grid,
    sampler: Box<dyn LayerSampler + 'a>,
}

impl<'a> LayerSampling<'a> {
    /// Prepares to sample `field` on `grid`'s layers, with the same coordinates as
    /// [`Grid::point`] (so the values are [`sample`]'s, bit for bit); the field's sampler does
    /// here what all layers share.
    pub fn new(field: &'a dyn Field, grid: &Grid) -> Self {
        let [nx, ny, _] = grid.dims;
        // The coordinates as `grid.point` computes them (each axis on its own).
        let xs: Vec<f64> = (0..nx).map(|i| grid.point(i, 0, 0).x).collect();
        let ys: Vec<f64> = (0..ny).map(|j| grid.point(0, j, 0).y).collect();
        LayerSampling { grid: *grid, sampler: field.sampler(&xs, &ys) }
    }

    /// Samples layer `k` into `out` (`nx·ny` values, x fastest), non-finite values replaced
    /// as [`sanitize`] does; returns how many were.
    pub fn layer(&self, k: usize, out: &mut [f32]) -> u64 {
        let mut bad = [0];
        self.layers(k, out, &mut bad);
        bad[0]
    }

    /// Samples layers `first..first + bad.len()` into `out` (one after the other), with
    /// `bad[n]` how many values of the `n`-th were not finite and were replaced. A block of
    /// rows is sampled on every layer before the next block, so that what the sampler keeps
    /// for all layers (a formula's terms of `x` and `y`) is read from cache, not memory.
    pub fn layers(&self, first: usize, out: &mut [f32], bad: &mut [u64]) {
        // SAFETY: MaybeUninit<f32> has f32's layout, and `fill` writes initialised values
        // only, so `out` stays initialised.
        let out = unsafe { &mut *(out as *mut [f32] as *mut [MaybeUninit<f32>]) };
        self.fill(first, out, bad);
    }

    /// [`LayerSampling::layers`] into memory not yet initialised: every element of `out` is
    /// written.
    fn fill(&self, first: usize, out: &mut [MaybeUninit<f32>], bad: &mut [u64]) {
        let [nx, ny, _] = self.grid.dims;
        let layer = nx * ny;
        // What makes every element written (`sample` relies on it).
        assert_eq!(out.len(), layer * bad.len(), "the output must hold the layers whole");
        bad.fill(0);
        // Rows a few at a time: a small buffer, and enough points per call to share the
        // work done once per call (the terms that vary along x only).
        let rows = (1usize << 13).div_ceil(nx.max(1)).min(ny.max(1));
        let mut values = vec![0f64; rows * nx];
        for at in (0..ny).step_by(rows) {
            let end = (at + rows).min(ny);
            let values = &mut values[..(end - at) * nx];
            for (n, bad) in bad.iter_mut().enumerate() {
                let z = self.grid.point(0, 0, first + n).z;
                self.sampler.layer(z, at..end, values);
                *bad += store_samples(values, &mut out[n * layer + at * nx..][..values.len()]);
            }
        }
    }
}

/// Samples `field` again at the lattice points of `volume` whose indices
/// ([`Grid::index`]) are listed, writing them in place: the values [`sample`] gives there,
/// bit for bit (the same coordinates, [`Grid::point`]'s, the same sanitizing; a field's
/// [`Field::eval_many`] must equal its sampler, as [`Field::sampler`] requires). For
/// incremental re-meshing, where an edit changes the field near some points only. Returns
/// how many of the new values were NaN.
///
/// `control` is asked between chunks of 4096 points: once it is cancelled the chunks not yet
/// sampled are skipped and the call returns [`GridError::Cancelled`], the chunks already done
/// written (the volume then holds the new field at some of `indices`, the old elsewhere;
/// the caller samples them again). Why: an incremental update of a large element is a
/// sizeable part of a run, and a newer edit must not wait for it.
pub fn resample_points(
    field: &dyn Field,
    volume: &mut Volume,
    indices: &[usize],
    control: &Control,
) -> Result<u64, GridError> {
    let grid = volume.grid;
    let [nx, ny, _] = grid.dims;
    let values: Vec<Option<(Vec<f32>, u64)>> = indices
        .par_chunks(4096)
        .map(|chunk| {
            if control.is_cancelled() {
                return None;
            }
            let points: Vec<DVec3> =
                chunk.iter().map(|&n| grid.point(n % nx, (n / nx) % ny, n / (nx * ny))).collect();
            let mut values = vec![0.0; points.len()];
            field.eval_many(&points, &mut values);
            let mut bad = 0;
            let out = values
                .iter()
                .map(|&v| {
                    let (sample, nan) = to_sample(v);
                    bad += u64::from(nan);
                    sample
                })
                .collect();
            Some((out, bad))
        })
        .collect();
    let mut bad = 0;
    let mut cancelled = false;
    for (chunk, done) in indices.chunks(4096).zip(values) {
        let Some((out, b)) = done else {
            cancelled = true;
            continue;
        };
        bad += b;
        for (&n, v) in chunk.iter().zip(out) {
            volume.values[n] = v;
        }
    }
    if cancelled { Err(GridError::Cancelled) } else { Ok(bad) }
}

/// Layers sampled together by [`sample`]: a block shares the sampler's cached rows.
const LAYER_BLOCK: usize = 8;

/// Samples `field` at every lattice point, in parallel over z-layers.
///
/// The result does not depend on the number of threads: each sample is computed on its own.
pub fn sample(field: &dyn Field, grid: &Grid, control: &Control) -> Result<Volume, GridError> {
    let [nx, ny, nz] = grid.dims;
    let layer = nx * ny;
    let mut values: Vec<f32> = Vec::with_capacity(layer * nz);
    crate::pages::advise_huge(values.as_ptr(), values.capacity());
    let done = AtomicU64::new(0);
    let sampling = LayerSampling::new(field, grid);
    // Each block of layers is written where it lies, once, by the thread that samples it (a
    // zeroing pass first would touch all the fresh memory on one thread, and write it twice).
    let non_finite = values.spare_capacity_mut()[..layer * nz]
        .par_chunks_mut(layer * LAYER_BLOCK)
        .enumerate()
        .map(|(b, out)| {
            let mut bad = [0; LAYER_BLOCK];
            let bad = &mut bad[..out.len() / layer];
            sampling.fill(b * LAYER_BLOCK, out, bad);
            let d = done.fetch_add(bad.len() as u64, Ordering::Relaxed) + bad.len() as u64;
            match control.report(Progress { phase: "sampling", done: d, total: Some(nz as u64) }) {
                ControlFlow::Continue(()) => Ok(bad.iter().sum::<u64>()),
                ControlFlow::Break(()) => Err(GridError::Cancelled),
            }
        })
        .try_reduce(|| 0, |a, b| Ok(a + b))?;
    // SAFETY: the blocks cover the first `layer·nz` elements, each written whole by `fill`.
    unsafe { values.set_len(layer * nz) };
    Ok(Volume { grid: *grid, values, non_finite })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::FnField;

    #[test]
    fn resolution_fits_longest_side_exactly() {
        let d = Aabb::new(DVec3::splat(-1.0), DVec3::new(1.0, 1.0, 0.5));
        let g = Grid::with_resolution(&d, 101).unwrap();
        assert_eq!(g.dims, [101, 101, 76]);
        assert!((g.cell - 0.02).abs() < 1e-15);
        let b = g.bounds();
        assert!((b.min.x + 1.0).abs() < 1e-12 && (b.max.x - 1.0).abs() < 1e-12);
        // z is grown to whole cells and centred: 75 cells = 1.5.
        assert!((b.min.z + 1.0).abs() < 1e-12 && (b.max.z - 0.5).abs() < 1e-12);
    }

    #[test]
    fn bad_grids_are_refused() {
        let d = Aabb::cube(1.0);
        assert_eq!(Grid::with_resolution(&d, 1), Err(GridError::BadResolution(1)));
        assert!(matches!(Grid::with_cell(&d, 0.0), Err(GridError::BadCell(_))));
        assert!(matches!(Grid::with_cell(&d, 1e-9), Err(GridError::TooLarge { .. })));
        // Counts past u64 are refused, not wrapped or saturated into a panic.
        let e = Grid::with_cell(&d, 1e-19).unwrap_err();
        assert!(e.to_string().contains("2.00e19 × 2.00e19 × 2.00e19"), "{e}");
        // Boxes whose size overflows, or that reach past f32 coordinates, are bad domains.
        for (lo, hi) in [(-1e308, 1.0), (-1e308, 1e308), (-1e39, 1e39)] {
            let b = Aabb::new(DVec3::new(-1.0, -1.0, lo), DVec3::new(1.0, 1.0, hi));
            assert!(matches!(Grid::with_cell(&b, 0.15), Err(GridError::BadDomain { .. })));
            assert!(matches!(Grid::with_resolution(&b, 20), Err(GridError::BadDomain { .. })));
        }
        let flat = Aabb::new(DVec3::ZERO, DVec3::new(1.0, 1.0, 0.0));
        assert!(matches!(Grid::with_cell(&flat, 0.1), Err(GridError::BadDomain { .. })));
    }

    /// The threshold says inside exactly when the shifted sample is negative, for levels
    /// and values around the edge cases: zeros, subnormal differences, ±∞, NaN, a level
    /// that is not an `f32`.
    /// Every special value and its neighbours come out of the two-comparison form as the
    /// rule says: NaN (any payload, either sign) and +∞ the largest finite value, −∞ the
    /// most negative, everything finite (±0, subnormals, ±f32::MAX) unchanged, bit for bit.
    #[test]
    fn samples_are_sanitised_by_the_rule() {
        let rule = |v: f32| {
            if v.is_nan() || v == f32::INFINITY {
                f32::MAX
            } else if v == f32::NEG_INFINITY {
                -f32::MAX
            } else {
                v
            }
        };
        let mut values = vec![
            0.0,
            -0.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::from_bits(1),
            f32::from_bits(1 | 1 << 31),
            f32::MAX,
            -f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
            f32::from_bits(0x7f80_0001),
            f32::from_bits(0xffc0_1234),
            1.5,
            -2.25e30,
        ];
        // Bit patterns across the whole range, both signs.
        values.extend((0..4096u32).map(|n| f32::from_bits(n.wrapping_mul(0x0010_0401))));
        for v in values {
            let (s, replaced) = sanitize_sample(v);
            assert_eq!(s.to_bits(), rule(v).to_bits(), "{v:?} ({:#x})", v.to_bits());
            assert_eq!(replaced, !v.is_finite(), "{v:?}");
            assert_eq!(AtZero { threshold: 0.0 }.sample(v).to_bits(), s.to_bits(), "{v:?}");
        }
    }

    #[test]
    fn shifted_threshold_matches_the_samples() {
        let levels = [
            0.0,
            -0.0,
            1.0,
            0.1,
            -3.7,
            1e-50,
            -1e-50,
            1e300,
            -1e300,
            f64::from(f32::MAX),
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            f64::from(f32::MIN_POSITIVE) / 4.0,
        ];
        let mut values = vec![
            0.0,
            -0.0,
            1.0,
            0.1,
            -3.7,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::from_bits(1),
            -f32::from_bits(1),
            f32::MAX,
            -f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for &l in &levels {
            let x = l as f32;
            values.extend([
                x,
                f32::from_bits(x.to_bits().wrapping_add(1)),
                f32::from_bits(x.to_bits().wrapping_sub(1)),
            ]);
        }
        for &l in &levels {
            let s = Shifted::new(l);
            for &x in &values {
                let inside = s.sample(x) < 0.0;
                assert_eq!(x < s.threshold(), inside, "level {l:e}, value {x:e}");
                assert!(s.sample(x).is_finite());
                let mut v = [(f64::from(x) - l) as f32];
                sanitize(&mut v);
                assert_eq!(v[0].to_bits(), s.sample(x).to_bits());
                // At +0 the reading without the subtraction is the same, bit for bit.
                if let Some(z) = s.at_zero() {
                    assert_eq!(z.sample(x).to_bits(), s.sample(x).to_bits(), "value {x:e}");
                    assert_eq!(z.threshold().to_bits(), s.threshold().to_bits());
                }
            }
            assert_eq!(s.at_zero().is_some(), l.to_bits() == 0, "level {l:e}");
        }
    }

    #[test]
    fn sampling_matches_pointwise_and_counts_non_finite() {
        let f = FnField(|p: DVec3| if p.x > 0.9 { f64::NAN } else { p.length() - 0.5 });
        let g = Grid::with_resolution(&Aabb::cube(1.0), 11).unwrap();
        let v = sample(&f, &g, &Control::default()).unwrap();
        assert_eq!(v.values.len(), 11 * 11 * 11);
        assert_eq!(v.get(5, 5, 5), -0.5);
        assert_eq!(v.get(2, 3, 4), (g.point(2, 3, 4).length() - 0.5) as f32);
        assert_eq!(v.non_finite, 11 * 11);
        assert_eq!(v.get(10, 0, 0), f32::MAX);
    }

    #[test]
    fn sampling_can_be_cancelled() {
        let f = FnField(|p: DVec3| p.x);
        let g = Grid::with_resolution(&Aabb::cube(1.0), 64).unwrap();
        let c = Control::with_callback(|_| ControlFlow::Break(()));
        assert_eq!(sample(&f, &g, &c).unwrap_err(), GridError::Cancelled);
    }
}
