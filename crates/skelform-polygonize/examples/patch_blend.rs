//! The chapter's blend of a sphere to a bicubic patch (dissertation §4.8.4), polygonized by
//! the non-manifold polygonizer and written as a labelled PLY:
//!
//! ```text
//! cargo run --release -p skelform-polygonize --example patch_blend -- patch-blend.ply
//! skelform render patch-blend.ply -o patch-blend.png
//! ```
//!
//! Regions (`skelform_field::region::PatchBlend`): 0 beyond the patch's edges, 1 the bump
//! (where the saucer's sigmoid, height 0.35 and radius 1/1.4 about the patch's centre,
//! exceeds the distance to the patch), 2 above the patch, 3 below. The chapter does not give
//! its patch; this one has the control points `(x, y, 0.15 (x² − y²) + 0.1 x)` on a 4 × 4
//! lattice over [-1, 1]². It is not a scene file: the region function needs the nearest
//! point on the patch (a projection from the nearest vertex of a 98-triangle mesh, as in the
//! chapter), which the formula language does not have.

use std::path::PathBuf;

use skelform_field::region::{BicubicPatch, PatchBlend};
use skelform_field::{Aabb, DVec3};
use skelform_mesh::RegionPair;
use skelform_mesh::io::{Format, WriteOptions, write_mesh};
use skelform_polygonize::nonmanifold::{Options, polygonize};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let out = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "patch-blend.ply".into()));
    let control = std::array::from_fn(|i| {
        std::array::from_fn(|j| {
            let (x, y) = (-1.0 + 2.0 * i as f64 / 3.0, -1.0 + 2.0 * j as f64 / 3.0);
            DVec3::new(x, y, 0.15 * (x * x - y * y) + 0.1 * x)
        })
    });
    let patch = BicubicPatch::new(control);
    let centre = patch.eval(0.5, 0.5)[0];
    let regions = PatchBlend { patch, centre, radius: 1.0 / 1.4, height: 0.35 };
    let opts = Options {
        domain: Aabb::cube(1.23),
        cell: 0.05,
        // The bump's top (where 0.35 Sigmoid(1.4 h) = h), within half a cell.
        seeds: vec![centre + DVec3::new(0.0, 0.0, 0.24)],
        interest: vec![RegionPair(1, 2), RegionPair(1, 3), RegionPair(2, 3)],
        ..Options::default()
    };
    let (mesh, stats) = polygonize(&regions, &opts)?;
    let format = Format::from_path(&out).ok_or("use a .ply, .obj, .stl or .glb file")?;
    write_mesh(&out, &mesh, format, &WriteOptions { ascii: false, normals: true })?;
    println!(
        "{}: {} vertices, {} triangles; {} region evaluations ({} for a conventional polygonizer)",
        out.display(),
        stats.vertices,
        stats.triangles,
        stats.region_evaluations,
        stats.conventional_evaluations
    );
    for (p, n) in &stats.triangles_per_pair {
        println!("  surface {p}: {n} triangles");
    }
    for (t, l) in &stats.curve_length_per_triple {
        println!("  curve {t}: length {l:.4}");
    }
    Ok(())
}
