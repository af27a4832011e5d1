//! Checks a non-manifold mesh against its region function: the two tests the chapter's
//! definitions imply for every vertex and triangle.
//!
//! - A vertex of a sheet labelled `(a, b)` lies on the boundary between `a` and `b`:
//!   stepping `±step` along its normal lands in `a` in front and `b` behind (its normal points
//!   into the lesser region, as its triangles do). Vertices on intersection curves and
//!   borders meet three regions, so a step can land in the third; they are counted apart.
//! - A triangle's right-hand normal points into its lesser region: from the triangle's centre,
//!   a step along the normal lands in `a` and one against it in `b`. The step is at least
//!   `step` and at least the triangle's own deviation from the surface (an eighth of its
//!   longest side), because a flat triangle under a curved surface can have its centre on
//!   either side. Triangles touching a curve are only checked not to face the wrong way.

use glam::DVec3;
use skelform_field::RegionField;
use skelform_mesh::Mesh;

/// What [`verify`] found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Verification {
    /// Vertices away from curves, and those of them stepping into their two regions.
    pub vertices: usize,
    /// See `vertices`: the ones whose steps land in their pair's two regions, lesser in front.
    pub vertices_between: usize,
    /// Vertices (away from curves) whose steps land in their regions the wrong way round.
    pub vertices_reversed: usize,
    /// Vertices on curves (skipped).
    pub curve_vertices: usize,
    /// Triangles with no vertex on a curve, and those of them facing their lesser region.
    pub triangles: usize,
    /// See `triangles`: the ones whose normal points into their lesser region.
    pub triangles_facing_lesser: usize,
    /// Triangles with a vertex on a curve: a step from their centre can reach the third
    /// region, so they count only when reversed.
    pub curve_triangles: usize,
    /// Triangles whose steps land in their regions the wrong way round.
    pub triangles_reversed: usize,
}

impl Verification {
    /// The fraction of sheet vertices between their regions (1 for none).
    pub fn vertex_fraction(&self) -> f64 {
        if self.vertices == 0 { 1.0 } else { self.vertices_between as f64 / self.vertices as f64 }
    }

    /// The fraction of triangles facing their lesser region (1 for none).
    pub fn triangle_fraction(&self) -> f64 {
        if self.triangles == 0 {
            1.0
        } else {
            self.triangles_facing_lesser as f64 / self.triangles as f64
        }
    }
}

/// Checks every labelled vertex and triangle of `mesh` (with normals) against `regions`,
/// stepping `step` (the chapter's test uses 2ε).
pub fn verify(mesh: &Mesh, regions: &dyn RegionField, step: f64) -> Verification {
    let p = |i: u32| DVec3::from_array(mesh.positions[i as usize].map(f64::from));
    let mut on_curve = vec![false; mesh.positions.len()];
    let key = |i: usize| mesh.positions[i].map(f32::to_bits);
    let curve_points: std::collections::HashSet<[u32; 3]> =
        mesh.curves.iter().flat_map(|c| c.v).map(|v| key(v as usize)).collect();
    for (i, c) in on_curve.iter_mut().enumerate() {
        *c = curve_points.contains(&key(i));
    }
    let mut pair_of = vec![None; mesh.positions.len()];
    for (t, l) in mesh.triangles.iter().zip(&mesh.labels) {
        for &v in t {
            pair_of[v as usize] = Some(*l);
        }
    }
    let mut out = Verification::default();
    for (i, pair) in pair_of.iter().enumerate() {
        let Some(pair) = pair else { continue };
        if on_curve[i] {
            out.curve_vertices += 1;
            continue;
        }
        let Some(n) = mesh.normals.get(i) else { continue };
        let n = DVec3::from_array(n.map(f64::from));
        let q = p(i as u32);
        let (front, back) = (regions.region(q + n * step), regions.region(q - n * step));
        out.vertices += 1;
        out.vertices_between += usize::from(front == pair.0 && back == pair.1);
        out.vertices_reversed += usize::from(front == pair.1 && back == pair.0);
    }
    for (t, pair) in mesh.triangles.iter().zip(&mesh.labels) {
        let [a, b, c] = t.map(p);
        let n = (b - a).cross(c - a).normalize_or_zero();
        if n == DVec3::ZERO {
            continue;
        }
        let longest = (b - a).length().max((c - b).length()).max((a - c).length());
        let s = step.max(longest / 8.0);
        let centre = (a + b + c) / 3.0;
        let (front, back) = (regions.region(centre + n * s), regions.region(centre - n * s));
        out.triangles_reversed += usize::from(front == pair.1 && back == pair.0);
        if t.iter().any(|&v| on_curve[v as usize]) {
            out.curve_triangles += 1;
            continue;
        }
        out.triangles += 1;
        out.triangles_facing_lesser += usize::from(front == pair.0 && back == pair.1);
    }
    out
}
