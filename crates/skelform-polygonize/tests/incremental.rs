//! `incremental::GridState`: an update after a local change of the field is the fresh grid
//! run's mesh, bit for bit; a cancelled update leaves a state the next update does not
//! trust.

use glam::DVec3;
use skelform_field::control::Control;
use skelform_field::{Aabb, FnField};
use skelform_polygonize::grid::{self, Options};
use skelform_polygonize::incremental::{self, GridState};
use skelform_polygonize::{LatticeOptions, Resolution};

/// Blobs with compact support (radius `R`): each contributes exactly nothing outside its box.
const R: f64 = 0.45;

fn blobs(centres: Vec<DVec3>) -> FnField<impl Fn(DVec3) -> f64 + Send + Sync> {
    FnField(move |p: DVec3| {
        let mut sum = 0.0;
        for c in &centres {
            let d2 = (p - *c).length_squared() / (R * R);
            if d2 < 1.0 {
                sum += (1.0 - d2).powi(3);
            }
        }
        0.3 - sum
    })
}

fn boxed(c: DVec3) -> Aabb {
    Aabb { min: c - DVec3::splat(R), max: c + DVec3::splat(R) }
}

fn options(control: Control) -> Options {
    let lattice = LatticeOptions {
        domain: Aabb::cube(1.5),
        resolution: Resolution::Samples(72),
        control,
        ..LatticeOptions::default()
    };
    Options { lattice, ..Options::default() }
}

fn centres(moved: f64) -> Vec<DVec3> {
    vec![
        DVec3::new(-0.7, -0.6, -0.8),
        DVec3::new(-0.3, -0.5, -0.7),
        DVec3::new(0.2, 0.1, 0.0),
        DVec3::new(0.5 + moved, 0.3, 0.1),
        DVec3::new(0.6, 0.7, 0.9),
    ]
}

#[test]
fn moving_a_blob_gives_the_fresh_mesh() {
    let o = options(Control::default());
    let (_, _, mut state): (_, _, GridState) =
        incremental::polygonize(&blobs(centres(0.0)), &o).unwrap();
    let mut last = 0.0;
    for step in [0.05, 0.12, -0.2, 0.3] {
        let field = blobs(centres(step));
        let changed = [boxed(centres(last)[3]), boxed(centres(step)[3])];
        let (mesh, _, reuse) = state.update(&field, &o, &changed).unwrap();
        let (fresh, _) = grid::polygonize(&field, &o).unwrap();
        assert!(!reuse.full);
        assert!(reuse.reused_vertices > 0, "{reuse:?}");
        assert!(reuse.resampled < 72 * 72 * 72 / 2, "{reuse:?}");
        assert_eq!(mesh, fresh, "after moving by {step}");
        last = step;
    }
}

/// An update cancelled before it replaced any vertex leaves a state the next update can
/// take on: that update names only its own change since the last finished run, and the
/// cancelled update's samples (of a field never shown) are taken again too.
#[test]
fn a_cancelled_update_leaves_its_boxes_to_the_next() {
    let control = Control::default();
    let o = options(control.clone());
    let (_, _, mut state) = incremental::polygonize(&blobs(centres(0.0)), &o).unwrap();
    control.cancel();
    let field = blobs(centres(0.1));
    let changed = [boxed(centres(0.0)[3]), boxed(centres(0.1)[3])];
    let err = state.update(&field, &o, &changed).unwrap_err();
    assert!(matches!(err, skelform_polygonize::Error::Cancelled), "{err}");
    let o = options(Control::default());
    assert!(state.matches(&o), "cancelled before any vertex was replaced: still trusted");
    // The blob goes the other way: the cancelled update's box is not within the new ones.
    let field = blobs(centres(-0.1));
    let changed = [boxed(centres(0.0)[3]), boxed(centres(-0.1)[3])];
    let (mesh, _, reuse) = state.update(&field, &o, &changed).unwrap();
    assert!(!reuse.full, "{reuse:?}");
    assert_eq!(mesh, grid::polygonize(&field, &o).unwrap().0);
}

/// `previous_vertex` names, for each vertex an update kept, the last run's vertex at the
/// same place with the same normal, on a lattice edge that misses the changed boxes (what
/// `Live` relies on to keep colours by vertex number); only lattice points within a cell's
/// rounding guard of the boxes are sampled again.
#[test]
fn kept_vertices_name_the_last_runs_vertex() {
    let o = options(Control::default());
    let (mut before, _, mut state) = incremental::polygonize(&blobs(centres(0.0)), &o).unwrap();
    let mut last = 0.0;
    for step in [0.05, -0.1, 0.2] {
        let field = blobs(centres(step));
        let changed = [boxed(centres(last)[3]), boxed(centres(step)[3])];
        let (mesh, _, reuse) = state.update(&field, &o, &changed).unwrap();
        let grid = *state.grid();
        // Only the lattice points inside the boxes (within the rounding guard): a two-cell
        // margin, as before, sampled 17 550 points at the first step, 10 626 inside.
        let [nx, ny, nz] = grid.dims;
        let grown: Vec<Aabb> = changed.iter().map(|b| b.inflate(0.011 * grid.cell)).collect();
        let mut inside = 0u64;
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let p = grid.point(i, j, k);
                    inside += u64::from(grown.iter().any(|b| b.contains(p)));
                }
            }
        }
        assert!(reuse.resampled <= inside, "{reuse:?}, {inside} points inside the boxes");
        let mut kept = 0;
        for i in 0..mesh.vertex_count() {
            let Some(o) = state.previous_vertex(i) else { continue };
            kept += 1;
            assert_eq!(mesh.positions[i], before.positions[o], "vertex {i} (was {o})");
            assert_eq!(mesh.normals[i], before.normals[o], "vertex {i} (was {o})");
            let p = DVec3::from_array(mesh.positions[i].map(f64::from));
            for b in &changed {
                assert!(!b.contains(p), "kept vertex {i} at {p} in a changed box");
            }
        }
        assert_eq!(kept, reuse.reused_vertices, "{reuse:?}");
        assert!(state.previous_vertex(mesh.vertex_count()).is_none());
        before = mesh;
        last = step;
    }
}
