//! `skelform extract`: marching cubes on a sampled volume from a raw file, without a field.
//!
//! This is the extraction-only path that other isosurface tools offer (scikit-image's
//! `marching_cubes`, VTK's Flying Edges, PyMCubes): the same topology guarantees as
//! `skelform mesh`, with vertices placed by linear interpolation (there is no field to
//! refine on) and no normals.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::anyhow;
use clap::Args;
use skelform::mesh::io::{WriteOptions, write_mesh};
use skelform::volume::{
    Grid, LayerSource, MAX_SAMPLES_PER_AXIS, StreamError, Streamed, Volume, extract_mesh,
    extract_streamed, sanitize,
};
use skelform::{Control, DVec3, Mesh};

use crate::{Failure, input, output_format, run::parse_bytes, run::parse_point, runtime};

#[derive(Args)]
pub struct ExtractArgs {
    /// Raw little-endian float32 samples, x varying fastest, then y, then z (a C-ordered
    /// NumPy array indexed [z][y][x], written with `tofile`).
    volume: PathBuf,
    /// Samples along x, y and z, e.g. 256,256,256.
    #[arg(long, value_parser = parse_dims)]
    dims: [usize; 3],
    /// Output mesh (.ply, .obj, .stl).
    #[arg(short, long)]
    output: PathBuf,
    /// The level to extract; inside is below it.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    iso: f64,
    /// Position of the first sample.
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true, default_value = "0,0,0")]
    origin: [f64; 3],
    /// Distance between samples.
    #[arg(long, default_value_t = 1.0)]
    spacing: f64,
    /// Worker threads (default: all cores). Several counts, comma-separated (`1,2`), measure
    /// how the extraction scales: each `--repeat` round extracts once with every count, in
    /// turn, and the report gives each count's times and its speed-up over the first count,
    /// the median of the rounds' (a round's runs are milliseconds apart, so a shared
    /// machine's drift cancels out of their ratio). The meshes must be identical.
    #[arg(long, value_delimiter = ',', num_args = 1..)]
    threads: Vec<usize>,
    /// Print statistics as JSON on standard output.
    #[arg(long)]
    json: bool,
    /// Write PLY as text.
    #[arg(long)]
    ascii: bool,
    /// Refuse volumes that would need more memory than this (default 4G).
    #[arg(long, value_parser = parse_bytes, default_value = "4G")]
    max_memory: u64,
    /// No summary line.
    #[arg(short, long)]
    quiet: bool,
    /// Read the file slab by slab as it is extracted instead of loading it whole: memory
    /// follows the thread count, not the volume (the time then includes reading).
    #[arg(long)]
    stream: bool,
    /// Extract this many times in this process (per thread count) and report the median time
    /// (the JSON lists each): for benchmarks, the way a program that links the library sees it.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    repeat: u32,
}

/// A raw float32 file read one z layer at a time, for `--stream`.
struct RawLayers {
    file: std::sync::Mutex<std::fs::File>,
    layer: usize,
    iso: f32,
}

impl LayerSource for RawLayers {
    type Error = std::io::Error;
    fn layer(&self, k: usize, out: &mut [f32]) -> Result<u64, Self::Error> {
        use std::io::{Read, Seek, SeekFrom};
        let mut bytes = vec![0u8; self.layer * 4];
        {
            let mut f = self.file.lock().unwrap_or_else(|e| e.into_inner());
            f.seek(SeekFrom::Start((k * self.layer * 4) as u64))?;
            f.read_exact(&mut bytes)?;
        }
        for (o, v) in out.iter_mut().zip(relative_samples(&bytes, self.iso)) {
            *o = v;
        }
        Ok(sanitize(out))
    }
}

fn parse_dims(s: &str) -> Result<[usize; 3], String> {
    let parts: Vec<Option<usize>> = s.split(',').map(|p| p.trim().parse().ok()).collect();
    match parts.as_slice() {
        [Some(x), Some(y), Some(z)] if *x >= 2 && *y >= 2 && *z >= 2 => Ok([*x, *y, *z]),
        _ => Err(format!("'{s}' is not three sample counts of at least 2, like 256,256,256")),
    }
}

pub fn extract(a: ExtractArgs) -> Result<(), Failure> {
    let format = output_format(&a.output)?;
    if !(a.spacing.is_finite() && a.spacing > 0.0) {
        return Err(input(anyhow!("--spacing must be a positive length")));
    }
    // As `mesh --threads` does: each count is a pool of that many threads, built up front.
    if let Some(n) = a.threads.iter().find(|&&n| !(1..=skelform::MAX_THREADS).contains(&n)) {
        return Err(input(anyhow!(
            "--threads must be between 1 and {} (got {n})",
            skelform::MAX_THREADS
        )));
    }
    let [nx, ny, nz] = a.dims;
    if a.dims.iter().any(|&d| d > MAX_SAMPLES_PER_AXIS) {
        return Err(input(anyhow!(
            "{}: --dims {nx},{ny},{nz}: at most {MAX_SAMPLES_PER_AXIS} samples are allowed along one axis",
            a.volume.display()
        )));
    }
    // Each axis is at most 2^15 samples, so the count fits in 45 bits and its bytes in 47:
    // checked anyway, as every size computed from input is.
    let bytes =
        a.dims.iter().try_fold(4u64, |acc, &d| acc.checked_mul(d as u64)).ok_or_else(|| {
            input(anyhow!("{}: --dims {nx},{ny},{nz} is too large", a.volume.display()))
        })?;
    // The samples as f32, plus about as much again for the extraction's bookkeeping (the
    // mesh); streamed, the samples are a few slabs.
    let needed = if a.stream { bytes } else { bytes.saturating_mul(2) };
    let max_memory = crate::run::memory_limit(a.max_memory, false);
    if needed > max_memory {
        return Err(input(anyhow!(
            "{}: a {nx}×{ny}×{nz} volume needs about {:.2} GiB, over the limit of {:.2} GiB (--max-memory)",
            a.volume.display(),
            needed as f64 / (1u64 << 30) as f64,
            max_memory as f64 / (1u64 << 30) as f64
        )));
    }
    // Positions are stored as f32: the far corner of the lattice must be one.
    let far = a.origin.iter().zip(a.dims).map(|(o, d)| o + a.spacing * (d - 1) as f64);
    // NaN is not finite either, so `is_finite` and the range check together refuse it.
    if a.origin.iter().copied().chain(far).any(|c| !c.is_finite() || c.abs() > f32::MAX as f64) {
        return Err(input(anyhow!(
            "{}: --origin and --spacing put the lattice beyond the range of 32-bit coordinates",
            a.volume.display()
        )));
    }
    let size = std::fs::metadata(&a.volume)
        .map_err(|e| input(anyhow!("{}: {e}", a.volume.display())))?
        .len();
    if size != bytes {
        return Err(input(anyhow!(
            "{}: {size} bytes, but {nx}×{ny}×{nz} float32 samples take {bytes}",
            a.volume.display(),
        )));
    }
    let iso = a.iso as f32;
    let grid = Grid { origin: DVec3::from_array(a.origin), cell: a.spacing, dims: a.dims };
    let counts = if a.threads.is_empty() { vec![0] } else { a.threads.clone() };
    let pools = counts
        .iter()
        .map(|&n| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| runtime(anyhow!("cannot start {n} threads: {e}")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let input = if a.stream {
        let file = std::fs::File::open(&a.volume)
            .map_err(|e| input(anyhow!("{}: {e}", a.volume.display())))?;
        let layer = a.dims[0] * a.dims[1];
        Samples::Streamed(RawLayers { file: std::sync::Mutex::new(file), layer, iso })
    } else {
        Samples::Whole(load_volume(&a.volume, grid, iso)?)
    };
    // The case table is generated once per process (a few milliseconds); build it before the
    // clock starts so that the reported time is the extraction's, comparable with tools whose
    // tables are compiled in.
    skelform::volume::prepare();
    let mut times = vec![Vec::new(); pools.len()];
    let mut last: Option<(Mesh, u64)> = None;
    for round in 0..a.repeat as usize {
        // The counts take turns at running first in a round, so that none always runs
        // right after the same one.
        let mut reference: Option<Mesh> = None;
        for c in 0..pools.len() {
            let p = (c + round) % pools.len();
            // Each earlier result is dropped before the next run, as a program would; only
            // the first round keeps its first mesh, to compare the other counts' with.
            if let Some((mesh, _)) = last.take()
                && round == 0
                && reference.is_none()
                && pools.len() > 1
            {
                reference = Some(mesh);
            }
            let t = Instant::now();
            let (mesh, non_finite) = input.extract(&pools[p], &grid, &a.volume)?;
            times[p].push(t.elapsed());
            if let Some(r) = &reference
                && (r.positions != mesh.positions || r.triangles != mesh.triangles)
            {
                return Err(runtime(anyhow!(
                    "{}: the mesh on {} threads differs from the one on {} (a bug: please report it)",
                    a.volume.display(),
                    pools[p].current_num_threads(),
                    pools[round % pools.len()].current_num_threads()
                )));
            }
            last = Some((mesh, non_finite));
        }
    }
    let Some((mesh, non_finite)) = last else { unreachable!("--repeat is at least 1") };
    if mesh.is_empty() {
        return Err(runtime(anyhow!(
            "{}: no surface: no sample pair straddles the iso value {}",
            a.volume.display(),
            a.iso
        )));
    }
    let t = Instant::now();
    write_mesh(
        &a.output,
        &mesh,
        format,
        &WriteOptions { ascii: a.ascii, normals: false, ..WriteOptions::default() },
    )
    .map_err(runtime)?;
    let writing = t.elapsed();
    let scaling = Scaling::of(&pools, &times);
    if a.json {
        let mut j = serde_json::json!({
            "volume": a.volume.display().to_string(),
            "dims": a.dims,
            "threads": pools[0].current_num_threads(),
            "non_finite_samples": non_finite,
            "streamed": a.stream,
            "vertices": mesh.vertex_count(),
            "triangles": mesh.triangle_count(),
            "seconds": {
                "extraction": scaling[0].median.as_secs_f64(),
                "extractions": seconds(&times[0]),
                "writing": writing.as_secs_f64(),
            },
        });
        if pools.len() > 1 {
            j["scaling"] = scaling
                .iter()
                .zip(&times)
                .map(|(s, t)| {
                    serde_json::json!({
                        "threads": s.threads,
                        "extraction": s.median.as_secs_f64(),
                        "extractions": seconds(t),
                        "speedup": s.speedup,
                        "speedups": s.speedups,
                    })
                })
                .collect();
        }
        outln!("{j}");
    } else if !a.quiet {
        errln!(
            "wrote {} ({} vertices, {} triangles; extraction {:.3}s)",
            a.output.display(),
            mesh.vertex_count(),
            mesh.triangle_count(),
            scaling[0].median.as_secs_f64()
        );
        for s in scaling.iter().skip(1) {
            errln!(
                "  on {} threads: {:.3}s, {:.2}× as fast as on {} (the median of {} rounds)",
                s.threads,
                s.median.as_secs_f64(),
                s.speedup,
                scaling[0].threads,
                s.speedups.len()
            );
        }
    }
    Ok(())
}

fn seconds(times: &[Duration]) -> Vec<f64> {
    times.iter().map(Duration::as_secs_f64).collect()
}

/// Reads a raw float32 volume into memory, relative to `iso`.
fn load_volume(path: &Path, grid: Grid, iso: f32) -> Result<Volume, Failure> {
    let raw = std::fs::read(path).map_err(|e| input(anyhow!("{}: {e}", path.display())))?;
    // On huge pages where the system has them: extraction streams through the whole
    // volume, and fewer pages mean fewer TLB misses on the way.
    let mut values: Vec<f32> = Vec::with_capacity(raw.len() / 4);
    skelform::field::pages::advise_huge(values.as_ptr(), values.capacity());
    values.extend(relative_samples(&raw, iso));
    Ok(Volume::from_values(grid, values))
}

/// The samples of raw little-endian float32 bytes, relative to `iso` (inside negative).
fn relative_samples(bytes: &[u8], iso: f32) -> impl Iterator<Item = f32> + '_ {
    bytes.chunks_exact(4).map(move |b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]) - iso)
}

/// Where the samples come from: the file slab by slab (`--stream`) or memory.
enum Samples {
    Streamed(RawLayers),
    Whole(Volume),
}

impl Samples {
    /// One extraction on `pool`; the mesh and how many samples were not finite.
    fn extract(
        &self,
        pool: &rayon::ThreadPool,
        grid: &Grid,
        path: &Path,
    ) -> Result<(Mesh, u64), Failure> {
        match self {
            Samples::Streamed(source) => {
                let Streamed { vertices: positions, triangles, stats } = pool
                    .install(|| extract_streamed::<[f32; 3], _>(source, grid, &Control::default()))
                    .map_err(|e| match e {
                        StreamError::Source(e) => runtime(anyhow!("{}: {e}", path.display())),
                        StreamError::Cancelled => runtime(anyhow!("cancelled")),
                    })?;
                Ok((Mesh { positions, triangles, ..Mesh::default() }, stats.non_finite))
            }
            Samples::Whole(volume) => {
                let mesh =
                    pool.install(|| extract_mesh(volume, &Control::default())).map_err(runtime)?;
                Ok((mesh, volume.non_finite))
            }
        }
    }
}

/// Each thread count's median time and its speed-up over the first count.
struct Scaling {
    threads: usize,
    median: Duration,
    /// Round by round: the first count's time over this count's.
    speedups: Vec<f64>,
    /// The median of `speedups`.
    speedup: f64,
}

impl Scaling {
    fn of(pools: &[rayon::ThreadPool], times: &[Vec<Duration>]) -> Vec<Scaling> {
        pools
            .iter()
            .zip(times)
            .map(|(pool, t)| {
                let speedups: Vec<f64> = times[0]
                    .iter()
                    .zip(t)
                    .map(|(a, b)| a.as_secs_f64() / b.as_secs_f64())
                    .collect();
                Scaling {
                    threads: pool.current_num_threads(),
                    median: median(t, |a, b| a.cmp(b)),
                    speedup: median(&speedups, f64::total_cmp),
                    speedups,
                }
            })
            .collect()
    }
}

/// The middle element (the upper one of an even count).
fn median<T: Copy>(v: &[T], order: impl Fn(&T, &T) -> std::cmp::Ordering) -> T {
    let mut sorted = v.to_vec();
    sorted.sort_by(order);
    sorted[sorted.len() / 2]
}
