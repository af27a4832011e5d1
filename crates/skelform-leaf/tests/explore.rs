use glam::DVec3;
use skelform_field::Aabb;
use skelform_leaf::{Fillet, Leaf, LeafParams};
use skelform_polygonize::nonmanifold::{Options, polygonize};
use skelform_skeleton::Kernel;
#[test]
fn explore() {
    let cell: f64 = std::env::var("CELL").ok().and_then(|s| s.parse().ok()).unwrap_or(0.05);
    let t = std::time::Instant::now();
    let p = LeafParams::default();
    let leaf = Leaf::maple(&p).unwrap();
    let v = leaf.venation.as_ref().unwrap();
    eprintln!("points {} veins {:?} margin {} stats {:?} area {} t {:?}", v.points.len(), v.counts(), v.margin().len(), leaf.stats, leaf.blade.area(), t.elapsed());
    let r = leaf.regions(Kernel::Wyvill, Fillet::Both).unwrap();
    let (lo, hi) = leaf.bounds(Kernel::Wyvill);
    eprintln!("bounds {lo:?} {hi:?}");
    let opts = Options {
        domain: Aabb::new(lo - DVec3::splat(0.1), hi + DVec3::splat(0.1)),
        cell,
        seeds: r.seeds(),
        interest: r.interest(),
        ..Options::default()
    };
    let (m, s) = polygonize(&r, &opts).unwrap();
    eprintln!("{s:?}");
    skelform_mesh::io::write_mesh(std::path::Path::new("/tmp/leaf.ply"), &m, skelform_mesh::io::Format::Ply, &Default::default()).unwrap();
}
