//! The grid polygonizer on shapes of known topology: closed, manifold, outward, the right
//! genus, and vertices on the true surface.

use glam::DVec3;
use skelform_field::formula::Formula;
use skelform_field::{Aabb, Field, FnField};
use skelform_mesh::Mesh;
use skelform_mesh::check::{Report, check};
use skelform_polygonize::LatticeOptions;
use skelform_polygonize::grid::{Options, Resolution, polygonize};

fn mesh(field: &dyn Field, domain: Aabb, samples: usize) -> (Mesh, f64) {
    let lattice =
        LatticeOptions { domain, resolution: Resolution::Samples(samples), ..Default::default() };
    let opts = Options { lattice, ..Options::default() };
    let (m, stats) = polygonize(field, &opts).expect("polygonize");
    (m, stats.cell)
}

/// Closed, manifold, consistently oriented outward, with these genera per component.
fn assert_closed_with_genus(m: &Mesh, genera: &[i64], what: &str) -> Report {
    let r = check(m);
    assert!(r.is_closed_manifold(), "{what}: not a closed manifold:\n{r}");
    assert_eq!(r.outward, Some(true), "{what}: faces must point outward:\n{r}");
    let mut got: Vec<i64> = r.components.iter().map(|c| c.genus.expect("genus")).collect();
    got.sort_unstable();
    assert_eq!(got, genera, "{what}: genera per component:\n{r}");
    assert_eq!(r.faces_with_repeated_vertex, 0, "{what}");
    assert_eq!(r.duplicate_faces, 0, "{what}");
    r
}

/// Largest distance from a vertex to the true surface, in cells.
fn max_error(m: &Mesh, cell: f64, distance: impl Fn(DVec3) -> f64) -> f64 {
    m.positions
        .iter()
        .map(|p| distance(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)).abs() / cell)
        .fold(0.0, f64::max)
}

#[test]
fn sphere_at_many_resolutions() {
    let sphere = FnField(|p: DVec3| p.length() - 0.8);
    for n in [4, 5, 7, 8, 13, 32, 64, 65, 101, 128, 129] {
        let (m, cell) = mesh(&sphere, Aabb::cube(1.0), n);
        assert_closed_with_genus(&m, &[0], &format!("sphere at {n}"));
        let err = max_error(&m, cell, |p| p.length() - 0.8);
        assert!(err < 0.01, "sphere at {n}: vertices {err} cells off the surface");
    }
}

#[test]
fn torus_has_genus_one_and_accurate_vertices() {
    let f = Formula::parse("q = sqrt(x^2 + y^2) - 0.6\nq^2 + z^2 - 0.25^2").unwrap();
    let exact = |p: DVec3| ((p.truncate().length() - 0.6).powi(2) + p.z * p.z).sqrt() - 0.25;
    for n in [24, 64, 128] {
        let (m, cell) = mesh(&f, Aabb::cube(1.0), n);
        assert_closed_with_genus(&m, &[1], &format!("torus at {n}"));
        let err = max_error(&m, cell, exact);
        assert!(err < 0.01, "torus at {n}: {err} cells");
        // Normals from the exact gradient agree with the true normal.
        for (p, nrm) in m.positions.iter().zip(&m.normals) {
            let p = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            let ring = p.truncate().normalize() * 0.6;
            let truth = (p - ring.extend(0.0)).normalize();
            let n = DVec3::new(nrm[0] as f64, nrm[1] as f64, nrm[2] as f64);
            assert!(n.dot(truth) > 0.999, "normal {n} vs {truth} at {p}");
        }
    }
}

#[test]
fn double_torus_has_genus_two() {
    let f = Formula::parse(
        "l = (sqrt((x + 0.6)^2 + y^2) - 0.5)^2 + z^2 - 0.2^2\n\
         r = (sqrt((x - 0.6)^2 + y^2) - 0.5)^2 + z^2 - 0.2^2\n\
         min(l, r)",
    )
    .unwrap();
    let domain = Aabb::new(DVec3::new(-1.4, -0.8, -0.4), DVec3::new(1.4, 0.8, 0.4));
    for n in [56, 100, 160] {
        let (m, _) = mesh(&f, domain, n);
        assert_closed_with_genus(&m, &[2], &format!("double torus at {n}"));
    }
}

#[test]
fn two_spheres_are_two_components() {
    let f = FnField(|p: DVec3| {
        let a = (p - DVec3::new(-0.7, 0.0, 0.0)).length() - 0.5;
        let b = (p - DVec3::new(0.7, 0.0, 0.0)).length() - 0.4;
        a.min(b)
    });
    let domain = Aabb::new(DVec3::new(-1.5, -1.0, -1.0), DVec3::new(1.5, 1.0, 1.0));
    let (m, _) = mesh(&f, domain, 64);
    let r = assert_closed_with_genus(&m, &[0, 0], "two spheres");
    assert_eq!(r.components.len(), 2);
}

#[test]
fn gyroid_cut_by_a_box_is_closed_with_stable_genus() {
    let f = Formula::parse(
        "g = sin(x)*cos(y) + sin(y)*cos(z) + sin(z)*cos(x)\n\
         b = max(abs(x), abs(y), abs(z)) - 5\n\
         max(g, b)",
    )
    .unwrap();
    let domain = Aabb::cube(5.3);
    let mut genera = Vec::new();
    for n in [96, 128, 192] {
        let (m, _) = mesh(&f, domain, n);
        let r = check(&m);
        assert!(r.is_closed_manifold(), "gyroid at {n}:\n{r}");
        assert_eq!(r.outward, Some(true));
        let mut g: Vec<i64> = r.components.iter().map(|c| c.genus.unwrap()).collect();
        g.sort_unstable();
        genera.push(g);
    }
    assert!(genera.windows(2).all(|w| w[0] == w[1]), "genus changes with resolution: {genera:?}");
    assert!(genera[0].iter().sum::<i64>() > 3, "a gyroid block has many handles: {genera:?}");
}

#[test]
fn surface_leaving_the_domain_is_open_but_manifold() {
    // A cylinder along z, cut by the domain's top and bottom.
    let f = FnField(|p: DVec3| (p.x * p.x + p.y * p.y).sqrt() - 0.5);
    let (m, _) = mesh(&f, Aabb::cube(1.0), 32);
    let r = check(&m);
    assert!(r.boundary_edges > 0);
    assert_eq!(r.non_manifold_edges, 0);
    assert!(r.consistently_oriented);
    assert_eq!(r.components.len(), 1);
    assert_eq!(r.components[0].boundary_loops, 2);
}

#[test]
fn same_mesh_on_any_thread_count() {
    let f =
        Formula::parse("sin(3*x)*cos(3*y) + sin(3*y)*cos(3*z) + sin(3*z)*cos(3*x) - 0.2").unwrap();
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| mesh(&f, Aabb::cube(1.0), 70).0)
    };
    let one = run(1);
    assert!(one.triangle_count() > 1000);
    for t in [2, 3, 8] {
        assert!(run(t) == one, "mesh differs with {t} threads");
    }
}

#[test]
fn streamed_volume_gives_the_same_mesh_and_counts() {
    use skelform_polygonize::grid::Streaming;
    // A gyroid with a band of NaN samples (treated as far outside) through several slabs.
    let f = FnField(|p: DVec3| {
        if p.y.abs() < 0.05 {
            f64::NAN
        } else {
            (3.0 * p.x).sin() * (3.0 * p.y).cos()
                + (3.0 * p.y).sin() * (3.0 * p.z).cos()
                + (3.0 * p.z).sin() * (3.0 * p.x).cos()
                - 0.2
        }
    });
    let run = |streaming, threads| {
        let lattice = LatticeOptions { resolution: Resolution::Samples(43), ..Default::default() };
        let opts = Options { lattice, streaming, ..Options::default() };
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| polygonize(&f, &opts).unwrap())
    };
    let (whole, ws) = run(Streaming::Never, 2);
    assert!(!ws.streamed && whole.triangle_count() > 1000);
    for threads in [1, 3] {
        let (streamed, ss) = run(Streaming::Always, threads);
        assert!(ss.streamed);
        assert!(streamed == whole, "streamed mesh differs on {threads} threads");
        assert_eq!(ss.non_finite_samples, ws.non_finite_samples);
        assert!(ws.non_finite_samples > 0);
        assert_eq!((ss.min_sample, ss.max_sample), (ws.min_sample, ws.max_sample));
        assert_eq!((ss.ambiguous_faces, ss.tunnels), (ws.ambiguous_faces, ws.tunnels));
        // 42 cube layers in slabs of 8: each of the 5 inner slab boundaries is sampled
        // once, or twice when its two slabs ran on different threads.
        if threads == 1 {
            assert_eq!(ss.samples, ws.samples);
        } else {
            assert!((ws.samples..=ws.samples + 5 * 43 * 43).contains(&ss.samples));
            assert_eq!(ss.samples % (43 * 43), 0);
        }
    }
}

#[test]
fn sample_values_exactly_zero_keep_the_mesh_closed() {
    // Planes through lattice points: x = 0 and friends are sampled exactly at zero.
    let f = FnField(|p: DVec3| p.x.abs().max(p.y.abs()).max(p.z.abs()) - 0.5);
    for n in [5, 9, 21] {
        let (m, _) = mesh(&f, Aabb::cube(1.0), n);
        let r = assert_closed_with_genus(&m, &[0], &format!("cube at {n}"));
        assert_eq!(r.zero_area_faces, 0, "cube at {n}:\n{r}");
    }
}

#[test]
fn memory_limit_is_checked_before_work() {
    let f = FnField(|_: DVec3| panic!("must not evaluate"));
    let lattice = LatticeOptions {
        resolution: Resolution::Samples(2000),
        max_memory: 1 << 30,
        ..Default::default()
    };
    let opts = Options { lattice, ..Options::default() };
    let err = polygonize(&f, &opts).unwrap_err();
    assert!(matches!(err, skelform_polygonize::Error::TooMuchMemory { .. }), "{err}");
    assert!(err.to_string().contains("GiB"));
}

#[test]
fn cancellation_stops_the_run() {
    use skelform_field::control::Control;
    use std::ops::ControlFlow;
    let f = FnField(|p: DVec3| p.length() - 0.5);
    let lattice = LatticeOptions {
        resolution: Resolution::Samples(96),
        control: Control::with_callback(|p| {
            if p.done > 2 { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
        }),
        ..Default::default()
    };
    let opts = Options { lattice, ..Options::default() };
    assert_eq!(polygonize(&f, &opts).unwrap_err(), skelform_polygonize::Error::Cancelled);
}

#[test]
fn no_surface_gives_an_empty_mesh_and_the_value_range() {
    let f = FnField(|p: DVec3| p.length() + 1.0);
    let lattice = LatticeOptions { resolution: Resolution::Samples(16), ..Default::default() };
    let opts = Options { lattice, ..Options::default() };
    let (m, s) = polygonize(&f, &opts).unwrap();
    assert!(m.is_empty());
    assert!(s.min_sample > 0.0);
}

#[test]
fn surface_cubes_counts_the_cubes_with_both_signs() {
    use skelform_field::control::Control;
    use skelform_field::grid::{Grid, sample};
    use skelform_polygonize::grid::surface_cubes;
    // 70 samples across: rows longer than one 64-bit word, so the word carry is exercised.
    let f =
        Formula::parse("sin(5*x)*cos(4*y) + sin(4*y)*cos(5*z) + sin(5*z)*cos(4*x) - 0.1").unwrap();
    let grid = Grid::with_resolution(&Aabb::cube(1.0), 70).unwrap();
    let v = sample(&f, &grid, &Control::default()).unwrap();
    let [nx, ny, nz] = grid.dims;
    let mut brute = 0;
    for k in 0..nz - 1 {
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let c: [f32; 8] =
                    std::array::from_fn(|c| v.get(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2)));
                let inside = c.iter().filter(|&&x| x < 0.0).count();
                brute += u64::from(inside != 0 && inside != 8);
            }
        }
    }
    assert!(brute > 10_000);
    assert_eq!(surface_cubes(&v), brute);
}

#[test]
fn threads_are_bounded_and_do_not_change_the_mesh() {
    use skelform_polygonize::{Error, MAX_THREADS, Threads};
    let f = FnField(|p: DVec3| p.length() - 0.5);
    let with = |threads| {
        let lattice =
            LatticeOptions { resolution: Resolution::Samples(24), threads, ..Default::default() };
        polygonize(&f, &Options { lattice, ..Options::default() })
    };
    for n in [0, MAX_THREADS + 1, 100_000] {
        assert!(matches!(with(Threads::Count(n)), Err(Error::BadOption(_))), "{n} threads");
    }
    let one = with(Threads::Count(1)).unwrap().0;
    assert!(with(Threads::Count(3)).unwrap().0 == one);
    let pool = std::sync::Arc::new(rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap());
    assert!(with(Threads::Pool(pool)).unwrap().0 == one);
}

#[test]
fn a_workspace_of_the_callers_own_gives_the_same_mesh() {
    use skelform_polygonize::grid::{Streaming, Workspace};
    let f = FnField(|p: DVec3| p.length() - 0.5);
    let lattice = LatticeOptions { resolution: Resolution::Samples(40), ..Default::default() };
    let shared = polygonize(&f, &Options { lattice: lattice.clone(), ..Options::default() });
    let own = std::sync::Arc::new(Workspace::new());
    for streaming in [Streaming::Never, Streaming::Always, Streaming::Never] {
        let opts = Options { lattice: lattice.clone(), streaming, workspace: Some(own.clone()) };
        let pool = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap();
        let mine = pool.install(|| polygonize(&f, &opts)).unwrap().0;
        assert!(mine == shared.as_ref().unwrap().0, "{streaming:?}");
    }
}
