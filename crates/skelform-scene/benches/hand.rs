//! The hand of DIS chapter 6 (`examples/skeleton/hand.toml`: 109 elements, Wyvill
//! convolution, eight blending sets) sampled on 64³ and 128³ lattices the way the grid
//! polygonizer samples (z-layers in parallel on all cores, each row through the field's
//! batch path). Throughput is in lattice points per second.
//!
//! Run with `cargo bench -p skelform-scene --bench hand`.

use std::hint::black_box;
use std::path::Path;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use skelform_field::control::Control;
use skelform_field::grid::{Grid, sample};
use skelform_field::{Aabb, DVec3, Field};
use skelform_scene::{LoadOptions, Scene};

fn bench(c: &mut Criterion) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/skeleton/hand.toml");
    let mut group = c.benchmark_group("hand");
    group.sample_size(10);
    for pose in ["open", "grip"] {
        let options = LoadOptions { pose: Some(pose.to_string()), ..Default::default() };
        let scene = Scene::load_with(&path, &options).expect("the hand scene");
        let field = scene.skeleton.clone().expect("a skeleton");
        // A cube around the posed hand's bounds, so that "n³" is n³ points.
        let b = field.bounds().expect("bounds");
        let half = 0.5 * b.size().max_element();
        let domain = Aabb::new(b.center() - DVec3::splat(half), b.center() + DVec3::splat(half));
        for n in [64usize, 128] {
            let grid = Grid::with_resolution(&domain, n).expect("grid");
            assert_eq!(grid.sample_count(), (n * n * n) as u64);
            group.throughput(Throughput::Elements(grid.sample_count()));
            group.bench_function(BenchmarkId::new(pose, format!("{n}^3")), |b| {
                b.iter(|| black_box(sample(&*field, &grid, &Control::default()).expect("sample")))
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
