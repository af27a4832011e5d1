//! Closed-form and quadrature convolution against a slow, independent numerical reference.
//!
//! The reference integrates the kernel over the primitive directly: adaptive Gauss–Legendre
//! (5 points, bisection until the halves agree) along a segment, and nested over a
//! triangle's two barycentric directions. It shares nothing with the library's formulas
//! except `Kernel::value`, the kernel being integrated.

use glam::DVec3;
use skelform_skeleton::convolution::convolve;
use skelform_skeleton::{Kernel, Polygon, Segment, Shape};

const GL_X: [f64; 5] = [
    -0.906_179_845_938_664,
    -0.538_469_310_105_683,
    0.0,
    0.538_469_310_105_683,
    0.906_179_845_938_664,
];
const GL_W: [f64; 5] = [
    0.236_926_885_056_189,
    0.478_628_670_499_366,
    0.568_888_888_888_889,
    0.478_628_670_499_366,
    0.236_926_885_056_189,
];

fn gl5(f: &dyn Fn(f64) -> f64, a: f64, b: f64) -> f64 {
    let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
    h * GL_X.iter().zip(GL_W).map(|(x, w)| w * f(c + h * x)).sum::<f64>()
}

/// Adaptive 1-D integral to an absolute tolerance.
fn adaptive(f: &dyn Fn(f64) -> f64, a: f64, b: f64, tol: f64) -> f64 {
    fn rec(f: &dyn Fn(f64) -> f64, a: f64, b: f64, whole: f64, tol: f64, depth: u32) -> f64 {
        let m = 0.5 * (a + b);
        let (l, r) = (gl5(f, a, m), gl5(f, m, b));
        // Stop at the tolerance, or where rounding noise dominates (the tolerance halves each
        // level; without the floor a kink would recurse to the depth limit everywhere).
        let noise = 8.0 * f64::EPSILON * (l.abs() + r.abs());
        if depth > 30 || ((l + r) - whole).abs() <= tol.max(noise) {
            l + r
        } else {
            rec(f, a, m, l, 0.5 * tol, depth + 1) + rec(f, m, b, r, 0.5 * tol, depth + 1)
        }
    }
    // Start from a few pieces so that a narrow feature is not missed entirely.
    let n = 16;
    (0..n)
        .map(|i| {
            let (x0, x1) =
                (a + (b - a) * i as f64 / n as f64, a + (b - a) * (i + 1) as f64 / n as f64);
            rec(f, x0, x1, gl5(f, x0, x1), tol / n as f64, 0)
        })
        .sum()
}

/// `∫_segment k(|p − u|/r) du / (r · line_norm)`.
fn reference_segment(k: Kernel, a: DVec3, b: DVec3, r: f64, p: DVec3) -> f64 {
    let len = (b - a).length();
    let f = |t: f64| k.value(((a + (b - a) * t) - p).length_squared() / (r * r)) * len;
    adaptive(&f, 0.0, 1.0, 1e-15) / (r * k.line_norm())
}

/// `∫_triangle k(|p − u|/r) du / (r² · area_norm)`, nested.
fn reference_triangle(k: Kernel, t: [DVec3; 3], r: f64, p: DVec3) -> f64 {
    let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
    let jac = e1.cross(e2).length();
    let outer = |u: f64| {
        let inner = |v: f64| k.value(((t[0] + u * e1 + v * e2) - p).length_squared() / (r * r));
        adaptive(&inner, 0.0, 1.0 - u, 1e-14)
    };
    adaptive(&outer, 0.0, 1.0, 1e-13) * jac / (r * r * k.area_norm())
}

fn close(got: f64, want: f64) -> bool {
    (got - want).abs() <= 1e-6 * want.abs() + 1e-13
}

#[test]
fn segment_closed_form_equals_quadrature() {
    let a = DVec3::new(-0.3, 0.1, 0.2);
    let b = DVec3::new(0.5, -0.2, 0.4);
    let r = 0.15;
    let dir = (b - a).normalize();
    let side = dir.any_orthonormal_vector();
    let points = [
        ("on the segment", a + 0.37 * (b - a)),
        ("at an end", a),
        ("near, beside", a + 0.5 * (b - a) + 0.05 * side),
        ("one radius out", a + 0.2 * (b - a) + r * side),
        ("beyond an end, on the line", b + 0.1 * dir),
        ("before the start, on the line", a - 0.25 * dir),
        ("off the end, diagonal", b + 0.1 * dir + 0.1 * side),
        ("far", a + 0.5 * (b - a) + 0.35 * side),
    ];
    for (name, k) in Kernel::ALL {
        for (where_, p) in points {
            let s = Shape::Segment(Segment::new(a, b).unwrap());
            let got = convolve(*k, &s, r, p).0;
            let want = reference_segment(*k, a, b, r, p);
            assert!(close(got, want), "{name}, {where_}: {got:e} vs {want:e}");
        }
    }
}

#[test]
fn very_short_segment_is_a_point_source_times_its_length() {
    // Degenerate but valid: 10⁻⁶ radii long. The closed form must not cancel itself away.
    let r = 0.2;
    let a = DVec3::new(0.1, 0.0, 0.0);
    let b = a + DVec3::new(0.0, 2e-7, 0.0);
    for (name, k) in Kernel::ALL {
        for p in [a + DVec3::new(0.0, 0.0, 0.1), a + DVec3::new(0.3, 0.1, 0.0), a] {
            let s = Shape::Segment(Segment::new(a, b).unwrap());
            let got = convolve(*k, &s, r, p).0;
            let want = reference_segment(*k, a, b, r, p);
            assert!(close(got, want), "{name}: {got:e} vs {want:e}");
            // …and equals a point source weighted by length/(r·norm), to first order.
            let point =
                k.value((p - 0.5 * (a + b)).length_squared() / (r * r)) * 1e-6 / k.line_norm();
            assert!((got - point).abs() <= 1e-6 * point, "{name}: {got:e} vs point {point:e}");
        }
    }
}

#[test]
fn triangle_quadrature_equals_reference() {
    let t = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(0.6, 0.1, 0.0), DVec3::new(0.2, 0.5, 0.1)];
    let r = 0.12;
    let poly = Polygon::triangle(t[0], t[1], t[2]).unwrap();
    let n = poly.normal();
    let c = (t[0] + t[1] + t[2]) / 3.0;
    let points = [
        ("centroid, in the plane", c),
        ("above the centroid", c + 0.08 * n),
        ("one radius below", c - r * n),
        ("at a vertex", t[1]),
        ("on an edge", 0.5 * (t[0] + t[1])),
        (
            "in the plane, outside near an edge",
            0.5 * (t[0] + t[1]) + 0.03 * (t[0] + t[1] - 2.0 * t[2]).normalize(),
        ),
        ("on an edge's line, outside", t[0] + 1.3 * (t[1] - t[0])),
        ("near a vertex, above", t[2] + 0.02 * n + DVec3::new(0.01, 0.0, 0.0)),
        ("far", c + 0.3 * n + DVec3::new(0.2, 0.0, 0.0)),
    ];
    // Not the sinc: the field does not convolve polygons with it, and the nested reference
    // over its rings takes seconds in debug; its polygon route is the B-spline's, tested here.
    for (name, k) in Kernel::ALL.iter().filter(|(_, k)| k.convolves_extended()) {
        for (where_, p) in points {
            let got = convolve(*k, &Shape::Polygon(poly.clone()), r, p).0;
            let want = reference_triangle(*k, t, r, p);
            assert!(close(got, want), "{name}, {where_}: {got:e} vs {want:e}");
        }
    }
}

#[test]
fn non_convex_polygon_equals_its_triangles() {
    // An L-shaped hexagon in a tilted plane; the reference integrates its four triangles.
    let frame = glam::DMat3::from_euler(glam::EulerRot::XYZ, 0.4, -0.3, 0.2);
    let flat = [(0.0, 0.0), (0.5, 0.0), (0.5, 0.15), (0.15, 0.15), (0.15, 0.4), (0.0, 0.4)];
    let v: Vec<DVec3> = flat.iter().map(|&(x, y)| frame * DVec3::new(x, y, 0.0)).collect();
    let tris = [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]];
    let poly = Polygon::new(v.clone()).unwrap();
    let r = 0.1;
    let n = poly.normal();
    let points = [
        frame * DVec3::new(0.3, 0.3, 0.0),  // in the notch, in the plane
        frame * DVec3::new(0.3, 0.3, 0.05), // in the notch, above
        frame * DVec3::new(0.07, 0.07, 0.0),
        frame * DVec3::new(0.15, 0.15, 0.0) + 0.1 * n, // above the reflex vertex
        frame * DVec3::new(0.8, -0.2, 0.1),
    ];
    // Not the sinc: the field does not convolve polygons with it, and the nested reference
    // over its rings takes seconds in debug; its polygon route is the B-spline's, tested here.
    for (name, k) in Kernel::ALL.iter().filter(|(_, k)| k.convolves_extended()) {
        for p in points {
            let got = convolve(*k, &Shape::Polygon(poly.clone()), r, p).0;
            let want: f64 = tris
                .iter()
                .map(|t| reference_triangle(*k, [v[t[0]], v[t[1]], v[t[2]]], r, p))
                .sum();
            assert!(close(got, want), "{name} at {p}: {got:e} vs {want:e}");
        }
    }
}

#[test]
fn superposition_split_segment_equals_whole() {
    let a = DVec3::new(-0.4, 0.0, 0.1);
    let b = DVec3::new(0.6, 0.2, -0.1);
    let r = 0.1;
    for (name, k) in Kernel::ALL {
        for f in [0.1, 0.5, 0.77] {
            let m = a + f * (b - a);
            for p in [
                m,
                m + DVec3::new(0.0, 0.05, 0.05),
                a + DVec3::new(0.0, 0.12, 0.0),
                DVec3::new(0.3, -0.1, 0.2),
            ] {
                let whole = convolve(*k, &Shape::Segment(Segment::new(a, b).unwrap()), r, p);
                let left = convolve(*k, &Shape::Segment(Segment::new(a, m).unwrap()), r, p);
                let right = convolve(*k, &Shape::Segment(Segment::new(m, b).unwrap()), r, p);
                assert!(
                    (whole.0 - left.0 - right.0).abs() < 1e-12,
                    "{name}: {} vs {}",
                    whole.0,
                    left.0 + right.0
                );
                assert!((whole.1 - left.1 - right.1).length() < 1e-10, "{name}: gradients");
            }
        }
    }
}

#[test]
fn triangles_add_up_to_their_polygon() {
    // Superposition for 2-D elements: a square equals its two triangles.
    let q = [DVec3::ZERO, DVec3::X * 0.4, DVec3::new(0.4, 0.4, 0.0), DVec3::Y * 0.4];
    let square = Shape::Polygon(Polygon::new(q.to_vec()).unwrap());
    let t1 = Shape::Polygon(Polygon::triangle(q[0], q[1], q[2]).unwrap());
    let t2 = Shape::Polygon(Polygon::triangle(q[0], q[2], q[3]).unwrap());
    for (name, k) in Kernel::ALL {
        for p in [
            DVec3::new(0.2, 0.2, 0.0),
            DVec3::new(0.2, 0.2, 0.1),
            DVec3::new(0.1, 0.1, 0.0),
            DVec3::new(0.5, 0.3, 0.05),
        ] {
            let (s, a, b) = (
                convolve(*k, &square, 0.1, p),
                convolve(*k, &t1, 0.1, p),
                convolve(*k, &t2, 0.1, p),
            );
            assert!((s.0 - a.0 - b.0).abs() < 1e-12, "{name} at {p}: {} vs {}", s.0, a.0 + b.0);
            assert!((s.1 - a.1 - b.1).length() < 1e-9, "{name} at {p}");
        }
    }
}

#[test]
fn long_segment_and_large_polygon_have_their_surface_at_one_radius() {
    let r = 0.1;
    let seg = Shape::Segment(
        Segment::new(DVec3::new(-5.0, 0.0, 0.0), DVec3::new(5.0, 0.0, 0.0)).unwrap(),
    );
    let big = Shape::Polygon(
        Polygon::new(vec![
            DVec3::new(-5.0, -5.0, 0.0),
            DVec3::new(5.0, -5.0, 0.0),
            DVec3::new(5.0, 5.0, 0.0),
            DVec3::new(-5.0, 5.0, 0.0),
        ])
        .unwrap(),
    );
    for (name, k) in Kernel::ALL {
        let v = convolve(*k, &seg, r, DVec3::new(0.3, 0.0, r)).0;
        assert!((v - 0.5).abs() < 1e-9, "{name}: segment {v}");
        let v = convolve(*k, &big, r, DVec3::new(0.3, 0.2, r)).0;
        assert!((v - 0.5).abs() < 1e-9, "{name}: polygon {v}");
        // The end of a Gaussian segment is on the surface: half the plateau (DIS §5.6.5).
        if *k == Kernel::Gaussian {
            let v = convolve(*k, &seg, r, DVec3::new(5.0, 0.0, 0.0)).0;
            assert!((v - 0.5).abs() < 1e-12, "end {v}");
        }
    }
}

#[test]
fn convolution_gradients_match_central_differences() {
    let shapes = [
        Shape::Point(DVec3::new(0.1, 0.0, 0.0)),
        Shape::Segment(
            Segment::new(DVec3::new(-0.2, 0.0, 0.0), DVec3::new(0.3, 0.1, 0.0)).unwrap(),
        ),
        Shape::Polygon(
            Polygon::triangle(DVec3::ZERO, DVec3::new(0.4, 0.0, 0.1), DVec3::new(0.0, 0.3, 0.0))
                .unwrap(),
        ),
    ];
    let points = [
        DVec3::new(0.05, 0.05, 0.05),
        DVec3::new(0.2, -0.1, 0.08),
        DVec3::new(-0.15, 0.1, -0.05),
        DVec3::new(0.3, 0.2, 0.15),
    ];
    for (name, k) in Kernel::ALL {
        for s in &shapes {
            for p in points {
                let (_, g) = convolve(*k, s, 0.12, p);
                let h = 1e-6;
                let fd = DVec3::new(
                    convolve(*k, s, 0.12, p + DVec3::X * h).0
                        - convolve(*k, s, 0.12, p - DVec3::X * h).0,
                    convolve(*k, s, 0.12, p + DVec3::Y * h).0
                        - convolve(*k, s, 0.12, p - DVec3::Y * h).0,
                    convolve(*k, s, 0.12, p + DVec3::Z * h).0
                        - convolve(*k, s, 0.12, p - DVec3::Z * h).0,
                ) / (2.0 * h);
                assert!(
                    (g - fd).length() <= 1e-6 * (1.0 + g.length()),
                    "{name} {s:?} at {p}: {g} vs {fd}"
                );
            }
        }
    }
}

/// The fast polygon paths (the Gaussian's edges by `erf`s, the polynomial kernels' wedges in
/// closed form, the winding angle counted by crossings) against every edge integrated by
/// adaptive quadrature with the angles summed from arc tangents.
fn polygon_fast_path_equals_adaptive_quadrature(kernel: Kernel) {
    use skelform_skeleton::convolution::convolve_adaptive;
    // The trapezoid of fig. 6.3 and a thin sliver, at points near, on and far, including
    // points on edges' lines (h = 0), at vertices and beyond the kernel's reach.
    let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
    let shapes = [
        Polygon::new(vec![v(0.0, 0.0), v(0.5, 0.0), v(0.4, 0.3), v(0.1, 0.3)]).unwrap(),
        Polygon::triangle(v(0.0, 0.0), v(1.0, 0.01), v(0.5, 0.03)).unwrap(),
    ];
    let r = 0.1;
    let mut worst: f64 = 0.0;
    let mut compare = |shape: &Shape, p: DVec3| {
        let (a, ga) = convolve(kernel, shape, r, p);
        let (b, gb) = convolve_adaptive(kernel, shape, r, p);
        // Relative 1e-6; below 1e-15 of the plateau (far beyond the Gaussian's cut-off at
        // 2^-40) both are rounding noise.
        assert!((a - b).abs() <= 1e-6 * b.abs() + 1e-15, "{kernel:?} at {p}: {a:e} vs {b:e}");
        if b.abs() > 1e-12 {
            worst = worst.max((a - b).abs() / b.abs());
        }
        assert!((ga - gb).length() <= 1e-6 * gb.length() + 1e-12, "{kernel:?}: ∇ at {p}");
    };
    for poly in &shapes {
        let shape = Shape::Polygon(poly.clone());
        for i in -4..=14 {
            for j in -4..=8 {
                for z in [0.0, 1e-9, 0.03, 0.1, 0.25, 0.55] {
                    compare(&shape, DVec3::new(0.05 * i as f64, 0.05 * j as f64, z));
                }
            }
        }
        // Next to the vertices and across the edges' lines, where the crossing count and
        // the wedges' orientation must agree.
        let vs = poly.vertices();
        for (k, vtx) in vs.iter().enumerate() {
            let next = vs[(k + 1) % vs.len()];
            let along = (next - *vtx).normalize();
            let across = DVec3::Z.cross(along);
            for d in [0.0, 1e-14, -1e-14, 1e-10, -1e-10, 1e-7, -1e-7, 1e-4, -1e-4] {
                for t in [-0.02, -1e-9, 0.0, 1e-9, 0.3] {
                    for z in [0.0, 0.05] {
                        compare(&shape, *vtx + t * (next - *vtx) + d * across + z * DVec3::Z);
                        compare(&shape, *vtx + t * along + d * across + z * DVec3::Z);
                    }
                }
            }
        }
    }
    println!("{kernel:?}: worst relative difference {worst:.2e}");
}

#[test]
fn gaussian_polygon_fast_path_equals_adaptive_quadrature() {
    polygon_fast_path_equals_adaptive_quadrature(Kernel::Gaussian);
}

#[test]
fn polynomial_kernels_closed_form_polygon_equals_adaptive_quadrature() {
    polygon_fast_path_equals_adaptive_quadrature(Kernel::Wyvill);
    polygon_fast_path_equals_adaptive_quadrature(Kernel::Triweight);
}

/// Polygon gradients skip the edges whose lines lie beyond a kernel of finite support, and
/// every edge where the polygon's plane does: the gradient must still be the derivative of
/// the value (which computes every edge), at points that see one edge of a large polygon
/// and not the others, across the edge of the plane's reach, and zero beyond it.
#[test]
fn polygon_gradients_skipping_out_of_reach_edges_match_central_differences() {
    let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
    // A large pentagon against r = 0.1 (reach 0.2 for the Wyvill kernel).
    let poly = Polygon::new(vec![v(0.0, 0.0), v(1.0, 0.0), v(1.2, 0.6), v(0.5, 1.0), v(-0.2, 0.6)])
        .unwrap();
    let shape = Shape::Polygon(poly);
    let r = 0.1;
    for k in [Kernel::Wyvill, Kernel::Triweight, Kernel::BSpline] {
        let reach = k.support() * r;
        let mut points = Vec::new();
        for x in [0.05, 0.5, 0.95] {
            for y in [-0.15, -0.05, 0.03, 0.1, 0.3] {
                for z in [0.0, 0.04, 0.5 * reach, 0.9 * reach, 0.999 * reach] {
                    points.push(DVec3::new(x, y, z));
                }
            }
        }
        for p in points {
            let (f, g) = convolve(k, &shape, r, p);
            let h = 1e-6;
            let at = |d: DVec3| convolve(k, &shape, r, p + d).0;
            let fd = DVec3::new(
                at(DVec3::X * h) - at(-DVec3::X * h),
                at(DVec3::Y * h) - at(-DVec3::Y * h),
                at(DVec3::Z * h) - at(-DVec3::Z * h),
            ) / (2.0 * h);
            assert!(
                (g - fd).length() <= 1e-6 * (1.0 + g.length()),
                "{k:?} at {p} (value {f}): {g} vs {fd}"
            );
        }
        for z in [1.0001 * reach, 2.0 * reach, -1.5 * reach] {
            let (f, g) = convolve(k, &shape, r, DVec3::new(0.5, 0.4, z));
            assert_eq!((f, g), (0.0, DVec3::ZERO), "{k:?} beyond the plane's reach, z = {z}");
        }
    }
}
