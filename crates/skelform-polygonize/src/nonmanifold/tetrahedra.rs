//! Tetrahedra: each cube split into five, each tetrahedron polygonized from its faces' lines
//! and face vertices (a fan round an internal vertex, or polygons walked vertex to partner).

use glam::DVec3;
use rustc_hash::{FxHashMap, FxHashSet};
use skelform_mesh::{CurveEdge, RegionPair, RegionTriple};

use super::faces::FaceInfo;
use super::{Run, tets};
use crate::grid::cube::CORNERS;
use crate::lattice::cubes::Key;

impl Run<'_> {
    /// Polygonizes one tetrahedron of lattice points.
    ///
    /// Its faces' contours of interest (lines and the spokes of face vertices) are split
    /// into the components they make on the tetrahedron's surface. A component without face
    /// vertices is a disjoint sheet, polygonized by walking vertex to partner (the chapter's
    /// polygons). One with face vertices gets internal vertices, beyond the chapter's one
    /// per tetrahedron (its future work): two face vertices of one label (the same regions
    /// meet there) in a component are a curve passing through, with its own internal vertex
    /// on the curve; the other face vertices meet at one internal vertex (a point where
    /// their curves meet). With one internal vertex in all the tetrahedron fans every
    /// contour to it, as the chapter does. With several, each sheet's contour runs from a
    /// face vertex to a face vertex and is fanned to the first one's internal vertex; where
    /// the last one's differs, a triangle joins the two internal vertices (the sheet runs
    /// between two curves), and the joins of one sheet that go round three or more internal
    /// vertices are closed by a fan. One internal vertex for everything had joined separate
    /// sheets at it and fused curves passing one tetrahedron into a false meeting point.
    ///
    /// This is done always, not only with `Options::junctions` (which adds face vertices,
    /// at a cost in evaluations; this costs none): with the chapter's one vertex at the mean
    /// of all face vertices, a curve clipping a tetrahedron's corner (two face vertices a
    /// few hundredths of a cell apart) was fanned to a centre pulled far away by another
    /// curve's face vertices, so the sheet's two triangles from its crossing to the two
    /// face vertices lay on top of each other (folded edges, issue 18), as where the
    /// three-lobed leaf's vein ends in a sheet within a hair of a lattice plane.
    pub(super) fn tetrahedron(&mut self, t: [Key; 4]) {
        let mut faces: Vec<FaceInfo> = Vec::with_capacity(4);
        for f in tets::FACES {
            faces.push(self.face([t[f[0]], t[f[1]], t[f[2]]]));
        }
        // Contours of interest, and the face vertices they reach (vertex, face, regions).
        let mut edges: Vec<(u32, u32, RegionPair)> = Vec::new();
        let mut hubs: Vec<(u32, usize, Vec<u32>)> = Vec::new();
        for (fi, f) in faces.iter().enumerate() {
            edges.extend(f.lines.iter().copied().filter(|l| self.interesting(l.2)));
            for h in &f.hubs {
                let spokes = h.spokes.iter().filter(|s| self.interesting(s.1));
                let before = edges.len();
                edges.extend(spokes.map(|&(c, p)| (c, h.vertex, p)));
                let linked = f
                    .lines
                    .iter()
                    .any(|l| self.interesting(l.2) && (l.0 == h.vertex || l.1 == h.vertex));
                if edges.len() > before || linked {
                    hubs.push((h.vertex, fi, h.regions.clone()));
                }
            }
        }
        if hubs.is_empty() {
            let lines: Vec<(usize, u32, u32, RegionPair)> = faces
                .iter()
                .enumerate()
                .flat_map(|(fi, f)| f.lines.iter().map(move |&(u, v, p)| (fi, u, v, p)))
                .collect();
            self.walk_polygons(&lines);
            return;
        }
        let mark = Mark::of(self);
        self.hub_tetrahedron(&faces, &hubs, &edges, t, &mark);
        for k in mark.triangles..self.triangles.len() {
            let tri = self.triangles[k];
            for i in 0..3 {
                let (a, b) = (tri[i], tri[(i + 1) % 3]);
                // Vertices made since the mark are this tetrahedron's internal ones; a side
                // between two older ones lies on a face, shared with the neighbour there.
                if a.max(b) < mark.positions as u32 {
                    self.fan_sides.entry([a.min(b), a.max(b)]).or_default().push(tri[(i + 2) % 3]);
                    self.inner_bytes += size_of::<u32>() as u64;
                }
            }
        }
    }

    /// A tetrahedron with face vertices ([`Run::tetrahedron`]): internal vertices per
    /// curve and component, the chapter's one centre where they make coincident faces, and
    /// a face vertex for a component's centre where the mean of its face vertices folds.
    fn hub_tetrahedron(
        &mut self,
        faces: &[FaceInfo],
        hubs: &[(u32, usize, Vec<u32>)],
        edges: &[(u32, u32, RegionPair)],
        t: [Key; 4],
        mark: &Mark,
    ) {
        self.several_centres(faces, hubs, edges, t, None);
        if self.coincident_since(mark) {
            // Two sheets of a lens thinner than the follower's triangles, pinched between
            // the same two curves, joined their internal vertices by the same triangle
            // (coincident faces): the chapter's one centre does not make that triangle.
            mark.roll_back(self);
            self.one_centre(hubs, edges, t);
            return;
        }
        if self.folded_since(mark) {
            // Curves meeting at a point a hair from one face vertex (a slab a few
            // hundredths of a cell thick ending at the margin a few thousandths of a cell
            // off a lattice plane: its corner's four regions meet just off the face, and
            // the other three curves leave through faces a cell away): their mean lies off
            // every curve, and two sheets fanned to it from that face vertex lay on top of
            // each other. The meeting point is then taken at a face vertex of the component
            // instead: the first whose fan folds nothing, here or onto what the neighbours
            // already made across the faces, trying first the one nearest all the others
            // (the curves leave the meeting point for their face vertices, so the one
            // nearest it is nearest them all). A face vertex ending a curve passing through
            // is tried as well: that curve is then one segment, its sheets fanned to that
            // end. No more evaluations: the vertices are there.
            let p = |v: u32| self.positions[v as usize];
            let spread = |v: u32| hubs.iter().map(|h| p(h.0).distance(p(v))).sum::<f64>();
            let mut order: Vec<(f64, usize)> =
                hubs.iter().enumerate().map(|(i, h)| (spread(h.0), i)).collect();
            order.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            for (_, i) in order {
                let h = &hubs[i];
                mark.roll_back(self);
                self.several_centres(faces, hubs, edges, t, Some(h.0));
                if !self.folded_since(mark) && !self.coincident_since(mark) {
                    return;
                }
            }
            mark.roll_back(self);
            self.several_centres(faces, hubs, edges, t, None);
        }
    }

    /// [`Run::tetrahedron`] with face vertices: internal vertices per curve and component.
    fn several_centres(
        &mut self,
        faces: &[FaceInfo],
        hubs: &[(u32, usize, Vec<u32>)],
        edges: &[(u32, u32, RegionPair)],
        t: [Key; 4],
        centre_at: Option<u32>,
    ) {
        // Components of the contours on the tetrahedron's surface.
        let mut index: FxHashMap<u32, usize> = FxHashMap::default();
        let mut parent: Vec<usize> = Vec::new();
        for &(u, v, _) in edges {
            for x in [u, v] {
                index.entry(x).or_insert_with(|| {
                    parent.push(parent.len());
                    parent.len() - 1
                });
            }
            let (a, b) = (root(&mut parent, index[&u]), root(&mut parent, index[&v]));
            parent[a.max(b)] = a.min(b);
        }
        let comp_of = |parent: &mut Vec<usize>, v: u32| index.get(&v).map(|&i| root(parent, i));
        // Internal vertex of each face vertex, component by component (in hub order).
        let mut internal: FxHashMap<u32, u32> = FxHashMap::default();
        let mut comps: Vec<usize> = hubs.iter().filter_map(|h| comp_of(&mut parent, h.0)).collect();
        comps.sort_unstable();
        comps.dedup();
        let mut centres: Vec<u32> = Vec::new();
        for &c in &comps {
            let mine: Vec<&(u32, usize, Vec<u32>)> =
                hubs.iter().filter(|h| comp_of(&mut parent, h.0) == Some(c)).collect();
            let mut rest: Vec<u32> = Vec::new();
            for (i, h) in mine.iter().enumerate() {
                let same: Vec<usize> = (0..mine.len()).filter(|&j| mine[j].2 == h.2).collect();
                let through =
                    same.len() == 2 && h.2.len() >= 3 && mine[same[0]].1 != mine[same[1]].1;
                if !through {
                    rest.push(h.0);
                } else if same[0] == i {
                    let (a, b) = (mine[same[0]].0, mine[same[1]].0);
                    if let Some(c) = centre_at.filter(|&c| c == a || c == b) {
                        // The fallback of `hub_tetrahedron` at one end of a curve passing
                        // through: the curve becomes the one segment between its face
                        // vertices, and its sheets fan to that end. Why: a curve crossing
                        // a slab only a few ε thick a hair off its face vertex left its
                        // midpoint vertex a sliver's width off the slab's other side, and
                        // the sheets fanned to it lay on top of each other (welded).
                        internal.extend([(a, c), (b, c)]);
                        centres.push(c);
                        continue;
                    }
                    let m = (self.positions[a as usize] + self.positions[b as usize]) * 0.5;
                    let v = self.internal_vertex(m);
                    self.through.push((v, [a, b], t));
                    internal.extend([(a, v), (b, v)]);
                    centres.push(v);
                }
            }
            if rest.len() == 1 {
                internal.insert(rest[0], rest[0]);
                centres.push(rest[0]);
            } else if let Some(c) = centre_at.filter(|c| rest.contains(c)) {
                internal.extend(rest.iter().map(|&h| (h, c)));
                centres.push(c);
            } else if !rest.is_empty() {
                let m = rest.iter().map(|&h| self.positions[h as usize]).sum::<DVec3>()
                    / rest.len() as f64;
                let v = self.internal_vertex(m);
                internal.extend(rest.iter().map(|&h| (h, v)));
                centres.push(v);
            }
        }
        for (h, _, regions) in hubs {
            let c = internal[h];
            if c != *h && regions.len() >= 5 {
                // Five or more regions at one face vertex: junctions too close on the face to
                // tell apart, the point where the curves meet at the face. Its segment to the
                // internal vertex would be a short piece of curve with an arbitrary label: the
                // two are made one point instead, where the curves meet.
                self.fused.push((*h, c));
            } else if c != *h && regions.len() >= 3 {
                let tri = RegionTriple::new([regions[0], regions[1], regions[2]]);
                if self.opts.curves.is_empty() || self.opts.curves.contains(&tri) {
                    self.curves.push(CurveEdge { v: [*h, c], label: tri });
                }
            }
        }
        let hub_free: Vec<bool> = {
            let hub_comps: FxHashSet<usize> = comps.iter().copied().collect();
            edges
                .iter()
                .map(|e| !hub_comps.contains(&comp_of(&mut parent, e.0).unwrap_or(usize::MAX)))
                .collect()
        };
        if centres.len() == 1 && !hub_free.contains(&true) {
            // The chapter's case: every contour fanned to the one internal vertex.
            let centre = centres[0];
            for &(u, v, pair) in edges {
                if u != centre && v != centre {
                    self.triangles.push([u, v, centre]);
                    self.labels.push(pair);
                }
            }
            return;
        }
        // Disjoint sheets beside the face vertices' components.
        let free_vertices: FxHashSet<u32> =
            edges.iter().zip(&hub_free).filter(|(_, f)| **f).map(|(e, _)| e.0).collect();
        let free: Vec<(usize, u32, u32, RegionPair)> = faces
            .iter()
            .enumerate()
            .flat_map(|(fi, f)| f.lines.iter().map(move |&(u, v, p)| (fi, u, v, p)))
            .filter(|&(_, u, _, p)| self.interesting(p) && free_vertices.contains(&u))
            .collect();
        if !free.is_empty() {
            self.walk_polygons(&free);
        }
        self.fan_paths(edges, &hub_free, &internal);
    }

    /// The chapter's tetrahedron with face vertices: one internal vertex (the face vertex
    /// itself when there is one, else their mean) and every contour fanned to it. Two face
    /// vertices of one label are a curve passing through, whose vertex may be sharpened.
    fn one_centre(
        &mut self,
        hubs: &[(u32, usize, Vec<u32>)],
        edges: &[(u32, u32, RegionPair)],
        t: [Key; 4],
    ) {
        let centre = if hubs.len() == 1 {
            hubs[0].0
        } else {
            let m = hubs.iter().map(|h| self.positions[h.0 as usize]).sum::<DVec3>()
                / hubs.len() as f64;
            let v = self.internal_vertex(m);
            if let [a, b] = hubs
                && a.2 == b.2
                && a.2.len() >= 3
                && a.1 != b.1
            {
                self.through.push((v, [a.0, b.0], t));
            }
            v
        };
        for (h, _, regions) in hubs {
            if *h != centre && regions.len() >= 3 {
                let tri = RegionTriple::new([regions[0], regions[1], regions[2]]);
                if self.opts.curves.is_empty() || self.opts.curves.contains(&tri) {
                    self.curves.push(CurveEdge { v: [*h, centre], label: tri });
                }
            }
        }
        for &(u, v, pair) in edges {
            if u != centre && v != centre {
                self.triangles.push([u, v, centre]);
                self.labels.push(pair);
            }
        }
    }

    /// Whether two triangles made since `mark` have the same three vertices.
    fn coincident_since(&self, mark: &Mark) -> bool {
        let mut keys: Vec<[u32; 3]> = self.triangles[mark.triangles..]
            .iter()
            .map(|t| {
                let mut k = *t;
                k.sort_unstable();
                k
            })
            .collect();
        keys.sort_unstable();
        keys.windows(2).any(|w| w[0] == w[1])
    }

    /// Whether a triangle made since `mark` lies on top of another on a side they alone
    /// share (made since the mark, or by a neighbour across a face, see `fan_sides`): their
    /// third corners seen from the side within [`FOLD_DEGREES`] of one direction, the
    /// checker's folded edge whatever the winding (which is not settled yet).
    fn folded_since(&self, mark: &Mark) -> bool {
        let cos = FOLD_DEGREES.to_radians().cos();
        let mut sides: Vec<([u32; 2], u32)> = Vec::new();
        for t in &self.triangles[mark.triangles..] {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                sides.push(([a.min(b), a.max(b)], t[(k + 2) % 3]));
            }
        }
        sides.sort_unstable();
        let p = |v: u32| self.positions[v as usize];
        sides.chunk_by(|x, y| x.0 == y.0).any(|mine| {
            let [a, b] = mine[0].0;
            let before = self.fan_sides.get(&[a, b]).map_or(&[][..], Vec::as_slice);
            let group: Vec<([u32; 2], u32)> =
                mine.iter().copied().chain(before.iter().map(|&c| ([a, b], c))).collect();
            let axis = (p(b) - p(a)).normalize_or_zero();
            let across: Vec<DVec3> = group
                .iter()
                .map(|&(_, c)| {
                    let d = p(c) - p(a);
                    (d - axis * d.dot(axis)).normalize_or_zero()
                })
                .collect();
            // Three or more on a side are sheets meeting at a curve, where a slab's two
            // sides meet at a hairline angle by right: the checker counts folds between two.
            group.len() == 2
                && (0..mine.len()).any(|i| {
                    (i + 1..across.len())
                        .any(|j| group[i].1 != group[j].1 && across[i].dot(across[j]) > cos)
                })
        })
    }

    /// A new vertex inside a tetrahedron.
    fn internal_vertex(&mut self, p: DVec3) -> u32 {
        self.positions.push(p);
        self.crossing.push(None);
        self.stats.internal_vertices += 1;
        self.positions.len() as u32 - 1
    }

    /// The contours of the face vertices' components, sheet by sheet, from face vertex to
    /// face vertex, each fanned to the internal vertex of the face vertex it starts from
    /// (see [`Run::tetrahedron`]).
    fn fan_paths(
        &mut self,
        edges: &[(u32, u32, RegionPair)],
        hub_free: &[bool],
        internal: &FxHashMap<u32, u32>,
    ) {
        let mut at: FxHashMap<u32, Vec<usize>> = FxHashMap::default();
        for (i, e) in edges.iter().enumerate() {
            if !hub_free[i] {
                at.entry(e.0).or_default().push(i);
                at.entry(e.1).or_default().push(i);
            }
        }
        let mut used: Vec<bool> = hub_free.to_vec();
        let mut joins: Vec<(RegionPair, u32, u32)> = Vec::new();
        let mut starts: Vec<u32> = internal.keys().copied().collect();
        starts.sort_unstable();
        let other = |e: usize, v: u32| if edges[e].0 == v { edges[e].1 } else { edges[e].0 };
        for &h in &starts {
            let cs = internal[&h];
            while let Some(&e) = at[&h].iter().find(|&&e| !used[e]) {
                used[e] = true;
                let pair = edges[e].2;
                let (mut cur, mut next) = (h, other(e, h));
                loop {
                    self.fan(cur, next, cs, pair);
                    cur = next;
                    if internal.contains_key(&cur) {
                        break;
                    }
                    let Some(&e2) = at[&cur].iter().find(|&&e2| !used[e2] && edges[e2].2 == pair)
                    else {
                        break;
                    };
                    used[e2] = true;
                    next = other(e2, cur);
                }
                if let Some(&ce) = internal.get(&cur)
                    && ce != cs
                {
                    self.fan(cur, ce, cs, pair);
                    joins.push((pair, cs, ce));
                }
            }
        }
        // Joins of a sheet round three or more internal vertices: close them with a fan.
        joins.sort_unstable();
        let mut i = 0;
        while i < joins.len() {
            let pair = joins[i].0;
            let mut j = i;
            while j < joins.len() && joins[j].0 == pair {
                j += 1;
            }
            let mut open: Vec<(u32, u32)> = Vec::new();
            for &(_, a, b) in &joins[i..j] {
                // A join back the same way cancels (two triangles on the shared side).
                if let Some(k) =
                    open.iter().position(|&(x, y)| (x, y) == (b, a) || (x, y) == (a, b))
                {
                    open.swap_remove(k);
                } else {
                    open.push((a, b));
                }
            }
            if open.len() >= 3 {
                let mut cycle = vec![open[0].0, open[0].1];
                let mut rest = open[1..].to_vec();
                while let Some(k) = rest
                    .iter()
                    .position(|&(x, y)| x == cycle[cycle.len() - 1] || y == cycle[cycle.len() - 1])
                {
                    let (x, y) = rest.swap_remove(k);
                    let last = cycle[cycle.len() - 1];
                    cycle.push(if x == last { y } else { x });
                }
                if cycle.first() == cycle.last() {
                    cycle.pop();
                    for k in 1..cycle.len().saturating_sub(1) {
                        self.fan(cycle[k], cycle[k + 1], cycle[0], pair);
                    }
                }
            }
            i = j;
        }
    }

    fn fan(&mut self, a: u32, b: u32, centre: u32, pair: RegionPair) {
        if a != centre && b != centre && a != b {
            self.triangles.push([a, b, centre]);
            self.labels.push(pair);
        }
    }

    /// Disjoint surfaces: walk vertex → partner in a face → the other face on its edge (or,
    /// from a loop vertex inside a face, on to its other partner in that face), and fan each
    /// polygon. `lines` are (face, u, v, pair).
    fn walk_polygons(&mut self, lines: &[(usize, u32, u32, RegionPair)]) {
        let mut links: FxHashMap<u32, Vec<(usize, u32)>> = FxHashMap::default();
        let mut pair_of: FxHashMap<u32, RegionPair> = FxHashMap::default();
        for &(fi, u, v, p) in lines {
            links.entry(u).or_default().push((fi, v));
            links.entry(v).or_default().push((fi, u));
            pair_of.insert(u, p);
            pair_of.insert(v, p);
        }
        let mut starts: Vec<u32> =
            pair_of.keys().copied().filter(|&v| self.crossing[v as usize].is_some()).collect();
        starts.sort_unstable();
        let mut used: FxHashSet<u32> = FxHashSet::default();
        for s in starts {
            let pair = pair_of[&s];
            if used.contains(&s) || !self.interesting(pair) {
                continue;
            }
            let mut poly = vec![s];
            used.insert(s);
            let (mut prev, (mut f, mut cur)) = (s, links[&s][0]);
            let mut closed = false;
            while poly.len() <= 12 {
                if cur == s {
                    closed = true;
                    break;
                }
                poly.push(cur);
                used.insert(cur);
                let Some(&(g, next)) = links[&cur].iter().find(|&&(g, o)| !(g == f && o == prev))
                else {
                    break;
                };
                (prev, f, cur) = (cur, g, next);
            }
            if !closed && self.opts.loops {
                continue;
            }
            // Fan from a loop vertex where there is one: a fan from an edge vertex could
            // draw a diagonal along the lattice segment the loop crosses, which every
            // tetrahedron around it would share.
            if let Some(i) = poly.iter().position(|&v| self.crossing[v as usize].is_none()) {
                poly.rotate_left(i);
            }
            if poly.len() >= 3 {
                for k in 1..poly.len() - 1 {
                    self.triangles.push([poly[0], poly[k], poly[k + 1]]);
                    self.labels.push(pair);
                }
            }
        }
    }

    pub(super) fn cube_tets(&self, c: [u32; 3]) -> Vec<[Key; 4]> {
        tets::split(c[0], c[1], c[2])
            .iter()
            .map(|t| {
                t.map(|corner| {
                    let o = CORNERS[corner];
                    self.key([c[0] + o[0] as u32, c[1] + o[1] as u32, c[2] + o[2] as u32])
                })
            })
            .collect()
    }

    /// Polygonizes a cube; returns the cube faces (axis, side) holding a surface of interest.
    pub(super) fn cube(&mut self, c: [u32; 3]) -> Vec<(usize, usize)> {
        let keys: Vec<Key> = CORNERS
            .iter()
            .map(|o| self.key([c[0] + o[0] as u32, c[1] + o[1] as u32, c[2] + o[2] as u32]))
            .collect();
        self.lattice_regions(&keys);
        let mut open = Vec::new();
        for t in self.cube_tets(c) {
            self.tetrahedron(t);
            for f in tets::FACES {
                let pts = [t[f[0]], t[f[1]], t[f[2]]].map(|k| self.unkey(k));
                // A tetrahedron face on the cube's boundary: its corners share a coordinate.
                for axis in 0..3 {
                    let v = pts[0][axis];
                    if pts.iter().all(|p| p[axis] == v) {
                        let info = self.face([t[f[0]], t[f[1]], t[f[2]]]);
                        if info.pairs().any(|p| self.interesting(p)) {
                            open.push((axis, usize::from(v != c[axis])));
                        }
                    }
                }
            }
        }
        open.sort_unstable();
        open.dedup();
        open
    }
}

/// Two triangles on one side whose third corners are seen from it within this angle of
/// each other lie on top of each other ([`Run::folded_since`]): the checker's folded edge
/// (normals more than 175° apart). No wider, so that fans which fold nothing keep the
/// mean of their face vertices, as before.
const FOLD_DEGREES: f64 = 5.0;

/// How much of the run's output existed before a tetrahedron was polygonized, so that
/// what it made can be taken back ([`Run::tetrahedron`]).
struct Mark {
    positions: usize,
    internal_vertices: usize,
    triangles: usize,
    curves: usize,
    through: usize,
    fused: usize,
}

impl Mark {
    fn of(run: &Run<'_>) -> Mark {
        Mark {
            positions: run.positions.len(),
            internal_vertices: run.stats.internal_vertices,
            triangles: run.triangles.len(),
            curves: run.curves.len(),
            through: run.through.len(),
            fused: run.fused.len(),
        }
    }

    fn roll_back(&self, run: &mut Run<'_>) {
        run.positions.truncate(self.positions);
        run.crossing.truncate(self.positions);
        run.stats.internal_vertices = self.internal_vertices;
        run.triangles.truncate(self.triangles);
        run.labels.truncate(self.triangles);
        run.curves.truncate(self.curves);
        run.through.truncate(self.through);
        run.fused.truncate(self.fused);
    }
}

/// Union-find root, halving the path.
fn root(parent: &mut [usize], mut x: usize) -> usize {
    while parent[x] != x {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    x
}
