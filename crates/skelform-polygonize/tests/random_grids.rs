//! Property test: marching cubes on random small sample grids, padded with positive values so
//! that the sampled field is closed, always gives a closed, manifold, consistently oriented
//! mesh, whatever the signs and however many values are exactly zero.

use proptest::prelude::*;
use skelform_field::DVec3;
use skelform_field::control::Control;
use skelform_field::grid::{Grid, Volume};
use skelform_mesh::check::check;
use skelform_polygonize::grid::extract_mesh;

fn volume(n: [usize; 3], inner: &[f32]) -> Volume {
    // Pad with a layer of positive values on every side.
    let dims = [n[0] + 2, n[1] + 2, n[2] + 2];
    let grid = Grid { origin: DVec3::ZERO, cell: 1.0, dims };
    let mut values = vec![1.0f32; dims.iter().product()];
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                values[grid.index(i + 1, j + 1, k + 1)] = inner[i + n[0] * (j + n[1] * k)];
            }
        }
    }
    Volume::from_values(grid, values)
}

fn value() -> impl Strategy<Value = f32> {
    prop_oneof![
        3 => -1.0f32..1.0,
        1 => Just(0.0f32),
        1 => prop::sample::select(vec![-1.0f32, 1.0, -0.5, 0.5]),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(3000))]
    #[test]
    fn closed_manifold_oriented(
        (n, inner) in (2usize..=4, 2usize..=4, 2usize..=4)
            .prop_flat_map(|(a, b, c)| (Just([a, b, c]), prop::collection::vec(value(), a * b * c)))
    ) {
        let v = volume(n, &inner);
        let m = extract_mesh(&v, &Control::default()).unwrap();
        let r = check(&m);
        if inner.iter().all(|&x| x >= 0.0) {
            prop_assert!(m.is_empty());
        } else {
            prop_assert!(r.is_closed_manifold(), "{:?}\n{}", inner, r);
            prop_assert_eq!(r.outward, Some(true));
            prop_assert_eq!(r.faces_with_repeated_vertex, 0);
            prop_assert_eq!(r.unreferenced_vertices, 0);
        }
    }
}
