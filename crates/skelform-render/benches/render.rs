//! Rendering a mesh of about a million triangles at 1024 × 1024.
//!
//! Run with `cargo bench -p skelform-render --bench render`. The mesh is a gyroid in a
//! cube of side 4π polygonized at 230 samples a side (about 1.0 M triangles, many layers
//! deep along every ray, so the z-buffer and the transparency sort both work hard). Each
//! picture is timed whole, up to the pixels in memory: projection, binning, rasterization,
//! shading and reduction of the samples (PNG encoding is timed on its own).
//!
//! One run (`-- --quick`, 2-core machine): 0.34 s with one sample a pixel, 0.58 s with the
//! default 2 × 2 samples, 0.53 s transparent; PNG encoding 0.15 s.

use criterion::{Criterion, criterion_group, criterion_main};
use skelform_field::formula::Formula;
use skelform_field::{Aabb, DVec3};
use skelform_polygonize::LatticeOptions;
use skelform_polygonize::grid::{Options, Resolution, polygonize};
use skelform_render::{Renderer, Settings};

fn gyroid() -> skelform_mesh::Mesh {
    let f = Formula::parse("sin(x)*cos(y) + sin(y)*cos(z) + sin(z)*cos(x)").expect("gyroid");
    let tau = 2.0 * std::f64::consts::PI;
    let lattice = LatticeOptions {
        domain: Aabb::new(DVec3::splat(-tau), DVec3::splat(tau)),
        resolution: Resolution::Samples(230),
        ..Default::default()
    };
    let opts = Options { lattice, ..Options::default() };
    polygonize(&f, &opts).expect("polygonize").0
}

fn bench(c: &mut Criterion) {
    let mesh = gyroid();
    eprintln!("gyroid: {} triangles", mesh.triangle_count());
    let renderer = Renderer::new(&mesh).expect("renderer");
    let mut group =
        c.benchmark_group(format!("{}k triangles at 1024x1024", mesh.triangle_count() / 1000));
    group.sample_size(10);
    for (name, s) in [
        (
            "opaque, 1 sample",
            Settings { width: 1024, height: 1024, supersample: 1, ..Settings::default() },
        ),
        ("opaque, 2x2 samples", Settings { width: 1024, height: 1024, ..Settings::default() }),
        (
            "transparent, 1 sample",
            Settings {
                width: 1024,
                height: 1024,
                supersample: 1,
                transparent: true,
                ..Settings::default()
            },
        ),
    ] {
        group.bench_function(name, |b| b.iter(|| renderer.render(&s).expect("render")));
    }
    let image = renderer
        .render(&Settings { width: 1024, height: 1024, ..Settings::default() })
        .expect("render");
    group.bench_function("PNG encoding", |b| b.iter(|| image.encode_png().expect("png")));
    group.bench_function("preparation (normals, labels)", |b| {
        b.iter(|| Renderer::new(&mesh).expect("renderer"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
