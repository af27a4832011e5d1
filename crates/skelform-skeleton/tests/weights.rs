//! Per-vertex weights and weight images on polygons (DIS §6.4) against numerical
//! integration, finite differences and the raster-image method.

use std::sync::Arc;

use glam::{DVec2, DVec3};
use skelform_field::Field;
use skelform_skeleton::convolution::{convolve, convolve_weighted};
use skelform_skeleton::{
    Blend, Element, Kernel, Polygon, PolygonMethod, Shape, Skeleton, SkeletonError, SkeletonField,
    WeightImage,
};

const KERNELS: [Kernel; 4] = [Kernel::Gaussian, Kernel::Wyvill, Kernel::Triweight, Kernel::BSpline];

/// A muscle-like hexagon (fig. 6.11: tendon, bulge, tendon) in a tilted plane, with
/// weights thin at the tendons.
fn muscle() -> (Polygon, Vec<f64>) {
    let flat = [(-1.0, 0.0), (-0.3, -0.35), (0.4, -0.3), (1.0, 0.0), (0.35, 0.3), (-0.35, 0.35)];
    let (u, v) = (DVec3::new(1.0, 0.0, 0.2).normalize(), DVec3::new(0.0, 1.0, -0.1).normalize());
    let o = DVec3::new(0.1, -0.2, 0.3);
    let poly = Polygon::new(flat.iter().map(|&(x, y)| o + x * u + y * v).collect()).unwrap();
    (poly, vec![0.3, 1.0, 1.2, 0.25, 0.9, 1.1])
}

/// `∫_P w(u)·k(|p − u|/r) du / (r² · area_norm)` by brute force: every fan triangle from
/// the vertex average (where the weight is the mean) split into `m²` small triangles, each
/// integrated with a Gauss–Legendre product rule through the Duffy map.
fn reference(kernel: Kernel, poly: &Polygon, weights: &[f64], r: f64, p: DVec3) -> f64 {
    // 16-point Gauss-Legendre on [0, 1], by Newton iteration on P16.
    let n = 16;
    let mut nodes = Vec::new();
    for i in 1..=n {
        let mut x = (std::f64::consts::PI * (i as f64 - 0.25) / (n as f64 + 0.5)).cos();
        let mut dp = 0.0;
        for _ in 0..100 {
            let (mut p0, mut p1) = (1.0, x);
            for k in 2..=n {
                let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                p0 = p1;
                p1 = p2;
            }
            dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
            let dx = p1 / dp;
            x -= dx;
            if dx.abs() < 1e-16 {
                break;
            }
        }
        nodes.push((0.5 * (1.0 - x), 1.0 / ((1.0 - x * x) * dp * dp)));
    }
    let verts = poly.vertices();
    let k = verts.len();
    let c = poly.origin();
    let wc = weights.iter().sum::<f64>() / k as f64;
    let m = 24;
    let mut total = 0.0;
    for i in 0..k {
        let (a, b) = (verts[i], verts[(i + 1) % k]);
        let (wa, wb) = (weights[i], weights[(i + 1) % k]);
        let at =
            |s: f64, t: f64| (c + s * (a - c) + t * (b - c), wc + s * (wa - wc) + t * (wb - wc));
        let area2 = (a - c).cross(b - c).length();
        let h = 1.0 / m as f64;
        for si in 0..m {
            for ti in 0..m - si {
                // Up and (when it fits) down triangles of the subdivision, in (s, t).
                let mut tris = vec![[(si, ti), (si + 1, ti), (si, ti + 1)]];
                if ti + si + 1 < m {
                    tris.push([(si + 1, ti), (si + 1, ti + 1), (si, ti + 1)]);
                }
                for tri in tris {
                    let q = tri.map(|(x, y)| DVec2::new(x as f64 * h, y as f64 * h));
                    for &(x, wx) in &nodes {
                        for &(y, wy) in &nodes {
                            // Duffy: (x, y) in the square to the triangle, Jacobian x.
                            let st = q[0] + x * (q[1] - q[0]) + x * y * (q[2] - q[1]);
                            let (u, w) = at(st.x, st.y);
                            let s2 = (p - u).length_squared() / (r * r);
                            total += wx * wy * x * w * kernel.value(s2) * area2 * h * h;
                        }
                    }
                }
            }
        }
    }
    total / (r * r * kernel.area_norm())
}

fn probes(poly: &Polygon) -> Vec<DVec3> {
    let (e1, e2, n) = poly.frame();
    let c = poly.origin();
    let mut v = Vec::new();
    for &(x, y) in &[(0.0, 0.0), (-0.8, 0.05), (0.7, -0.1), (0.2, 0.33), (1.1, 0.1), (-0.2, -0.6)] {
        for z in [0.0, 0.1, 0.25, 0.45] {
            v.push(c + x * e1 + y * e2 + z * n);
        }
    }
    v
}

#[test]
fn weighted_polygon_matches_numerical_integration_for_every_kernel() {
    let (poly, w) = muscle();
    let r = 0.3;
    for kernel in KERNELS {
        let mut worst: f64 = 0.0;
        for p in probes(&poly) {
            let (got, _) = convolve_weighted(kernel, &poly, &w, r, p).unwrap();
            let want = reference(kernel, &poly, &w, r, p);
            worst = worst.max((got - want).abs());
        }
        println!("{}: max |closed form − quadrature| = {worst:.2e}", kernel.name());
        // The reference's own error is what limits this: the kernels with a support are
        // only C¹ or C² where it ends, which a product rule converges to slowly.
        assert!(worst < 2e-6, "{}: {worst}", kernel.name());
    }
}

#[test]
fn weighted_gradient_matches_finite_differences() {
    let (poly, w) = muscle();
    let r = 0.3;
    for kernel in KERNELS {
        let mut worst: f64 = 0.0;
        for p in probes(&poly) {
            let (_, g) = convolve_weighted(kernel, &poly, &w, r, p).unwrap();
            // Not smaller: near the fan's centre, where q is close to a vertex of every fan
            // triangle, each triangle's value carries the ~10⁻¹² error of its edge rule,
            // which a step of 10⁻⁵ would amplify to 4·10⁻⁷.
            let h = 1e-4;
            for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
                let f = |q: DVec3| convolve_weighted(kernel, &poly, &w, r, q).unwrap().0;
                let fd = (f(p + h * axis) - f(p - h * axis)) / (2.0 * h);
                worst = worst.max((fd - g.dot(axis)).abs());
            }
        }
        println!("{}: max |gradient − central difference| = {worst:.2e}", kernel.name());
        // What remains is the central difference's own truncation error, h²·f'''/6.
        assert!(worst < 5e-7, "{}: {worst}", kernel.name());
    }
}

#[test]
fn uniform_weights_scale_the_unweighted_integral() {
    let (poly, _) = muscle();
    for kernel in KERNELS {
        for p in probes(&poly) {
            let (v, g) = convolve(kernel, &Shape::Polygon(poly.clone()), 0.3, p);
            let (wv, wg) = convolve_weighted(kernel, &poly, &[0.7; 6], 0.3, p).unwrap();
            assert!((wv - 0.7 * v).abs() < 1e-12, "{}: {wv} vs {}", kernel.name(), 0.7 * v);
            assert!((wg - 0.7 * g).length() < 1e-11, "{}", kernel.name());
        }
    }
}

fn field(e: Element, kernel: Kernel) -> SkeletonField {
    let mut s = Skeleton::new();
    s.push(e).unwrap();
    SkeletonField::new(&s, Blend::Convolution(kernel)).unwrap()
}

/// The surface's half-thickness along the polygon's normal at an in-plane point: where the
/// field crosses 0 (bisection).
fn thickness(f: &SkeletonField, poly: &Polygon, x: f64, y: f64) -> f64 {
    let (e1, e2, n) = poly.frame();
    let at = poly.origin() + x * e1 + y * e2;
    let (mut lo, mut hi) = (0.0, 1.0);
    if f.eval(at) >= 0.0 {
        return 0.0;
    }
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if f.eval(at + mid * n) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

#[test]
fn weights_taper_the_surface_and_the_image_method_agrees() {
    // A long rectangle, weight 1 at the left end and 0.3 at the right: the right end thins
    // (fig. 6.12's tendons).
    let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
    let poly = Polygon::new(vec![v(-1.0, -0.3), v(1.0, -0.3), v(1.0, 0.3), v(-1.0, 0.3)]).unwrap();
    let w = vec![1.0, 0.6, 0.6, 1.0];
    let make = |m: PolygonMethod| {
        let e = Element::new(Shape::Polygon(poly.clone()), 0.1)
            .unwrap()
            .with_vertex_weights(w.clone())
            .unwrap()
            .with_polygon_method(m)
            .unwrap();
        field(e, Kernel::Gaussian)
    };
    let exact = make(PolygonMethod::Exact);
    let image = make(PolygonMethod::Image { resolution: 160 });
    // The polygon's frame: e1 from the centre towards vertex 0, so x runs right to left.
    let (e1, _, _) = poly.frame();
    let sx = if e1.x < 0.0 { -1.0 } else { 1.0 };
    let left = thickness(&exact, &poly, -0.6 * sx, 0.0);
    let right = thickness(&exact, &poly, 0.6 * sx, 0.0);
    println!("half-thickness: weight 0.92 side {left:.4}, weight 0.68 side {right:.4}");
    assert!(left > 0.08 && left < 0.1, "{left}");
    assert!(right > 0.02 && right < 0.75 * left, "{right} vs {left}");
    let mut worst: f64 = 0.0;
    for i in 0..=20 {
        for z in [0.0, 0.05, 0.1, 0.15] {
            let p = DVec3::new(-1.2 + 2.4 * i as f64 / 20.0, 0.1, z);
            worst = worst.max((exact.eval(p) - image.eval(p)).abs());
        }
    }
    println!("image method (160 px) vs exact weighted: max density difference {worst:.2e}");
    assert!(worst < 5e-3, "{worst}");
}

#[test]
fn weight_image_scales_the_polygon_image() {
    let v = |x: f64, y: f64| DVec3::new(x, y, 0.0);
    let poly = Polygon::new(vec![v(-1.0, -0.3), v(1.0, -0.3), v(1.0, 0.3), v(-1.0, 0.3)]).unwrap();
    let plain = || Element::new(Shape::Polygon(poly.clone()), 0.1).unwrap();
    // A uniform image of 0.5 halves the density, like a strength of 0.5.
    let half = Arc::new(WeightImage::new(2, 2, vec![0.5; 4]).unwrap());
    let weighted = field(plain().with_weight_image(half).unwrap(), Kernel::Gaussian);
    assert!(matches!(
        plain().with_weight_image(Arc::new(WeightImage::new(1, 1, vec![1.0]).unwrap())),
        Ok(e) if e.polygon_method() == PolygonMethod::Image { resolution: 80 }
    ));
    let halved = field(
        plain()
            .with_strength(0.5)
            .unwrap()
            .with_polygon_method(PolygonMethod::Image { resolution: 80 })
            .unwrap(),
        Kernel::Gaussian,
    );
    for p in [v(0.0, 0.0), v(0.5, 0.1), v(0.9, 0.25)] {
        let p = p + DVec3::Z * 0.05;
        assert!((weighted.eval(p) - halved.eval(p)).abs() < 1e-12);
    }
    // An image with a ramp across it (columns along the first edge): the image method with the ramp
    // against per-vertex weights of the same ramp, exact.
    // The image's columns run along the first edge, here +x: a ramp in x.
    let xs: Vec<f64> = poly.vertices().iter().map(|q| q.x).collect();
    let (lo, hi) =
        xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), x| (l.min(*x), h.max(*x)));
    let ramp: Vec<f64> = (0..64).map(|i| 0.2 + 0.8 * (i as f64 + 0.5) / 64.0).collect();
    let img = Arc::new(WeightImage::new(64, 1, ramp).unwrap());
    let by_image = field(plain().with_weight_image(img).unwrap(), Kernel::Gaussian);
    let w: Vec<f64> = xs.iter().map(|x| 0.2 + 0.8 * (x - lo) / (hi - lo)).collect();
    // Both by the image method, so that only the mapping of the image onto the polygon
    // and its sampling differ.
    let by_vertex = field(
        plain()
            .with_vertex_weights(w)
            .unwrap()
            .with_polygon_method(PolygonMethod::Image { resolution: 80 })
            .unwrap(),
        Kernel::Gaussian,
    );
    let mut worst: f64 = 0.0;
    for i in 0..=20 {
        let p = v(-0.9 + 1.8 * i as f64 / 20.0, 0.0) + DVec3::Z * 0.08;
        worst = worst.max((by_image.eval(p) - by_vertex.eval(p)).abs());
    }
    println!("weight-image ramp vs per-vertex ramp (image method, 80 px): {worst:.2e}");
    assert!(worst < 1e-3, "{worst}");
    // The exact method cannot apply an image.
    let e = plain().with_weight_image(Arc::new(WeightImage::new(1, 1, vec![1.0]).unwrap()));
    assert_eq!(
        e.unwrap().with_polygon_method(PolygonMethod::Exact).err(),
        Some(SkeletonError::WeightImageNeedsImageMethod)
    );
}

#[test]
fn changed_weights_are_an_incremental_change_of_their_polygon() {
    let (poly, w) = muscle();
    let make = |w: Vec<f64>| {
        field(
            Element::new(Shape::Polygon(poly.clone()), 0.1)
                .unwrap()
                .with_vertex_weights(w)
                .unwrap(),
            Kernel::Gaussian,
        )
    };
    let old = make(w.clone());
    assert_eq!(make(w.clone()).changes_since(&old), Ok(vec![]));
    let mut w2 = w;
    w2[0] = 0.9;
    assert_eq!(make(w2).changes_since(&old).map(|b| b.len()), Ok(2));
}

#[test]
fn weights_need_a_polygon_and_convolution() {
    let seg = Element::new(
        Shape::Segment(skelform_skeleton::Segment::new(DVec3::ZERO, DVec3::X).unwrap()),
        0.1,
    )
    .unwrap();
    assert_eq!(
        seg.with_vertex_weights(vec![1.0, 1.0]).err(),
        Some(SkeletonError::WeightsNeedPolygon)
    );
    let (poly, w) = muscle();
    let e = Element::new(Shape::Polygon(poly), 0.1).unwrap().with_vertex_weights(w).unwrap();
    let mut s = Skeleton::new();
    s.push(e).unwrap();
    assert!(matches!(
        SkeletonField::new(&s, Blend::Sum(Kernel::Gaussian)),
        Err(SkeletonError::WeightsNeedConvolution(_))
    ));
}
