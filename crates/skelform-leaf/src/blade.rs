//! The blade as a triangle mesh and the signed distance to it (dissertation §7.2).
//!
//! For each triangle, `p` is projected onto the triangle's plane: inside the triangle the
//! distance is the plane distance, outside it the distance to the nearest edge (or corner);
//! the triangle with the least distance wins. If `p`'s projection falls outside that
//! triangle and the nearest feature is on the margin, `p` is *beyond* the blade; otherwise
//! the sign says above (+) or below (−).
//!
//! Two refinements of the chapter's description, both kept exact:
//! * the sign near an interior edge or corner, where the projection falls outside every
//!   nearby triangle (on the convex side of a fold), comes from the feature's pseudo-normal
//!   (the sum of the adjacent faces' normals, angle-weighted at corners), so above and below
//!   never swap along a fold;
//! * instead of the chapter's octree, a bounding-volume hierarchy with branch-and-bound
//!   search: a box is skipped only when it is strictly farther than the best triangle so
//!   far, and ties are broken by the same key as a brute-force search, so the answer is
//!   bit-for-bit the brute-force answer (tested on random points).

use std::collections::HashMap;

use glam::DVec3;

/// Where a point is relative to the blade.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// On the side the triangles' normals point to (counter-clockwise seen from there; +z for a
    /// flat leaf): the signed distance is positive.
    Above,
    /// On the other side of the blade: the signed distance is negative.
    Below,
    /// Past the margin: the nearest feature is a margin edge or vertex and the point does not
    /// project onto the blade. The distance is unsigned there.
    Beyond,
}

/// The nearest feature of a triangle.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Feature {
    Face,
    /// Edge k runs from corner k to corner k + 1.
    Edge(u8),
    Vertex(u8),
}

impl Feature {
    fn rank(self) -> u8 {
        match self {
            Feature::Face => 0,
            Feature::Edge(_) => 1,
            Feature::Vertex(_) => 2,
        }
    }
}

/// The answer of a distance query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BladeDistance {
    /// Distance to the blade: positive above, negative below, positive (unsigned) beyond.
    pub distance: f64,
    /// Which side of the blade the point is on; decides the leaf region (above, below, beyond).
    pub side: Side,
    /// The nearest triangle.
    pub triangle: usize,
}

#[derive(Clone, Debug)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    /// Leaf: triangles `start..start + count` of `order`; inner: children `start`, `start + 1`.
    start: u32,
    count: u32,
}

/// A triangle mesh blade, ready for distance queries.
#[derive(Clone, Debug)]
pub struct Blade {
    /// Vertex positions in scene units, indexed by `triangles`.
    pub vertices: Vec<DVec3>,
    /// Vertex indices, counter-clockwise seen from above (so that face normals point to the
    /// [`Side::Above`] side).
    pub triangles: Vec<[u32; 3]>,
    /// Per triangle, whether edge k (corner k to k + 1) is on the margin (has one triangle).
    pub margin_edge: Vec<[bool; 3]>,
    /// Per vertex, whether it is an end of a margin edge; a point whose nearest feature is such a
    /// vertex may be beyond.
    pub vertex_on_margin: Vec<bool>,
    face_normal: Vec<DVec3>,
    edge_normal: Vec<[DVec3; 3]>,
    vertex_normal: Vec<DVec3>,
    nodes: Vec<Node>,
    order: Vec<u32>,
    scale: f64,
}

fn closest_on_triangle(p: DVec3, a: DVec3, b: DVec3, c: DVec3) -> (DVec3, Feature) {
    // Regions of the triangle's plane by the sign of dot products with its sides.
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Feature::Vertex(0));
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Feature::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (a + ab * (d1 / (d1 - d3)), Feature::Edge(0));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Feature::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (a + ac * (d2 / (d2 - d6)), Feature::Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, Feature::Edge(1));
    }
    let s = 1.0 / (va + vb + vc);
    (a + ab * (vb * s) + ac * (vc * s), Feature::Face)
}

fn box_distance2(p: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    let d = (lo - p).max(p - hi).max(DVec3::ZERO);
    d.length_squared()
}

/// A candidate's ordering key: distance², feature rank, triangle index.
type Key = (f64, u8, u32);

fn better(a: Key, b: Key) -> bool {
    a.0 < b.0 || (a.0 == b.0 && (a.1 < b.1 || (a.1 == b.1 && a.2 < b.2)))
}

impl Blade {
    /// A blade from triangles (counter-clockwise seen from above). Edges used by one triangle
    /// are the margin.
    pub fn new(vertices: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Blade {
        let mut uses: HashMap<(u32, u32), Vec<(usize, usize)>> = HashMap::new();
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                uses.entry((a.min(b), a.max(b))).or_default().push((t, k));
            }
        }
        let face_normal: Vec<DVec3> = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| vertices[i as usize]);
                (b - a).cross(c - a).normalize_or_zero()
            })
            .collect();
        let mut margin_edge = vec![[false; 3]; triangles.len()];
        let mut vertex_on_margin = vec![false; vertices.len()];
        let mut edge_normal = vec![[DVec3::ZERO; 3]; triangles.len()];
        for (&(a, b), list) in &uses {
            let n: DVec3 =
                list.iter().map(|&(t, _)| face_normal[t]).sum::<DVec3>().normalize_or_zero();
            for &(t, k) in list {
                edge_normal[t][k] = n;
                if list.len() == 1 {
                    margin_edge[t][k] = true;
                    vertex_on_margin[a as usize] = true;
                    vertex_on_margin[b as usize] = true;
                }
            }
        }
        let mut vertex_normal = vec![DVec3::ZERO; vertices.len()];
        for (t, tri) in triangles.iter().enumerate() {
            for k in 0..3 {
                let [a, b, c] =
                    [tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]].map(|i| vertices[i as usize]);
                let angle = (b - a).angle_between(c - a);
                if angle.is_finite() {
                    vertex_normal[tri[k] as usize] += face_normal[t] * angle;
                }
            }
        }
        for n in &mut vertex_normal {
            *n = n.normalize_or_zero();
        }
        let (lo, hi) = vertices
            .iter()
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(l, h), v| (l.min(*v), h.max(*v)));
        let scale = (hi - lo).max_element().max(1e-300);
        let mut blade = Blade {
            vertices,
            triangles,
            margin_edge,
            vertex_on_margin,
            face_normal,
            edge_normal,
            vertex_normal,
            nodes: Vec::new(),
            order: Vec::new(),
            scale,
        };
        blade.build_bvh();
        blade
    }

    fn tri_box(&self, t: u32) -> (DVec3, DVec3) {
        let [a, b, c] = self.triangles[t as usize].map(|i| self.vertices[i as usize]);
        (a.min(b).min(c), a.max(b).max(c))
    }

    fn build_bvh(&mut self) {
        let mut order: Vec<u32> = (0..self.triangles.len() as u32).collect();
        let centre: Vec<DVec3> = order
            .iter()
            .map(|&t| {
                let (l, h) = self.tri_box(t);
                (l + h) * 0.5
            })
            .collect();
        let mut nodes = vec![Node { lo: DVec3::ZERO, hi: DVec3::ZERO, start: 0, count: 0 }];
        // (node, start, end) to fill.
        let mut stack = vec![(0usize, 0usize, order.len())];
        while let Some((node, s, e)) = stack.pop() {
            let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
            for &t in &order[s..e] {
                let (l, h) = self.tri_box(t);
                lo = lo.min(l);
                hi = hi.max(h);
            }
            // A little slack, so rounding in a triangle's nearest point can never put it
            // outside its box (the search must stay exact).
            let slack = DVec3::splat(1e-9 * self.scale);
            let (lo, hi) = (lo - slack, hi + slack);
            if e - s <= 4 {
                nodes[node] = Node { lo, hi, start: s as u32, count: (e - s) as u32 };
                continue;
            }
            let (clo, chi) =
                order[s..e].iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(l, h), &t| {
                    (l.min(centre[t as usize]), h.max(centre[t as usize]))
                });
            let ext = chi - clo;
            let axis = if ext.x >= ext.y && ext.x >= ext.z {
                0
            } else if ext.y >= ext.z {
                1
            } else {
                2
            };
            order[s..e].sort_by(|&a, &b| {
                centre[a as usize][axis].total_cmp(&centre[b as usize][axis]).then(a.cmp(&b))
            });
            let mid = (s + e) / 2;
            let child = nodes.len();
            nodes.push(Node { lo: DVec3::ZERO, hi: DVec3::ZERO, start: 0, count: 0 });
            nodes.push(Node { lo: DVec3::ZERO, hi: DVec3::ZERO, start: 0, count: 0 });
            nodes[node] = Node { lo, hi, start: child as u32, count: 0 };
            stack.push((child, s, mid));
            stack.push((child + 1, mid, e));
        }
        self.nodes = nodes;
        self.order = order;
    }

    fn candidate(&self, p: DVec3, t: u32) -> (Key, DVec3, Feature) {
        let [a, b, c] = self.triangles[t as usize].map(|i| self.vertices[i as usize]);
        let (q, f) = closest_on_triangle(p, a, b, c);
        ((p.distance_squared(q), f.rank(), t), q, f)
    }

    fn answer(&self, p: DVec3, t: u32, q: DVec3, f: Feature) -> BladeDistance {
        let tri = self.triangles[t as usize];
        let d = p - q;
        let len = d.length();
        let n = self.face_normal[t as usize];
        let on_margin = match f {
            Feature::Face => false,
            Feature::Edge(k) => self.margin_edge[t as usize][k as usize],
            Feature::Vertex(k) => self.vertex_on_margin[tri[k as usize] as usize],
        };
        // Outside the triangle: the offset has a component in the triangle's plane.
        let in_plane = (d - n * d.dot(n)).length();
        if on_margin && in_plane > 1e-12 * self.scale {
            return BladeDistance { distance: len, side: Side::Beyond, triangle: t as usize };
        }
        let normal = match f {
            Feature::Face => n,
            Feature::Edge(k) => self.edge_normal[t as usize][k as usize],
            Feature::Vertex(k) => self.vertex_normal[tri[k as usize] as usize],
        };
        let s = d.dot(normal);
        let (distance, side) = if s > 0.0 { (len, Side::Above) } else { (-len, Side::Below) };
        BladeDistance { distance, side, triangle: t as usize }
    }

    /// Signed distance and side of `p` (see the module documentation).
    pub fn distance(&self, p: DVec3) -> BladeDistance {
        let mut best: Option<(Key, DVec3, Feature)> = None;
        let mut stack: Vec<u32> = vec![0];
        while let Some(n) = stack.pop() {
            let node = &self.nodes[n as usize];
            let bd = box_distance2(p, node.lo, node.hi);
            if let Some((k, _, _)) = &best
                && bd > k.0
            {
                continue;
            }
            if node.count > 0 {
                for &t in &self.order[node.start as usize..(node.start + node.count) as usize] {
                    let c = self.candidate(p, t);
                    if best.as_ref().is_none_or(|b| better(c.0, b.0)) {
                        best = Some(c);
                    }
                }
            } else {
                let (a, b) = (node.start, node.start + 1);
                let da = box_distance2(p, self.nodes[a as usize].lo, self.nodes[a as usize].hi);
                let db = box_distance2(p, self.nodes[b as usize].lo, self.nodes[b as usize].hi);
                // Nearer child last, so it is searched first.
                if da <= db {
                    stack.push(b);
                    stack.push(a);
                } else {
                    stack.push(a);
                    stack.push(b);
                }
            }
        }
        match best {
            Some((k, q, f)) => self.answer(p, k.2, q, f),
            None => BladeDistance { distance: f64::INFINITY, side: Side::Beyond, triangle: 0 },
        }
    }

    /// The same answer by testing every triangle (for tests and as the definition).
    pub fn distance_brute_force(&self, p: DVec3) -> BladeDistance {
        let mut best: Option<(Key, DVec3, Feature)> = None;
        for t in 0..self.triangles.len() as u32 {
            let c = self.candidate(p, t);
            if best.as_ref().is_none_or(|b| better(c.0, b.0)) {
                best = Some(c);
            }
        }
        match best {
            Some((k, q, f)) => self.answer(p, k.2, q, f),
            None => BladeDistance { distance: f64::INFINITY, side: Side::Beyond, triangle: 0 },
        }
    }

    /// Total area.
    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize]);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }

    /// Bounding box of the blade.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (self.nodes[0].lo, self.nodes[0].hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Blade {
        let v = vec![
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(1.0, -1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0),
        ];
        Blade::new(v, vec![[0, 1, 2], [0, 2, 3]])
    }

    #[test]
    fn above_below_and_beyond_a_square() {
        let b = square();
        let d = b.distance(DVec3::new(0.3, 0.2, 0.5));
        assert_eq!(d.side, Side::Above);
        assert!((d.distance - 0.5).abs() < 1e-15);
        let d = b.distance(DVec3::new(0.3, 0.2, -0.25));
        assert_eq!(d.side, Side::Below);
        assert!((d.distance + 0.25).abs() < 1e-15);
        // On the diagonal (an interior edge): still above.
        assert_eq!(b.distance(DVec3::new(0.5, 0.5, 0.1)).side, Side::Above);
        let d = b.distance(DVec3::new(1.5, 0.0, 0.0));
        assert_eq!(d.side, Side::Beyond);
        assert!((d.distance - 0.5).abs() < 1e-15);
        let d = b.distance(DVec3::new(1.3, 1.4, 0.3));
        assert_eq!(d.side, Side::Beyond);
        assert!((d.distance - (0.09f64 + 0.16 + 0.09).sqrt()).abs() < 1e-15);
        // Straight above the margin: the projection is on the triangle, so above.
        assert_eq!(b.distance(DVec3::new(1.0, 0.0, 0.2)).side, Side::Above);
    }

    #[test]
    fn a_fold_keeps_above_above() {
        // Two triangles folded up along x = 0 (a valley): points above the crease are above.
        let v = vec![
            DVec3::new(-1.0, -1.0, 0.5),
            DVec3::new(0.0, -1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.5),
            DVec3::new(1.0, -1.0, 0.5),
            DVec3::new(1.0, 1.0, 0.5),
        ];
        let b = Blade::new(v, vec![[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]]);
        // A ridge instead (negate z) and a point above the crest, outside both projections.
        let v2: Vec<DVec3> = b.vertices.iter().map(|p| DVec3::new(p.x, p.y, -p.z)).collect();
        let ridge = Blade::new(v2, b.triangles.clone());
        let d = ridge.distance(DVec3::new(0.0, 0.0, 0.3));
        assert_eq!(d.side, Side::Above);
        assert!((d.distance - 0.3).abs() < 1e-12);
        assert_eq!(ridge.distance(DVec3::new(0.0, 0.0, -0.3)).side, Side::Below);
        assert_eq!(b.distance(DVec3::new(0.0, 0.0, 0.3)).side, Side::Above);
    }
}
