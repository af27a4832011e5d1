//! Non-manifold polygonization of multiple regions of space (dissertation ch. 4, after
//! Bloomenthal and Ferguson): space is divided into numbered regions by a
//! [`RegionField`]; the surfaces between chosen pairs of regions are polygonized together,
//! meet along curves where three regions meet, and every triangle carries its pair.
//!
//! Steps, as the chapter gives them: cubes propagate from a start across faces that hold a
//! surface of interest (or every cube of the domain is visited); each cube is split into
//! five tetrahedra, alternating with the cube's parity; every tetrahedron edge is divided
//! into `sections` pieces and each piece whose ends lie in different regions is bisected
//! `refinements` times or more, to ε, so an edge can hold several vertices; looped pairs of
//! crossings ((a,b) then (b,a) on one edge) are ignored. A face whose crossings pair off as
//! disjoint lines has no face vertex; otherwise a contour follower walks small triangles
//! along a contour to the first foreign region and puts the face vertex there. A
//! tetrahedron without face vertices of interest gives polygons of 3 or 4 sides by walking
//! from vertex to partner across its faces; one with them gets an internal vertex at their
//! mean and a triangle to each face line of interest. Triangles are wound counter-clockwise
//! seen from the lesser region of their pair. Afterwards vertices closer than
//! `close_factor · ε` along a triangle edge are merged, a vertex closer than that to the
//! opposite side of its triangle is moved onto it (the side split there), degenerate
//! triangles dropped, and vertices duplicated per region pair so each sheet has its own
//! normal: the region function's gradient for the pair where it has one (the chapter's
//! `Gradient(p, pair)`), else the pair's area-weighted triangle normals.
//! [`verify`] checks a result against its region function.
//!
//! Guarantees: deterministic output on any thread count; every triangle labelled with a
//! pair of interest; intersection curves output as labelled polylines. Not guaranteed
//! (the chapter's stated limits): one face vertex per face and one internal vertex per
//! tetrahedron, so features finer than a cell can be lost; looped intersections are cut off
//! unless `Options::loops` (beyond the chapter) keeps them, and one entering and leaving
//! within one section of an edge is never seen.

pub mod tets;
pub mod verify;

use std::time::{Duration, Instant};

use glam::DVec3;
use rustc_hash::{FxHashMap, FxHashSet};
use skelform_field::RegionField;
use skelform_field::grid::Grid;
use skelform_mesh::{CurveEdge, Mesh, RegionPair, RegionTriple};

use crate::grid::cube::CORNERS;
use crate::lattice::cubes::{CubeLattice, Key};
use crate::lattice::propagate::{Cubes, Limits, Order, propagate};
use crate::lattice::search::CoarseSearch;
use crate::{Error, LatticeOptions, Resolution};

/// Settings of the non-manifold polygonizer.
#[derive(Clone, Debug)]
pub struct Options {
    /// The lattice, progress and threads. Vertices are placed by bisection on the region
    /// function to `epsilon`, so `refine`, `tolerance` and `normals` are not read (normals
    /// always come out), and storage grows with the surfaces (bounded by `max_cells`), so
    /// `max_memory` is not read either.
    pub lattice: LatticeOptions,
    /// Start points within about half a cell of a surface of interest; with none, the
    /// domain is searched every `search_stride` cells.
    pub seeds: Vec<DVec3>,
    pub search_stride: usize,
    /// Visit every cube of the domain instead of propagating from starts.
    pub full_grid: bool,
    /// The surfaces to polygonize; empty means every pair that occurs.
    pub interest: Vec<RegionPair>,
    /// The intersection curves to output (the chapter's curves of interest); empty means
    /// every curve of the surfaces of interest.
    pub curves: Vec<RegionTriple>,
    /// Edge sections (the chapter's n = 16).
    pub sections: u32,
    /// Least bisections per section (the chapter's m = 4).
    pub refinements: u32,
    /// Accuracy of edge and face vertices; `None`: cell / 256.
    pub epsilon: Option<f64>,
    /// Vertices closer than `close_factor · ε` along a triangle edge are merged.
    pub close_factor: f64,
    /// Beyond the chapter: keep looped crossings ((a,b) then (b,a) on one edge, a surface
    /// poking through the edge) instead of ignoring them; in each face around the edge the
    /// contour between them is followed and a vertex put where it is farthest from the
    /// edge, so the poke is made rather than cut off. Off: the chapter's truncation.
    pub loops: bool,
    pub max_cells: u64,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            lattice: LatticeOptions {
                resolution: Resolution::Cell(1.0 / 32.0),
                ..LatticeOptions::default()
            },
            seeds: Vec::new(),
            search_stride: 4,
            full_grid: false,
            interest: Vec::new(),
            curves: Vec::new(),
            sections: 16,
            refinements: 4,
            epsilon: None,
            close_factor: 1.0,
            loops: false,
            max_cells: 5_000_000,
        }
    }
}

/// What a run did.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Stats {
    pub cell: f64,
    pub epsilon: f64,
    pub region_evaluations: u64,
    /// What a conventional (manifold) tetrahedral polygonizer would evaluate on the same
    /// cells: the corners, and eight bisection steps on each edge whose ends differ (the
    /// chapter's comparison, about four times fewer).
    pub conventional_evaluations: u64,
    pub cells_visited: u64,
    pub edge_vertices: usize,
    pub face_vertices: usize,
    pub internal_vertices: usize,
    /// Face vertices the contour follower could not reach (placed at the mean of the
    /// face's crossings instead).
    pub face_vertex_fallbacks: usize,
    /// Face vertices put on an edge crossing because a third region lies within 2ε of it
    /// along its edge (the follower's first triangle would already hold it).
    pub face_vertices_at_crossing: usize,
    pub looped_pairs_ignored: usize,
    /// Looped pairs kept (`Options::loops`), and their face vertices placed by following
    /// the contour (the rest by a fallback half a crossing gap into the face).
    pub looped_pairs_kept: usize,
    pub loop_vertices: usize,
    pub loop_vertex_fallbacks: usize,
    pub merged_vertices: usize,
    /// Vertices of thin triangles moved onto the midpoint of the opposite side.
    pub snapped_to_edges: usize,
    pub dropped_triangles: usize,
    /// Vertex normals taken from the region function's per-pair gradient (the rest are
    /// area-weighted triangle normals).
    pub gradient_normals: usize,
    /// Triangles whose side regions could not be told apart by a probe (kept as wound).
    pub unoriented_triangles: usize,
    pub triangles_per_pair: Vec<(RegionPair, usize)>,
    pub curve_length_per_triple: Vec<(RegionTriple, f64)>,
    pub reached_domain: bool,
    pub reached_budget: bool,
    pub vertices: usize,
    pub triangles: usize,
    pub time: Duration,
}

#[derive(Clone, Copy, Debug)]
struct Crossing {
    /// Regions before and after, in that direction.
    from: u32,
    to: u32,
    vertex: u32,
}

/// A crossing met while walking a face boundary in one direction.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Walked {
    vertex: u32,
    from: u32,
    to: u32,
}

#[derive(Clone, Debug, Default)]
struct FaceInfo {
    /// Lines between two crossings (disjoint lines), with their pair.
    lines: Vec<(u32, u32, RegionPair)>,
    /// Crossings joined to the face vertex, with their pair.
    spokes: Vec<(u32, RegionPair)>,
    face_vertex: Option<u32>,
    /// The regions meeting at the face vertex.
    regions: Vec<u32>,
}

struct Run<'a> {
    regions: &'a dyn RegionField,
    grid: Grid,
    cubes: CubeLattice,
    opts: &'a Options,
    eps: f64,
    interest: Option<FxHashSet<RegionPair>>,
    point_region: FxHashMap<Key, u32>,
    edges: FxHashMap<(Key, Key), Vec<Crossing>>,
    faces: FxHashMap<[Key; 3], FaceInfo>,
    positions: Vec<DVec3>,
    /// The lattice segment of each edge vertex.
    on_edge: FxHashMap<u32, (Key, Key)>,
    /// For edge vertices: the segment's direction and the regions before and after the
    /// crossing along it, which say on which side of the surface each region lies.
    crossing: Vec<Option<(DVec3, u32, u32)>>,
    triangles: Vec<[u32; 3]>,
    labels: Vec<RegionPair>,
    curves: Vec<CurveEdge>,
    visited: FxHashSet<Key>,
    stats: Stats,
}

/// Polygonizes the surfaces of interest between the regions of `regions`.
///
/// ```
/// use skelform_field::{Aabb, DVec3, region::FnRegions};
/// use skelform_mesh::RegionPair;
/// use skelform_polygonize::{LatticeOptions, Resolution};
/// use skelform_polygonize::nonmanifold::{polygonize, Options};
/// // A ball (1) cut by the plane z = 0 into an upper (2) and lower (3) half-space.
/// let regions = FnRegions(|p: DVec3| if p.length() < 0.5 { 1 } else if p.z > 0.0 { 2 } else { 3 });
/// let lattice = LatticeOptions { domain: Aabb::cube(1.0), resolution: Resolution::Cell(0.1), ..Default::default() };
/// let opts = Options { lattice, full_grid: true, ..Options::default() };
/// let (mesh, stats) = polygonize(&regions, &opts).unwrap();
/// let pairs: Vec<RegionPair> = stats.triangles_per_pair.iter().map(|(p, _)| *p).collect();
/// assert_eq!(pairs, vec![RegionPair(1, 2), RegionPair(1, 3), RegionPair(2, 3)]);
/// assert!(!mesh.curves.is_empty());
/// ```
pub fn polygonize(regions: &dyn RegionField, options: &Options) -> Result<(Mesh, Stats), Error> {
    options.lattice.threads.install(|| polygonize_here(regions, options))
}

/// [`polygonize`] on the current thread pool.
fn polygonize_here(regions: &dyn RegionField, options: &Options) -> Result<(Mesh, Stats), Error> {
    let started = Instant::now();
    let grid = options.lattice.grid()?;
    if options.sections == 0 || options.close_factor.is_nan() || options.close_factor < 0.0 {
        return Err(Error::BadOption(
            "sections must be at least 1 and close_factor not negative".into(),
        ));
    }
    if let Some(ids) = regions.region_ids() {
        for t in &options.curves {
            if let Some(r) = t.0.iter().find(|r| !ids.contains(r)) {
                return Err(Error::BadOption(format!(
                    "the curve {t} names region {r}, which the region function does not have (it has {ids:?})"
                )));
            }
        }
        for p in &options.interest {
            for r in [p.0, p.1] {
                if !ids.contains(&r) {
                    return Err(Error::BadOption(format!(
                        "the pair {}_{} names region {r}, which the region function does not have (it has {ids:?})",
                        p.0, p.1
                    )));
                }
            }
        }
    }
    let eps = options.epsilon.unwrap_or(grid.cell / 256.0);
    let mut run = Run {
        regions,
        grid,
        cubes: CubeLattice::new(grid),
        opts: options,
        eps,
        interest: (!options.interest.is_empty())
            .then(|| options.interest.iter().copied().collect()),
        point_region: FxHashMap::default(),
        edges: FxHashMap::default(),
        faces: FxHashMap::default(),
        positions: Vec::new(),
        on_edge: FxHashMap::default(),
        crossing: Vec::new(),
        triangles: Vec::new(),
        labels: Vec::new(),
        curves: Vec::new(),
        visited: FxHashSet::default(),
        stats: Stats { cell: grid.cell, epsilon: eps, ..Stats::default() },
    };
    let starts = if options.full_grid { run.all_cubes() } else { run.starts()? };
    run.propagate(starts)?;
    run.orient();
    let mesh = run.finish();
    let mut stats = run.stats;
    stats.time = started.elapsed();
    Ok((mesh, stats))
}

impl Run<'_> {
    fn key(&self, p: [u32; 3]) -> Key {
        self.cubes.key(p)
    }

    fn unkey(&self, k: Key) -> [u32; 3] {
        self.cubes.unkey(k)
    }

    fn point(&self, k: Key) -> DVec3 {
        self.cubes.point(self.unkey(k))
    }

    fn interesting(&self, pair: RegionPair) -> bool {
        pair.0 != pair.1 && self.interest.as_ref().is_none_or(|s| s.contains(&pair))
    }

    fn regions_of(&mut self, pts: &[DVec3]) -> Vec<u32> {
        let mut out = vec![0; pts.len()];
        self.regions.region_many(pts, &mut out);
        self.stats.region_evaluations += pts.len() as u64;
        out
    }

    fn region_at(&mut self, p: DVec3) -> u32 {
        self.stats.region_evaluations += 1;
        self.regions.region(p)
    }

    /// Regions at lattice points, cached.
    fn lattice_regions(&mut self, keys: &[Key]) {
        let todo: Vec<Key> = {
            let mut t: Vec<Key> =
                keys.iter().copied().filter(|k| !self.point_region.contains_key(k)).collect();
            t.sort_unstable();
            t.dedup();
            t
        };
        if todo.is_empty() {
            return;
        }
        let pts: Vec<DVec3> = todo.iter().map(|&k| self.point(k)).collect();
        let r = self.regions_of(&pts);
        self.stats.conventional_evaluations += todo.len() as u64;
        for (k, r) in todo.into_iter().zip(r) {
            self.point_region.insert(k, r);
        }
    }

    /// The crossings on the segment between two lattice points, in the direction a → b.
    fn edge(&mut self, a: Key, b: Key) -> Vec<Walked> {
        let (lo, hi) = if a < b { (a, b) } else { (b, a) };
        if !self.edges.contains_key(&(lo, hi)) {
            let c = self.sample_edge(lo, hi);
            self.edges.insert((lo, hi), c);
        }
        let c = &self.edges[&(lo, hi)];
        let walked = c.iter().map(|x| Walked { vertex: x.vertex, from: x.from, to: x.to });
        if a < b {
            walked.collect()
        } else {
            walked.rev().map(|w| Walked { from: w.to, to: w.from, ..w }).collect()
        }
    }

    /// Sections, bisection, loop removal and vertices for one segment (lo → hi).
    fn sample_edge(&mut self, lo: Key, hi: Key) -> Vec<Crossing> {
        let (pa, pb) = (self.point(lo), self.point(hi));
        let (ra, rb) = (self.point_region[&lo], self.point_region[&hi]);
        let n = self.opts.sections as usize;
        let inner: Vec<DVec3> = (1..n).map(|i| pa.lerp(pb, i as f64 / n as f64)).collect();
        let mut rs = vec![ra];
        rs.extend(self.regions_of(&inner));
        rs.push(rb);
        if ra != rb {
            self.stats.conventional_evaluations += 8;
        }
        let len = (pb - pa).length();
        let tol = (2.0 * self.eps / len).max(f64::EPSILON);
        let mut found: Vec<(f64, u32, u32)> = Vec::new();
        for i in 0..n {
            if rs[i] != rs[i + 1] {
                self.bisect(
                    pa,
                    pb,
                    i as f64 / n as f64,
                    rs[i],
                    (i + 1) as f64 / n as f64,
                    rs[i + 1],
                    0,
                    tol,
                    &mut found,
                );
            }
        }
        // Looped pairs: a crossing (x, y) followed by (y, x) enters and leaves along this edge.
        let mut kept: Vec<(f64, u32, u32)> = Vec::new();
        for c in found {
            if !self.opts.loops
                && let Some(&(_, f, t)) = kept.last()
                && f == c.2
                && t == c.1
            {
                kept.pop();
                self.stats.looped_pairs_ignored += 1;
                continue;
            }
            kept.push(c);
        }
        if self.opts.loops {
            self.stats.looped_pairs_kept +=
                kept.windows(2).filter(|w| w[0].1 == w[1].2 && w[0].2 == w[1].1).count();
        }
        kept.into_iter()
            .map(|(t, from, to)| {
                self.on_edge.insert(self.positions.len() as u32, (lo, hi));
                self.positions.push(pa.lerp(pb, t));
                self.crossing.push(Some((pb - pa, from, to)));
                self.stats.edge_vertices += 1;
                Crossing { from, to, vertex: self.positions.len() as u32 - 1 }
            })
            .collect()
    }

    #[allow(clippy::too_many_arguments)]
    fn bisect(
        &mut self,
        pa: DVec3,
        pb: DVec3,
        t0: f64,
        r0: u32,
        t1: f64,
        r1: u32,
        depth: u32,
        tol: f64,
        out: &mut Vec<(f64, u32, u32)>,
    ) {
        if (t1 - t0 <= tol && depth >= self.opts.refinements) || depth > 60 {
            out.push((0.5 * (t0 + t1), r0, r1));
            return;
        }
        let tm = 0.5 * (t0 + t1);
        let rm = self.region_at(pa.lerp(pb, tm));
        if rm == r0 {
            self.bisect(pa, pb, tm, rm, t1, r1, depth + 1, tol, out);
        } else if rm == r1 {
            self.bisect(pa, pb, t0, r0, tm, rm, depth + 1, tol, out);
        } else {
            // A foreign region: crossings on both sides of it.
            self.bisect(pa, pb, t0, r0, tm, rm, depth + 1, tol, out);
            self.bisect(pa, pb, tm, rm, t1, r1, depth + 1, tol, out);
        }
    }

    /// Lines and the face vertex of a triangular face of lattice points.
    fn face(&mut self, corners: [Key; 3]) -> FaceInfo {
        let mut sorted = corners;
        sorted.sort_unstable();
        if let Some(f) = self.faces.get(&sorted) {
            return f.clone();
        }
        // Walk the boundary in a fixed (sorted) order, so that both tetrahedra agree.
        let [a, b, c] = sorted;
        let mut ring: Vec<Walked> = Vec::new();
        for (p, q) in [(a, b), (b, c), (c, a)] {
            ring.extend(self.edge(p, q));
        }
        let mut info = FaceInfo::default();
        let unmatched = pair_off(&ring, &mut info.lines);
        if self.opts.loops {
            // A line between two crossings on one lattice segment is a loop: replace it by
            // two lines through a vertex on the contour inside the face.
            let mut lines = Vec::with_capacity(info.lines.len());
            for (u, v, pair) in std::mem::take(&mut info.lines) {
                match (self.on_edge.get(&u), self.on_edge.get(&v)) {
                    (Some(eu), Some(ev)) if eu == ev => {
                        let l = self.loop_vertex(sorted, u, v);
                        lines.push((u, l, pair));
                        lines.push((l, v, pair));
                    }
                    _ => lines.push((u, v, pair)),
                }
            }
            info.lines = lines;
        }
        if !unmatched.is_empty() {
            let mut regions: Vec<u32> = unmatched.iter().flat_map(|w| [w.from, w.to]).collect();
            regions.sort_unstable();
            regions.dedup();
            info.regions = regions;
            let interesting: Vec<&Walked> = unmatched
                .iter()
                .filter(|w| self.interesting(RegionPair::new(w.from, w.to)))
                .collect();
            if !interesting.is_empty() {
                let p = self.face_vertex(sorted, &unmatched, &interesting);
                self.positions.push(p);
                self.crossing.push(None);
                self.stats.face_vertices += 1;
                let v = self.positions.len() as u32 - 1;
                info.face_vertex = Some(v);
                info.spokes =
                    unmatched.iter().map(|w| (w.vertex, RegionPair::new(w.from, w.to))).collect();
            }
        }
        self.faces.insert(sorted, info.clone());
        info
    }

    /// The vertex of a loop on a face: the contour leaves the face's side at crossing `u`
    /// and comes back at `v`; follow it from `u` in small triangles (as for face vertices)
    /// until it returns to that side, and take the triangle centre farthest from the side.
    /// If the walk does not come back (the loop is thinner than the triangles), the vertex
    /// goes half the gap between the crossings into the face from their midpoint.
    fn loop_vertex(&mut self, corners: [Key; 3], u: u32, v: u32) -> u32 {
        let [a, b, c] = corners.map(|k| self.point(k));
        let n = (b - a).cross(c - a).normalize();
        let (pu, pv) = (self.positions[u as usize], self.positions[v as usize]);
        let dir = (pv - pu).normalize_or_zero();
        // Into the face, perpendicular to the side: towards the corner off the side.
        let third = [a, b, c]
            .into_iter()
            .max_by(|x, y| (*x - pu).cross(dir).length().total_cmp(&(*y - pu).cross(dir).length()))
            .unwrap_or(c);
        let mut inward = n.cross(dir);
        if inward.dot(third - pu) < 0.0 {
            inward = -inward;
        }
        let Some((x, y)) = self.crossing[u as usize].map(|(_, from, to)| (from, to)) else {
            return u;
        };
        let side = 4.0 * self.eps;
        let gap = pu.distance(pv);
        let max_steps = (16.0 * (b - a).length().max((c - a).length()) / side) as usize + 16;
        // Straddle u along the side: x before it, y after it, walking from u towards v.
        let (mut px, mut py) = (pu - dir * side * 0.5, pu + dir * side * 0.5);
        let (rx, ry) = (self.region_at(px), self.region_at(py));
        let mut found = None;
        if rx == x && ry == y {
            let mid = (px + py) * 0.5;
            let mut apex = mid + inward * side * 3f64.sqrt() * 0.5;
            let (mut best, mut far) = (None, 0.0);
            for _ in 0..max_steps {
                let centre = (px + py + apex) / 3.0;
                let depth = (centre - pu).dot(inward);
                if depth > far {
                    (best, far) = (Some(centre), depth);
                }
                // Back at the side: the loop is closed.
                if (apex - pu).dot(inward) < 0.0 {
                    found = best;
                    break;
                }
                let r = self.region_at(apex);
                if !flip_strip(r, x, y, &mut px, &mut py, &mut apex) {
                    // A third region inside the loop: stop there.
                    found = Some(centre);
                    break;
                }
            }
        }
        let p = match found {
            Some(p) if (p - pu).dot(inward) > self.eps => {
                self.stats.loop_vertices += 1;
                p
            }
            _ => {
                self.stats.loop_vertex_fallbacks += 1;
                (pu + pv) * 0.5 + inward * (0.5 * gap).max(2.0 * self.eps)
            }
        };
        self.positions.push(p);
        self.crossing.push(None);
        self.positions.len() as u32 - 1
    }

    /// Where the contours of a face meet: follow the contour from a crossing of interest in
    /// small equilateral steps to the first region foreign to it (the chapter's follower),
    /// and put the vertex at the centre of that last triangle, moved at least 2ε into the
    /// face. Two cases the plain follower misses are handled: a third region already at a
    /// corner of the first triangle (the crossing is within 2ε of the meeting point, as at
    /// the saucer's rim, thinner than ε) ends the walk at once; and the walk may run up to
    /// two triangles beyond the face, for regions that meet on the face's own side (a wall
    /// half-way between lattice planes puts the square's border through the midpoints of
    /// face diagonals). Otherwise the next start is tried, and only when none succeeds is
    /// the vertex put at the mean of the face's crossings (`face_vertex_fallbacks`).
    fn face_vertex(
        &mut self,
        corners: [Key; 3],
        crossings: &[Walked],
        starts: &[&Walked],
    ) -> DVec3 {
        let [a, b, c] = corners.map(|k| self.point(k));
        let n = (b - a).cross(c - a);
        let area2 = n.length_squared();
        // Barycentric coordinates within the face's plane.
        let bary = |p: DVec3| {
            [
                (c - b).cross(p - b).dot(n) / area2,
                (a - c).cross(p - c).dot(n) / area2,
                (b - a).cross(p - a).dot(n) / area2,
            ]
        };
        // How far outside the face a point is (0 inside): the largest distance beyond one of
        // its sides (a barycentric coordinate times that side's height).
        let heights = [(c - b).length(), (a - c).length(), (b - a).length()]
            .map(|l| area2.sqrt() / l.max(f64::MIN_POSITIVE));
        let outside = move |p: DVec3| {
            let w = bary(p);
            (0..3).map(|i| -w[i] * heights[i]).fold(0.0f64, f64::max)
        };
        let inside = |p: DVec3| outside(p) <= 1e-9 * heights[0];
        // A point of the plane moved into the face, at least 2ε from its sides: a face
        // vertex on a side would coincide with the one of the face across that side (where a
        // curve runs along a lattice edge), pinching the sheets there.
        let inset = heights.map(|h| (2.0 * self.eps / h).min(0.3));
        let clamp = |p: DVec3| {
            let mut w = bary(p);
            for _ in 0..3 {
                w = std::array::from_fn(|i| w[i].max(inset[i]));
                let s = w[0] + w[1] + w[2];
                w = w.map(|x| x / s);
            }
            a * w[0] + b * w[1] + c * w[2]
        };
        let side = 4.0 * self.eps;
        let max_steps = (8.0 * (b - a).length().max((c - a).length()) / side) as usize + 16;
        for s in starts {
            let v = self.positions[s.vertex as usize];
            // The crossing lies on one of the three edges; find which, to step along it.
            let edge_dir = [(a, b), (b, c), (c, a)]
                .into_iter()
                .map(|(p, q)| {
                    let d = (q - p).normalize();
                    ((v - p).cross(d).length(), d)
                })
                .min_by(|x, y| x.0.total_cmp(&y.0))
                .map_or(DVec3::X, |(_, d)| d);
            let mut px = v - edge_dir * side * 0.5;
            let mut py = v + edge_dir * side * 0.5;
            let mid = (px + py) * 0.5;
            let mut w = n.normalize().cross(py - px).normalize();
            if !inside(mid + w * side) {
                w = -w;
            }
            let mut apex = mid + w * side * 3f64.sqrt() * 0.5;
            let (rx, ry) = (self.region_at(px), self.region_at(py));
            let (x, y) = (s.from, s.to);
            if ![rx, ry].iter().all(|&r| r == x || r == y) {
                // The first triangle already has a corner in a third region (the crossing is
                // within 2ε of it along the edge): it is the final triangle.
                self.stats.face_vertices_at_crossing += 1;
                return clamp((px + py + apex) / 3.0);
            }
            if !(rx == x && ry == y) {
                if !(rx == y && ry == x) {
                    continue;
                }
                std::mem::swap(&mut px, &mut py);
            }
            // The strip may run up to two triangles beyond the face: where the regions meet
            // on (or within ε of) the face's own edge, as when a wall falls half-way between
            // lattice planes, the contour reaches the foreign region only just outside.
            for _ in 0..max_steps {
                if outside(apex) > 2.0 * side {
                    break;
                }
                let r = self.region_at(apex);
                if !flip_strip(r, x, y, &mut px, &mut py, &mut apex) {
                    return clamp((px + py + apex) / 3.0);
                }
            }
        }
        self.stats.face_vertex_fallbacks += 1;
        let n = crossings.len() as f64;
        crossings.iter().map(|w| self.positions[w.vertex as usize]).sum::<DVec3>() / n
    }

    /// Polygonizes one tetrahedron of lattice points.
    fn tetrahedron(&mut self, t: [Key; 4]) {
        let mut faces: Vec<FaceInfo> = Vec::with_capacity(4);
        for f in tets::FACES {
            faces.push(self.face([t[f[0]], t[f[1]], t[f[2]]]));
        }
        let hubs: Vec<u32> = faces
            .iter()
            .filter(|f| f.spokes.iter().any(|(_, p)| self.interesting(*p)))
            .filter_map(|f| f.face_vertex)
            .collect();
        if !hubs.is_empty() {
            let centre = if hubs.len() == 1 {
                hubs[0]
            } else {
                let m = hubs.iter().map(|&h| self.positions[h as usize]).sum::<DVec3>()
                    / hubs.len() as f64;
                self.positions.push(m);
                self.crossing.push(None);
                self.stats.internal_vertices += 1;
                self.positions.len() as u32 - 1
            };
            for f in &faces {
                let mut lines: Vec<(u32, u32, RegionPair)> = f.lines.clone();
                if let Some(fv) = f.face_vertex {
                    lines.extend(f.spokes.iter().map(|&(v, p)| (v, fv, p)));
                    if fv != centre
                        && f.spokes.iter().any(|(_, p)| self.interesting(*p))
                        && f.regions.len() >= 3
                    {
                        let tri = RegionTriple::new([f.regions[0], f.regions[1], f.regions[2]]);
                        if self.opts.curves.is_empty() || self.opts.curves.contains(&tri) {
                            self.curves.push(CurveEdge { v: [fv, centre], label: tri });
                        }
                    }
                }
                for (u, v, pair) in lines {
                    if self.interesting(pair) && u != centre && v != centre {
                        self.triangles.push([u, v, centre]);
                        self.labels.push(pair);
                    }
                }
            }
            return;
        }
        // Disjoint surfaces: walk vertex → partner in a face → the other face on its edge
        // (or, from a loop vertex inside a face, on to its other partner in that face).
        let mut links: FxHashMap<u32, Vec<(usize, u32)>> = FxHashMap::default();
        let mut pair_of: FxHashMap<u32, RegionPair> = FxHashMap::default();
        for (fi, f) in faces.iter().enumerate() {
            for &(u, v, p) in &f.lines {
                links.entry(u).or_default().push((fi, v));
                links.entry(v).or_default().push((fi, u));
                pair_of.insert(u, p);
                pair_of.insert(v, p);
            }
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

    fn cube_tets(&self, c: [u32; 3]) -> Vec<[Key; 4]> {
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
    fn cube(&mut self, c: [u32; 3]) -> Vec<(usize, usize)> {
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
                        let lines =
                            info.lines.iter().map(|l| l.2).chain(info.spokes.iter().map(|s| s.1));
                        if lines.into_iter().any(|p| self.interesting(p)) {
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

    fn all_cubes(&self) -> Vec<[u32; 3]> {
        let [nx, ny, nz] = self.grid.dims.map(|d| d as u32 - 1);
        let mut v = Vec::with_capacity((nx * ny * nz) as usize);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    v.push([i, j, k]);
                }
            }
        }
        v
    }

    /// Start cubes: from the seeds, or from a coarse search of the domain.
    fn starts(&mut self) -> Result<Vec<[u32; 3]>, Error> {
        let mut points = self.opts.seeds.clone();
        if points.is_empty() {
            let search = CoarseSearch::new(&self.grid, self.opts.search_stride);
            let (pts, stride) = (&search.points, search.stride);
            let r = self.regions_of(pts);
            search.edges(|a, b| {
                if self.interesting(RegionPair::new(r[a], r[b])) {
                    // Every cube along the coarse edge is a candidate start.
                    for s in 0..=stride {
                        points.push(pts[a].lerp(pts[b], s as f64 / stride as f64));
                    }
                }
            });
            if points.is_empty() {
                return Err(Error::NoSurfaceFound { samples: pts.len() as u64, stride });
            }
        }
        let seeded = !self.opts.seeds.is_empty();
        let mut cubes: Vec<[u32; 3]> = Vec::new();
        for p in points.iter().filter(|p| self.grid.bounds().contains(**p)) {
            let c = self.cubes.cube_of_u32(*p);
            cubes.push(c);
            if seeded {
                // A seed within half a cell of the surface may sit on a lattice point or in a
                // cube the surface misses: its 26 neighbours start too.
                cubes.extend(self.cubes.around(c));
            }
        }
        if cubes.is_empty() {
            return Err(Error::BadSeed {
                seed: points[0].to_array(),
                why: "it is outside the domain".into(),
            });
        }
        cubes.sort_unstable();
        cubes.dedup();
        Ok(cubes)
    }

    fn propagate(&mut self, starts: Vec<[u32; 3]>) -> Result<(), Error> {
        let limits = Limits { max_cells: self.opts.max_cells, limit: None, origin: [0; 3] };
        let (lattice, control) = (self.cubes, &self.opts.lattice.control);
        let stops = propagate(
            self,
            &lattice,
            starts,
            &limits,
            Order::Coordinates,
            control,
            "non-manifold",
        )?;
        self.stats.reached_domain |= stops.domain;
        self.stats.reached_budget |= stops.budget;
        self.stats.cells_visited = self.visited.len() as u64;
        Ok(())
    }

    /// Winds every triangle counter-clockwise seen from its lesser region. Each triangle has
    /// an edge vertex of its own pair, whose lattice segment runs from one region into the
    /// other: the normal must point back along it towards the lesser region. (A probe off
    /// the triangle would do for large triangles, but a flat triangle under a curved surface
    /// can have both probes on one side.)
    fn orient(&mut self) {
        for (t, pair) in self.triangles.iter_mut().zip(&self.labels) {
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
                None => self.stats.unoriented_triangles += 1,
            }
        }
    }

    /// Merges close vertices, drops degenerate triangles, duplicates vertices per pair.
    fn finish(&mut self) -> Mesh {
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

impl Cubes for Run<'_> {
    fn process(&mut self, c: [u32; 3]) -> u8 {
        let open = self.cube(c);
        if self.opts.full_grid {
            // Every cube is a start already.
            return 0;
        }
        open.iter().fold(0, |m, &(axis, side)| m | 1 << (2 * axis + side))
    }

    fn is_visited(&mut self, c: [u32; 3]) -> bool {
        self.visited.contains(&self.key(c))
    }

    fn visit(&mut self, c: [u32; 3]) {
        let k = self.key(c);
        self.visited.insert(k);
    }

    fn visited(&self) -> u64 {
        self.visited.len() as u64
    }
}

/// The chapter's second post-process: a vertex closer than `limit` to the opposite side
/// of one of its triangles (a thin triangle) moves onto that side (to its nearest point
/// there, not the chapter's midpoint, which can be half a side away); the thin
/// triangle, now flat, is dropped, and every other triangle on that side is split at the
/// vertex (so no crack opens: on an intersection curve that is each sheet's triangle),
/// as is a curve segment along it. One move per vertex and per side, in triangle order.
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
    let mut neighbours: FxHashMap<u32, Vec<u32>> = FxHashMap::default();
    for (t, _) in tris.iter() {
        for k in 0..3 {
            neighbours.entry(t[k]).or_default().extend([t[(k + 1) % 3], t[(k + 2) % 3]]);
        }
    }
    for (t, _) in tris.iter() {
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
            if neighbours[&v].iter().any(|&w| pos[w as usize].distance(q) < limit) {
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

/// Pairs off crossings around a face boundary like brackets: (x→y) with a later (y→x) with
/// everything between them paired too. Paired crossings become disjoint lines; the rest
/// meet at the face vertex.
fn pair_off(ring: &[Walked], lines: &mut Vec<(u32, u32, RegionPair)>) -> Vec<Walked> {
    // Reduce the cycle: remove adjacent matching pairs until none is left (cyclically).
    let mut items: Vec<Walked> = ring.to_vec();
    loop {
        let n = items.len();
        if n < 2 {
            break;
        }
        let found = (0..n).find(|&i| {
            let (a, b) = (items[i], items[(i + 1) % n]);
            a.from == b.to && a.to == b.from
        });
        let Some(i) = found else { break };
        let (a, b) = (items[i], items[(i + 1) % n]);
        lines.push((a.vertex, b.vertex, RegionPair::new(a.from, a.to)));
        let j = (i + 1) % n;
        let (hi, lo) = if i > j { (i, j) } else { (j, i) };
        items.remove(hi);
        items.remove(lo);
    }
    items
}

/// One step of the contour follower's strip of triangles: the apex, in region `r`, replaces
/// the base corner of the same region (`px` in `x`, `py` in `y`), and the new apex is that
/// corner mirrored across the new base. False (nothing moved) when `r` is a third region.
fn flip_strip(r: u32, x: u32, y: u32, px: &mut DVec3, py: &mut DVec3, apex: &mut DVec3) -> bool {
    let old = if r == x {
        std::mem::replace(px, *apex)
    } else if r == y {
        std::mem::replace(py, *apex)
    } else {
        return false;
    };
    *apex = *px + *py - old;
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    fn w(vertex: u32, from: u32, to: u32) -> Walked {
        Walked { vertex, from, to }
    }

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
    fn disjoint_lines_pair_off_and_intersections_remain() {
        let mut lines = Vec::new();
        // Two parallel bands 1 | 2 | 3 across a face: all paired.
        let left = pair_off(&[w(0, 1, 2), w(1, 2, 3), w(2, 3, 2), w(3, 2, 1)], &mut lines);
        assert!(left.is_empty());
        assert_eq!(lines.len(), 2);
        // Three regions meeting inside: nothing pairs.
        lines.clear();
        let left = pair_off(&[w(0, 1, 2), w(1, 2, 3), w(2, 3, 1)], &mut lines);
        assert_eq!(left.len(), 3);
        assert!(lines.is_empty());
    }
}
