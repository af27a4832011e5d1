//! Sampling and extraction of the gyroid and the torus at 128³ and 256³ samples.
//!
//! Run with `cargo bench -p skelform-polygonize --bench grid`. Each phase is measured on its
//! own: `sample` evaluates the compiled formula on the lattice; `classify` finds the cubes
//! the surface passes through (row sign bits, no triangles); `extract` runs marching cubes
//! on a volume sampled once beforehand, making lattice vertex records for refinement and
//! building the merged index; `extract-positions` the same with interpolated positions
//! straight away (the extraction-only path); `polygonize` is the whole pipeline with
//! refinement and normals, and `polygonize-streamed` the same sampling slab by slab.

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use skelform_field::control::Control;
use skelform_field::formula::Formula;
use skelform_field::grid::{Grid, sample};
use skelform_field::{Aabb, DVec3};
use skelform_polygonize::LatticeOptions;
use skelform_polygonize::grid::{
    Options, Resolution, Streaming, extract, extract_positions, polygonize, surface_cubes,
};

fn shapes() -> Vec<(&'static str, Formula, Aabb)> {
    let torus = Formula::parse("q = sqrt(x^2 + y^2) - 0.6\nq^2 + z^2 - 0.25^2").expect("torus");
    let gyroid = Formula::parse("sin(x)*cos(y) + sin(y)*cos(z) + sin(z)*cos(x)").expect("gyroid");
    let tau = 2.0 * std::f64::consts::PI;
    vec![
        ("torus", torus, Aabb::cube(1.0)),
        ("gyroid", gyroid, Aabb::new(DVec3::splat(-tau), DVec3::splat(tau))),
    ]
}

fn bench(c: &mut Criterion) {
    for (name, f, domain) in shapes() {
        let mut group = c.benchmark_group(name);
        group.sample_size(10);
        for n in [128usize, 256] {
            let grid = Grid::with_resolution(&domain, n).expect("grid");
            group.bench_with_input(BenchmarkId::new("sample", n), &grid, |b, g| {
                b.iter(|| sample(&f, g, &Control::default()).expect("sample"))
            });
            let volume = sample(&f, &grid, &Control::default()).expect("sample");
            group.bench_with_input(BenchmarkId::new("classify", n), &volume, |b, v| {
                b.iter(|| surface_cubes(v))
            });
            group.bench_with_input(BenchmarkId::new("extract", n), &volume, |b, v| {
                b.iter(|| extract(v, &Control::default()).expect("extract"))
            });
            group.bench_with_input(BenchmarkId::new("extract-positions", n), &volume, |b, v| {
                b.iter(|| extract_positions(v, &Control::default()).expect("extract"))
            });
            for (label, streaming) in
                [("polygonize", Streaming::Never), ("polygonize-streamed", Streaming::Always)]
            {
                let lattice = LatticeOptions {
                    domain,
                    resolution: Resolution::Samples(n),
                    ..Default::default()
                };
                let opts = Options { lattice, streaming, ..Options::default() };
                group.bench_with_input(BenchmarkId::new(label, n), &opts, |b, o| {
                    b.iter(|| polygonize(&f, o).expect("polygonize"))
                });
            }
        }
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
