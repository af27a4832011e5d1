//! Batch evaluation of compiled formulas over 1M points (a 100³ lattice): one `eval_many`
//! call per row of 100 points, one call for all points, and layer by layer with
//! `eval_layer` (terms of fewer axes hoisted), as grid sampling does it.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::DVec3;
use skelform_field::{Field, formula::Formula};

const N: usize = 100;

fn lattice() -> Vec<DVec3> {
    let step = 3.0 / (N - 1) as f64;
    let mut pts = Vec::with_capacity(N * N * N);
    for k in 0..N {
        for j in 0..N {
            for i in 0..N {
                pts.push(DVec3::new(i as f64, j as f64, k as f64) * step - DVec3::splat(1.5));
            }
        }
    }
    pts
}

fn formulas() -> Vec<(&'static str, Formula)> {
    let torus = "R = 1; r = 0.25\nq = sqrt(x^2 + y^2) - R\nsqrt(q^2 + z^2) - r";
    let gyroid = "s = 2*pi\nsin(s*x)*cos(s*y) + sin(s*y)*cos(s*z) + sin(s*z)*cos(s*x)";
    vec![("torus", Formula::parse(torus).unwrap()), ("gyroid", Formula::parse(gyroid).unwrap())]
}

fn bench(c: &mut Criterion) {
    let pts = lattice();
    let mut out = vec![0.0; pts.len()];
    let mut group = c.benchmark_group("formula");
    group.throughput(Throughput::Elements(pts.len() as u64));
    for (name, f) in formulas() {
        group.bench_function(BenchmarkId::new("eval_many_rows", name), |b| {
            b.iter(|| {
                for (p, o) in pts.chunks(N).zip(out.chunks_mut(N)) {
                    f.eval_many(black_box(p), o);
                }
                black_box(&out);
            })
        });
        group.bench_function(BenchmarkId::new("eval_many_all", name), |b| {
            b.iter(|| {
                f.eval_many(black_box(&pts), &mut out);
                black_box(&out);
            })
        });
        let axis: Vec<f64> = pts[..N].iter().map(|p| p.x).collect();
        group.bench_function(BenchmarkId::new("eval_layer", name), |b| {
            b.iter(|| {
                for (k, o) in out.chunks_mut(N * N).enumerate() {
                    f.eval_layer(black_box(&axis), &axis, axis[k], o);
                }
                black_box(&out);
            })
        });
    }
    group.finish();

    // Gradients and single points, on fewer points.
    let few = &pts[..100_000];
    let mut vals = vec![0.0; few.len()];
    let mut grads = vec![DVec3::ZERO; few.len()];
    let mut group = c.benchmark_group("formula_100k");
    group.throughput(Throughput::Elements(few.len() as u64));
    for (name, f) in formulas() {
        group.bench_function(BenchmarkId::new("eval_grad_many", name), |b| {
            b.iter(|| {
                f.eval_grad_many(black_box(few), &mut vals, &mut grads);
                black_box(&grads);
            })
        });
        group.bench_function(BenchmarkId::new("eval_point", name), |b| {
            b.iter(|| few.iter().map(|p| f.eval(black_box(*p))).sum::<f64>())
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
