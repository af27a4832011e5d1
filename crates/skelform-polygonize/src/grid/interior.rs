//! The interior ambiguity: does the trilinear interpolant join two caps through the cube?
//!
//! When the surface meets a cube's boundary in two loops, the cube's corner values admit two
//! surfaces inside it: two separate disks, or one tube joining the loops. Marching cubes
//! without this test always picks the disks and so loses tunnels that the trilinear
//! interpolant of the samples has (the configurations MC33 numbers 4.1.2, 6.1.2, 7.4.2,
//! 10.1.2, 12.1.2 and 13.5.2). The choice never affects a neighbouring cube, so either
//! answer keeps the mesh closed; this test makes it agree with the interpolant.
//!
//! The trilinear function has at most two interior critical points, both saddles (its
//! Hessian has zero trace). A saddle with one descending direction joins regions where
//! `f < 0` once the level passes its value; one with two joins regions where `f > 0`. The
//! caps of the inside sign are joined through the interior exactly when the cube holds a
//! saddle of the kind that joins that sign, at a value of that sign. The unit test checks
//! this rule against a brute-force flood fill of the interpolant on a fine lattice.

/// The coefficients of `a + b x + c y + d z + e xy + f yz + g xz + h xyz` for corner values.
fn coefficients(v: &[f32; 8]) -> [f64; 8] {
    let v = v.map(|x| x as f64);
    [
        v[0],
        v[1] - v[0],
        v[2] - v[0],
        v[4] - v[0],
        v[3] - v[1] - v[2] + v[0],
        v[6] - v[2] - v[4] + v[0],
        v[5] - v[1] - v[4] + v[0],
        v[7] - v[6] - v[5] - v[3] + v[1] + v[2] + v[4] - v[0],
    ]
}

/// The trilinear interpolant at `p` in the unit cube.
pub fn trilinear(v: &[f32; 8], p: [f64; 3]) -> f64 {
    let [a, b, c, d, e, f, g, h] = coefficients(v);
    let [x, y, z] = p;
    a + b * x + c * y + d * z + e * x * y + f * y * z + g * x * z + h * x * y * z
}

/// A critical point of the interpolant strictly inside the cube.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Saddle {
    pub p: [f64; 3],
    pub value: f64,
    /// True for a saddle with one descending direction, which joins `f < 0` regions.
    pub joins_inside: bool,
}

/// The interior saddles of the interpolant (zero, one or two).
pub fn saddles(v: &[f32; 8]) -> Vec<Saddle> {
    let [_, b, c, d, e, f, g, h] = coefficients(v);
    let scale = v.iter().fold(0f64, |m, &x| m.max((x as f64).abs()));
    if h.abs() <= 1e-12 * scale {
        // Without the cubic term the gradient equations are linear in pairs and the critical
        // set is a line or empty; such cubes have no isolated saddle to join caps through.
        return Vec::new();
    }
    // With X = x + f/h, Y = y + g/h, Z = z + e/h the gradient is
    // h·(YZ, XZ, XY) + (bx, by, bz), so YZ = P, XZ = Q, XY = R.
    let p = -(b - e * g / h) / h;
    let q = -(c - e * f / h) / h;
    let r = -(d - f * g / h) / h;
    let w2 = p * q * r;
    if w2.is_nan() || w2 <= 0.0 || p == 0.0 || q == 0.0 || r == 0.0 {
        return Vec::new();
    }
    let w = w2.sqrt();
    let mut out = Vec::new();
    for w in [w, -w] {
        let pt = [w / p - f / h, w / q - g / h, w / r - e / h];
        if pt.iter().all(|&t| t > 0.0 && t < 1.0) {
            // det(Hessian) = 2 h³ XYZ = 2 h³ w; negative ⇔ one descending direction.
            out.push(Saddle { p: pt, value: trilinear(v, pt), joins_inside: h * h * h * w < 0.0 });
        }
    }
    out
}

/// The saddle through which caps of the given side join, if there is one.
pub fn tunnel(v: &[f32; 8], caps_inside: bool) -> Option<Saddle> {
    saddles(v).into_iter().find(|s| {
        s.joins_inside == caps_inside && if caps_inside { s.value < 0.0 } else { s.value >= 0.0 }
    })
}

#[cfg(test)]
mod tests {
    use super::super::cell::face_decisions;
    use super::super::table::{corner_groups, table};
    use super::*;
    use std::collections::VecDeque;

    /// How many components of the interpolant's `side` region (inside: `f < 0`) within the
    /// cube hold corners, by flood fill on an n³ lattice.
    fn interior_groups(v: &[f32; 8], inside: bool, n: usize) -> usize {
        let on = |val: f64| if inside { val < 0.0 } else { val >= 0.0 };
        let idx = |i: usize, j: usize, k: usize| i + n * (j + n * k);
        let at = |i: usize, j: usize, k: usize| {
            let s = (n - 1) as f64;
            on(trilinear(v, [i as f64 / s, j as f64 / s, k as f64 / s]))
        };
        let mut label = vec![usize::MAX; n * n * n];
        let mut comp = 0;
        for k in 0..n {
            for j in 0..n {
                for i in 0..n {
                    if label[idx(i, j, k)] != usize::MAX || !at(i, j, k) {
                        continue;
                    }
                    label[idx(i, j, k)] = comp;
                    let mut queue = VecDeque::from([(i, j, k)]);
                    while let Some((a, b, c)) = queue.pop_front() {
                        let next = [
                            (a.wrapping_sub(1), b, c),
                            (a + 1, b, c),
                            (a, b.wrapping_sub(1), c),
                            (a, b + 1, c),
                            (a, b, c.wrapping_sub(1)),
                            (a, b, c + 1),
                        ];
                        for (x, y, z) in next {
                            if x < n
                                && y < n
                                && z < n
                                && label[idx(x, y, z)] == usize::MAX
                                && at(x, y, z)
                            {
                                label[idx(x, y, z)] = comp;
                                queue.push_back((x, y, z));
                            }
                        }
                    }
                    comp += 1;
                }
            }
        }
        let m = n - 1;
        let mut held: Vec<usize> = (0..8)
            .filter(|&c| on(v[c] as f64))
            .map(|c| label[idx((c & 1) * m, ((c >> 1) & 1) * m, (c >> 2) * m)])
            .collect();
        held.sort_unstable();
        held.dedup();
        held.len()
    }

    /// Whether some face's bilinear saddle value is too close to zero for a lattice to see.
    fn near_face_saddle(v: &[f32; 8]) -> bool {
        super::super::cube::FACES.iter().any(|q| {
            let [a, b, c, d] = q.map(|i| v[i] as f64);
            let den = a + c - b - d;
            den != 0.0 && ((a * c - b * d) / den).abs() < 0.02
        })
    }

    fn lcg(seed: &mut u64) -> f32 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        ((*seed >> 33) as f64 / (1u64 << 31) as f64 * 2.0 - 1.0) as f32
    }

    /// The mesh joins boundary groups of corners exactly where the interpolant does: through a
    /// tube for two loops when the saddle rule says so, never for three or four loops (which
    /// this test confirms rather than assumes).
    #[test]
    fn interior_topology_agrees_with_flood_fill() {
        let t = table();
        let mut seed = 7u64;
        let (mut two, mut tunnels, mut more) = (0, 0, 0);
        while two < 400 || tunnels < 20 || more < 150 {
            let v: [f32; 8] = std::array::from_fn(|_| lcg(&mut seed));
            let case = (0..8).fold(0usize, |m, c| m | (((v[c] < 0.0) as usize) << c));
            let d = face_decisions(&v, t.ambiguous[case]);
            let e = t.entry(case, d as usize);
            if e.loop_count < 2
                || saddles(&v).iter().any(|s| s.value.abs() < 0.02)
                || near_face_saddle(&v)
            {
                continue; // near-degenerate cubes a lattice cannot resolve
            }
            for side in [true, false] {
                let on_boundary = corner_groups(case as u8, d, side);
                let joined = on_boundary - interior_groups(&v, side, 33);
                let predicted = usize::from(
                    e.loop_count == 2 && e.caps_inside == side && tunnel(&v, side).is_some(),
                );
                assert_eq!(joined, predicted, "values {v:?} case {case} decisions {d} side {side}");
                tunnels += predicted;
            }
            if e.loop_count == 2 { two += 1 } else { more += 1 }
        }
    }
}
