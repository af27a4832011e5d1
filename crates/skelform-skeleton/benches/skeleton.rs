//! Sampling skeletal fields on 64³ and 128³ lattices, as the grid polygonizer does it (rows
//! through `eval_many`, z-layers in parallel on all cores). Throughput is in lattice points
//! per second.
//!
//! Also `gaussian-polygon`: one Gaussian polygon's convolution, default path against
//! adaptive quadrature.
//!
//! Two skeletons:
//! * `segments`: 22 segments in five chains and five point sources, Gaussian convolution;
//! * `hand-like`: the dissertation's hand in element counts (ch. 6: 15 palm triangles, 48
//!   finger triangles, 22 segments — 85 elements), laid out as a flat palm with four
//!   fingers, Wyvill convolution. Not the hand itself (that is later work), but the same
//!   kind and number of elements.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use glam::DVec3;
use skelform_field::control::Control;
use skelform_field::grid::{Grid, sample};
use skelform_field::{Aabb, Field};
use skelform_skeleton::{Blend, GroupId, Kernel, Skeleton, SkeletonField};

fn segments() -> Skeleton {
    let mut s = Skeleton::new();
    let g = GroupId::DEFAULT;
    for chain in 0..5 {
        let a = chain as f64 * 0.3 - 0.6;
        let pts: Vec<DVec3> = (0..5)
            .map(|i| {
                let t = i as f64 / 4.0;
                DVec3::new(a + 0.1 * (3.0 * t).sin(), -0.6 + 1.2 * t, 0.15 * (2.0 * t + a).cos())
            })
            .collect();
        s.add_polyline(&pts, 0.06, g).unwrap();
    }
    // Two more segments across the chains, five point sources at the tips.
    s.add_segment(DVec3::new(-0.6, -0.2, 0.0), DVec3::new(0.6, -0.2, 0.0), 0.05, g).unwrap();
    s.add_segment(DVec3::new(-0.6, 0.2, 0.0), DVec3::new(0.6, 0.2, 0.0), 0.05, g).unwrap();
    for chain in 0..5 {
        s.add_point(DVec3::new(chain as f64 * 0.3 - 0.6, 0.7, 0.0), 0.08, g).unwrap();
    }
    s
}

fn hand_like() -> Skeleton {
    let mut s = Skeleton::new();
    let g = GroupId::DEFAULT;
    let r = 0.05;
    // Palm: a 0.6 × 0.5 plate as 15 triangles (a fan of five strips, three triangles each).
    let grid = |i: usize, j: usize| {
        DVec3::new(-0.3 + 0.6 * i as f64 / 5.0, -0.5 + 0.5 * j as f64 / 3.0, 0.0)
    };
    let mut palm = 0;
    'palm: for i in 0..5 {
        for j in 0..3 {
            let tri = if (i + j) % 2 == 0 {
                [grid(i, j), grid(i + 1, j), grid(i + 1, j + 1)]
            } else {
                [grid(i, j), grid(i + 1, j + 1), grid(i, j + 1)]
            };
            s.add_polygon(tri.to_vec(), r, g).unwrap();
            palm += 1;
            if palm == 15 {
                break 'palm;
            }
        }
    }
    // Four fingers: strips of six quads (12 triangles) each, 0.06 wide, 0.45 long.
    for f in 0..4 {
        let x0 = -0.27 + 0.18 * f as f64;
        for k in 0..6 {
            let (y0, y1) = (0.02 + 0.075 * k as f64, 0.02 + 0.075 * (k + 1) as f64);
            let q = [
                DVec3::new(x0, y0, 0.0),
                DVec3::new(x0 + 0.06, y0, 0.0),
                DVec3::new(x0 + 0.06, y1, 0.0),
                DVec3::new(x0, y1, 0.0),
            ];
            s.add_polygon(vec![q[0], q[1], q[2]], r * 0.8, g).unwrap();
            s.add_polygon(vec![q[0], q[2], q[3]], r * 0.8, g).unwrap();
        }
    }
    // Tendons and veins: 22 segments in chains along the back of the palm and fingers.
    for f in 0..4 {
        let x = -0.24 + 0.18 * f as f64;
        let pts: Vec<DVec3> =
            (0..6).map(|i| DVec3::new(x, -0.45 + 0.18 * i as f64, 0.03)).collect();
        s.add_polyline(&pts, 0.02, g).unwrap();
    }
    s.add_polyline(
        &[DVec3::new(-0.3, -0.4, 0.04), DVec3::new(0.0, -0.3, 0.04), DVec3::new(0.3, -0.4, 0.04)],
        0.015,
        g,
    )
    .unwrap();
    assert_eq!(s.len(), 85);
    s
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("skeleton");
    group.sample_size(10);
    for (name, skeleton, blend) in [
        ("segments", segments(), Blend::Convolution(Kernel::Gaussian)),
        ("hand-like", hand_like(), Blend::Convolution(Kernel::Wyvill)),
    ] {
        let field = SkeletonField::new(&skeleton, blend).unwrap();
        // A cube around the field's bounds, so that "n³" is n³ points.
        let b = field.bounds().unwrap();
        let half = 0.5 * b.size().max_element();
        let domain = Aabb::new(b.center() - DVec3::splat(half), b.center() + DVec3::splat(half));
        for n in [64usize, 128] {
            let grid = Grid::with_resolution(&domain, n).unwrap();
            assert_eq!(grid.sample_count(), (n * n * n) as u64);
            group.throughput(Throughput::Elements(grid.sample_count()));
            group.bench_function(BenchmarkId::new(name, format!("{n}^3")), |b| {
                b.iter(|| black_box(sample(&field, &grid, &Control::default()).unwrap()))
            });
        }
    }
    group.finish();
}

/// One Gaussian polygon (the trapezoid of DIS fig. 6.3, radius 0.1) evaluated with its
/// gradient at 4 096 points around it: the default path (closed form up to a fixed 20-point
/// rule per edge, `gauss_edge`) against adaptive Gauss–Kronrod quadrature of every edge.
fn gaussian_polygon(c: &mut Criterion) {
    use skelform_skeleton::convolution::{convolve, convolve_adaptive};
    use skelform_skeleton::{Polygon, Shape};
    let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
    let shape = Shape::Polygon(
        Polygon::new(vec![v(0.0, 0.0), v(0.5, 0.0), v(0.4, 0.3), v(0.1, 0.3)]).unwrap(),
    );
    let points: Vec<DVec3> = (0..4096)
        .map(|i| {
            let (a, b, c) = (i % 16, (i / 16) % 16, i / 256);
            DVec3::new(-0.2 + 0.06 * a as f64, -0.2 + 0.045 * b as f64, -0.3 + 0.04 * c as f64)
        })
        .collect();
    let mut group = c.benchmark_group("gaussian-polygon");
    group.sample_size(10);
    group.throughput(Throughput::Elements(points.len() as u64));
    group.bench_function("fast", |b| {
        b.iter(|| points.iter().map(|p| convolve(Kernel::Gaussian, &shape, 0.1, *p).0).sum::<f64>())
    });
    group.bench_function("adaptive", |b| {
        b.iter(|| {
            points
                .iter()
                .map(|p| convolve_adaptive(Kernel::Gaussian, &shape, 0.1, *p).0)
                .sum::<f64>()
        })
    });
    group.finish();
}

criterion_group!(benches, bench, gaussian_polygon);
criterion_main!(benches);
