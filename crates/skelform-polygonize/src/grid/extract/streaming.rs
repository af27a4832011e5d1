//! Streaming: marching cubes over a volume that is never held whole, each slab's sample
//! layers fetched from a [`LayerSource`] as the slab is extracted, so memory follows the
//! number of threads instead of the volume.

use std::sync::atomic::AtomicU64;

use skelform_field::control::Control;
use skelform_field::grid::{Grid, Relative};

use super::slabs::{Workspace, run_slabs};
use super::{Near, SLAB, SlabVertex, extract_slab, slab_done};

/// The output of [`extract_streamed`].
#[derive(Clone, Debug)]
pub struct Streamed<V> {
    /// The vertices, in the record the caller chose (a lattice place, with or without its
    /// end samples, or a position).
    pub vertices: Vec<V>,
    /// The triangles, wound with their normals towards `f > 0`.
    pub triangles: Vec<[u32; 3]>,
    /// What the run read and found, since the samples are not kept to look at afterwards.
    pub stats: StreamStats,
}

/// Where streamed extraction gets its samples from, one `z` layer at a time (`nx·ny` values,
/// x fastest), already relative to the iso value (inside negative) and finite.
pub trait LayerSource: Sync {
    /// Why a layer could not be had (a read error, for a file): extraction stops and
    /// returns it as [`StreamError::Source`].
    type Error: Send;
    /// Fills `out` with sample layer `k`; returns how many of its samples were not finite
    /// (NaN, ±∞) and were replaced as [`skelform_field::grid::sanitize`] does.
    fn layer(&self, k: usize, out: &mut [f32]) -> Result<u64, Self::Error>;

    /// Fills `out` with layers `first..first + bad.len()`, one after the other, and `bad[n]`
    /// with the count [`LayerSource::layer`] returns for the `n`-th. The default fetches one
    /// layer at a time; a source that shares work between layers can do better.
    fn layers(&self, first: usize, out: &mut [f32], bad: &mut [u64]) -> Result<(), Self::Error> {
        let layer = out.len() / bad.len().max(1);
        for (n, (out, bad)) in out.chunks_mut(layer.max(1)).zip(bad).enumerate() {
            *bad = self.layer(first + n, out)?;
        }
        Ok(())
    }
}

/// Why streamed extraction stopped.
#[derive(Debug)]
pub enum StreamError<E> {
    /// The control asked the run to stop.
    Cancelled,
    /// The source failed (the lowest slab's failure, when several did).
    Source(E),
}

/// What streamed extraction gives besides the mesh.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StreamStats {
    /// Ambiguous faces decided by the asymptotic decider (each counted once per cube).
    pub ambiguous_faces: u64,
    /// Cubes whose interior tunnel test joined two loops.
    pub tunnels: u64,
    /// Samples that were not finite (each lattice point counted once).
    pub non_finite: u64,
    /// The smallest sample: with `max_sample`, whether the volume has a surface at all.
    pub min_sample: f32,
    /// The largest sample.
    pub max_sample: f32,
    /// Samples read (or evaluated): each layer once, and a layer that two slabs share twice
    /// when they ran on different threads.
    pub samples_read: u64,
    /// Time spent in the source and in extraction, summed over the workers.
    pub source_time: std::time::Duration,
    /// See `source_time`: the time in extraction proper.
    pub extract_time: std::time::Duration,
}

/// Marching cubes over a volume that is never held whole: each worker fetches the `SLAB + 1`
/// sample layers of one slab from `source`, extracts it and drops them, so memory follows the
/// number of threads, not the volume. The layer between two slabs is fetched once when one
/// thread runs both (on one thread, always), by each otherwise. The mesh is identical to
/// [`extract_positions`](super::extract_positions)'s on the same samples, on any number of threads.
pub fn extract_streamed<V: SlabVertex, S: LayerSource>(
    source: &S,
    grid: &Grid,
    control: &Control,
) -> Result<Streamed<V>, StreamError<S::Error>> {
    extract_streamed_with(source, grid, control, Workspace::shared())
}

/// [`extract_streamed`] with the slab buffers of `workspace`.
pub fn extract_streamed_with<V: SlabVertex, S: LayerSource>(
    source: &S,
    grid: &Grid,
    control: &Control,
    workspace: &Workspace,
) -> Result<Streamed<V>, StreamError<S::Error>> {
    use std::time::Instant;
    if !super::has_cells(grid) {
        return Ok(Streamed {
            vertices: Vec::new(),
            triangles: Vec::new(),
            stats: StreamStats::default(),
        });
    }
    let [nx, ny, nz] = grid.dims;
    let layer = nx * ny;
    let cube_layers = nz - 1;
    let slabs = cube_layers.div_ceil(SLAB);
    let done = AtomicU64::new(0);
    type Part = ((u64, u64), u64, (f32, f32), u64, std::time::Duration, std::time::Duration);
    let (vertices, triangles, parts) = run_slabs(
        slabs,
        [nx, ny],
        workspace,
        Default::default(),
        |s, scratch, store| -> Result<Part, _> {
            let z0 = s * SLAB;
            let z1 = (z0 + SLAB).min(cube_layers);
            let last = z1 == cube_layers;
            let t = Instant::now();
            if control.is_cancelled() {
                return Err(StreamError::Cancelled);
            }
            let mut layers = std::mem::take(&mut scratch.layers);
            let mut bad = [0; SLAB + 1];
            let bad = &mut bad[..=z1 - z0];
            // The slab below's top layer is this slab's first: when this thread ran that
            // slab, the layer is still here (always so on one thread).
            let first = match scratch.top.take() {
                Some((z, b)) if z == z0 => {
                    let len = layers.len();
                    layers.copy_within(len - layer.., 0);
                    bad[0] = b;
                    1
                }
                _ => 0,
            };
            layers.resize((z1 - z0 + 1) * layer, 0.0);
            source
                .layers(z0 + first, &mut layers[first * layer..], &mut bad[first..])
                .map_err(StreamError::Source)?;
            scratch.top = Some((z1, bad[z1 - z0]));
            // The top layer is counted by the slab above, unless there is none.
            let non_finite: u64 = bad[..z1 - z0 + usize::from(last)].iter().sum();
            let fetched = (z1 - z0 + 1 - first) as u64;
            let range = skelform_field::grid::value_range(&layers);
            let sourced = t.elapsed();
            let t = Instant::now();
            let near = Near {
                values: &layers,
                first: z0,
                layers: z1 - z0 + 1,
                dims: grid.dims,
                level: Relative,
            };
            let counts = extract_slab(grid, &near, (z0, z1), scratch, store, control)
                .map_err(|_| StreamError::Cancelled)?;
            scratch.layers = layers;
            let extracted = t.elapsed();
            slab_done(control, &done, z1 - z0, cube_layers, "sampling and extracting")
                .map_err(|_| StreamError::Cancelled)?;
            Ok((counts, non_finite, range, fetched, sourced, extracted))
        },
    )?;
    let mut stats = StreamStats {
        min_sample: f32::INFINITY,
        max_sample: f32::NEG_INFINITY,
        ..StreamStats::default()
    };
    for ((ambiguous_faces, tunnels), non_finite, (lo, hi), fetched, sourced, extracted) in parts {
        stats.samples_read += fetched * layer as u64;
        stats.non_finite += non_finite;
        stats.min_sample = stats.min_sample.min(lo);
        stats.max_sample = stats.max_sample.max(hi);
        stats.source_time += sourced;
        stats.extract_time += extracted;
        stats.ambiguous_faces += ambiguous_faces;
        stats.tunnels += tunnels;
    }
    Ok(Streamed { vertices, triangles, stats })
}
