//! The skeletal field as a `Field`: gradients, batches, culling, blends and groups.

use glam::DVec3;
use skelform_field::Field;
use skelform_skeleton::{Blend, Falloff, GroupId, Kernel, Skeleton, SkeletonField};

/// A small skeleton with every kind of element: a point, an L-shaped polyline and a
/// triangle.
fn mixed() -> Skeleton {
    let mut s = Skeleton::new();
    let g = GroupId::DEFAULT;
    s.add_point(DVec3::new(-0.4, 0.3, 0.0), 0.15, g).unwrap();
    s.add_polyline(
        &[DVec3::new(-0.3, -0.2, 0.0), DVec3::new(0.2, -0.2, 0.05), DVec3::new(0.25, 0.3, 0.0)],
        0.1,
        g,
    )
    .unwrap();
    s.add_polygon(
        vec![DVec3::new(0.3, -0.4, 0.1), DVec3::new(0.6, -0.3, 0.0), DVec3::new(0.45, 0.0, 0.2)],
        0.08,
        g,
    )
    .unwrap();
    // A tapered segment with per-end strengths.
    let e = skelform_skeleton::Element::new(
        skelform_skeleton::Shape::Segment(
            skelform_skeleton::Segment::new(
                DVec3::new(-0.5, -0.4, -0.1),
                DVec3::new(0.1, -0.5, 0.1),
            )
            .unwrap(),
        ),
        0.06,
    )
    .unwrap()
    .with_end_radius(0.12)
    .unwrap()
    .with_strength(0.8)
    .unwrap()
    .with_end_strength(1.2)
    .unwrap();
    s.push(e).unwrap();
    s
}

fn blends() -> Vec<Blend> {
    // The sinc convolves points only (see `sinc_convolves_points_only`).
    let mut v: Vec<Blend> = Kernel::ALL
        .iter()
        .filter(|(_, k)| k.convolves_extended())
        .map(|(_, k)| Blend::Convolution(*k))
        .collect();
    v.extend(Kernel::ALL.iter().map(|(_, k)| Blend::Sum(*k)));
    v.extend([
        Blend::Union(Falloff::Linear),
        Blend::Union(Falloff::Squared),
        Blend::SuperElliptic { range: 1.0, thumbweight: 2.0, angle_scaled: false },
        Blend::SuperElliptic { range: 0.7, thumbweight: 3.0, angle_scaled: true },
        Blend::Combination { range: 1.0, clamp: true },
        Blend::Combination { range: 1.5, clamp: false },
    ]);
    v
}

/// Deterministic points around the skeleton.
fn sample_points(n: usize) -> Vec<DVec3> {
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    (0..n)
        .map(|_| DVec3::new(next() * 1.4 - 0.7, next() * 1.0 - 0.6, next() * 0.5 - 0.25))
        .collect()
}

#[test]
fn analytic_gradients_match_central_differences_for_every_blend() {
    let s = mixed();
    for blend in blends() {
        let f = SkeletonField::new(&s, blend).unwrap();
        let mut checked = 0;
        for p in sample_points(60) {
            let g = f.gradient(p);
            let h = 1e-6;
            let d = |e: DVec3| (f.eval(p + e * h) - f.eval(p - e * h)) / (2.0 * h);
            let fd = DVec3::new(d(DVec3::X), d(DVec3::Y), d(DVec3::Z));
            // Skip the measure-zero places where the field has a kink inside the stencil
            // (a union switching element): there the two one-sided differences disagree.
            let one_sided = |e: DVec3| (f.eval(p + e * h) - f.eval(p)) / h;
            let kink = [DVec3::X, DVec3::Y, DVec3::Z]
                .iter()
                .any(|e| (one_sided(*e) - d(*e)).abs() > 1e-3 * (1.0 + d(*e).abs()));
            if kink {
                continue;
            }
            checked += 1;
            assert!(
                (g - fd).length() <= 1e-5 * (1.0 + g.length()),
                "{blend:?} at {p}: {g} vs {fd}"
            );
        }
        assert!(checked >= 50, "{blend:?}: only {checked} smooth points");
    }
}

#[test]
fn batches_give_exactly_the_single_point_values() {
    let s = mixed();
    let pts = sample_points(200);
    for blend in blends() {
        let f = SkeletonField::new(&s, blend).unwrap();
        let mut many = vec![0.0; pts.len()];
        f.eval_many(&pts, &mut many);
        let mut vals = vec![0.0; pts.len()];
        let mut grads = vec![DVec3::ZERO; pts.len()];
        f.eval_grad_many(&pts, &mut vals, &mut grads);
        for (i, p) in pts.iter().enumerate() {
            assert_eq!(many[i].to_bits(), f.eval(*p).to_bits(), "{blend:?}");
            assert_eq!(vals[i].to_bits(), many[i].to_bits(), "{blend:?}");
            assert_eq!(grads[i], f.gradient(*p), "{blend:?}");
        }
    }
}

#[test]
fn an_element_out_of_reach_changes_nothing() {
    let mut s = mixed();
    let near = SkeletonField::new(&s, Blend::Convolution(Kernel::Wyvill)).unwrap();
    s.add_segment(DVec3::new(5.0, 5.0, 5.0), DVec3::new(6.0, 5.0, 5.0), 0.1, GroupId::DEFAULT)
        .unwrap();
    let both = SkeletonField::new(&s, Blend::Convolution(Kernel::Wyvill)).unwrap();
    for p in sample_points(50) {
        assert_eq!(near.eval(p).to_bits(), both.eval(p).to_bits());
    }
    let b = both.bounds().unwrap();
    assert!(b.contains(DVec3::new(5.5, 5.0, 5.0)) && b.contains(DVec3::ZERO));
}

#[test]
fn seeds_are_inside_and_on_every_element() {
    let s = mixed();
    for blend in blends() {
        let f = SkeletonField::new(&s, blend).unwrap();
        let seeds = f.seed_points();
        assert_eq!(seeds.len(), s.len());
        for p in seeds {
            assert!(f.eval(p) < 0.0, "{blend:?}: seed {p} is outside");
        }
    }
}

#[test]
fn lone_elements_have_their_surface_at_their_radius_under_every_blend() {
    let r = 0.1;
    for blend in blends().into_iter().chain([Blend::Convolution(Kernel::Sinc)]) {
        let mut s = Skeleton::new();
        s.add_point(DVec3::ZERO, r, GroupId::DEFAULT).unwrap();
        let f = SkeletonField::new(&s, blend).unwrap();
        let v = f.eval(DVec3::new(0.0, r, 0.0));
        assert!(v.abs() < 1e-12, "{blend:?}: {v}");
        assert!(
            f.eval(DVec3::new(0.0, 0.5 * r, 0.0)) < 0.0
                && f.eval(DVec3::new(0.0, 1.5 * r, 0.0)) > 0.0
        );
    }
}

/// Two parallel "fingers" of radius `r` whose surfaces are 0.2 r apart.
fn fingers(same_group: bool) -> (Skeleton, f64) {
    let r = 0.1;
    let y = r + 0.1 * r; // half the distance between the axes
    let mut s = Skeleton::new();
    let g1 = s.add_group("finger1").unwrap();
    let g2 = if same_group { g1 } else { s.add_group("finger2").unwrap() };
    s.add_segment(DVec3::new(-0.4, y, 0.0), DVec3::new(0.4, y, 0.0), r, g1).unwrap();
    s.add_segment(DVec3::new(-0.4, -y, 0.0), DVec3::new(0.4, -y, 0.0), r, g2).unwrap();
    (s, r)
}

#[test]
fn fingers_in_different_groups_keep_their_gap() {
    let mid = DVec3::ZERO;
    let (same, _) = fingers(true);
    let (apart, _) = fingers(false);
    for blend in [
        Blend::Convolution(Kernel::Gaussian),
        Blend::Convolution(Kernel::Wyvill),
        Blend::Sum(Kernel::Gaussian),
    ] {
        let f = SkeletonField::new(&same, blend).unwrap();
        assert!(f.eval(mid) < 0.0, "{blend:?}: one group blends across the gap");
        let f = SkeletonField::new(&apart, blend).unwrap();
        assert!(f.eval(mid) > 0.0, "{blend:?}: two groups must not blend");
        assert_eq!(f.clique_count(), 2);
    }
}

#[test]
fn fingers_blend_into_a_shared_palm_but_not_into_each_other() {
    let (mut s, r) = fingers(false);
    let palm = s.add_group("palm").unwrap();
    let (f1, f2) = (s.group_named("finger1").unwrap(), s.group_named("finger2").unwrap());
    s.blend_groups(palm, f1).unwrap();
    s.blend_groups(palm, f2).unwrap();
    // A palm across the fingers' bases.
    s.add_segment(DVec3::new(-0.5, -0.3, 0.0), DVec3::new(-0.5, 0.3, 0.0), 1.5 * r, palm).unwrap();
    let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
    assert_eq!(f.clique_count(), 2);
    assert!(f.eval(DVec3::ZERO) > 0.0, "the fingers stay apart");
    // Where a finger meets the palm they blend: a fillet fills the corner.
    let corner = DVec3::new(-0.5 + 1.5 * r + 0.02, 0.11 + r + 0.01, 0.0);
    let alone = {
        let mut t = Skeleton::new();
        t.add_segment(DVec3::new(-0.4, 0.11, 0.0), DVec3::new(0.4, 0.11, 0.0), r, GroupId::DEFAULT)
            .unwrap();
        t.add_segment(
            DVec3::new(-0.5, -0.3, 0.0),
            DVec3::new(-0.5, 0.3, 0.0),
            1.5 * r,
            GroupId::DEFAULT,
        )
        .unwrap();
        let u = SkeletonField::new(&t, Blend::Union(Falloff::Linear)).unwrap();
        u.eval(corner)
    };
    assert!(alone > 0.0, "the corner point is outside the plain union");
    assert!(f.eval(corner) < 0.0, "…and inside the blended finger and palm");
}

#[test]
fn tee_bulges_under_convolution_as_the_dissertation_computes() {
    // DIS §5.6.14: two segments of radius r meeting in a tee; at (0, 0, r) above the
    // junction the density is ½·1 + ½·½ = ¾.
    let r = 0.1;
    let mut s = Skeleton::new();
    s.add_segment(DVec3::new(-1.0, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0), r, GroupId::DEFAULT)
        .unwrap();
    s.add_segment(DVec3::ZERO, DVec3::new(0.0, 1.0, 0.0), r, GroupId::DEFAULT).unwrap();
    let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
    assert!((f.eval(DVec3::new(0.0, 0.0, r)) - (0.5 - 0.75)).abs() < 1e-9);
    // So (0, 0, r) is inside: the surface above the junction stands higher than r.
    assert!(f.eval(DVec3::new(0.0, 0.0, r)) < 0.0);
    // Far from the junction it is r exactly.
    assert!(f.eval(DVec3::new(-0.5, 0.0, r)).abs() < 1e-6);
}

#[test]
fn combination_removes_the_bulge_of_the_product_blend_where_convex() {
    // Two perpendicular segments meeting at a corner (DIS fig. 5.32). Outside the corner
    // (convex side) the combination follows the union; inside it (concave) it blends.
    let r = 0.1;
    let mut s = Skeleton::new();
    s.add_segment(DVec3::ZERO, DVec3::new(0.6, 0.0, 0.0), r, GroupId::DEFAULT).unwrap();
    s.add_segment(DVec3::ZERO, DVec3::new(0.0, 0.6, 0.0), r, GroupId::DEFAULT).unwrap();
    let comb = SkeletonField::new(&s, Blend::Combination { range: 1.0, clamp: true }).unwrap();
    let union = SkeletonField::new(&s, Blend::Union(Falloff::Linear)).unwrap();
    // Convex side: beyond the corner, the vectors to the two nearest points coincide.
    // (The product blend alone, 1 − (1 − P)², is ½ + 0.01 here: it would bulge.)
    let convex = DVec3::new(-r * 0.8, -r * 0.8, 0.0);
    assert!(union.eval(convex) > 0.0 && comb.eval(convex) > 0.0, "no bulge outside the corner");
    // Concave side: in the crotch the blend adds material the union does not have.
    let crotch = DVec3::new(1.05 * r, 1.05 * r, 0.0);
    assert!(union.eval(crotch) > 0.0 && comb.eval(crotch) < 0.0, "a fillet inside the corner");
}

#[test]
fn sinc_convolves_points_only() {
    let g = GroupId::DEFAULT;
    // A lone sinc point: its surface at its radius, and no second contour in its rings —
    // the second lobe peaks at 0.128, far below ½.
    let mut s = Skeleton::new();
    s.add_point(DVec3::ZERO, 0.1, g).unwrap();
    let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Sinc)).unwrap();
    assert!(f.eval(DVec3::new(0.0, 0.1, 0.0)).abs() < 1e-15);
    let density = |x: f64| 0.5 - f.eval(DVec3::new(x, 0.0, 0.0));
    assert!((101..600).all(|i| density(i as f64 * 1e-3) < 0.5));
    let ring = (170..600).map(|i| density(i as f64 * 1e-3)).fold(0.0, f64::max);
    assert!((0.128..0.1284).contains(&ring), "{ring}");
    // The sum blend takes every element.
    let m = mixed();
    assert!(SkeletonField::new(&m, Blend::Sum(Kernel::Sinc)).is_ok());
    // Convolution refuses segments and polygons, naming the first one.
    s.add_segment(DVec3::X, DVec3::Y, 0.1, g).unwrap();
    let e = SkeletonField::new(&s, Blend::Convolution(Kernel::Sinc)).unwrap_err();
    assert_eq!(
        e,
        skelform_skeleton::SkeletonError::KernelConvolvesPointsOnly {
            kernel: "sinc",
            shape: "segment",
            element: 1
        }
    );
    let msg = e.to_string();
    assert!(msg.contains("not separable") && msg.contains("blend = \"sum\""), "{msg}");
    let mut t = Skeleton::new();
    t.add_polygon(vec![DVec3::ZERO, DVec3::X, DVec3::Y], 0.1, g).unwrap();
    let e = SkeletonField::new(&t, Blend::Convolution(Kernel::Sinc)).unwrap_err();
    assert!(e.to_string().contains("a polygon's convolution"), "{e}");
}

/// Groups shared by several cliques are summed once per point (additive blends); the field
/// is still the minimum over cliques of each clique's field alone, with its gradient.
#[test]
fn shared_groups_give_each_clique_its_own_field() {
    let r = 0.08;
    let build = |fingers: &[usize]| {
        let mut s = Skeleton::new();
        let palm = s.add_group("palm").unwrap();
        s.add_segment(DVec3::new(-0.5, -0.3, 0.0), DVec3::new(-0.5, 0.3, 0.0), 1.5 * r, palm)
            .unwrap();
        s.add_point(DVec3::new(-0.6, 0.0, 0.05), 1.2 * r, palm).unwrap();
        for &k in fingers {
            let g = s.add_group(&format!("finger{k}")).unwrap();
            s.blend_groups(palm, g).unwrap();
            let y = -0.2 + 0.2 * k as f64;
            s.add_segment(DVec3::new(-0.45, y, 0.0), DVec3::new(0.3, y, 0.02), r, g).unwrap();
        }
        s
    };
    for blend in [Blend::Convolution(Kernel::Gaussian), Blend::Sum(Kernel::Wyvill)] {
        let whole = SkeletonField::new(&build(&[0, 1, 2]), blend).unwrap();
        assert_eq!(whole.clique_count(), 3);
        let alone: Vec<SkeletonField> =
            (0..3).map(|k| SkeletonField::new(&build(&[k]), blend).unwrap()).collect();
        let mut seed = 7u64;
        let mut next = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
        };
        for _ in 0..300 {
            let p = DVec3::new(0.7 * next(), 0.5 * next(), 0.2 * next());
            let expect = alone.iter().map(|f| f.eval(p)).fold(f64::INFINITY, f64::min);
            assert!((whole.eval(p) - expect).abs() < 1e-12, "{blend:?} at {p}");
            let best = alone.iter().min_by(|a, b| a.eval(p).total_cmp(&b.eval(p))).unwrap();
            assert!((whole.gradient(p) - best.gradient(p)).length() < 1e-9, "{blend:?} at {p}");
        }
    }
}
