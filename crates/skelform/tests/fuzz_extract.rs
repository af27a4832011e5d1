//! Fuzzing the inputs of `skelform extract` through the library (`skelform::volume`): the
//! raw-volume path, with random dims, iso values, spacings, origins and samples.
//!
//! Generators: lattices of 2 to 12 samples a side (up to 40 layers, so several slabs), and
//! lattices with an axis of 0 or 1 sample; origins and spacings ordinary, tiny (5e-324),
//! huge (1e30, past f32), and (given to the library though the command line
//! refuses them) zero, negative, NaN and infinite; iso values ordinary, ±0, NaN, ±∞, 1e300; samples
//! from smooth fields (spheres, planes, gyroids) with noise, from a palette of extremes
//! (NaN, ±∞, ±f32::MAX, subnormals, exact zeros), and uniform noise; and domains and cells
//! for `Grid::with_cell` and `Grid::with_resolution`, extremes included.
//!
//! Properties: no panic, no hang (each case within its limit), no allocation past the
//! harness's 1 GiB; every mesh passes `Mesh::validate`; when every sample on the lattice's
//! boundary is outside (positive) and the vertices are finite, every component is closed,
//! manifold and consistently oriented; streaming the layers gives exactly the mesh of the
//! whole volume, and so does extraction on one thread and on three; grid constructors either
//! refuse or give a lattice of 2 to `MAX_SAMPLES_PER_AXIS` samples a side whose corners are
//! finite.
//!
//! CI runs a hundred or two cases per property in a few seconds. A longer run:
//! `SKELFORM_FUZZ_SECONDS=3600 cargo test --release -p skelform --test fuzz_extract -- --nocapture`
//! runs every property for an hour, side by side as the test harness runs them (as many at
//! once as there are cores, or `--test-threads`), with fresh seeds each round
//! (`SKELFORM_FUZZ_CASES=N` sets the cases per round; see `fuzz/harness.rs`).

#[path = "../../../fuzz/harness.rs"]
mod harness;

use std::time::Duration;

use proptest::prelude::*;
use skelform::mesh::check::check;
use skelform::volume::{
    Grid, LayerSource, MAX_SAMPLES_PER_AXIS, Volume, extract_mesh, extract_streamed, sanitize,
};
use skelform::{Aabb, Control, DVec3, Mesh};

#[global_allocator]
static GUARD: harness::Guard = harness::Guard;

const LIMIT: Duration = Duration::from_secs(20);

/// How the samples are made.
#[derive(Clone, Debug)]
enum Pattern {
    Sphere { centre: [f64; 3], radius: f64, noise: f64 },
    Plane { normal: [f64; 3], offset: f64 },
    Gyroid { scale: f64 },
    Palette(Vec<u8>),
    Noise(Vec<f32>),
}

const PALETTE: &[f32] = &[
    -1.0,
    1.0,
    0.0,
    -0.0,
    0.5,
    -0.5,
    f32::NAN,
    f32::INFINITY,
    f32::NEG_INFINITY,
    f32::MAX,
    -f32::MAX,
    f32::MIN_POSITIVE,
    -f32::MIN_POSITIVE,
    1e-45,
    -1e-45,
    1e30,
    -1e30,
];

fn pattern() -> impl Strategy<Value = Pattern> {
    let c = -1.5..1.5f64;
    prop_oneof![
        3 => ([c.clone(), c.clone(), c.clone()], 0.0..1.5f64, prop_oneof![Just(0.0), 0.0..0.3f64])
            .prop_map(|(centre, radius, noise)| Pattern::Sphere { centre, radius, noise }),
        1 => ([c.clone(), c.clone(), c.clone()], c)
            .prop_map(|(normal, offset)| Pattern::Plane { normal, offset }),
        1 => (0.5..8.0f64).prop_map(|scale| Pattern::Gyroid { scale }),
        2 => prop::collection::vec(any::<u8>(), 1..64).prop_map(Pattern::Palette),
        1 => prop::collection::vec(-2.0f32..2.0, 1..64).prop_map(Pattern::Noise),
    ]
}

/// The lattice and how the samples are turned, as the command line would be given them.
#[derive(Clone, Debug)]
struct Case {
    dims: [usize; 3],
    origin: [f64; 3],
    spacing: f64,
    iso: f64,
    pattern: Pattern,
}

fn coordinate() -> impl Strategy<Value = f64> {
    prop_oneof![
        6 => -10.0..10.0f64,
        1 => prop::sample::select(vec![
            0.0, -0.0, 1e30, -1e30, 3e38, -3e38, 1e-300, 5e-324, 1e39, f64::NAN,
            f64::NEG_INFINITY,
        ]),
    ]
}

fn case(max_side: usize, max_layers: usize) -> impl Strategy<Value = Case> {
    let side = 2..=max_side;
    (
        (side.clone(), side, 2..=max_layers),
        [coordinate(), coordinate(), coordinate()],
        prop_oneof![
            6 => 0.01..2.0f64,
            1 => prop::sample::select(vec![5e-324, 1e-300, 1e-30, 1e-7, 1e30, 1e38, 1e300]),
            // What the command line refuses, given to the library anyway.
            1 => prop::sample::select(vec![0.0, -0.0, -1.0, f64::NAN, f64::INFINITY]),
        ],
        prop_oneof![
            6 => -0.5..0.5f64,
            1 => prop::sample::select(vec![
                0.0, -0.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 1e300, -1e300, 1e-300,
                f32::MAX as f64, 3.5e38,
            ]),
        ],
        pattern(),
    )
        .prop_map(|(dims, origin, spacing, iso, pattern)| Case {
            dims: [dims.0, dims.1, dims.2],
            origin,
            spacing,
            iso,
            pattern,
        })
}

/// The raw samples of a case, before the iso value is subtracted (what a raw file holds).
fn raw(c: &Case) -> Vec<f32> {
    let [nx, ny, nz] = c.dims;
    let mut out = Vec::with_capacity(nx * ny * nz);
    let mut n = 0usize;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                // Positions in [-1, 1] whatever the lattice, so patterns look alike at any size.
                let t = |a: usize, m: usize| -1.0 + 2.0 * a as f64 / (m - 1).max(1) as f64;
                let p = [t(i, nx), t(j, ny), t(k, nz)];
                let v = match &c.pattern {
                    Pattern::Sphere { centre, radius, noise } => {
                        let d = (0..3).map(|a| (p[a] - centre[a]).powi(2)).sum::<f64>().sqrt();
                        let wobble = noise * ((n as f64 * 12.9898).sin() * 43758.5453).fract();
                        (d - radius + wobble) as f32
                    }
                    Pattern::Plane { normal, offset } => {
                        ((0..3).map(|a| p[a] * normal[a]).sum::<f64>() - offset) as f32
                    }
                    Pattern::Gyroid { scale } => {
                        let q = p.map(|x| x * scale);
                        (q[0].sin() * q[1].cos()
                            + q[1].sin() * q[2].cos()
                            + q[2].sin() * q[0].cos()) as f32
                    }
                    Pattern::Palette(idx) => PALETTE[idx[n % idx.len()] as usize % PALETTE.len()],
                    Pattern::Noise(v) => v[n % v.len()],
                };
                out.push(v);
                n += 1;
            }
        }
    }
    out
}

/// The samples relative to the iso value, as `skelform extract` makes them.
fn relative(raw: &[f32], iso: f64) -> Vec<f32> {
    let iso = iso as f32;
    raw.iter().map(|v| v - iso).collect()
}

fn grid(c: &Case) -> Grid {
    Grid { origin: DVec3::from_array(c.origin), cell: c.spacing, dims: c.dims }
}

/// Layers of a sanitised volume, for streamed extraction.
struct Layers<'a>(&'a [f32], usize);

impl LayerSource for Layers<'_> {
    type Error = String;
    fn layer(&self, k: usize, out: &mut [f32]) -> Result<u64, String> {
        let from = self.0.get(k * self.1..(k + 1) * self.1).ok_or(format!("no layer {k}"))?;
        out.copy_from_slice(from);
        Ok(sanitize(out))
    }
}

fn boundary_outside(v: &Volume) -> bool {
    let [nx, ny, nz] = v.grid.dims;
    (0..nz).all(|k| {
        (0..ny).all(|j| {
            (0..nx).all(|i| {
                let edge = i == 0 || j == 0 || k == 0 || i == nx - 1 || j == ny - 1 || k == nz - 1;
                !edge || v.get(i, j, k) > 0.0
            })
        })
    })
}

fn extract(volume: &Volume, threads: usize) -> Result<Mesh, String> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| format!("no thread pool: {e}"))?;
    pool.install(|| extract_mesh(volume, &Control::default()))
        .map_err(|e| format!("extraction failed: {e}"))
}

/// Positions equal bit for bit, any NaN matching any other (a NaN origin or an infinite
/// spacing, which the command line refuses, gives NaN coordinates whose sign depends on the
/// order of the arithmetic).
fn same_bits(a: &[[f32; 3]], b: &[[f32; 3]]) -> bool {
    let bits = |c: f32| if c.is_nan() { f32::NAN.to_bits() } else { c.to_bits() };
    a.len() == b.len() && a.iter().zip(b).all(|(p, q)| p.map(bits) == q.map(bits))
}

fn run(c: &Case) -> Result<(), String> {
    let values = relative(&raw(c), c.iso);
    let volume = Volume::from_values(grid(c), values.clone());
    let mesh = extract(&volume, 1)?;
    mesh.validate().map_err(|e| format!("an invalid mesh: {e}"))?;
    let finite = mesh.positions.iter().flatten().all(|c| c.is_finite());
    if finite && boundary_outside(&volume) && !mesh.triangles.is_empty() {
        let report = check(&mesh);
        if let Some(bad) = report.components.iter().position(|k| !k.is_closed_manifold()) {
            return Err(format!(
                "the volume is outside on its boundary, but component {bad} is not a closed, \
                 manifold, oriented surface: {:?}",
                report.components[bad]
            ));
        }
    }
    let again = extract(&volume, 3)?;
    if !same_bits(&again.positions, &mesh.positions) || again.triangles != mesh.triangles {
        return Err("the mesh on three threads differs from the mesh on one".into());
    }
    let layer = c.dims[0] * c.dims[1];
    let streamed =
        extract_streamed::<[f32; 3], _>(&Layers(&values, layer), &volume.grid, &Control::default())
            .map_err(|e| format!("streamed extraction failed: {e:?}"))?;
    let same_positions = same_bits(&streamed.vertices, &mesh.positions);
    if !same_positions || streamed.triangles != mesh.triangles {
        return Err(format!(
            "streaming gives {} vertices and {} triangles, the whole volume {} and {}",
            streamed.vertices.len(),
            streamed.triangles.len(),
            mesh.positions.len(),
            mesh.triangles.len()
        ));
    }
    if streamed.stats.non_finite != volume.non_finite {
        return Err(format!(
            "streaming counts {} non-finite samples, the whole volume {}",
            streamed.stats.non_finite, volume.non_finite
        ));
    }
    Ok(())
}

#[test]
fn random_volumes_give_valid_meshes_every_way() {
    harness::fuzz("extract volumes", 384, LIMIT, case(12, 40), |c| run(&c));
}

#[test]
fn flat_lattices_give_no_cells_and_no_panic() {
    // An axis of 0 or 1 sample has no cell: nothing to extract, and nothing may break.
    let strategy = (case(5, 5), 0usize..3, 0usize..2);
    harness::fuzz("extract flat", 256, LIMIT, strategy, |(mut c, axis, n)| {
        c.dims[axis] = n;
        let values = relative(&raw(&c), c.iso);
        let volume = Volume::from_values(grid(&c), values);
        let mesh = extract(&volume, 1)?;
        if !mesh.triangles.is_empty() {
            return Err(format!("{} triangles from a lattice without cells", mesh.triangles.len()));
        }
        let layer = c.dims[0] * c.dims[1];
        let streamed = extract_streamed::<[f32; 3], _>(
            &Layers(&volume.values, layer),
            &volume.grid,
            &Control::default(),
        )
        .map_err(|e| format!("streamed extraction failed: {e:?}"))?;
        if !streamed.triangles.is_empty() {
            return Err("streamed triangles from a lattice without cells".into());
        }
        Ok(())
    });
}

#[test]
fn grid_constructors_refuse_or_give_usable_lattices() {
    let c = prop_oneof![
        4 => -100.0..100.0f64,
        1 => prop::sample::select(vec![
            0.0, -0.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY, f64::MAX, f64::MIN, 3.4e38,
            -3.4e38, 3.5e38, 1e-300, 5e-324,
        ]),
    ];
    let cell = prop_oneof![
        4 => 0.001..10.0f64,
        1 => prop::sample::select(vec![
            0.0, -1.0, f64::NAN, f64::INFINITY, 5e-324, 1e-19, 1e-300, 1e300, f64::MAX,
        ]),
    ];
    let samples = prop_oneof![
        0usize..300,
        Just(usize::MAX),
        Just(MAX_SAMPLES_PER_AXIS),
        Just(MAX_SAMPLES_PER_AXIS + 1)
    ];
    let strategy = ([c.clone(), c.clone(), c.clone()], [c.clone(), c.clone(), c], cell, samples);
    harness::fuzz("extract grids", 1024, LIMIT, strategy, |(a, b, cell, samples)| {
        let domain = Aabb { min: DVec3::from_array(a), max: DVec3::from_array(b) };
        for g in [Grid::with_cell(&domain, cell), Grid::with_resolution(&domain, samples)] {
            let Ok(g) = g else { continue };
            if g.dims.iter().any(|&d| !(2..=MAX_SAMPLES_PER_AXIS).contains(&d)) {
                return Err(format!("a lattice of {:?} samples", g.dims));
            }
            let far = g.bounds().max;
            if !(g.origin.is_finite() && far.is_finite() && g.cell > 0.0) {
                return Err(format!("a lattice from {} to {far} with cell {}", g.origin, g.cell));
            }
            let _ = (g.sample_count(), g.cell_count(), Volume::bytes_for(&g));
        }
        Ok(())
    });
}

/// Regression (found by `flat_lattices_give_no_cells_and_no_panic`): a `Grid` built by hand
/// with 0 or 1 sample along an axis made extraction subtract past zero ("attempt to
/// subtract with overflow" in `for_each_mixed_cube`, or at `dims[2] - 1`). It now has no
/// cube, so no triangle.
#[test]
fn a_lattice_with_a_flat_axis_extracts_nothing() {
    for dims in [[5, 0, 5], [1, 4, 4], [4, 1, 4], [4, 4, 1], [4, 4, 0], [0, 0, 0]] {
        let g = Grid { origin: DVec3::ZERO, cell: 1.0, dims };
        let values: Vec<f32> =
            (0..dims.iter().product::<usize>()).map(|k| k as f32 - 3.0).collect();
        let layer = dims[0] * dims[1];
        let volume = Volume::from_values(g, values.clone());
        let mesh = extract_mesh(&volume, &Control::default()).expect("no cancellation");
        assert!(mesh.is_empty(), "{dims:?}");
        let s = extract_streamed::<[f32; 3], _>(&Layers(&values, layer), &g, &Control::default())
            .expect("no source error");
        assert!(s.triangles.is_empty() && s.vertices.is_empty(), "{dims:?}");
    }
}
