//! Skeletal fields through the grid polygonizer: radii measured on meshes, components
//! counted by the checker.

use glam::DVec3;
use skelform_field::Aabb;
use skelform_mesh::Mesh;
use skelform_mesh::check::check;
use skelform_polygonize::LatticeOptions;
use skelform_polygonize::grid::{Options, Resolution, polygonize};
use skelform_skeleton::{Blend, GroupId, Kernel, Skeleton, SkeletonField};

const R: f64 = 0.1;

fn mesh(f: &SkeletonField, domain: Aabb, cell: f64) -> Mesh {
    let lattice =
        LatticeOptions { domain, resolution: Resolution::Cell(cell), ..Default::default() };
    let opts = Options { lattice, ..Default::default() };
    polygonize(f, &opts).unwrap().0
}

/// Mean distance from the x axis of the mesh vertices within `half` of `x0`.
fn radius_at(m: &Mesh, x0: f64, half: f64) -> f64 {
    let rs: Vec<f64> = m
        .positions
        .iter()
        .filter(|p| (p[0] as f64 - x0).abs() < half)
        .map(|p| (p[1] as f64).hypot(p[2] as f64))
        .collect();
    assert!(rs.len() > 20, "too few vertices near x = {x0}");
    rs.iter().sum::<f64>() / rs.len() as f64
}

fn axis_domain() -> Aabb {
    Aabb::new(DVec3::new(-0.75, -0.2, -0.2), DVec3::new(0.75, 0.2, 0.2))
}

/// A straight polyline of three collinear segments from −0.6 to 0.6, joints at ±0.2.
fn polyline() -> Skeleton {
    let mut s = Skeleton::new();
    let pts = [-0.6, -0.2, 0.2, 0.6].map(|x| DVec3::new(x, 0.0, 0.0));
    s.add_polyline(&pts, R, GroupId::DEFAULT).unwrap();
    s
}

#[test]
fn polyline_convolution_has_no_bulge_at_its_joints() {
    let f = SkeletonField::new(&polyline(), Blend::Convolution(Kernel::Gaussian)).unwrap();
    let m = mesh(&f, axis_domain(), 0.01);
    let report = check(&m);
    assert_eq!(report.components.len(), 1);
    assert!(report.components[0].is_closed_manifold());
    // Stated tolerance: the radius along the middle, joints included, is r within 1 %.
    for x in [-0.3, -0.2, -0.1, 0.0, 0.1, 0.2, 0.3] {
        let r = radius_at(&m, x, 0.006);
        assert!((r - R).abs() < 0.01 * R, "radius {r} at x = {x}");
    }
}

#[test]
fn summed_distance_kernels_bulge_at_the_same_joints() {
    // Soft objects on the distance to each segment: at a joint both neighbours contribute
    // fully, so the density doubles there and the surface swells (to √2·r for the Gaussian).
    let f = SkeletonField::new(&polyline(), Blend::Sum(Kernel::Gaussian)).unwrap();
    let m = mesh(&f, axis_domain(), 0.01);
    let joint = radius_at(&m, 0.2, 0.006);
    let middle = radius_at(&m, 0.0, 0.006);
    assert!(joint > 1.3 * R, "joint radius {joint}");
    assert!(joint > 1.25 * middle, "joint {joint} vs middle {middle}");
}

#[test]
fn summed_point_sources_are_lumpy_where_segments_are_smooth() {
    // The same line as point sources two radii apart, each weighted by its share of the line
    // (spacing/(r·line_norm)), the discrete convolution of DIS eq. 5.19 / fig. 5.57.
    let spacing = 2.0 * R;
    let w = spacing / (R * Kernel::Gaussian.line_norm());
    let mut s = Skeleton::new();
    let mut x = -0.6;
    while x <= 0.6 + 1e-9 {
        let i = s.add_point(DVec3::new(x, 0.0, 0.0), R, GroupId::DEFAULT).unwrap();
        s.set_strength(i, w).unwrap();
        x += spacing;
    }
    let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
    let m = mesh(&f, axis_domain(), 0.01);
    let at_point = radius_at(&m, 0.0, 0.006);
    let between = radius_at(&m, 0.1, 0.006);
    assert!(at_point > 1.04 * between, "at a source {at_point}, between {between}");
}

#[test]
fn fingers_in_two_groups_are_two_components_in_one_group_one() {
    for same in [true, false] {
        let mut s = Skeleton::new();
        let g1 = s.add_group("finger1").unwrap();
        let g2 = if same { g1 } else { s.add_group("finger2").unwrap() };
        let y = 1.1 * R; // surfaces 0.2 r apart
        s.add_segment(DVec3::new(-0.4, y, 0.0), DVec3::new(0.4, y, 0.0), R, g1).unwrap();
        s.add_segment(DVec3::new(-0.4, -y, 0.0), DVec3::new(0.4, -y, 0.0), R, g2).unwrap();
        let f = SkeletonField::new(&s, Blend::Convolution(Kernel::Gaussian)).unwrap();
        let domain = Aabb::new(DVec3::new(-0.55, -0.3, -0.15), DVec3::new(0.55, 0.3, 0.15));
        let m = mesh(&f, domain, 0.005);
        let report = check(&m);
        let want = if same { 1 } else { 2 };
        assert_eq!(report.components.len(), want, "same group: {same}");
        assert!(report.components.iter().all(|c| c.is_closed_manifold() && c.genus == Some(0)));
        if !same {
            // The gap measured on the mesh: no vertex between the fingers' facing surfaces.
            let inner =
                m.positions.iter().map(|p| (p[1] as f64).abs()).fold(f64::INFINITY, f64::min);
            assert!(inner > 0.005, "closest vertex to the mid-plane: {inner}");
        }
    }
}

/// A row of point sources one radius apart along x, from −0.7 to 0.7, each weighted by its
/// share of the line (spacing/(r·line_norm)): the discrete convolution of a segment.
fn row_of_points(kernel: Kernel) -> SkeletonField {
    let w = R / (R * kernel.line_norm());
    let mut s = Skeleton::new();
    for i in -7..=7 {
        let at = DVec3::new(i as f64 * R, 0.0, 0.0);
        let e = s.add_point(at, R, GroupId::DEFAULT).unwrap();
        s.set_strength(e, w).unwrap();
    }
    SkeletonField::new(&s, Blend::Convolution(kernel)).unwrap()
}

#[test]
fn a_row_of_sinc_sources_grows_a_spurious_shell_that_the_gaussian_does_not() {
    // DIS §5.6.8, fig. 5.49: the sinc is not monotone, so the lobes of many sources add up
    // to a second contour away from the skeleton. The Gaussian's row is one tube of radius
    // r; the sinc's is the same tube inside a ring-shaped band (a solid torus around the
    // row, open past its ends) at 3–4 radii, where the sources' second lobes add up to more
    // than ½ (the line integral's secondary maximum, J₀'s at a·d ≈ 7.0, is 1.1 times its
    // value at one radius).
    let domain = Aabb::new(DVec3::new(-1.25, -0.55, -0.55), DVec3::new(1.25, 0.55, 0.55));
    for kernel in [Kernel::Gaussian, Kernel::Sinc] {
        let m = mesh(&row_of_points(kernel), domain, 0.02);
        let report = check(&m);
        assert!(report.components.iter().all(|c| c.is_closed_manifold()), "{kernel:?}");
        let mut genera: Vec<i64> = report.components.iter().filter_map(|c| c.genus).collect();
        genera.sort_unstable();
        let axis = |p: &[f32; 3]| (p[1] as f64).hypot(p[2] as f64);
        let tube = m.positions.iter().filter(|p| axis(p) < 1.5 * R).count();
        let band = m.positions.iter().filter(|p| (3.0 * R..4.5 * R).contains(&axis(p))).count();
        assert_eq!(tube + band, m.positions.len(), "{kernel:?}: a vertex elsewhere");
        assert!(tube > 1000, "{kernel:?}: {tube}");
        if kernel == Kernel::Gaussian {
            assert_eq!(genera, [0], "one tube");
            assert_eq!(band, 0);
        } else {
            assert_eq!(genera, [0, 1], "the tube and the spurious band around it");
            assert!(band > 1000, "{band}");
        }
    }
}
