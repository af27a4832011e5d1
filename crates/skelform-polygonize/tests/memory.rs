//! `LatticeOptions::max_memory` holds for every polygonizer: what is known from the lattice
//! is refused before anything is allocated (`Error::TooMuchMemory`), what grows with the
//! surface stops the run at the limit (`Error::MemoryLimit`), at the same point on any
//! thread count; under the limit the mesh is the same as with none.

use glam::DVec3;
use skelform_field::region::FnRegions;
use skelform_field::{Field, FnField, RegionField};
use skelform_polygonize::{Error, LatticeOptions, Resolution, Threads};
use skelform_polygonize::{continuation, grid, healed, nonmanifold};

fn lattice(cell: f64, max_memory: u64) -> LatticeOptions {
    LatticeOptions { resolution: Resolution::Cell(cell), max_memory, ..Default::default() }
}

fn sphere() -> impl Field {
    FnField(|p: DVec3| p.length() - 0.6)
}

/// A ball (1) cut by the plane z = 0 into an upper (2) and lower (3) half-space.
fn cut_ball() -> impl RegionField {
    FnRegions(|p: DVec3| {
        if p.length() < 0.5 {
            1
        } else if p.z > 0.0 {
            2
        } else {
            3
        }
    })
}

fn continuation_opts(cells: continuation::Cells, max_memory: u64) -> continuation::Options {
    continuation::Options {
        lattice: lattice(0.02, max_memory),
        seeds: vec![DVec3::ZERO],
        cells,
        ..Default::default()
    }
}

fn stopped_at_limit(e: &Error, method: &str, limit: u64) {
    match e {
        Error::MemoryLimit { method: m, held, limit: l, cells } => {
            assert_eq!(*m, method);
            assert_eq!(*l, limit);
            assert!(*held > limit && *cells > 0, "{e}");
            let msg = e.to_string();
            assert!(msg.contains("memory limit") && msg.contains("--max-memory"), "{msg}");
            assert!(!msg.contains('\n'), "{msg}");
        }
        e => panic!("{method}: expected MemoryLimit, got {e:?}"),
    }
}

#[test]
fn continuation_and_tetra_stop_at_the_limit() {
    use continuation::Cells;
    let f = sphere();
    for (cells, method) in [(Cells::Cubes, "continuation"), (Cells::Tetrahedra, "tetra")] {
        let e = continuation::polygonize(&f, &continuation_opts(cells, 256 << 10)).unwrap_err();
        stopped_at_limit(&e, method, 256 << 10);
        // The default limit: the mesh of an unlimited run.
        let (a, _) = continuation::polygonize(&f, &continuation_opts(cells, 4 << 30)).unwrap();
        let (b, _) = continuation::polygonize(&f, &continuation_opts(cells, u64::MAX)).unwrap();
        assert!(a.triangle_count() > 0);
        assert_eq!(a, b, "{method}");
    }
}

#[test]
fn the_stop_is_the_same_on_any_thread_count() {
    let f = sphere();
    let run = |threads: usize| {
        let mut o = continuation_opts(continuation::Cells::Cubes, 300 << 10);
        o.lattice.threads = Threads::Count(threads);
        continuation::polygonize(&f, &o).unwrap_err()
    };
    assert_eq!(run(1), run(3));
    let r = cut_ball();
    let run = |threads: usize| {
        let mut o = nonmanifold::Options { lattice: lattice(0.05, 1 << 20), ..Default::default() };
        o.lattice.threads = Threads::Count(threads);
        nonmanifold::polygonize(&r, &o).unwrap_err()
    };
    assert_eq!(run(1), run(3));
}

#[test]
fn nonmanifold_stops_at_the_limit() {
    let r = cut_ball();
    for full_grid in [false, true] {
        let o = |max_memory| nonmanifold::Options {
            lattice: lattice(0.1, max_memory),
            full_grid,
            ..Default::default()
        };
        let e = nonmanifold::polygonize(&r, &o(1 << 20)).unwrap_err();
        if full_grid {
            // 20³ cubes need more than a MiB for their list and caches alone.
            assert!(matches!(e, Error::TooMuchMemory { .. }), "{e:?}");
        } else {
            stopped_at_limit(&e, "nonmanifold", 1 << 20);
        }
        let (a, _) = nonmanifold::polygonize(&r, &o(4 << 30)).unwrap();
        let (b, _) = nonmanifold::polygonize(&r, &o(u64::MAX)).unwrap();
        assert!(a.triangle_count() > 0);
        assert_eq!(a, b, "full grid {full_grid}");
    }
}

#[test]
fn full_grid_past_the_up_front_check_stops_at_the_limit() {
    // Enough for the cube list and caches of 20³ cubes, not for their crossings and mesh.
    let r = cut_ball();
    let o = nonmanifold::Options {
        lattice: lattice(0.1, 12 << 20),
        full_grid: true,
        ..Default::default()
    };
    let e = nonmanifold::polygonize(&r, &o).unwrap_err();
    stopped_at_limit(&e, "nonmanifold", 12 << 20);
}

#[test]
fn what_the_lattice_alone_needs_is_refused_before_any_work() {
    let never = FnField(|_: DVec3| -> f64 { panic!("must not evaluate") });
    let no_regions = FnRegions(|_: DVec3| -> u32 { panic!("must not evaluate") });
    // Full grid at a thousandth: billions of cubes, refused at once (the reports: 44 GB
    // asked in one allocation).
    let o = nonmanifold::Options {
        lattice: lattice(0.001, 4 << 30),
        full_grid: true,
        ..Default::default()
    };
    let e = nonmanifold::polygonize(&no_regions, &o).unwrap_err();
    assert!(matches!(e, Error::TooMuchMemory { dims: [2001, 2001, 2001], .. }), "{e:?}");
    // The coarse search of the domain when no seed is given.
    let o = nonmanifold::Options { lattice: lattice(0.0002, 1 << 30), ..Default::default() };
    let e = nonmanifold::polygonize(&no_regions, &o).unwrap_err();
    assert!(matches!(e, Error::TooMuchMemory { .. }), "{e:?}");
    let o = continuation::Options { lattice: lattice(0.0002, 1 << 30), ..Default::default() };
    let e = continuation::polygonize(&never, &o).unwrap_err();
    assert!(matches!(e, Error::TooMuchMemory { .. }), "{e:?}");
}

#[test]
fn healed_counts_what_it_adds_to_the_grid() {
    let f = FnField(|p: DVec3| p.y * p.z + 0.01 * p.x);
    let base = LatticeOptions { resolution: Resolution::Samples(24), ..Default::default() };
    let g = base.grid().unwrap();
    let dense = grid::memory_needed(&g, false);
    // The grid's own need passes the up-front check; what healing adds does not fit.
    let o = healed::Options {
        lattice: LatticeOptions { max_memory: dense + 1, ..base.clone() },
        ..Default::default()
    };
    let e = healed::polygonize(&f, &o).unwrap_err();
    assert!(matches!(e, Error::MemoryLimit { method: "healed", .. }), "{e:?}");
    let o = healed::Options {
        lattice: LatticeOptions { max_memory: dense - 1, ..base.clone() },
        ..Default::default()
    };
    let e = healed::polygonize(&f, &o).unwrap_err();
    assert!(matches!(e, Error::TooMuchMemory { .. }), "{e:?}");
    let o = healed::Options { lattice: base, ..Default::default() };
    assert!(healed::polygonize(&f, &o).unwrap().0.triangle_count() > 0);
}
