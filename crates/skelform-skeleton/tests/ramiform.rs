//! Ramiform skeletons (DIS eqs. 3.3 and 5.36): parents' radii matched at their joint planes,
//! the recursive maximum, and the trifurcation of fig. 5.59 meshed as one closed surface.

use glam::DVec3;
use skelform_field::{Aabb, Field};
use skelform_mesh::check::check;
use skelform_polygonize::LatticeOptions;
use skelform_polygonize::grid::{Options, Resolution, polygonize};
use skelform_skeleton::{Ramiform, RamiformField, RamiformOptions, SkeletonError};

/// A trunk along +z from the origin to (0, 0, 1) and three branches of radius `r`, 120°
/// apart, leaving the joint at `tilt` degrees from the trunk's axis.
fn trifurcation(r: f64, tilt: f64) -> Ramiform {
    let mut t = Ramiform::new();
    let trunk = t.add_root(DVec3::ZERO, DVec3::Z, None).unwrap();
    for k in 0..3 {
        let az = (120.0 * k as f64).to_radians();
        let tl = tilt.to_radians();
        let dir = DVec3::new(tl.sin() * az.cos(), tl.sin() * az.sin(), tl.cos());
        t.add_child(trunk, DVec3::Z + dir * 0.8, Some(r)).unwrap();
    }
    t
}

/// Distance from `from` along `dir` to the surface (the field's zero), by bisection.
fn surface_along(f: &RamiformField, from: DVec3, dir: DVec3, max: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, max);
    assert!(f.eval(from) < 0.0 && f.eval(from + dir * max) > 0.0);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if f.eval(from + dir * mid) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[test]
fn the_surface_in_the_joint_plane_is_the_parents_radius() {
    for (r, tilt) in [(0.1, 40.0), (0.08, 55.0), (0.12, 30.0)] {
        let f = RamiformField::new(&trifurcation(r, tilt), &RamiformOptions::default()).unwrap();
        let parent = f.radii()[0];
        // Three branches sum to a wider section than any one of them.
        assert!(parent > r * 1.2 && parent < r * 4.0, "r {r}, tilt {tilt}: parent {parent}");
        assert_eq!(&f.radii()[1..], &[r; 3]);
        // In the plane perpendicular to the trunk at the joint, every direction (also those
        // between the sampled ones) meets the surface at the parent's radius.
        for k in 0..37 {
            let t = (k as f64 * 9.7).to_radians();
            let dir = DVec3::new(t.cos(), t.sin(), 0.0);
            let rho = surface_along(&f, DVec3::Z, dir, 1.0);
            assert!((rho - parent).abs() < 1e-6 * parent, "r {r}, tilt {tilt}: {rho} vs {parent}");
        }
        // Along the trunk, away from the joint, the radius is the parent's within 2 %
        // (the branches' densities reach it faintly).
        let rho = surface_along(&f, DVec3::new(0.0, 0.0, 0.4), DVec3::X, 1.0);
        assert!((rho - parent).abs() < 0.02 * parent, "{rho} vs {parent}");
        // Along a branch it has its own radius, widened by its siblings' share of the sum
        // (never thinner; up to 12 % where, at a 30° tilt, they run close).
        let az = 0.0f64;
        let tl = tilt.to_radians();
        let dir = DVec3::new(tl.sin() * az.cos(), tl.sin() * az.sin(), tl.cos());
        let mid = DVec3::Z + dir * 0.6;
        let side = dir.cross(DVec3::Y).normalize();
        let rho = surface_along(&f, mid, side, 1.0);
        assert!(rho > r && rho < 1.12 * r, "branch radius {rho} vs {r}");
    }
}

#[test]
fn the_recursive_maximum_matches_every_level() {
    // A trunk, two branches, and two twigs on the first branch: the first branch's radius
    // is matched to its twigs, the trunk's to both branches.
    let mut t = Ramiform::new();
    let trunk = t.add_root(DVec3::ZERO, DVec3::Z, None).unwrap();
    let b1 = t.add_child(trunk, DVec3::new(0.4, 0.0, 1.6), None).unwrap();
    t.add_child(trunk, DVec3::new(-0.4, 0.0, 1.6), Some(0.1)).unwrap();
    t.add_child(b1, DVec3::new(0.8, 0.2, 2.1), Some(0.06)).unwrap();
    t.add_child(b1, DVec3::new(0.8, -0.2, 2.1), Some(0.06)).unwrap();
    let f = RamiformField::new(&t, &RamiformOptions::default()).unwrap();
    let radii = f.radii();
    assert!(radii[1] > 0.06 && radii[0] > radii[1].max(0.1), "{radii:?}");
    // The first branch's radius comes from its own subtree: the same as when it is a root.
    let mut sub = Ramiform::new();
    let b = sub.add_root(DVec3::Z, DVec3::new(0.4, 0.0, 1.6), None).unwrap();
    sub.add_child(b, DVec3::new(0.8, 0.2, 2.1), Some(0.06)).unwrap();
    sub.add_child(b, DVec3::new(0.8, -0.2, 2.1), Some(0.06)).unwrap();
    let g = RamiformField::new(&sub, &RamiformOptions::default()).unwrap();
    assert!((g.radii()[0] - radii[1]).abs() < 1e-12, "{} vs {}", g.radii()[0], radii[1]);
    for (field, limb, joint, axis) in
        [(&f, 0, DVec3::Z, DVec3::Z), (&g, 0, DVec3::new(0.4, 0.0, 1.6), DVec3::new(0.4, 0.0, 0.6))]
    {
        let axis = axis.normalize();
        let u = axis.any_orthonormal_vector();
        let v = axis.cross(u);
        let want = field.radii()[limb];
        for k in 0..24 {
            let t = (k as f64 * 15.0 + 3.0).to_radians();
            let rho = surface_along(field, joint, u * t.cos() + v * t.sin(), 1.0);
            assert!((rho - want).abs() < 1e-6 * want, "limb {limb}: {rho} vs {want}");
        }
    }
    // The field's gradient is exact: it agrees with central differences.
    for p in [DVec3::new(0.12, 0.05, 0.5), DVec3::new(0.3, 0.1, 1.5), DVec3::new(-0.1, 0.0, 1.2)] {
        let g = f.gradient(p);
        let h = 1e-6;
        let fd = DVec3::new(
            f.eval(p + DVec3::X * h) - f.eval(p - DVec3::X * h),
            f.eval(p + DVec3::Y * h) - f.eval(p - DVec3::Y * h),
            f.eval(p + DVec3::Z * h) - f.eval(p - DVec3::Z * h),
        ) / (2.0 * h);
        assert!((g - fd).length() < 1e-5 * g.length().max(1.0), "{p}: {g} vs {fd}");
    }
}

#[test]
fn the_trifurcation_meshes_as_one_closed_genus_zero_surface() {
    let f = RamiformField::new(&trifurcation(0.1, 40.0), &RamiformOptions::default()).unwrap();
    let domain = f.bounds().unwrap();
    assert!(domain.contains(DVec3::Z));
    let lattice = LatticeOptions {
        domain: Aabb::new(DVec3::new(-0.8, -0.8, -0.4), DVec3::new(0.8, 0.8, 2.0)),
        resolution: Resolution::Cell(0.02),
        ..Default::default()
    };
    let (mesh, _) = polygonize(&f, &Options { lattice, ..Default::default() }).unwrap();
    let r = check(&mesh);
    assert_eq!(r.components.len(), 1);
    let c = &r.components[0];
    assert!(c.is_closed_manifold() && c.consistently_oriented);
    assert_eq!(c.genus, Some(0));
    assert_eq!(r.outward, Some(true));
    // Vertices near the joint plane lie on the parent's circle, within a few % of a cell.
    let parent = f.radii()[0];
    let near: Vec<f64> = mesh
        .positions
        .iter()
        .filter(|p| (p[2] as f64 - 1.0).abs() < 0.004)
        .map(|p| (p[0] as f64).hypot(p[1] as f64))
        .collect();
    assert!(near.len() > 20);
    for rho in near {
        assert!((rho - parent).abs() < 0.01 * parent, "{rho} vs {parent}");
    }
}

#[test]
fn bad_trees_are_errors() {
    let mut t = Ramiform::new();
    assert!(matches!(
        RamiformField::new(&t, &RamiformOptions::default()),
        Err(SkeletonError::Empty)
    ));
    let root = t.add_root(DVec3::ZERO, DVec3::Z, Some(0.1)).unwrap();
    t.add_child(root, DVec3::new(0.0, 0.5, 1.5), Some(0.1)).unwrap();
    // A parent with a radius of its own.
    assert_eq!(
        RamiformField::new(&t, &RamiformOptions::default()).unwrap_err(),
        SkeletonError::ParentRadiusGiven(0)
    );
    let mut t = Ramiform::new();
    t.add_root(DVec3::ZERO, DVec3::Z, None).unwrap();
    assert_eq!(
        RamiformField::new(&t, &RamiformOptions::default()).unwrap_err(),
        SkeletonError::LeafNeedsRadius(0)
    );
    assert_eq!(t.add_child(5, DVec3::X, Some(0.1)).unwrap_err(), SkeletonError::UnknownLimb(5));
    assert!(t.add_child(0, DVec3::Z, Some(0.1)).is_err(), "zero length");
    assert!(t.add_root(DVec3::ZERO, DVec3::X, Some(-1.0)).is_err());
    let opts = RamiformOptions { directions: 2 };
    let mut t = Ramiform::new();
    t.add_root(DVec3::ZERO, DVec3::Z, Some(0.1)).unwrap();
    assert!(RamiformField::new(&t, &opts).is_err());
}
