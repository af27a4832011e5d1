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
