//! Post-processing: winding each triangle from its lesser region, merging close vertices,
//! snapping thin triangles' vertices onto the opposite side, dropping degenerate triangles,
//! and duplicating vertices per region pair with their normals.

use glam::DVec3;
use rustc_hash::{FxHashMap, FxHashSet};
use skelform_mesh::{CurveEdge, Mesh, RegionPair, RegionTriple};

use super::Run;

/// Least turn of a curve (radians, 30°) that [`Run::sharpen`] takes for a corner.
const CORNER_TURN: f64 = std::f64::consts::PI / 6.0;

/// Least cosine between a triangle's normal and the direction across a face's line that
/// [`Run::orient`] winds it by: a triangle closer to the face's plane leaves it to its
/// neighbours.
const LINK_STEEP: f64 = 0.2;

impl Run<'_> {
    /// Winds every triangle counter-clockwise seen from its lesser region. Each triangle has
    /// an edge vertex of its own pair, whose lattice segment runs from one region into the
    /// other: the normal must point back along it towards the lesser region. (A probe off
    /// the triangle would do for large triangles, but a flat triangle under a curved surface
    /// can have both probes on one side.)
    pub(super) fn orient(&mut self) {
        let mut unknown: Vec<usize> = Vec::new();
        // Triangles the link sides would wind: wound by their neighbours first, by the link
        // side only where no neighbour reaches them. Why: a side's direction across a cap's
        // line is a guess from where its regions touch the face, and two faces' guesses can
        // disagree (a slab tilted along the vein near a lattice plane: 2 inconsistent cap
        // edges), while a neighbour across a shared side is exact.
        let mut guessed: FxHashMap<usize, DVec3> = FxHashMap::default();
        for (i, (t, pair)) in self.triangles.iter_mut().zip(&self.labels).enumerate() {
            let [a, b, c] = t.map(|i| self.positions[i as usize]);
            let n = (b - a).cross(c - a);
            let witness = t.iter().find_map(|&v| match self.crossing[v as usize] {
                Some((dir, from, to)) if RegionPair::new(from, to) == *pair => Some((dir, from)),
                _ => None,
            });
            match witness {
                // Along `dir` the region goes from `from` to the other: the lesser region lies
                // against `dir` when it is `from`.
                Some((dir, from)) => {
                    let towards_lesser = if from == pair.0 { -dir } else { dir };
                    if n.dot(towards_lesser) < 0.0 {
                        t.swap(1, 2);
                    }
                }
                // A triangle on a line joining two face vertices (a sheet crossing the face
                // between two junctions, as the end of a vein slab thinner than the cell
                // crosses it without an edge vertex of its own) is wound by which region
                // lies on which side of the line in the face, when it leaves the face's
                // plane steeply enough for that to tell.
                None => {
                    let side = (0..3).find_map(|k| {
                        let (u, v) = (t[k], t[(k + 1) % 3]);
                        let s = self.link_sides.get(&(u.min(v), u.max(v)))?;
                        (s.2 == *pair).then_some((u, v, s.0, s.1))
                    });
                    let across = side.and_then(|(u, v, dir, region)| {
                        let e = (self.positions[v as usize] - self.positions[u as usize])
                            .normalize_or_zero();
                        let d = (dir - e * dir.dot(e)).normalize_or_zero();
                        let steep = n.normalize_or_zero().dot(d).abs() >= LINK_STEEP;
                        steep.then_some(if region == pair.0 { d } else { -d })
                    });
                    match across {
                        Some(towards_lesser) => {
                            guessed.insert(i, towards_lesser);
                            unknown.push(i);
                        }
                        None => unknown.push(i),
                    }
                }
            }
        }
        if !unknown.is_empty() {
            let mut left = self.orient_from_neighbours(&unknown);
            if !guessed.is_empty() {
                let mut rest = Vec::new();
                for &i in &left {
                    match guessed.get(&i) {
                        Some(&towards_lesser) => {
                            let t = &mut self.triangles[i];
                            let [a, b, c] = t.map(|v| self.positions[v as usize]);
                            if (b - a).cross(c - a).dot(towards_lesser) < 0.0 {
                                t.swap(1, 2);
                            }
                        }
                        None => rest.push(i),
                    }
                }
                left = if rest.is_empty() { rest } else { self.orient_from_neighbours(&rest) };
            }
            self.stats.unoriented_triangles += left.len();
        }
    }

    /// Winds the triangles without an edge vertex of their own pair (the joins between two
    /// internal vertices, and fans of a contour between two face vertices) like a
    /// neighbour of their pair across a shared side, which the two must cross in opposite
    /// directions; repeated until no more can be wound. Returns the rest ([`Run::orient`]
    /// winds those it can by their link side and counts the others,
    /// `unoriented_triangles`).
    fn orient_from_neighbours(&mut self, unknown: &[usize]) -> Vec<usize> {
        let key = |a: u32, b: u32| (a.min(b), a.max(b));
        let mut sharing: FxHashMap<((u32, u32), RegionPair), Vec<usize>> = FxHashMap::default();
        for &i in unknown {
            let t = self.triangles[i];
            for k in 0..3 {
                sharing.insert((key(t[k], t[(k + 1) % 3]), self.labels[i]), Vec::new());
            }
        }
        for (i, (t, pair)) in self.triangles.iter().zip(&self.labels).enumerate() {
            for k in 0..3 {
                if let Some(v) = sharing.get_mut(&(key(t[k], t[(k + 1) % 3]), *pair)) {
                    v.push(i);
                }
            }
        }
        let mut done = vec![true; self.triangles.len()];
        for &i in unknown {
            done[i] = false;
        }
        let mut left = unknown.to_vec();
        loop {
            let before = left.len();
            let mut still = Vec::with_capacity(left.len());
            for &i in &left {
                let t = self.triangles[i];
                let found = (0..3).find_map(|k| {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    let s = &sharing[&(key(a, b), self.labels[i])];
                    let j = match s.as_slice() {
                        [x, y] if *x == i => *y,
                        [x, y] if *y == i => *x,
                        _ => return None,
                    };
                    done[j].then(|| {
                        let tj = self.triangles[j];
                        (0..3).any(|m| tj[m] == a && tj[(m + 1) % 3] == b)
                    })
                });
                match found {
                    Some(same_way) => {
                        if same_way {
                            self.triangles[i].swap(1, 2);
                        }
                        done[i] = true;
                    }
                    None => still.push(i),
                }
            }
            left = still;
            if left.is_empty() || left.len() == before {
                break;
            }
        }
        left
    }

    /// Keeps the corners of curves sharp, beyond the chapter (which notes that its corners
    /// come out bevelled): the internal vertex of a curve passing through a tetrahedron is
    /// put at the midpoint of the face vertices where it enters and leaves, which cuts a
    /// corner inside the tetrahedron short by up to a quarter of a cell. Where the curve
    /// runs straight for two face vertices before and after (each side bends by at most a
    /// fifth of the turn between them) and turns by at least [`CORNER_TURN`], the lines
    /// through those sides are extended; where they meet (to within 16ε) inside the
    /// tetrahedron, the vertex moves to the meeting point, the corner. A smooth curve bends
    /// on each side about half as much as between them and is left alone.
    pub(super) fn sharpen(&mut self) {
        let mut at: FxHashMap<u32, Vec<usize>> = FxHashMap::default();
        for (i, (_, hubs, _)) in self.through.iter().enumerate() {
            for &h in hubs {
                at.entry(h).or_default().push(i);
            }
        }
        // Along the curve from face vertex `h`, away from the pass `i`: the next pass and
        // the face vertex it leaves by.
        let beyond = |h: u32, i: usize| -> Option<(usize, u32)> {
            let j = match at.get(&h)?.as_slice() {
                [a, b] if *a == i => *b,
                [a, b] if *b == i => *a,
                _ => return None,
            };
            let hs = self.through[j].1;
            Some((j, if hs[0] == h { hs[1] } else { hs[0] }))
        };
        let mut moves: Vec<(u32, DVec3)> = Vec::new();
        for (i, &(c, [h1, h2], tet)) in self.through.iter().enumerate() {
            let side = |h: u32| -> Option<[u32; 3]> {
                let (j, a) = beyond(h, i)?;
                let (_, b) = beyond(a, j)?;
                Some([h, a, b])
            };
            let (Some(s1), Some(s2)) = (side(h1), side(h2)) else { continue };
            let p = |v: u32| self.positions[v as usize];
            let [p1, p0, pm] = s1.map(p);
            let [p2, p3, p4] = s2.map(p);
            // Each side's line runs through the face vertex and the one two further on; the
            // one between tells how much the side bends, unless a side is too short to tell
            // a direction (the curve clipping a tetrahedron's corner).
            let short = self.grid.cell / 8.0;
            let angle = |a: DVec3, b: DVec3| {
                a.normalize_or_zero().dot(b.normalize_or_zero()).clamp(-1.0, 1.0).acos()
            };
            let bend = |h: DVec3, a: DVec3, b: DVec3| {
                if h.distance(a) < short || a.distance(b) < short {
                    0.0
                } else {
                    angle(h - a, a - b)
                }
            };
            let (d1, d2) = ((p1 - pm).normalize_or_zero(), (p2 - p4).normalize_or_zero());
            let turn = angle(d1, -d2);
            let bends = bend(p1, p0, pm).max(bend(p2, p3, p4));
            if turn < CORNER_TURN || bends > turn / 5.0 {
                continue;
            }
            // Closest points of the lines p1 + s d1 and p2 + u d2.
            let w = p1 - p2;
            let (b, d, e) = (d1.dot(d2), d1.dot(w), d2.dot(w));
            let den = 1.0 - b * b;
            if den < 1e-6 {
                continue;
            }
            let (s, u) = ((b * e - d) / den, (e - b * d) / den);
            let (q1, q2) = (p1 + d1 * s, p2 + d2 * u);
            if s < 0.0 || u < 0.0 || q1.distance(q2) > 16.0 * self.eps {
                continue;
            }
            let x = (q1 + q2) * 0.5;
            // At a face vertex the chord already follows the curve on both sides.
            if x.distance(p1).min(x.distance(p2)) < 16.0 * self.eps {
                continue;
            }
            if self.in_tetrahedron(tet, x) {
                moves.push((c, x));
            }
        }
        self.stats.sharpened_corners += moves.len();
        for (c, x) in moves {
            self.positions[c as usize] = x;
        }
    }

    /// Whether `x` lies in the tetrahedron of lattice points `t` (to within ε).
    fn in_tetrahedron(&self, t: [crate::lattice::cubes::Key; 4], x: DVec3) -> bool {
        let [a, b, c, d] = t.map(|k| self.point(k));
        let vol = |p: DVec3, q: DVec3, r: DVec3, s: DVec3| (q - p).cross(r - p).dot(s - p);
        let total = vol(a, b, c, d);
        let parts = [vol(x, b, c, d), vol(a, x, c, d), vol(a, b, x, d), vol(a, b, c, x)];
        let cell3 = self.grid.cell.powi(2) * self.eps;
        parts.iter().all(|&v| v * total.signum() >= -cell3)
    }

    /// Merges close vertices, drops degenerate triangles, duplicates vertices per pair.
    pub(super) fn finish(&mut self) -> Mesh {
        let n = self.positions.len();
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn root(p: &mut [u32], mut x: u32) -> u32 {
            while p[x as usize] != x {
                p[x as usize] = p[p[x as usize] as usize];
                x = p[x as usize];
            }
            x
        }
        let limit = self.opts.close_factor * self.eps;
        for &(u, v) in &self.fused {
            let (ru, rv) = (root(&mut parent, u), root(&mut parent, v));
            if ru != rv {
                parent[ru.max(rv) as usize] = ru.min(rv);
                self.stats.merged_vertices += 1;
            }
        }
        for t in &self.triangles {
            for k in 0..3 {
                let (u, v) = (t[k], t[(k + 1) % 3]);
                if self.positions[u as usize].distance(self.positions[v as usize]) < limit {
                    let (ru, rv) = (root(&mut parent, u), root(&mut parent, v));
                    if ru != rv {
                        parent[ru.max(rv) as usize] = ru.min(rv);
                        self.stats.merged_vertices += 1;
                    }
                }
            }
        }
        let mut sum: FxHashMap<u32, (DVec3, f64)> = FxHashMap::default();
        for v in 0..n as u32 {
            let r = root(&mut parent, v);
            let e = sum.entry(r).or_insert((DVec3::ZERO, 0.0));
            e.0 += self.positions[v as usize];
            e.1 += 1.0;
        }
        let mut pos = self.positions.clone();
        for (&r, &(s, c)) in &sum {
            pos[r as usize] = s / c;
        }
        let mut tris: Vec<([u32; 3], RegionPair)> = Vec::with_capacity(self.triangles.len());
        for (t, &pair) in self.triangles.iter().zip(&self.labels) {
            let r = t.map(|v| root(&mut parent, v));
            if r[0] == r[1] || r[1] == r[2] || r[0] == r[2] {
                self.stats.dropped_triangles += 1;
                continue;
            }
            tris.push((r, pair));
        }
        let mut curves: Vec<CurveEdge> = Vec::with_capacity(self.curves.len());
        for c in &self.curves {
            let v = c.v.map(|v| root(&mut parent, v));
            if v[0] != v[1] {
                curves.push(CurveEdge { v, label: c.label });
            }
        }
        let (snapped, dropped) = snap_to_edges(&mut pos, &mut tris, &mut curves, limit);
        self.stats.snapped_to_edges += snapped;
        self.stats.dropped_triangles += dropped;
        // Duplicate per (merged vertex, pair); keep first-use order, so output is stable.
        let mut copy: FxHashMap<(u32, RegionPair), u32> = FxHashMap::default();
        let mut copy_of: Vec<(DVec3, RegionPair)> = Vec::new();
        let mut first_copy: FxHashMap<u32, u32> = FxHashMap::default();
        let mut mesh = Mesh::default();
        let mut counts: FxHashMap<RegionPair, usize> = FxHashMap::default();
        for &(r, pair) in &tris {
            let tri = r.map(|v| {
                *copy.entry((v, pair)).or_insert_with(|| {
                    let p = pos[v as usize];
                    mesh.positions.push(p.as_vec3().to_array());
                    copy_of.push((p, pair));
                    let id = mesh.positions.len() as u32 - 1;
                    first_copy.entry(v).or_insert(id);
                    id
                })
            });
            mesh.triangles.push(tri);
            mesh.labels.push(pair);
            *counts.entry(pair).or_default() += 1;
        }
        // Normals per copy: area-weighted, from its pair's triangles only.
        let mut acc = vec![DVec3::ZERO; mesh.positions.len()];
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| DVec3::from_array(mesh.positions[i as usize].map(f64::from)));
            let nrm = (b - a).cross(c - a);
            for &i in t {
                acc[i as usize] += nrm;
            }
        }
        // Where the region function has a gradient for the pair (the chapter's
        // `Gradient(p, pair)`), it gives the normal. Its sign is the function's own, so it is
        // turned, once per pair, to agree with most of the pair's triangles (weighted by
        // area): per vertex, a few tiny triangles at the curves could turn it the wrong way.
        let grads: Vec<Option<DVec3>> = copy_of
            .iter()
            .map(|&(p, pair)| {
                let g = self.regions.gradient(p, (pair.0, pair.1))?.normalize_or_zero();
                (g != DVec3::ZERO).then_some(g)
            })
            .collect();
        let mut agree: FxHashMap<RegionPair, f64> = FxHashMap::default();
        for ((g, n), &(_, pair)) in grads.iter().zip(&acc).zip(&copy_of) {
            if let Some(g) = g {
                *agree.entry(pair).or_default() += g.dot(*n);
            }
        }
        for ((g, n), &(_, pair)) in grads.iter().zip(acc.iter_mut()).zip(&copy_of) {
            if let Some(g) = g {
                *n = if agree[&pair] < 0.0 { -*g } else { *g };
                self.stats.gradient_normals += 1;
            }
        }
        mesh.normals = acc.iter().map(|n| n.normalize_or_zero().as_vec3().to_array()).collect();
        let mut lengths: FxHashMap<RegionTriple, f64> = FxHashMap::default();
        for c in &curves {
            let r = c.v;
            let (Some(&a), Some(&b)) = (first_copy.get(&r[0]), first_copy.get(&r[1])) else {
                continue;
            };
            let pa = DVec3::from_array(mesh.positions[a as usize].map(f64::from));
            let pb = DVec3::from_array(mesh.positions[b as usize].map(f64::from));
            *lengths.entry(c.label).or_default() += pa.distance(pb);
            mesh.curves.push(CurveEdge { v: [a, b], label: c.label });
        }
        let mut per_pair: Vec<(RegionPair, usize)> = counts.into_iter().collect();
        per_pair.sort_unstable();
        self.stats.triangles_per_pair = per_pair;
        let mut per_triple: Vec<(RegionTriple, f64)> = lengths.into_iter().collect();
        per_triple.sort_by_key(|(t, _)| *t);
        self.stats.curve_length_per_triple = per_triple;
        self.stats.vertices = mesh.vertex_count();
        self.stats.triangles = mesh.triangle_count();
        mesh
    }
}

/// The chapter's second post-process: a vertex closer than `limit` to the opposite side
/// of one of its triangles (a thin triangle) moves onto that side (to its nearest point
/// there, not the chapter's midpoint, which can be half a side away); the thin
/// triangle, now flat, is dropped, and every other triangle on that side is split at the
/// vertex (so no crack opens: on an intersection curve that is each sheet's triangle),
/// as is a curve segment along it. One move per vertex and per side, in triangle order.
/// A move that would fold a side round the vertex (two triangles alone there lying on top
/// of each other, see [`Around::folds`]) is not made: the thin triangle stays.
fn snap_to_edges(
    pos: &mut [DVec3],
    tris: &mut Vec<([u32; 3], RegionPair)>,
    curves: &mut Vec<CurveEdge>,
    limit: f64,
) -> (usize, usize) {
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let (mut snapped, mut dropped) = (0, 0);
    let mut touched: FxHashSet<u32> = FxHashSet::default();
    let mut splits: FxHashMap<(u32, u32), u32> = FxHashMap::default();
    // The triangles round each vertex, as they are before the splits made at the end.
    let mut around = Around::default();
    for (i, (t, _)) in tris.iter().enumerate() {
        for &v in t {
            around.of_vertex.entry(v).or_default().push(i);
        }
    }
    for (i, (t, _)) in tris.iter().enumerate() {
        for k in 0..3 {
            let (v, a, b) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
            if touched.contains(&v) || touched.contains(&a) || touched.contains(&b) {
                continue;
            }
            let (pv, pa, pb) = (pos[v as usize], pos[a as usize], pos[b as usize]);
            let ab = pb - pa;
            let len2 = ab.length_squared();
            if len2 == 0.0 {
                continue;
            }
            let s = (pv - pa).dot(ab) / len2;
            // Near an end it is a short side, the merge's business.
            if !(0.0..=1.0).contains(&s) || (pa + ab * s).distance(pv) >= limit {
                continue;
            }
            // Nor may the move bring it within `limit` of a neighbour (a short side whose
            // triangles would have no reliable normal).
            let q = pa + ab * s;
            let mut neighbours = around.of_vertex[&v].iter().flat_map(|&j| tris[j].0);
            if neighbours.any(|w| w != v && pos[w as usize].distance(q) < limit) {
                continue;
            }
            // Nor may it fold a side round `v` that was not folded.
            if around.folds(pos, tris, i, [v, a, b], q) {
                continue;
            }
            pos[v as usize] = q;
            touched.extend([v, a, b]);
            splits.insert(key(a, b), v);
            snapped += 1;
        }
    }
    if splits.is_empty() {
        return (0, 0);
    }
    let mut out = Vec::with_capacity(tris.len() + splits.len());
    for &(t, pair) in tris.iter() {
        let side = (0..3).find_map(|k| {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            splits.get(&key(a, b)).map(|&v| (k, v))
        });
        match side {
            None => out.push((t, pair)),
            // The thin triangle itself.
            Some((_, v)) if t.contains(&v) => dropped += 1,
            Some((k, v)) => {
                let (a, b, c) = (t[k], t[(k + 1) % 3], t[(k + 2) % 3]);
                out.push(([a, v, c], pair));
                out.push(([v, b, c], pair));
            }
        }
    }
    *tris = out;
    let mut split_curves = Vec::with_capacity(curves.len());
    for c in curves.iter() {
        match splits.get(&key(c.v[0], c.v[1])) {
            Some(&v) => {
                split_curves.push(CurveEdge { v: [c.v[0], v], label: c.label });
                split_curves.push(CurveEdge { v: [v, c.v[1]], label: c.label });
            }
            None => split_curves.push(*c),
        }
    }
    *curves = split_curves;
    (snapped, dropped)
}

/// Normals of two triangles on one side, wound as they are, more than 175° apart (a
/// dot product below this, as `skelform check` counts a folded edge).
const FOLD_COS: f64 = -0.996_194_698;

/// The triangles round each vertex, as [`snap_to_edges`] found them (its splits, made at
/// the end, keep every half in its triangle's plane).
#[derive(Default)]
struct Around {
    of_vertex: FxHashMap<u32, Vec<usize>>,
}

impl Around {
    /// The triangles on the side `x`–`y`.
    fn on_side(&self, tris: &[([u32; 3], RegionPair)], (x, y): (u32, u32)) -> Vec<usize> {
        let round = self.of_vertex.get(&x).map_or(&[][..], Vec::as_slice);
        round.iter().copied().filter(|&t| tris[t].0.contains(&y)).collect()
    }

    /// Whether moving `v` to `q`, dropping the thin triangle `thin` (`v`, `a`, `b`) and
    /// splitting the other triangles on `a`–`b` at `v`, folds more sides round `v` than
    /// were folded: two triangles alone on a side (or the only two of their pair there),
    /// lying on top of each other.
    ///
    /// Why: a vertex a sliver off a face can be the corner of several thin triangles of
    /// different sheets. Moved onto one's side, it can leave another flat and turned over
    /// (a slab's end face crossing a lattice plane at a shallow angle: a sliver of it lay
    /// in the plane, on the slab's bottom); and the dropped triangle can be the third sheet
    /// on a curve's segment, leaving the other two alone there at the hairline angle a
    /// slab's two sides meet at (a slab's side end at the domain's side).
    fn folds(
        &self,
        pos: &mut [DVec3],
        tris: &[([u32; 3], RegionPair)],
        thin: usize,
        [v, a, b]: [u32; 3],
        q: DVec3,
    ) -> bool {
        let key = |x: u32, y: u32| (x.min(y), x.max(y));
        let mut sides: Vec<(u32, u32)> = vec![key(v, a), key(v, b)];
        for &t in &self.of_vertex[&v] {
            let t = tris[t].0;
            sides.extend((0..3).map(|k| key(t[k], t[(k + 1) % 3])));
        }
        sides.sort_unstable();
        sides.dedup();
        let before = self.count(pos, tris, thin, [v, a, b], &sides, false);
        let old = std::mem::replace(&mut pos[v as usize], q);
        let after = self.count(pos, tris, thin, [v, a, b], &sides, true);
        pos[v as usize] = old;
        after > before
    }

    /// Folded sides among `sides`, before the move (`after` false) or after it, with the
    /// thin triangle dropped and the halves of the split triangles on `v`'s sides.
    fn count(
        &self,
        pos: &[DVec3],
        tris: &[([u32; 3], RegionPair)],
        thin: usize,
        [v, a, b]: [u32; 3],
        sides: &[(u32, u32)],
        after: bool,
    ) -> usize {
        let key = |x: u32, y: u32| (x.min(y), x.max(y));
        let split = self.on_side(tris, key(a, b));
        // What the split drops: the thin triangle, and any other on a–b with v.
        let dropped = |t: usize| t == thin || split.contains(&t) && tris[t].0.contains(&v);
        let mut n = 0;
        for &side in sides {
            let on = self.on_side(tris, side);
            let mut group: Vec<([u32; 3], RegionPair)> =
                on.iter().filter(|&&t| !after || !dropped(t)).map(|&t| tris[t]).collect();
            if after {
                // The half of a triangle on a–b split at v that keeps a (or b) lies on v–a
                // (or v–b).
                for (end, gone) in [(a, b), (b, a)] {
                    if side == key(v, end) {
                        group.extend(split.iter().filter(|&&t| !dropped(t)).map(|&t| {
                            let (s, p) = tris[t];
                            (s.map(|w| if w == gone { v } else { w }), p)
                        }));
                    }
                }
            }
            n += usize::from(folded(pos, &group, side));
        }
        n
    }
}

/// Whether two triangles alone on the side `x`–`y` among `group`, or the only two of
/// their pair there, lie on top of each other (see [`FOLD_COS`]).
fn folded(pos: &[DVec3], group: &[([u32; 3], RegionPair)], (x, y): (u32, u32)) -> bool {
    let normal = |t: [u32; 3]| {
        let [p, q, r] = t.map(|i| pos[i as usize]);
        let (u, w, s) = (q - p, r - p, r - q);
        let n = u.cross(w);
        let longest = u.length_squared().max(w.length_squared()).max(s.length_squared());
        (n.length() > 1e-10 * longest).then(|| n.normalize())
    };
    let forward = |t: [u32; 3]| (0..3).any(|k| t[k] == x && t[(k + 1) % 3] == y);
    let two = |s: &([u32; 3], RegionPair), t: &([u32; 3], RegionPair)| {
        let (Some(n), Some(m)) = (normal(s.0), normal(t.0)) else { return false };
        let same = forward(s.0) == forward(t.0);
        n.dot(m) * if same { -1.0 } else { 1.0 } < FOLD_COS
    };
    if let [s, t] = group {
        return two(s, t);
    }
    // Each pair once, from its first triangle on the side.
    group.iter().any(|s| {
        let mine: Vec<&([u32; 3], RegionPair)> = group.iter().filter(|t| t.1 == s.1).collect();
        mine.len() == 2 && std::ptr::eq(mine[0], s) && two(mine[0], mine[1])
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_thin_triangles_vertex_moves_onto_the_side_which_is_split() {
        // A thin triangle (a, b, v), v 0.1 from the middle of a-b, and two sheets beyond a-b
        // (a non-manifold edge, as on a curve): v moves onto a-b, the thin triangle goes, and
        // each other triangle on a-b is split at v, so every edge keeps its triangles.
        let mut pos = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(4.0, 0.1, 0.0),
            DVec3::new(5.0, -5.0, 0.0),
            DVec3::new(5.0, 0.0, 5.0),
        ];
        let (p, q) = (RegionPair(1, 2), RegionPair(1, 3));
        let mut tris = vec![([0, 1, 2], p), ([1, 0, 3], p), ([1, 0, 4], q)];
        let mut curves = vec![CurveEdge { v: [0, 1], label: RegionTriple([1, 2, 3]) }];
        let (snapped, dropped) = snap_to_edges(&mut pos, &mut tris, &mut curves, 0.5);
        assert_eq!((snapped, dropped), (1, 1));
        assert_eq!(pos[2], DVec3::new(4.0, 0.0, 0.0));
        assert_eq!(tris, vec![([1, 2, 3], p), ([2, 0, 3], p), ([1, 2, 4], q), ([2, 0, 4], q)]);
        assert_eq!(curves.iter().map(|c| c.v).collect::<Vec<_>>(), vec![[0, 2], [2, 1]]);
        // Farther than the limit: nothing moves.
        let mut tris = vec![([0, 1, 2], p)];
        pos[2].y = 0.6;
        assert_eq!(snap_to_edges(&mut pos, &mut tris, &mut Vec::new(), 0.5), (0, 0));
    }

    #[test]
    fn a_snap_that_would_leave_two_sheets_folded_on_a_curve_is_not_made() {
        // A curve a-v with three sheets: the thin (2, 3) triangle (a, b, v), v 0.1 off its
        // side a-b, and a slab's two sides (1, 2) and (1, 3) reaching the curve from far
        // away, 0.2 apart. Snapping v onto a-b would drop the thin triangle and leave the
        // slab's sides alone on a-v, 1° apart: folded. It is not made; without the second
        // side it is.
        let pos = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.5, 0.0, 0.1),
            DVec3::new(0.2, 10.0, 0.1),
            DVec3::new(0.2, 10.0, -0.1),
        ];
        let thin = ([0, 1, 2], RegionPair(2, 3));
        let (top, bottom) = (([0, 2, 3], RegionPair(1, 2)), ([2, 0, 4], RegionPair(1, 3)));
        let mut tris = vec![thin, top, bottom];
        let mut moved = pos.clone();
        assert_eq!(snap_to_edges(&mut moved, &mut tris, &mut Vec::new(), 0.3), (0, 0));
        assert_eq!((moved, tris.len()), (pos.clone(), 3));
        let mut tris = vec![thin, top];
        let mut moved = pos.clone();
        assert_eq!(snap_to_edges(&mut moved, &mut tris, &mut Vec::new(), 0.3), (1, 1));
        assert_eq!(moved[2], DVec3::new(0.5, 0.0, 0.0));
    }
}
