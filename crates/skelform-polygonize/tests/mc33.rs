//! Chernyaev's Marching Cubes 33: every configuration and subcase, as the literature lists
//! them (Chernyaev 1995; Lewiner et al. 2003; Custodio et al. 2013), through the public
//! extraction API.
//!
//! Each case is one cube of corner values (corner `c` at `(c & 1, c >> 1 & 1, c >> 2)`,
//! inside negative) with the surface the literature gives it inside the cube, as
//! (components, Euler characteristic): a disk counts (1, 1), a tube (1, 0). The cube is
//! extracted as the middle cell of a 4×4×4 volume whose outer samples repeat the nearest
//! corner's value (the field `f(clamp(p))`), so the mesh outside the cube is a collar over
//! each boundary loop and the whole mesh has the cube's topology. Every case is checked
//! three ways: the published value against a brute-force reference (the interpolant's
//! regions on a fine lattice), the mesh against the published value, and the mesh again
//! under all 48 symmetries of the cube, and with the signs flipped against the flipped
//! cube's brute force. Where they exist, each subcase also comes
//! in degenerate variants: `h = 0` (no `xyz` term: the interpolant's gradient is linear,
//! as for any field point-symmetric about the cube's centre) and a sample exactly at the
//! iso value (which counts as outside). Configuration 13 has no `h = 0` variant: with its
//! signs, `h` is the sum of the eight samples' magnitudes.
//!
//! The published values and the brute force agree for every subcase listed here. (Custodio
//! et al. list errors in the published *tilings*, such as triangles of 13.5.2 and of some
//! complemented cases in Lewiner's tables; this polygonizer builds its tilings from the
//! loops, so those do not apply, and the topology counts are what is checked.)

use std::collections::{BTreeSet, HashMap};

use skelform_field::DVec3;
use skelform_field::control::Control;
use skelform_field::grid::{Grid, Volume};
use skelform_mesh::Mesh;
use skelform_polygonize::grid::extract_mesh;

const O: f32 = 1.0;

/// (name, values, expected (components, χ) inside the cube, negative corners of the
/// configuration).
type Case = (&'static str, [f32; 8], (usize, i64), usize);

#[rustfmt::skip]
const CASES: &[Case] = &[
    ("1", [-O, O, O, O, O, O, O, O], (1, 1), 1),
    ("1 (a sample at the iso value)", [-0.375, 2.0, 0.0, 1.375, 1.5, 0.75, 0.375, 1.5], (1, 1), 1),
    ("2", [-O, -O, O, O, O, O, O, O], (1, 1), 2),
    ("2 (h = 0)", [-2.5, -2.25, 0.625, 2.25, 1.125, 1.0, 0.125, 1.375], (1, 1), 2),
    ("2 (zero)", [-1.375, -0.75, 1.5, 2.125, 2.5, 1.875, 0.0, 1.25], (1, 1), 2),
    ("3.1", [-0.5, O, O, -0.5, O, O, O, O], (2, 2), 2),
    ("3.1 (h = 0)", [-0.75, 0.625, 0.75, -0.5, 0.375, 1.0, 2.375, 0.375], (2, 2), 2),
    ("3.1 (zero)", [-0.375, 1.125, 1.875, -0.875, 1.875, 2.5, 2.125, 0.0], (2, 2), 2),
    ("3.2", [-2.0, O, O, -2.0, O, O, O, O], (1, 1), 2),
    ("3.2 (h = 0)", [-0.125, 0.375, 0.25, -1.125, 0.5, 0.5, 2.0, 0.125], (1, 1), 2),
    ("3.2 (zero)", [-1.0, 0.625, 0.5, -1.5, 1.0, 0.0, 2.5, 2.375], (1, 1), 2),
    ("4.1.1", [-O, O, O, O, O, O, O, -O], (2, 2), 2),
    ("4.1.1 (h = 0)", [-0.75, 1.25, 0.125, 0.875, 1.75, 0.125, 1.125, -1.75], (2, 2), 2),
    ("4.1.1 (zero)", [-1.625, 2.5, 1.625, 0.5, 0.0, 1.75, 0.375, -0.625], (2, 2), 2),
    ("4.1.2", [-O, 0.2, 0.1, 0.3, 0.15, 0.1, 0.2, -0.8], (1, 0), 2),
    // Issue 18's reproducer: h = 0, one tube along the diagonal.
    ("4.1.2 (h = 0, symmetric)", [-O, 0.1, 0.1, 0.1, 0.1, 0.1, 0.1, -O], (1, 0), 2),
    ("4.1.2 (h = 0)", [-2.375, 1.25, 2.0, 0.125, 0.375, 0.25, 1.25, -4.375], (1, 0), 2),
    ("4.1.2 (zero)", [-2.125, 0.125, 0.0, 0.375, 1.0, 0.125, 1.125, -1.0], (1, 0), 2),
    ("5", [-O, -O, -O, O, O, O, O, O], (1, 1), 3),
    ("5 (h = 0)", [-0.25, -1.375, -2.375, 2.0, 0.625, 2.125, 2.0, 9.0], (1, 1), 3),
    ("5 (zero)", [-1.375, -0.375, -2.5, 0.0, 1.75, 0.875, 0.875, 0.75], (1, 1), 3),
    ("6.1.1", [-O, -O, O, O, O, O, O, -O], (2, 2), 3),
    ("6.1.1 (h = 0)", [-2.0, -1.125, 0.625, 1.375, 1.75, 0.5, 0.875, -0.5], (2, 2), 3),
    ("6.1.1 (zero)", [-1.375, -1.0, 0.0, 1.0, 1.125, 1.0, 1.5, -0.75], (2, 2), 3),
    ("6.1.2", [-2.25, -0.125, 0.375, 0.375, 0.875, 2.5, 0.5, -2.375], (1, 0), 3),
    ("6.1.2 (h = 0)", [-2.5, -0.25, 0.375, 0.875, 1.625, 1.0, 0.5, -1.875], (1, 0), 3),
    ("6.1.2 (zero)", [-2.0, -0.25, 1.375, 1.75, 0.0, 0.875, 0.25, -2.125], (1, 0), 3),
    ("6.2", [-0.125, -1.375, 1.875, 2.125, 1.875, 1.125, 0.25, -2.125], (1, 1), 3),
    ("6.2 (h = 0)", [-2.125, -1.125, 1.25, 0.25, 1.625, 0.25, 0.25, -3.125], (1, 1), 3),
    ("6.2 (zero)", [-1.5, -0.875, 1.25, 1.625, 0.25, 0.375, 0.0, -2.125], (1, 1), 3),
    ("7.1", [O, -O, -O, O, -O, O, O, O], (3, 3), 3),
    ("7.1 (h = 0)", [1.0, -2.125, -0.125, 1.625, -0.375, 1.0, 1.875, 8.125], (3, 3), 3),
    ("7.1 (zero)", [1.125, -0.25, -2.5, 1.625, -0.25, 0.625, 2.125, 0.0], (3, 3), 3),
    // 7.2 comes in three rotations (which of the three faces joins); one is enough here, the
    // symmetry sweep below reaches the others.
    ("7.2", [1.25, -0.5, -1.0, 1.75, -2.0, 1.375, 0.875, 2.5], (2, 2), 3),
    ("7.2 (h = 0)", [2.125, -1.0, -0.875, 1.625, -1.875, 2.125, 0.375, 10.0], (2, 2), 3),
    ("7.2 (zero)", [1.625, -0.125, -0.75, 0.625, -0.125, 0.25, 0.0, 1.75], (2, 2), 3),
    ("7.3", [1.5, -1.25, -2.5, 2.5, -0.75, 0.375, 1.0, 1.875], (1, 1), 3),
    ("7.3 (h = 0)", [1.875, -0.75, -1.0, 1.625, -2.125, 0.5, 0.875, 8.75], (1, 1), 3),
    ("7.3 (zero)", [2.0, -1.875, -1.875, 2.5, -2.25, 0.5, 0.0, 0.75], (1, 1), 3),
    ("7.4.1", [0.875, -2.5, -2.5, 2.375, -1.5, 1.5, 2.25, 2.25], (2, 2), 3),
    ("7.4.1 (h = 0)", [0.75, -2.375, -1.75, 1.375, -1.125, 0.875, 0.5, 8.75], (2, 2), 3),
    ("7.4.1 (zero)", [0.625, -2.375, -1.5, 0.375, -2.5, 0.0, 2.5, 1.0], (2, 2), 3),
    ("7.4.2", [1.5, -1.875, -1.75, 2.0, -1.75, 1.5, 1.875, 1.125], (1, 0), 3),
    ("7.4.2 (h = 0)", [1.75, -1.375, -2.25, 0.25, -2.125, 1.375, 0.125, 9.25], (1, 0), 3),
    ("7.4.2 (zero)", [0.75, -0.25, -1.25, 0.0, -1.125, 0.25, 1.25, 2.5], (1, 0), 3),
    ("8", [-O, -O, -O, -O, O, O, O, O], (1, 1), 4),
    ("8 (h = 0)", [-1.0, -1.125, -1.875, -1.625, 1.5, 1.0, 2.375, 2.25], (1, 1), 4),
    ("8 (zero)", [-2.0, -1.5, -2.5, -1.125, 1.25, 1.5, 1.125, 0.0], (1, 1), 4),
    ("9", [-O, O, -O, -O, O, O, -O, O], (1, 1), 4),
    ("9 (h = 0)", [-0.625, 0.125, -2.0, -0.75, 0.625, 1.875, -1.0, 0.75], (1, 1), 4),
    ("9 (zero)", [-1.25, 1.875, -1.375, -1.375, 1.875, 0.125, -1.125, 0.0], (1, 1), 4),
    ("10.1.1", [-1.25, 1.625, 1.875, -2.125, -1.25, 2.0, 1.375, -1.375], (2, 2), 4),
    ("10.1.1 (h = 0)", [-0.875, 1.625, 2.25, -0.125, -1.25, 2.125, 1.375, -0.125], (2, 2), 4),
    // Both faces join the inside corners: 10.1.1 of the complement.
    ("10.1.1 (complement, zero)", [-0.125, 1.0, 0.125, -1.75, -2.125, 1.625, 0.0, -1.125], (2, 2), 4),
    ("10.1.2", [-0.125, 1.375, 0.375, -2.5, -2.25, 1.625, 0.25, -0.125], (1, 0), 4),
    ("10.1.2 (h = 0)", [-2.0, 2.375, 1.125, -1.25, -0.125, 0.875, 1.5, -4.25], (1, 0), 4),
    ("10.1.2 (complement, h = 0)", [-1.0, 1.375, 0.25, -1.0, -0.75, 0.125, 2.25, -0.5], (1, 0), 4),
    ("10.1.2 (complement, zero)", [-1.625, 1.625, 0.125, -0.25, -2.125, 0.0, 2.375, -0.5], (1, 0), 4),
    ("10.2", [-1.875, 0.125, 2.25, -2.25, -1.875, 0.75, 2.375, -0.5], (1, 1), 4),
    ("10.2 (h = 0)", [-1.875, 2.125, 1.0, -1.875, -0.5, 2.5, 2.0, -1.875], (1, 1), 4),
    ("10.2 (zero)", [-0.25, 0.125, 0.0, -2.25, -0.25, 2.375, 2.5, -2.375], (1, 1), 4),
    ("11", [-O, O, -O, O, -O, -O, O, O], (1, 1), 4),
    ("11 (h = 0)", [-1.625, 2.0, -1.75, 2.0, -1.125, -2.5, 2.5, 1.25], (1, 1), 4),
    ("11 (zero)", [-2.0, 2.375, -2.0, 0.0, -1.5, -2.25, 0.5, 1.625], (1, 1), 4),
    ("12.1.1", [-0.75, -1.0, -2.5, 2.125, 0.375, 1.25, 1.875, -0.875], (2, 2), 4),
    ("12.1.1 (h = 0)", [-2.125, -0.875, -0.25, 0.375, 2.125, 1.625, 1.0, -0.125], (2, 2), 4),
    ("12.1.1 (zero)", [-1.75, -0.125, -1.0, 0.625, 0.0, 1.75, 0.625, -0.25], (2, 2), 4),
    ("12.1.2", [-2.375, -0.125, -1.0, 2.0, 1.0, 0.5, 1.625, -2.25], (1, 0), 4),
    ("12.1.2 (h = 0)", [-2.375, -0.125, -0.125, 0.875, 1.75, 0.875, 0.5, -1.625], (1, 0), 4),
    ("12.1.2 (zero)", [-2.0, -0.375, -0.5, 0.875, 0.0, 1.125, 2.5, -1.875], (1, 0), 4),
    // 12.2 and 12.3: one of the two ambiguous faces (x = 1, then y = 1) joins the inside
    // corners; they are mirror images, distinct under rotation.
    ("12.2", [-2.5, -1.75, -0.375, 1.0, 0.375, 0.5, 0.75, -0.375], (1, 1), 4),
    ("12.2 (h = 0)", [-2.375, -0.5, -0.125, 0.75, 2.25, 0.375, 1.125, -1.75], (1, 1), 4),
    ("12.2 (zero)", [-1.25, -1.875, -1.5, 2.375, 1.0, 0.0, 1.0, -0.125], (1, 1), 4),
    ("12.3", [-1.125, -0.875, -1.25, 0.875, 1.875, 2.5, 1.375, -2.125], (1, 1), 4),
    ("12.3 (h = 0)", [-2.25, -0.125, -0.625, 0.625, 0.875, 0.625, 0.125, -1.0], (1, 1), 4),
    ("12.3 (zero)", [-2.375, -1.875, -1.375, 2.0, 1.75, 1.125, 0.0, -0.875], (1, 1), 4),
    // 13: all six faces ambiguous. 13.1: none joins the inside corners; 13.2: one; 13.3:
    // two (adjacent: two opposite faces cannot both join); 13.4: three round one inside
    // corner (one loop of twelve crossings); 13.5: three round a triangle of inside
    // corners, leaving one inside and one outside corner cut off: three disks (13.5.1) or
    // a tube joining the two inside groups beside one disk (13.5.2). More joined faces are
    // the complements of these.
    ("13.1", [-1.25, 0.75, 2.375, -0.5, 2.5, -0.875, -2.25, 2.125], (4, 4), 4),
    ("13.1 (complement, zero)", [-2.375, 0.0, 0.375, -1.125, 0.25, -0.75, -1.0, 2.25], (4, 4), 4),
    ("13.2", [-1.625, 0.625, 1.375, -0.25, 1.0, -0.125, -1.625, 2.125], (3, 3), 4),
    ("13.2 (complement, zero)", [-1.25, 0.25, 1.625, -2.125, 1.125, -0.5, -0.125, 0.0], (3, 3), 4),
    ("13.3", [-2.0, 1.875, 0.75, -0.625, 1.375, -1.875, -0.625, 1.375], (2, 2), 4),
    ("13.3 (complement, zero)", [-0.375, 0.5, 1.375, -2.25, 0.75, -0.75, -1.0, 0.0], (2, 2), 4),
    ("13.4", [-1.875, 2.25, 1.0, -2.125, 0.125, -0.25, -0.375, 1.75], (1, 1), 4),
    ("13.5.1", [-1.875, 0.625, 1.875, -2.0, 0.875, -0.875, -0.75, 2.5], (3, 3), 4),
    ("13.5.1 (zero)", [-2.125, 0.0, 1.125, -1.875, 1.125, -1.375, -0.25, 2.5], (3, 3), 4),
    ("13.5.2", [-2.0, 2.125, 1.75, -2.125, 1.75, -2.5, -0.25, 2.375], (2, 1), 4),
    ("13.5.2 (zero)", [-1.5, 0.0, 2.0, -1.75, 1.5, -1.25, -1.625, 1.5], (2, 1), 4),
    ("14", [-O, O, -O, -O, O, O, O, -O], (1, 1), 4),
    ("14 (h = 0)", [-1.125, 2.375, -1.0, -1.0, 1.125, 1.75, 0.375, -2.5], (1, 1), 4),
    ("14 (zero)", [-2.125, 0.0, -0.125, -2.125, 2.25, 1.625, 1.75, -0.75], (1, 1), 4),
];

/// The trilinear interpolant of the corner values at `p` in the unit cube.
fn trilinear(v: &[f32; 8], p: [f64; 3]) -> f64 {
    (0..8)
        .map(|c| {
            let w = |i: usize| if (c >> i) & 1 == 1 { p[i] } else { 1.0 - p[i] };
            v[c] as f64 * w(0) * w(1) * w(2)
        })
        .sum()
}

/// The interpolant's surface inside the cube by brute force on an n³ lattice: a surface
/// properly embedded in a ball separates it, so components = regions − 1 and, by
/// Mayer–Vietoris, χ(surface) = χ(inside) + χ(outside) − 1, each region's χ counted on the
/// cubical complex of lattice cells whose corners all lie in it.
fn reference(v: &[f32; 8], n: usize) -> (usize, i64) {
    let s = (n - 1) as f64;
    let idx = |i: usize, j: usize, k: usize| i + n * (j + n * k);
    let inside: Vec<bool> = (0..n * n * n)
        .map(|q| {
            trilinear(v, [(q % n) as f64 / s, ((q / n) % n) as f64 / s, (q / (n * n)) as f64 / s])
                < 0.0
        })
        .collect();
    let (mut regions, mut chi) = (0usize, 0i64);
    for side in [true, false] {
        let on = |q: usize| inside[q] == side;
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    for dims in 0u8..8 {
                        let d = [dims & 1, (dims >> 1) & 1, dims >> 2].map(usize::from);
                        if i + d[0] >= n || j + d[1] >= n || k + d[2] >= n {
                            continue;
                        }
                        let all = (0..8u8).filter(|c| c & !dims == 0).all(|c| {
                            on(idx(
                                i + usize::from(c & 1),
                                j + usize::from((c >> 1) & 1),
                                k + usize::from(c >> 2),
                            ))
                        });
                        if all {
                            chi += if dims.count_ones() % 2 == 0 { 1 } else { -1 };
                        }
                    }
                }
            }
        }
        let mut parent: Vec<usize> = (0..inside.len()).collect();
        for q in (0..inside.len()).filter(|&q| on(q)) {
            let (i, j, k) = (q % n, (q / n) % n, q / (n * n));
            for (ok, r) in [(i + 1 < n, q + 1), (j + 1 < n, q + n), (k + 1 < n, q + n * n)] {
                if ok && on(r) {
                    let (a, b) = (root(&mut parent, q), root(&mut parent, r));
                    parent[a] = b;
                }
            }
        }
        let roots: BTreeSet<usize> =
            (0..inside.len()).filter(|&q| on(q)).map(|q| root(&mut parent, q)).collect();
        regions += roots.len();
    }
    (regions - 1, chi - 1)
}

fn root(p: &mut [usize], mut c: usize) -> usize {
    while p[c] != c {
        p[c] = p[p[c]];
        c = p[c];
    }
    c
}

/// The cube's mesh through the public API: the middle cell of a 4×4×4 volume whose outer
/// samples repeat the nearest corner's value.
fn extract(v: &[f32; 8]) -> Mesh {
    let grid = Grid { origin: DVec3::ZERO, cell: 1.0, dims: [4, 4, 4] };
    let mut values = vec![0f32; 64];
    for k in 0..4 {
        for j in 0..4 {
            for i in 0..4 {
                let c = |t: usize| usize::from(t >= 2);
                values[grid.index(i, j, k)] = v[c(i) | c(j) << 1 | c(k) << 2];
            }
        }
    }
    extract_mesh(&Volume::from_values(grid, values), &Control::default())
        .expect("a 4³ volume extracts")
}

/// Components and Euler characteristic of a mesh that may be open only on the volume's
/// boundary; also checks that every other edge has two oppositely wound triangles.
fn topology(m: &Mesh, name: &str) -> (usize, i64) {
    let mut winding: HashMap<(u32, u32), (usize, i32)> = HashMap::new();
    for t in &m.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let e = winding.entry((a.min(b), a.max(b))).or_default();
            e.0 += 1;
            e.1 += if a < b { 1 } else { -1 };
        }
    }
    let on_border = |a: u32, b: u32| {
        let (p, q) = (m.positions[a as usize], m.positions[b as usize]);
        (0..3).any(|i| [0.0, 3.0].iter().any(|&s| p[i] == s && q[i] == s))
    };
    for (&(a, b), &(n, w)) in &winding {
        if on_border(a, b) {
            assert_eq!(n, 1, "{name}: border edge {a}-{b} used {n} times");
        } else {
            assert_eq!((n, w), (2, 0), "{name}: edge {a}-{b} used {n} times, winding {w}");
        }
    }
    let mut parent: Vec<usize> = (0..m.positions.len()).collect();
    for t in &m.triangles {
        for k in 1..3 {
            let (a, b) = (root(&mut parent, t[0] as usize), root(&mut parent, t[k] as usize));
            parent[a] = b;
        }
    }
    let used: BTreeSet<u32> = m.triangles.iter().flatten().copied().collect();
    let comps: BTreeSet<usize> = used.iter().map(|&i| root(&mut parent, i as usize)).collect();
    let chi = used.len() as i64 - winding.len() as i64 + m.triangles.len() as i64;
    (comps.len(), chi)
}

/// The 48 symmetries of the cube applied to corner values: axes permuted, then flipped.
fn symmetries(v: &[f32; 8]) -> Vec<[f32; 8]> {
    let perms = [[0, 1, 2], [0, 2, 1], [1, 0, 2], [1, 2, 0], [2, 0, 1], [2, 1, 0]];
    let mut out = Vec::new();
    for p in perms {
        for flip in 0..8usize {
            let mut w = [0f32; 8];
            for (c, &x) in v.iter().enumerate() {
                let to = (0..3).fold(0, |m, i| m | ((((c >> i) & 1) ^ ((flip >> i) & 1)) << p[i]));
                w[to] = x;
            }
            out.push(w);
        }
    }
    out
}

#[test]
fn every_mc33_subcase_has_the_published_topology() {
    for &(name, v, expected, negatives) in CASES {
        let inside = v.iter().filter(|&&x| x < 0.0).count();
        assert!(inside == negatives || inside == 8 - negatives, "{name}: {inside} inside corners");
        assert_eq!(reference(&v, 49), expected, "{name}: published value against brute force");
        assert_eq!(topology(&extract(&v), name), expected, "{name}: mesh");
        // With the signs flipped the surface is the same set except where the interpolant
        // is exactly zero at a saddle (a sample at the iso value, a tie of a face's
        // products), which counts as outside either way; so the flipped cube is checked
        // against its own brute force.
        let flipped = v.map(|x| -x);
        let flipped_reference = reference(&flipped, 49);
        for (s, w) in symmetries(&v).iter().enumerate() {
            assert_eq!(topology(&extract(w), name), expected, "{name}: mesh under symmetry {s}");
            let f = w.map(|x| -x);
            assert_eq!(topology(&extract(&f), name), flipped_reference, "{name}: flipped, {s}");
        }
    }
}

#[test]
fn the_suite_covers_every_configuration_and_subcase() {
    let names: BTreeSet<&str> =
        CASES.iter().map(|c| c.0.split(' ').next().unwrap_or_default()).collect();
    for want in [
        "1", "2", "3.1", "3.2", "4.1.1", "4.1.2", "5", "6.1.1", "6.1.2", "6.2", "7.1", "7.2",
        "7.3", "7.4.1", "7.4.2", "8", "9", "10.1.1", "10.1.2", "10.2", "11", "12.1.1", "12.1.2",
        "12.2", "12.3", "13.1", "13.2", "13.3", "13.4", "13.5.1", "13.5.2", "14",
    ] {
        assert!(names.contains(want), "MC33 subcase {want} missing");
    }
}
