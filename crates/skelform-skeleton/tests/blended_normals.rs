//! The blended normals of DIS appendix A.2 at a junction: the joint combination surface's
//! own gradient creases in the starfish's webbing (§5.6.14.5, fig. 5.73); the blended normal
//! does not.

use glam::DVec3;
use skelform_field::{Aabb, Field};
use skelform_mesh::Mesh;
use skelform_polygonize::LatticeOptions;
use skelform_polygonize::grid::{Options, Resolution, polygonize};
use skelform_skeleton::{Blend, GroupId, Kernel, Skeleton, SkeletonField};

/// The starfish of `examples/skeleton/starfish-junction.toml` (appendix A.2's five limbs).
fn starfish() -> SkeletonField {
    let mut s = Skeleton::new();
    let g = GroupId::DEFAULT;
    s.add_segment(DVec3::new(-0.5, -0.2, 0.0), DVec3::ZERO, 0.1, g).unwrap();
    for (x, y) in [(0.06, 0.6), (0.6, 0.4), (0.7, -0.2), (0.1, -0.6)] {
        s.add_segment(DVec3::ZERO, DVec3::new(x, y, 0.0), 0.1, g).unwrap();
    }
    s.add_junction(DVec3::ZERO, Some(DVec3::Z)).unwrap();
    SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap()
}

fn mesh(f: &SkeletonField) -> Mesh {
    let domain = Aabb::new(DVec3::new(-0.7, -0.8, -0.25), DVec3::new(0.85, 0.75, 0.25));
    let lattice =
        LatticeOptions { domain, resolution: Resolution::Cell(0.0125), ..Default::default() };
    polygonize(f, &Options { lattice, ..Default::default() }).unwrap().0
}

/// The angles (degrees) between the normals at the two ends of every mesh edge in the
/// webbing: within 0.3 of the joint and off the starfish's plane (|z| > 0.03), where the
/// union's crease lies.
fn webbing_edges(m: &Mesh) -> Vec<(f64, u32, u32)> {
    let keep = |i: u32| {
        let p = m.positions[i as usize];
        let p = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        p.length() < 0.3 && p.z.abs() > 0.03
    };
    let n = |i: u32| {
        let v = m.normals[i as usize];
        DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
    };
    let mut out = Vec::new();
    for t in &m.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            if a < b && keep(a) && keep(b) {
                let ang = n(a).dot(n(b)).clamp(-1.0, 1.0).acos().to_degrees();
                out.push((ang, a, b));
            }
        }
    }
    out.sort_by(|x, y| x.0.total_cmp(&y.0));
    out
}

/// The largest angle (degrees) between the normals at consecutive points of 200 steps from
/// `a` to `b`: a crease shows as a jump that does not shrink with the step.
fn largest_step(f: &SkeletonField, a: DVec3, b: DVec3) -> f64 {
    let n = |t: f64| f.gradient(a + (b - a) * t).normalize();
    (0..200)
        .map(|i| n(i as f64 / 200.0).dot(n((i + 1) as f64 / 200.0)).clamp(-1.0, 1.0).acos())
        .fold(0.0, f64::max)
        .to_degrees()
}

#[test]
fn blended_normals_remove_the_crease_in_the_starfish_webbing() {
    let plain = starfish();
    let blended = starfish().with_blended_normals(true);
    // The values are the same: only gradients change.
    for p in [DVec3::new(0.1, 0.1, 0.08), DVec3::new(-0.2, 0.0, 0.05), DVec3::new(0.3, 0.0, 0.0)] {
        assert_eq!(plain.eval(p), blended.eval(p));
    }
    let (mp, mb) = (mesh(&plain), mesh(&blended));
    assert_eq!(mp.positions, mb.positions, "same surface");
    let (ep, eb) = (webbing_edges(&mp), webbing_edges(&mb));
    let (ap, ab): (Vec<f64>, Vec<f64>) =
        (ep.iter().map(|e| e.0).collect(), eb.iter().map(|e| e.0).collect());
    assert!(ap.len() > 500, "{} edges", ap.len());
    let q = |a: &[f64], f: f64| a[((a.len() - 1) as f64 * f) as usize];
    println!(
        "webbing edges: {}; normal angle across an edge (deg) without / with blended normals: \
         max {:.1} / {:.1}, 99th percentile {:.1} / {:.1}, median {:.2} / {:.2}",
        ap.len(),
        q(&ap, 1.0),
        q(&ab, 1.0),
        q(&ap, 0.99),
        q(&ab, 0.99),
        q(&ap, 0.5),
        q(&ab, 0.5),
    );
    assert!(q(&ab, 0.99) < 0.6 * q(&ap, 0.99), "{} vs {}", q(&ab, 0.99), q(&ap, 0.99));
    assert!(q(&ab, 1.0) < 0.7 * q(&ap, 1.0), "{} vs {}", q(&ab, 1.0), q(&ap, 1.0));
    // The crease itself: across the twenty mesh edges where the plain normals differ most,
    // sampled 200 times finer, the plain gradient jumps (a crease does not shrink with the
    // step) and the blended normal turns smoothly (its largest step is a small fraction of
    // the edge's turn).
    let at = |i: u32| {
        let p = mp.positions[i as usize];
        DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)
    };
    let (mut jump_plain, mut jump_blended) = (f64::INFINITY, 0.0f64);
    for &(_, a, b) in ep.iter().rev().take(20) {
        jump_plain = jump_plain.min(largest_step(&plain, at(a), at(b)));
        jump_blended = jump_blended.max(largest_step(&blended, at(a), at(b)));
    }
    println!(
        "across the 20 sharpest webbing edges, in 200 steps: the plain normal jumps at least \
         {jump_plain:.1}° in one step, the blended one turns at most {jump_blended:.2}° per step"
    );
    assert!(jump_plain > 10.0, "{jump_plain}");
    assert!(jump_blended < 1.0, "{jump_blended}");
}
