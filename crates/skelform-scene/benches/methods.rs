//! The polygonizers against each other on example scenes, at the scenes' own cell sizes.
//!
//! Run with `cargo bench -p skelform-scene --bench methods`. `bench/methods.sh` prints the
//! field evaluations beside the times.

use std::path::Path;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use skelform_polygonize::{LatticeOptions, continuation, grid};
use skelform_scene::Scene;

fn load(name: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples").join(name);
    Scene::load(&path).expect("example scene")
}

fn bench(c: &mut Criterion) {
    for name in ["continuation/blobs-50.toml", "continuation/torus.toml"] {
        let scene = load(name);
        let lattice = LatticeOptions {
            domain: scene.domain,
            resolution: scene.resolution,
            ..Default::default()
        };
        let gopts = grid::Options { lattice: lattice.clone(), ..Default::default() };
        let cell = lattice.grid().expect("grid").cell;
        let mut group = c.benchmark_group(name);
        group.sample_size(10);
        group.bench_function(BenchmarkId::new("grid", cell), |b| {
            b.iter(|| grid::polygonize(scene.field.as_ref(), &gopts).expect("grid"))
        });
        for (label, cells) in [
            ("continuation", continuation::Cells::Cubes),
            ("tetra", continuation::Cells::Tetrahedra),
        ] {
            let opts = continuation::Options {
                lattice: lattice.clone(),
                seeds: scene.continuation.seeds.clone(),
                cells,
                ..Default::default()
            };
            group.bench_function(BenchmarkId::new(label, cell), |b| {
                b.iter(|| {
                    continuation::polygonize(scene.field.as_ref(), &opts).expect("continuation")
                })
            });
        }
        group.finish();
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
