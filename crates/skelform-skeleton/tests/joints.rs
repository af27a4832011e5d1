//! Blend control at joints and along limbs: the joint combination surface (DIS eq. 5.37,
//! appendix A.2), the angle-scaled super-elliptic blend (eq. 5.14) and tapered segments.

use glam::DVec3;
use skelform_field::Field;
use skelform_skeleton::{Blend, GroupId, Kernel, Skeleton, SkeletonField};

const G: GroupId = GroupId::DEFAULT;
const R: f64 = 0.1;

/// Where the field crosses zero going from `from` (inside) along `dir`, by bisection up to
/// `max` away.
fn surface_along(f: &dyn Field, from: DVec3, dir: DVec3, max: f64) -> f64 {
    assert!(f.eval(from) < 0.0, "start {from} is not inside");
    let (mut lo, mut hi) = (0.0, max);
    assert!(f.eval(from + dir * hi) > 0.0, "no surface within {max} of {from} along {dir}");
    for _ in 0..60 {
        let m = 0.5 * (lo + hi);
        if f.eval(from + dir * m) < 0.0 {
            lo = m;
        } else {
            hi = m;
        }
    }
    0.5 * (lo + hi)
}

fn tee(junction: bool) -> SkeletonField {
    let mut s = Skeleton::new();
    // The bar passes through the joint: the junction splits it there.
    s.add_segment(DVec3::new(-1.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0), R, G).unwrap();
    s.add_segment(DVec3::ZERO, DVec3::new(0.0, 1.0, 0.0), R, G).unwrap();
    if junction {
        let j = s.add_junction(DVec3::ZERO, None).unwrap();
        assert_eq!(s.junctions()[j].limbs.len(), 3, "bar split in two, plus the stem");
        let d = s.junction_direction(&s.junctions()[j], 0);
        assert!((d.z.abs() - 1.0).abs() < 1e-12, "{d}");
    }
    SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap()
}

/// The starfish of appendix A.2: a parent limb and four children, radius 0.1. One child's
/// end is lost in the text; (0.1, −0.6, 0) is our choice.
fn starfish(junction: bool) -> SkeletonField {
    let mut s = Skeleton::new();
    s.add_segment(DVec3::new(-0.5, -0.2, 0.0), DVec3::ZERO, R, G).unwrap();
    for end in [[0.06, 0.6, 0.0], [0.6, 0.4, 0.0], [0.7, -0.2, 0.0], [0.1, -0.6, 0.0]] {
        s.add_segment(DVec3::ZERO, DVec3::from_array(end), R, G).unwrap();
    }
    if junction {
        s.add_junction(DVec3::ZERO, None).unwrap();
    }
    SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap()
}

#[test]
fn the_junction_removes_the_bulge_above_the_tee() {
    let (plain, joint) = (tee(false), tee(true));
    // Above the junction: ¾ density, a bulge, without; the union's radius with.
    assert!((plain.eval(DVec3::new(0.0, 0.0, R)) - (0.5 - 0.75)).abs() < 1e-9);
    let h_plain = surface_along(&plain, DVec3::ZERO, DVec3::Z, 3.0 * R);
    let h_joint = surface_along(&joint, DVec3::ZERO, DVec3::Z, 3.0 * R);
    println!("tee: height above the junction {h_plain:.5} plain, {h_joint:.5} with the junction");
    assert!(h_plain > 1.15 * R, "the plain tee bulges: {h_plain}");
    assert!((h_joint - R).abs() < 0.02 * R, "no bulge with the junction: {h_joint}");
    // Away from the joint the limbs keep their radius, above and beside.
    for (from, dir) in [
        (DVec3::new(-0.5, 0.0, 0.0), DVec3::Z),
        (DVec3::new(0.5, 0.0, 0.0), DVec3::new(0.0, -1.0, 0.0)),
        (DVec3::new(0.0, 0.5, 0.0), DVec3::Z),
        (DVec3::new(0.0, 0.5, 0.0), DVec3::new(1.0, 0.0, 1.0).normalize()),
    ] {
        let r = surface_along(&joint, from, dir, 3.0 * R);
        assert!((r - R).abs() < 1e-3 * R, "radius {r} at {from} along {dir}");
    }
}

#[test]
fn the_junction_keeps_the_convolution_in_the_joint_plane() {
    // In the plane of the joint the convolution's gradient lies in the plane, so the
    // Convexity is 0 and the surface is the convolution's: smooth webbing.
    let (plain, joint) = (starfish(false), starfish(true));
    for p in [
        DVec3::new(0.12, 0.12, 0.0),
        DVec3::new(0.2, -0.15, 0.0),
        DVec3::new(-0.1, 0.15, 0.0),
        DVec3::new(0.3, 0.05, 0.0),
    ] {
        assert!((plain.eval(p) - joint.eval(p)).abs() < 1e-12, "at {p}");
    }
}

#[test]
fn the_junction_removes_the_bulge_of_the_starfish() {
    let (plain, joint) = (starfish(false), starfish(true));
    let h_plain = surface_along(&plain, DVec3::ZERO, DVec3::Z, 4.0 * R);
    let h_joint = surface_along(&joint, DVec3::ZERO, DVec3::Z, 4.0 * R);
    println!("starfish: height above the joint {h_plain:.5} plain, {h_joint:.5} with the junction");
    assert!(h_plain > 1.3 * R, "five limbs bulge: {h_plain}");
    assert!((h_joint - R).abs() < 0.03 * R, "{h_joint}");
    // Out of the plane near the joint, over the limbs, the radius stays close to r.
    for end in [[0.06, 0.6, 0.0], [0.6, 0.4, 0.0], [0.7, -0.2, 0.0], [0.1, -0.6, 0.0]] {
        let d = DVec3::from_array(end).normalize();
        for t in [0.15, 0.3] {
            let h = surface_along(&joint, d * t, DVec3::Z, 3.0 * R);
            let hp = surface_along(&plain, d * t, DVec3::Z, 4.0 * R);
            println!("limb to {end:?}, {t} from the joint: height {h:.5} (plain {hp:.5})");
            assert!((h - R).abs() < 0.08 * R, "height {h} at {t} along the limb");
            assert!(h < hp, "lower than the plain convolution");
        }
    }
    // The gradient is consistent with the values.
    for p in [DVec3::new(0.05, 0.03, 0.09), DVec3::new(-0.1, 0.1, 0.05)] {
        let g = joint.gradient(p);
        let h = 1e-5;
        let d = |e: DVec3| (joint.eval(p + e * h) - joint.eval(p - e * h)) / (2.0 * h);
        let fd = DVec3::new(d(DVec3::X), d(DVec3::Y), d(DVec3::Z));
        assert!((g - fd).length() < 1e-4 * g.length(), "{g} vs {fd}");
    }
}

#[test]
fn junction_errors_are_clear() {
    let mut s = Skeleton::new();
    s.add_segment(DVec3::ZERO, DVec3::X, R, G).unwrap();
    let e = s.add_junction(DVec3::Y, None).unwrap_err().to_string();
    assert!(e.contains("at least 2 limbs") && e.contains("found 0"), "{e}");
    s.add_segment(DVec3::ZERO, -DVec3::X, R, G).unwrap();
    s.add_junction(DVec3::ZERO, Some(DVec3::Z)).unwrap();
    let e = s.add_junction(DVec3::X, Some(DVec3::Z)).unwrap_err().to_string();
    assert!(e.contains("at least 2 limbs") && e.contains("found 1"), "{e}");
    let e = s.add_junction(DVec3::Y, Some(DVec3::ZERO)).unwrap_err().to_string();
    assert!(e.contains("non-zero vector"), "{e}");
    let e = SkeletonField::new(&s, Blend::Sum(Kernel::Gaussian)).unwrap_err().to_string();
    assert!(e.contains("convolution blend only"), "{e}");
}

#[test]
fn collinear_limbs_get_a_direction_across_them_and_stay_a_cylinder() {
    let mut s = Skeleton::new();
    s.add_segment(DVec3::new(-1.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0), R, G).unwrap();
    let j = s.add_junction(DVec3::ZERO, None).unwrap();
    let d = s.junction_direction(&s.junctions()[j], 0);
    assert!(d.x.abs() < 1e-12 && (d.length() - 1.0).abs() < 1e-12, "{d}");
    let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
    for dir in [DVec3::Y, DVec3::Z, DVec3::new(0.0, 0.6, 0.8)] {
        for x in [-0.3, 0.0, 0.05] {
            let r = surface_along(&f, DVec3::X * x, dir, 3.0 * R);
            assert!((r - R).abs() < 1e-3 * R, "radius {r} at x = {x} along {dir}");
        }
    }
}

/// Two cylinders on the x and z axes crossing at the origin (DIS fig. 5.29), super-elliptic
/// blend with `t = 3`.
fn cross(angle_scaled: bool) -> SkeletonField {
    let mut s = Skeleton::new();
    s.add_segment(DVec3::new(-1.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0), R, G).unwrap();
    s.add_segment(DVec3::new(0.0, 0.0, -1.0), DVec3::new(0.0, 0.0, 1.0), R, G).unwrap();
    SkeletonField::new(&s, Blend::SuperElliptic { range: 1.0, thumbweight: 3.0, angle_scaled })
        .unwrap()
}

#[test]
fn angle_scaled_ranges_shrink_the_super_elliptic_bulge() {
    let (plain, scaled) = (cross(false), cross(true));
    // Radius across the crossing (along y, where both nearest points are the origin) and far
    // along a cylinder.
    let at_cross = |f: &SkeletonField| surface_along(f, DVec3::ZERO, DVec3::Y, 4.0 * R);
    let far = |f: &SkeletonField| surface_along(f, DVec3::new(0.7, 0.0, 0.0), DVec3::Y, 4.0 * R);
    let (bp, bs) = (at_cross(&plain) / far(&plain), at_cross(&scaled) / far(&scaled));
    println!("crossing/far radius: {bp:.4} plain (eq. 5.13), {bs:.4} angle-scaled (eq. 5.14)");
    // Plain: both terms equal on the y axis, 2x³ = 1, so the radius is r + range·r·(1 − 2^(−1/3)).
    assert!((bp - (2.0 - 0.5f64.cbrt())).abs() < 1e-6, "{bp}");
    assert!(bs < 1.0 + 0.01 * (1.0 - 0.5f64.cbrt()) + 1e-9, "{bs}");
    assert!((far(&scaled) - R).abs() < 1e-9);
    // The crotch between the two cylinders is still filled (the blend acts where the
    // gradients are at right angles).
    let d = DVec3::new(1.0, 0.0, 1.0).normalize();
    let crotch = |f: &SkeletonField| surface_along(f, DVec3::ZERO, d, 4.0 * R);
    println!(
        "crotch: {:.4} plain, {:.4} scaled, union {:.4}",
        crotch(&plain),
        crotch(&scaled),
        R * 2f64.sqrt()
    );
    assert!(crotch(&scaled) > 1.2 * R * 2f64.sqrt(), "a fillet in the crotch");
}

#[test]
fn a_long_tapered_segment_has_the_interpolated_radius() {
    let (ra, rb, len) = (0.05, 0.15, 4.0);
    let mut s = Skeleton::new();
    s.add_tapered_segment(DVec3::ZERO, DVec3::X * len, (ra, rb), G).unwrap();
    for (name, blend) in [
        ("gaussian", Blend::Convolution(Kernel::Gaussian)),
        ("wyvill", Blend::Convolution(Kernel::Wyvill)),
        ("bspline", Blend::Convolution(Kernel::BSpline)),
        ("union", Blend::Union(Default::default())),
        ("sum", Blend::Sum(Kernel::Wyvill)),
    ] {
        let f = SkeletonField::new(&s, blend).unwrap();
        for alpha in [0.1, 0.25, 0.5, 0.75, 0.9] {
            let want = ra + alpha * (rb - ra);
            let got = surface_along(&f, DVec3::X * (alpha * len), DVec3::Y, 3.0 * rb);
            // A taper of 0.025 per unit length: the convolution sees a slightly different
            // radius on either side, so allow 2 %.
            assert!((got - want).abs() < 0.02 * want, "{name}: α = {alpha}: {got} vs {want}");
        }
        // The ends: the Gaussian convolution surface passes through them (the field there
        // is ½ of the plateau times the distance filter at 0, i.e. iso), and the union's
        // caps are spheres of the end radii.
        if let Blend::Convolution(Kernel::Gaussian) = blend {
            assert!(f.eval(DVec3::ZERO).abs() < 1e-9, "{name}");
            assert!(f.eval(DVec3::X * len).abs() < 1e-9, "{name}");
        } else if let Blend::Union(_) = blend {
            assert!((surface_along(&f, DVec3::ZERO, -DVec3::X, 1.0) - ra).abs() < 1e-9);
            let end = surface_along(&f, DVec3::X * len, DVec3::X, 1.0);
            assert!((end - rb).abs() < 1e-9);
        }
    }
}

#[test]
fn a_tapered_polyline_is_the_sum_of_its_segments_and_has_no_joint_bulge() {
    let pts = [
        DVec3::ZERO,
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(2.0, 0.0, 0.0),
        DVec3::new(3.0, 0.0, 0.0),
    ];
    let radii = [0.06, 0.09, 0.12, 0.15];
    let mut chain = Skeleton::new();
    chain.add_tapered_polyline(&pts, &radii, G).unwrap();
    let fc = SkeletonField::new(&chain, Blend::Convolution(Kernel::Gaussian)).unwrap();
    let parts: Vec<SkeletonField> = (0..3)
        .map(|i| {
            let mut s = Skeleton::new();
            s.add_tapered_segment(pts[i], pts[i + 1], (radii[i], radii[i + 1]), G).unwrap();
            SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap()
        })
        .collect();
    for k in 0..40 {
        let p = DVec3::new(-0.2 + 0.085 * k as f64, 0.03 * (k % 5) as f64, 0.02 * (k % 3) as f64);
        let sum: f64 = parts.iter().map(|f| 0.5 - f.eval(p)).sum();
        assert!(((0.5 - fc.eval(p)) - sum).abs() < 1e-12, "superposition at {p}");
    }
    // Along the chain, through its joints, the radius follows the interpolation.
    for k in 1..12 {
        let x = 0.25 * k as f64;
        let want = 0.06 + 0.03 * x;
        let got = surface_along(&fc, DVec3::X * x, DVec3::Z, 0.5);
        assert!((got - want).abs() < 0.02 * want, "at x = {x}: {got} vs {want}");
    }
    // One radius per point.
    let e = Skeleton::new().add_tapered_polyline(&pts, &radii[..3], G).unwrap_err().to_string();
    assert!(e.contains("4 points, 3 radii"), "{e}");
}

#[test]
fn a_junction_follows_its_limbs_when_they_move() {
    // Rotate the whole starfish (as a pose would, element by element): the junction's
    // default direction is recomputed from the moved limbs, so the field rotates with it.
    let mut s = Skeleton::new();
    s.add_segment(DVec3::new(-0.5, -0.2, 0.0), DVec3::ZERO, R, G).unwrap();
    for end in [[0.06, 0.6, 0.0], [0.6, 0.4, 0.0], [0.7, -0.2, 0.0], [0.1, -0.6, 0.0]] {
        s.add_segment(DVec3::ZERO, DVec3::from_array(end), R, G).unwrap();
    }
    s.add_junction(DVec3::ZERO, None).unwrap();
    let before = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
    let m = glam::DAffine3::from_rotation_translation(
        glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.7, -0.4, 1.1),
        DVec3::new(0.2, -0.1, 0.3),
    );
    s.transform_elements(|_, e| e.shape.transformed(&m)).unwrap();
    let after = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
    for p in [DVec3::new(0.0, 0.0, 0.1), DVec3::new(0.1, 0.05, 0.08), DVec3::new(-0.2, 0.1, -0.05)]
    {
        let (a, b) = (before.eval(p), after.eval(m.transform_point3(p)));
        assert!((a - b).abs() < 1e-9, "at {p}: {a} vs {b}");
    }
}

#[test]
fn junction_batches_give_exactly_the_single_point_values() {
    let f = starfish(true);
    let pts: Vec<DVec3> = (0..300)
        .map(|i| {
            let t = i as f64;
            DVec3::new((t * 0.37).sin() * 0.6, (t * 0.53).cos() * 0.6, (t * 0.11).sin() * 0.2)
        })
        .collect();
    let mut values = vec![0.0; pts.len()];
    let mut grads = vec![DVec3::ZERO; pts.len()];
    f.eval_grad_many(&pts, &mut values, &mut grads);
    let mut only = vec![0.0; pts.len()];
    f.eval_many(&pts, &mut only);
    for (i, p) in pts.iter().enumerate() {
        assert_eq!(values[i].to_bits(), f.eval(*p).to_bits());
        assert_eq!(only[i].to_bits(), values[i].to_bits());
        assert_eq!(grads[i], f.gradient(*p));
    }
}

#[test]
fn a_junction_takes_in_the_chains_that_continue_from_its_limbs() {
    // The tee's stem continues as a polyline past 0.3: without the continuation inside the
    // junction, the union would end at 0.3 while the convolution goes on (a 7.6 % bump
    // at 0.2 and a dip beyond, measured before the chain was taken in).
    let mut s = Skeleton::new();
    s.add_segment(DVec3::new(-1.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0), R, G).unwrap();
    s.add_polyline(&[DVec3::ZERO, DVec3::new(0.0, 0.3, 0.0), DVec3::new(0.0, 0.8, 0.0)], R, G)
        .unwrap();
    let j = s.add_junction(DVec3::ZERO, None).unwrap();
    assert_eq!(s.junctions()[j].limbs.len(), 4, "two bar halves, the stem and its continuation");
    let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
    for y in [0.15, 0.2, 0.25, 0.3, 0.35, 0.4, 0.5, 0.6] {
        let h = surface_along(&f, DVec3::new(0.0, y, 0.0), DVec3::Z, 3.0 * R);
        assert!((h - R).abs() < 0.01 * R, "height {h} at y = {y}");
    }
}

#[test]
fn a_tree_with_two_branch_points_is_one_junction_with_two_joints() {
    // A tee at the origin whose stem ends in a second tee, upright (in the xz plane) at
    // (0, 0.6, 0): each joint has its own plane, and each bulges without its junction.
    let mut s = Skeleton::new();
    s.add_segment(DVec3::new(-0.6, 0.0, 0.0), DVec3::new(0.6, 0.0, 0.0), R, G).unwrap();
    s.add_segment(DVec3::ZERO, DVec3::new(0.0, 0.6, 0.0), R, G).unwrap();
    s.add_segment(DVec3::new(0.0, 0.6, -0.5), DVec3::new(0.0, 0.6, 0.5), R, G).unwrap();
    let plain = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
    let first = s.add_junction(DVec3::ZERO, None).unwrap();
    let second = s.add_junction(DVec3::new(0.0, 0.6, 0.0), None).unwrap();
    assert_eq!(first, second, "the second joint joins the first junction");
    let j = &s.junctions()[0];
    assert_eq!(j.joints.len(), 2);
    assert_eq!(j.limbs.len(), 5, "two bar halves, the stem, two halves of the upright bar");
    assert!((s.junction_direction(j, 0).z.abs() - 1.0).abs() < 1e-12);
    assert!((s.junction_direction(j, 1).x.abs() - 1.0).abs() < 1e-12);
    let joint = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
    // Over the first joint along z, beside the second along x (out of each joint's plane).
    let over_first = (DVec3::ZERO, DVec3::Z);
    let over_second = (DVec3::new(0.0, 0.6, 0.0), DVec3::X);
    for (from, dir) in [over_first, over_second] {
        let hp = surface_along(&plain, from, dir, 3.0 * R);
        let hj = surface_along(&joint, from, dir, 3.0 * R);
        println!("out of the plane at {from}: plain {hp:.4}, junction {hj:.4}");
        assert!(hp > 1.2 * R, "the plain tree bulges: {hp}");
        assert!((hj - R).abs() < 0.03 * R, "{hj}");
    }
    // The field is continuous: no step as a point moves past where limbs meet.
    let mut worst: f64 = 0.0;
    for k in 0..1000 {
        for (x, z) in [(0.08, 0.05), (0.1, 0.1), (0.05, 0.12)] {
            let p = DVec3::new(x, 0.35 + 0.25 * k as f64 / 1000.0, z);
            let q = p + DVec3::Y * 2.5e-4;
            worst = worst.max((joint.eval(q) - joint.eval(p)).abs());
        }
    }
    println!("largest step over 2.5e-4: {worst:.2e}");
    assert!(worst < 2e-3, "a step of {worst} over 2.5e-4");
    // Along the stem between the joints the radius stays r: midway in every direction
    // around it, and nearer a joint out of that joint's plane (in the plane the webbing
    // of the convolution widens it, as at a single tee).
    let d = DVec3::new(1.0, 0.0, 1.0).normalize();
    for (y, dir) in [(0.3, DVec3::X), (0.3, DVec3::Z), (0.3, d), (0.2, DVec3::Z), (0.4, DVec3::X)] {
        let h = surface_along(&joint, DVec3::new(0.0, y, 0.0), dir, 3.0 * R);
        assert!((h - R).abs() < 0.03 * R, "radius {h} at y = {y} along {dir}");
    }
}
