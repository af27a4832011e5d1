//! The continuation polygonizer: the same surfaces as the grid polygonizer, at a cost that
//! grows with area, with clear reports when propagation is cut short.

use glam::DVec3;
use skelform_field::formula::Formula;
use skelform_field::{Aabb, Field, FnField};
use skelform_mesh::Mesh;
use skelform_mesh::check::{Report, check};
use skelform_polygonize::continuation::{Cells, Options, SeedNote, Stats, Stop, polygonize};
use skelform_polygonize::refine::RootMethod;
use skelform_polygonize::{Error, LatticeOptions, Resolution, Threads, grid};

fn run(field: &dyn Field, domain: Aabb, cell: f64, seeds: &[DVec3], cells: Cells) -> (Mesh, Stats) {
    let lattice =
        LatticeOptions { domain, resolution: Resolution::Cell(cell), ..Default::default() };
    let opts = Options { lattice, seeds: seeds.to_vec(), cells, ..Options::default() };
    polygonize(field, &opts).expect("polygonize")
}

/// `f` run on a pool of `threads` threads.
fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("a pool").install(f)
}

/// The point `k` of `n` evenly spaced round the circle of radius `r` about the z axis, in
/// the plane z = 0.
fn on_circle(r: f64, k: usize, n: usize) -> DVec3 {
    let a = k as f64 * std::f64::consts::TAU / n as f64;
    DVec3::new(r * a.cos(), r * a.sin(), 0.0)
}

fn closed(m: &Mesh, genera: &[i64], what: &str) -> Report {
    let r = check(m);
    assert!(r.is_closed_manifold(), "{what}:\n{r}");
    assert_eq!(r.outward, Some(true), "{what}");
    let mut g: Vec<i64> = r.components.iter().map(|c| c.genus.unwrap()).collect();
    g.sort_unstable();
    assert_eq!(g, genera, "{what}");
    r
}

fn torus() -> Formula {
    Formula::parse("q = sqrt(x^2 + y^2) - 0.6\nq^2 + z^2 - 0.25^2").unwrap()
}

fn torus_distance(p: DVec3) -> f64 {
    ((p.truncate().length() - 0.6).powi(2) + p.z * p.z).sqrt() - 0.25
}

#[test]
fn shapes_are_closed_with_the_right_genus_in_both_variants() {
    let sphere = FnField(|p: DVec3| p.length() - 0.8);
    let double = Formula::parse(
        "l = (sqrt((x + 0.6)^2 + y^2) - 0.5)^2 + z^2 - 0.2^2\nr = (sqrt((x - 0.6)^2 + y^2) - 0.5)^2 + z^2 - 0.2^2\nmin(l, r)",
    )
    .unwrap();
    let wide = Aabb::new(DVec3::new(-1.4, -0.8, -0.4), DVec3::new(1.4, 0.8, 0.4));
    for cells in [Cells::Cubes, Cells::Tetrahedra] {
        for h in [0.3, 0.1, 2.0 / 63.0] {
            let (m, _) = run(&sphere, Aabb::cube(1.0), h, &[DVec3::ZERO], cells);
            closed(&m, &[0], &format!("sphere {cells:?} {h}"));
            let err = m
                .positions
                .iter()
                .map(|p| (DVec3::from_array(p.map(f64::from)).length() - 0.8).abs())
                .fold(0.0, f64::max);
            assert!(err < 0.01 * h, "sphere {cells:?} {h}: {err}");
        }
        let (m, s) = run(&torus(), Aabb::cube(1.0), 0.04, &[DVec3::new(0.6, 0.0, 0.0)], cells);
        closed(&m, &[1], &format!("torus {cells:?}"));
        let err = m
            .positions
            .iter()
            .map(|p| torus_distance(DVec3::from_array(p.map(f64::from))).abs())
            .fold(0.0, f64::max);
        assert!(err < 0.01 * s.cell, "torus {cells:?}: {err}");
        let (m, _) = run(&double, wide, 0.03, &[DVec3::new(-1.1, 0.0, 0.0)], cells);
        closed(&m, &[2], &format!("double torus {cells:?}"));
    }
}

/// The same mesh as the grid polygonizer: the same triangles over the same lattice
/// segments. Vertex positions differ by root finding alone (the grid's regula falsi from
/// the segment's end values; continuation's Newton step from the ends' values and
/// gradients, for a field with an exact gradient as this one), both within a hundredth of
/// the tolerance of the surface, so each vertex is matched to the grid's nearest.
#[test]
fn cube_variant_makes_the_grid_polygonizers_mesh() {
    let f =
        Formula::parse("sin(3*x)*cos(3*y) + sin(3*y)*cos(3*z) + sin(3*z)*cos(3*x) - 0.3").unwrap();
    let domain = Aabb::cube(1.0);
    let h = 2.0 / 40.0;
    let lattice = LatticeOptions { domain, resolution: Resolution::Cell(h), ..Default::default() };
    let gopts = grid::Options { lattice, ..Default::default() };
    let (g, _) = grid::polygonize(&f, &gopts).unwrap();
    // Seed every component the grid mesh has, from one of its vertices.
    let r = check(&g);
    let seeds: Vec<DVec3> = r
        .components
        .iter()
        .map(|c| {
            DVec3::from_array(g.positions[g.triangles[c.first_face][0] as usize].map(f64::from))
        })
        .collect();
    let (m, s) = run(&f, domain, h, &seeds, Cells::Cubes);
    assert_eq!(s.components.len(), r.components.len());
    assert_eq!(m.triangle_count(), g.triangle_count());
    assert_eq!(m.vertex_count(), g.vertex_count());
    let at = |p: &[f32; 3]| DVec3::from_array(p.map(f64::from));
    let bucket = |p: DVec3| (p / h).floor().as_i64vec3().to_array();
    let mut buckets: std::collections::HashMap<[i64; 3], Vec<usize>> = Default::default();
    for (i, p) in g.positions.iter().enumerate() {
        buckets.entry(bucket(at(p))).or_default().push(i);
    }
    // Each continuation vertex to the grid's nearest, within 1e-3 cells, one to one.
    let to_grid: Vec<u32> = m
        .positions
        .iter()
        .map(|p| {
            let (p, b) = (at(p), bucket(at(p)));
            let mut best = (f64::INFINITY, usize::MAX);
            for d in 0..27i64 {
                let k = [b[0] + d % 3 - 1, b[1] + d / 3 % 3 - 1, b[2] + d / 9 - 1];
                for &i in buckets.get(&k).into_iter().flatten() {
                    let d = (at(&g.positions[i]) - p).length();
                    if d < best.0 {
                        best = (d, i);
                    }
                }
            }
            assert!(best.0 < 1e-3 * h, "vertex {p} is {} from the grid's", best.0);
            best.1 as u32
        })
        .collect();
    let mut distinct = to_grid.clone();
    distinct.sort_unstable();
    distinct.dedup();
    assert_eq!(distinct.len(), to_grid.len(), "one to one");
    let canonical = |t: [u32; 3]| {
        let k = (0..3).min_by_key(|&k| t[k]).unwrap_or(0);
        [t[k], t[(k + 1) % 3], t[(k + 2) % 3]]
    };
    let mut a: Vec<_> = g.triangles.iter().map(|&t| canonical(t)).collect();
    let mut b: Vec<_> =
        m.triangles.iter().map(|t| canonical(t.map(|v| to_grid[v as usize]))).collect();
    a.sort_unstable();
    b.sort_unstable();
    assert_eq!(a, b, "the same triangles, wound alike");
}

#[test]
fn tetrahedra_make_more_triangles_within_a_cell_of_the_cubes() {
    let sphere = FnField(|p: DVec3| p.length() - 0.8);
    let (c, _) = run(&sphere, Aabb::cube(1.0), 0.05, &[DVec3::ZERO], Cells::Cubes);
    let (t, _) = run(&sphere, Aabb::cube(1.0), 0.05, &[DVec3::ZERO], Cells::Tetrahedra);
    assert!(
        t.triangle_count() as f64 > 1.5 * c.triangle_count() as f64,
        "{} vs {}",
        t.triangle_count(),
        c.triangle_count()
    );
}

#[test]
fn evaluations_grow_with_area_not_volume() {
    let sphere = FnField(|p: DVec3| p.length() - 0.8);
    let (_, coarse) =
        run(&sphere, Aabb::cube(1.0), 2.0 / 64.0, &[DVec3::new(0.8, 0.0, 0.0)], Cells::Cubes);
    let (_, fine) =
        run(&sphere, Aabb::cube(1.0), 2.0 / 128.0, &[DVec3::new(0.8, 0.0, 0.0)], Cells::Cubes);
    let ratio = fine.corner_evaluations as f64 / coarse.corner_evaluations as f64;
    assert!(
        (3.5..4.6).contains(&ratio),
        "halving the cell multiplied corner evaluations by {ratio}"
    );
    let ratio = fine.evaluations() as f64 / coarse.evaluations() as f64;
    assert!((3.5..4.6).contains(&ratio), "all evaluations: {ratio}");
}

#[test]
fn small_object_in_a_large_domain_is_cheap() {
    let sphere = FnField(|p: DVec3| p.length() - 0.1);
    let domain = Aabb::cube(5.0);
    let h = 0.02;
    let (m, s) = run(&sphere, domain, h, &[DVec3::ZERO], Cells::Cubes);
    closed(&m, &[0], "small sphere");
    let full = skelform_field::grid::Grid::with_cell(&domain, h).unwrap().sample_count();
    assert!(s.evaluations() * 100 <= full, "{} evaluations vs {full} samples", s.evaluations());
}

#[test]
fn the_domain_search_finds_every_component() {
    let f = FnField(|p: DVec3| {
        let a = (p - DVec3::new(-0.6, 0.0, 0.0)).length() - 0.3;
        let b = (p - DVec3::new(0.6, 0.2, 0.0)).length() - 0.25;
        a.min(b)
    });
    let (m, s) = run(&f, Aabb::cube(1.0), 0.04, &[], Cells::Cubes);
    closed(&m, &[0, 0], "two spheres, no seeds");
    assert_eq!(s.components.len(), 2);
    assert!(s.seed_notes.iter().all(|n| matches!(n, SeedNote::SameComponent { .. })));
}

#[test]
fn seeds_of_one_component_are_reported_as_such() {
    let sphere = FnField(|p: DVec3| p.length() - 0.5);
    let seeds = [DVec3::ZERO, DVec3::new(0.5, 0.0, 0.0), DVec3::new(0.9, 0.9, 0.9)];
    let (_, s) = run(&sphere, Aabb::cube(1.0), 0.05, &seeds, Cells::Cubes);
    assert_eq!(s.components.len(), 1);
    assert_eq!(s.seed_notes.len(), 2);
    assert!(s.seed_notes.iter().all(|n| matches!(n, SeedNote::SameComponent { as_seed: 0, .. })));
}

#[test]
fn bad_seeds_get_clear_errors() {
    let plane_far = FnField(|p: DVec3| p.x + 10.0); // no surface in the domain
    let opts = Options {
        lattice: LatticeOptions {
            domain: Aabb::cube(1.0),
            resolution: Resolution::Cell(0.1),
            ..Default::default()
        },
        seeds: vec![DVec3::ZERO],
        ..Options::default()
    };
    let e = polygonize(&plane_far, &opts).unwrap_err();
    assert!(matches!(e, Error::BadSeed { .. }), "{e}");
    assert!(e.to_string().contains("no surface was found"), "{e}");
    let sphere = FnField(|p: DVec3| p.length() - 0.5);
    let opts = Options {
        lattice: LatticeOptions {
            domain: Aabb::cube(1.0),
            resolution: Resolution::Cell(0.1),
            ..Default::default()
        },
        seeds: vec![DVec3::splat(3.0)],
        ..Options::default()
    };
    assert!(polygonize(&sphere, &opts).unwrap_err().to_string().contains("outside the domain"));
    let nan = FnField(|_: DVec3| f64::NAN);
    let opts = Options {
        lattice: LatticeOptions {
            domain: Aabb::cube(1.0),
            resolution: Resolution::Cell(0.1),
            ..Default::default()
        },
        seeds: vec![DVec3::ZERO],
        ..Options::default()
    };
    assert!(polygonize(&nan, &opts).unwrap_err().to_string().contains("NaN"));
    let lattice = LatticeOptions { resolution: Resolution::Cell(0.1), ..Default::default() };
    let opts = Options { lattice, ..Options::default() };
    assert!(matches!(polygonize(&plane_far, &opts).unwrap_err(), Error::NoSurfaceFound { .. }));
}

#[test]
fn nans_in_the_field_do_not_hang_or_panic() {
    let f = FnField(|p: DVec3| if p.x > 0.3 { f64::NAN } else { p.length() - 0.6 });
    let (m, s) = run(&f, Aabb::cube(1.0), 0.05, &[DVec3::new(-0.6, 0.0, 0.0)], Cells::Cubes);
    assert!(s.non_finite > 0);
    assert!(m.triangle_count() > 0);
    let r = check(&m);
    assert_eq!(r.non_manifold_edges, 0);
    assert!(r.consistently_oriented);
}

#[test]
fn stops_at_the_domain_the_budget_and_the_limit_are_reported() {
    let cylinder = FnField(|p: DVec3| (p.x * p.x + p.y * p.y).sqrt() - 0.5);
    let (m, s) = run(&cylinder, Aabb::cube(1.0), 0.1, &[DVec3::ZERO], Cells::Cubes);
    assert_eq!(s.stops, vec![Stop::Domain]);
    let r = check(&m);
    assert!(r.boundary_edges > 0 && r.non_manifold_edges == 0 && r.consistently_oriented);

    let sphere = FnField(|p: DVec3| p.length() - 0.8);
    let opts = Options {
        lattice: LatticeOptions {
            domain: Aabb::cube(1.0),
            resolution: Resolution::Cell(0.02),
            ..Default::default()
        },
        seeds: vec![DVec3::ZERO],
        max_cells: 500,
        ..Options::default()
    };
    let (m, s) = polygonize(&sphere, &opts).unwrap();
    assert_eq!(s.stops, vec![Stop::Budget]);
    assert!(s.cells_visited <= 500);
    assert!(check(&m).boundary_edges > 0);

    // The chapter's unbounded two-tori surface, t1 = t2, with a propagation limit of 7.
    let two_tori = Formula::parse(
        "R = 1; r = R/4\n\
         t1 = (x^2 + y^2 + z^2 + R^2 - r^2)^2 - 4*R^2*(x^2 + y^2)\n\
         t2 = (x^2 + (y + R)^2 + z^2 + R^2 - r^2)^2 - 4*R^2*((y + R)^2 + z^2)\n\
         t1 - t2",
    )
    .unwrap();
    let opts = Options {
        lattice: LatticeOptions {
            domain: Aabb::cube(50.0),
            resolution: Resolution::Cell(0.1),
            ..Default::default()
        },
        seeds: vec![DVec3::new(0.0, -0.5, 0.0)],
        limit: Some(7),
        ..Options::default()
    };
    let (m, s) = polygonize(&two_tori, &opts).unwrap();
    assert_eq!(s.stops, vec![Stop::Limit]);
    assert!(m.triangle_count() > 0);
    assert!(s.cells_visited <= 15 * 15 * 15);
}

#[test]
fn bisection_and_regula_falsi_reach_the_same_surface() {
    let t = torus();
    let mut evals = Vec::new();
    for (root, tol) in
        [(RootMethod::Bisection, 1.0 / 1024.0), (RootMethod::RegulaFalsi, 1.0 / 1024.0)]
    {
        let opts = Options {
            lattice: LatticeOptions {
                domain: Aabb::cube(1.0),
                resolution: Resolution::Cell(2.0 / 100.0),
                tolerance: tol,
                ..Default::default()
            },
            seeds: vec![DVec3::new(0.6, 0.0, 0.0)],
            root,
            ..Options::default()
        };
        let (m, s) = polygonize(&t, &opts).unwrap();
        let err = m
            .positions
            .iter()
            .map(|p| torus_distance(DVec3::from_array(p.map(f64::from))).abs())
            .fold(0.0, f64::max);
        assert!(err < s.cell / 1024.0 * 2.0, "{root:?}: {err}");
        evals.push(s.refine_evaluations);
    }
    assert!(evals[1] < evals[0], "regula falsi needs fewer evaluations: {evals:?}");
}

#[test]
fn same_mesh_on_any_thread_count() {
    let f = torus();
    let go =
        |threads| on_threads(threads, || run(&f, Aabb::cube(1.0), 0.03, &[], Cells::Tetrahedra).0);
    let one = go(1);
    assert!(go(2) == one && go(4) == one);
}

/// Blobs (the sum of `e^(-|p - c|² / r²)` over some centres, a level below one) that melt
/// into each other in some places and stand apart in others: several components, some
/// reached from many seeds, of different sizes, so that the waves differ in size from one
/// another.
fn blobs() -> (impl Field, Vec<DVec3>) {
    let mut state = 7u64;
    let mut next = || {
        state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let centres: Vec<(DVec3, f64)> = (0..24)
        .map(|_| (DVec3::new(next(), next(), next()) * 0.75, 0.08 + 0.07 * (next() + 1.0)))
        .collect();
    let seeds = centres.iter().map(|c| c.0).collect();
    let field = FnField(move |p: DVec3| {
        0.5 - centres.iter().map(|(c, r)| (-(p - *c).length_squared() / (r * r)).exp()).sum::<f64>()
    });
    (field, seeds)
}

/// The requirement: the same mesh, byte for byte (vertex and triangle order, positions
/// and normals), and the same counts, on 1, 2 and 4 threads, from seeds and from the domain
/// search, with cubes and with tetrahedra.
#[test]
fn several_components_give_the_same_mesh_on_1_2_and_4_threads() {
    let (field, seeds) = blobs();
    for (seeds, cells) in [
        (seeds.clone(), Cells::Cubes),
        (Vec::new(), Cells::Cubes),
        (seeds.clone(), Cells::Tetrahedra),
    ] {
        let go =
            |threads| on_threads(threads, || run(&field, Aabb::cube(1.0), 0.02, &seeds, cells));
        let (one, s1) = go(1);
        assert!(s1.components.len() > 3, "{:?}", s1.components);
        assert!(one.triangle_count() > 10_000 && !one.normals.is_empty());
        for threads in [2, 4] {
            let (m, s) = go(threads);
            let what = format!("{cells:?}, {} seeds, {threads} threads", seeds.len());
            assert_eq!(m.positions, one.positions, "{what}");
            assert_eq!(m.triangles, one.triangles, "{what}");
            assert_eq!(m.normals, one.normals, "{what}");
            assert_eq!(s.components, s1.components, "{what}");
            assert_eq!(s.seed_notes, s1.seed_notes, "{what}");
            assert_eq!(s.evaluations(), s1.evaluations(), "{what}");
            assert_eq!(s.corner_evaluations, s1.corner_evaluations, "{what}");
        }
    }
}

/// With a field that has an exact gradient (corner gradients, Newton roots, normals from
/// the root's evaluation), several components from seeds, one of them reached from two, and
/// from the domain search: the same mesh and counts on 1, 2 and 4 threads.
#[test]
fn gradient_roots_give_the_same_mesh_on_1_2_and_4_threads() {
    let f = Formula::parse(
        "a = sqrt((x - 0.5)^2 + y^2 + z^2) - 0.3\nb = sqrt((x + 0.45)^2 + y^2 + z^2) - 0.25\nc = sqrt(x^2 + (y - 0.6)^2 + z^2) - 0.2 + 0.02*sin(20*x)\nmin(a, min(b, c))",
    )
    .unwrap();
    assert!(f.has_exact_gradient());
    let seeds = [
        DVec3::new(0.5, 0.0, 0.0),
        DVec3::new(-0.45, 0.0, 0.0),
        DVec3::new(0.55, 0.1, 0.0),
        DVec3::new(0.0, 0.6, 0.0),
    ];
    for seeds in [&seeds[..], &[]] {
        let go =
            |threads| on_threads(threads, || run(&f, Aabb::cube(1.0), 0.03, seeds, Cells::Cubes));
        let (one, s1) = go(1);
        closed(&one, &[0, 0, 0], "three spheres");
        assert_eq!(s1.components.len(), 3);
        assert!(s1.refine_evaluations < s1.vertices as u64 * 5 / 4, "{s1:?}");
        for threads in [2, 4] {
            let (m, s) = go(threads);
            assert_eq!(m.positions, one.positions, "{threads}");
            assert_eq!(m.triangles, one.triangles, "{threads}");
            assert_eq!(m.normals, one.normals, "{threads}");
            assert_eq!(s.seed_notes, s1.seed_notes, "{threads}");
            assert_eq!(s.evaluations(), s1.evaluations(), "{threads}");
        }
    }
}

/// `RootMethod::Hermite` on a smooth field with an exact gradient: the triangles of the
/// default (Newton) roots, no root-finding evaluation at all (under 3 evaluations per
/// vertex), vertices within a hundredth of a cell of the torus, normals within a degree of
/// the default's, and the same mesh on 1, 2 and 4 threads.
#[test]
fn hermite_roots_keep_the_triangles_and_take_no_evaluation_on_a_smooth_field() {
    let t = torus();
    assert!(t.has_exact_gradient());
    let go = |root, threads| {
        let opts = Options {
            lattice: LatticeOptions {
                domain: Aabb::cube(1.0),
                resolution: Resolution::Cell(0.04),
                ..Default::default()
            },
            seeds: vec![DVec3::new(0.6, 0.0, 0.0)],
            root,
            ..Options::default()
        };
        on_threads(threads, || polygonize(&t, &opts).unwrap())
    };
    let (newton, sn) = go(RootMethod::RegulaFalsi, 1);
    let (hermite, sh) = go(RootMethod::Hermite, 1);
    closed(&hermite, &[1], "torus, hermite roots");
    assert_eq!(hermite.triangles, newton.triangles);
    assert!(sn.refine_evaluations > 0);
    assert_eq!(sh.refine_evaluations, 0, "{sh:?}");
    assert_eq!(sh.corner_evaluations, sn.corner_evaluations);
    assert!(sh.evaluations() < 3 * sh.vertices as u64, "{sh:?}");
    let err = hermite
        .positions
        .iter()
        .map(|p| torus_distance(DVec3::from_array(p.map(f64::from))).abs())
        .fold(0.0, f64::max);
    assert!(err < sh.cell / 100.0, "{err}");
    assert!(hermite.positions != newton.positions);
    for (a, b) in hermite.normals.iter().zip(&newton.normals) {
        let cos = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        assert!(cos > 0.9998, "{a:?} {b:?}");
    }
    for threads in [2, 4] {
        assert!(go(RootMethod::Hermite, threads).0 == hermite, "{threads} threads");
    }
}

/// A sphere of radius 0.8 from a seed at its centre, at a 0.01 cell on `threads`,
/// cancelled once the progress passes `after`.
fn cancelled_sphere(
    sphere: &dyn Field,
    threads: Threads,
    after: u64,
) -> Result<(Mesh, Stats), Error> {
    use skelform_field::control::Control;
    use std::ops::ControlFlow;
    let opts = Options {
        lattice: LatticeOptions {
            domain: Aabb::cube(1.0),
            resolution: Resolution::Cell(0.01),
            threads,
            control: Control::with_callback(move |p| {
                if p.done > after { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
            }),
            ..Default::default()
        },
        seeds: vec![DVec3::ZERO],
        ..Options::default()
    };
    polygonize(sphere, &opts)
}

#[test]
fn cancellation_stops_the_run() {
    let sphere = FnField(|p: DVec3| p.length() - 0.8);
    assert_eq!(cancelled_sphere(&sphere, Threads::default(), 100).unwrap_err(), Error::Cancelled);
}

/// Root finding overlapped with propagation (a field with an exact gradient): a torus
/// reached from 24 seeds around it, so that on several threads components are propagated
/// for nothing and their vertices, refined already or not, are dropped, and six small
/// spheres each reached from a seed. Every thread count gives the one thread's mesh
/// (positions, normals, triangles) and statistics, root finding's evaluations included; the
/// mesh is closed and its vertices lie on the surface.
#[test]
fn overlapped_root_finding_gives_the_one_thread_mesh_and_counts() {
    let centres: Vec<DVec3> = (0..6).map(|i| on_circle(0.9, i, 6)).collect();
    let mut src = "sqrt((sqrt(x^2 + y^2) - 0.45)^2 + z^2) - 0.12".to_string();
    for c in &centres {
        src = format!("min({src}, sqrt((x - {})^2 + (y - {})^2 + z^2) - 0.07)", c.x, c.y);
    }
    let f = Formula::parse(&src).unwrap();
    assert!(f.has_exact_gradient());
    let mut seeds = Vec::new();
    for i in 0..24 {
        seeds.push(on_circle(0.45, i * 7 % 24, 24));
        if i % 4 == 0 {
            seeds.push(centres[i / 4] * 1.01);
        }
    }
    let domain = Aabb::new(DVec3::splat(-1.05), DVec3::splat(1.05));
    let go = |threads| on_threads(threads, || run(&f, domain, 0.015, &seeds, Cells::Cubes));
    let (one, s1) = go(1);
    closed(&one, &[0, 0, 0, 0, 0, 0, 1], "torus and spheres");
    assert_eq!(s1.components.len(), 7);
    // More vertices than one chunk of root finding, so that chunks are handed over while
    // propagating.
    assert!(s1.vertices > 4 * 1024, "{s1:?}");
    assert!(s1.refine_evaluations >= s1.vertices as u64 * 9 / 10, "{s1:?}");
    let worst = one
        .positions
        .iter()
        .map(|p| f.eval(DVec3::from_array(p.map(f64::from))).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-3 * s1.cell, "{worst}");
    let s1 = untimed(s1);
    for threads in [2, 3, 4, 8, 2] {
        let (m, s) = go(threads);
        assert!(m == one, "{threads} threads");
        assert_eq!(untimed(s), s1, "{threads} threads");
    }
}

/// Cancelled while propagating, with root finding overlapped (a field with an exact
/// gradient): the run stops with the cancellation, not with a partial mesh.
#[test]
fn cancellation_stops_a_run_with_overlapped_root_finding() {
    let sphere = Formula::parse("sqrt(x^2 + y^2 + z^2) - 0.8").unwrap();
    assert!(sphere.has_exact_gradient());
    for threads in [1, 2] {
        let got = cancelled_sphere(&sphere, Threads::Count(threads), 20_000);
        assert_eq!(got.unwrap_err(), Error::Cancelled, "{threads}");
    }
}

/// Statistics without their timings, to compare runs.
fn untimed(mut s: Stats) -> Stats {
    use std::time::Duration;
    (s.search, s.propagation, s.refinement, s.normals) =
        (Duration::ZERO, Duration::ZERO, Duration::ZERO, Duration::ZERO);
    s
}

/// Components propagated on several threads at once (see the continuation's seeds module):
/// a torus reached from 48 seeds around it (so that threads start on one component from
/// far apart and all but the first seed's work is thrown away), interleaved with seeds of
/// 12 small spheres, some seeds outside everything (the 26-direction march) and one seed
/// that finds nothing. Every thread count, several times over (the threads' timing
/// differs), gives the one thread's mesh and every one of its statistics but the timings:
/// components, notes, stops, cells and evaluation counts.
#[test]
fn seeds_of_one_component_on_many_threads_give_the_one_thread_mesh_and_counts() {
    let spheres: Vec<DVec3> = (0..12).map(|i| on_circle(0.9, i, 12)).collect();
    let centres = spheres.clone();
    let field = FnField(move |p: DVec3| {
        let torus = ((p.truncate().length() - 0.45).powi(2) + p.z * p.z).sqrt() - 0.12;
        centres.iter().map(|c| (p - *c).length() - 0.06).fold(torus, f64::min)
    });
    let mut seeds = Vec::new();
    for i in 0..48 {
        seeds.push(on_circle(0.45, i * 29 % 48, 48));
        if i % 4 == 0 {
            seeds.push(spheres[i / 4] * 1.01);
        }
        if i % 16 == 5 {
            seeds.push(DVec3::new(0.1, 0.05, 0.7));
        }
    }
    let domain = Aabb::new(DVec3::splat(-1.05), DVec3::splat(1.05));
    for cells in [Cells::Cubes, Cells::Tetrahedra] {
        let go = |threads| on_threads(threads, || run(&field, domain, 0.02, &seeds, cells));
        let (one, s1) = go(1);
        assert_eq!(s1.components.len(), 13, "{cells:?}");
        assert!(s1.seed_notes.len() == seeds.len() - 13, "{:?}", s1.seed_notes);
        let s1 = untimed(s1);
        for threads in [2, 3, 4, 8, 2, 4] {
            let (m, s) = go(threads);
            assert!(m == one, "{cells:?}, {threads} threads");
            assert_eq!(untimed(s), s1, "{cells:?}, {threads} threads");
        }
    }
    // The cell budget, reached on several threads, is the one thread's stop.
    let opts = |threads| Options {
        lattice: LatticeOptions {
            domain,
            resolution: Resolution::Cell(0.02),
            threads: Threads::Count(threads),
            ..Default::default()
        },
        seeds: seeds.clone(),
        max_cells: 3000,
        ..Options::default()
    };
    let (one, s1) = polygonize(&field, &opts(1)).unwrap();
    assert_eq!(s1.stops, vec![Stop::Budget]);
    for threads in [2, 4] {
        let (m, s) = polygonize(&field, &opts(threads)).unwrap();
        assert!(m == one && untimed(s) == untimed(s1.clone()), "{threads} threads");
    }
}
