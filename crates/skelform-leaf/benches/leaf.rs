//! The leaf's costs: building it, the signed distance to its blade (bounding-volume
//! hierarchy against testing every triangle), and the region function the non-manifold
//! polygonizer calls. Throughput in points per second, on points spread over the leaf's box.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use glam::DVec3;
use skelform_field::RegionField;
use skelform_leaf::{Fillet, Leaf, LeafParams};
use skelform_skeleton::Kernel;

fn points(leaf: &Leaf, n: usize) -> Vec<DVec3> {
    let (lo, hi) = leaf.bounds(Kernel::Wyvill);
    let mut s = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n).map(|_| lo + (hi - lo) * DVec3::new(next(), next(), next())).collect()
}

fn bench(c: &mut Criterion) {
    let params = LeafParams::default();
    c.bench_function("build the default maple", |b| {
        b.iter(|| Leaf::maple(black_box(&params)).unwrap())
    });
    let leaf = Leaf::maple(&params).unwrap();
    let pts = points(&leaf, 4096);
    let mut g = c.benchmark_group("blade distance");
    g.throughput(Throughput::Elements(pts.len() as u64));
    g.bench_function("bvh", |b| {
        b.iter(|| pts.iter().map(|p| leaf.blade.distance(*p).distance).sum::<f64>())
    });
    g.sample_size(10);
    g.bench_function("every triangle", |b| {
        b.iter(|| pts.iter().map(|p| leaf.blade.distance_brute_force(*p).distance).sum::<f64>())
    });
    g.finish();
    let regions = leaf.regions(Kernel::Wyvill, Fillet::Both).unwrap();
    let mut g = c.benchmark_group("leaf regions");
    g.throughput(Throughput::Elements(pts.len() as u64));
    g.bench_function("region_many", |b| {
        let mut out = vec![0u32; pts.len()];
        b.iter(|| {
            regions.region_many(&pts, &mut out);
            out[0]
        })
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
