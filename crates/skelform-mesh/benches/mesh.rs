//! The checker and the readers and writers on a 2-million-triangle torus.
//!
//! Run with `cargo bench -p skelform-mesh --bench mesh`.

use criterion::{Criterion, criterion_group, criterion_main};
use skelform_mesh::Mesh;
use skelform_mesh::check::check;
use skelform_mesh::io::{Format, WriteOptions, read_mesh_from, write_mesh_to};

/// A torus as an `n × m` quad grid wrapped both ways: `2·n·m` triangles.
fn torus(n: u32, m: u32) -> Mesh {
    let mut positions = Vec::new();
    for i in 0..n {
        for j in 0..m {
            let u = std::f64::consts::TAU * f64::from(i) / f64::from(n);
            let v = std::f64::consts::TAU * f64::from(j) / f64::from(m);
            let r = 2.0 + 0.7 * v.cos();
            positions.push([(r * u.cos()) as f32, (r * u.sin()) as f32, (0.7 * v.sin()) as f32]);
        }
    }
    let id = |i: u32, j: u32| (i % n) * m + (j % m);
    let mut triangles = Vec::new();
    for i in 0..n {
        for j in 0..m {
            let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    Mesh { positions, triangles, ..Mesh::default() }
}

fn bench(c: &mut Criterion) {
    let m = torus(1000, 1000);
    let mut group = c.benchmark_group("2M triangles");
    group.sample_size(10);
    group.bench_function("check", |b| b.iter(|| check(&m)));
    for format in [Format::Ply, Format::Obj, Format::Stl] {
        let mut bytes = Vec::new();
        write_mesh_to(&mut bytes, &m, format, &WriteOptions::default()).expect("write");
        group.bench_function(format!("write {format}"), |b| {
            b.iter(|| {
                let mut out = Vec::with_capacity(bytes.len());
                write_mesh_to(&mut out, &m, format, &WriteOptions::default()).expect("write");
                out
            })
        });
        group.bench_function(format!("read {format}"), |b| {
            b.iter(|| read_mesh_from(&bytes, format).expect("read"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
