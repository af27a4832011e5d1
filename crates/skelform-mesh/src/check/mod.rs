//! The topology checker behind `skelform check`: counts, edge degrees, components, Euler
//! characteristic and genus, orientation, degenerate and duplicate faces, labels.
//!
//! Definitions:
//! - A face is *valid* when its three indices are in range and distinct. Faces with an
//!   out-of-range index are only counted (`out_of_range_faces`); faces with a repeated index
//!   are degenerate (`faces_with_repeated_vertex`). Neither takes part in the edge topology
//!   (edges, components, orientation, non-manifold vertices), which is about valid faces.
//! - Edges are the distinct undirected edges of valid faces; an edge's degree is the number
//!   of face sides on it: 1 boundary, 2 manifold, 3 or more non-manifold.
//! - Components are the classes of valid faces connected through shared edges (of any
//!   degree). A component is closed when it has neither boundary nor non-manifold edges.
//! - A vertex is non-manifold when its valid faces, linked through the manifold edges at
//!   the vertex, form more than one fan (two cones touching at their tips, or the ends of a
//!   non-manifold edge).
//! - An inconsistent edge is a manifold edge whose two faces traverse it the same way.
//! - A face has zero area when `|(p1 − p0) × (p2 − p0)| ≤ 1e-12 · d²`, `d` the diagonal of
//!   the bounding box (so exactly-zero cross products are included); only faces with distinct
//!   indices are counted there.
//!
//! Everything runs in O(n log n) (a sort of the half-edges and union-finds).
//!
//! Besides the counts: [`weld`] identifies coincident vertex copies (so that a non-manifold
//! mesh's sheets are seen to meet) and [`crossings`] finds triangles that pass through each
//! other, which no count reveals.

use std::collections::BTreeMap;
use std::fmt;

use serde::Serialize;

use crate::mesh::{Mesh, RegionPair, RegionTriple};

mod crossings;
mod weld;

pub use crossings::crossings;
pub use weld::weld;

/// What [`check`] finds in a mesh. Serializes to JSON for `skelform check --json`; displays
/// as a compact text report.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Report {
    /// Length of the mesh's position list, referenced or not.
    pub vertices: usize,
    /// Triangles in the mesh, valid or not (out-of-range and degenerate ones included).
    pub faces: usize,
    /// Vertices used by no face (curves do not count as use).
    pub unreferenced_vertices: usize,
    /// Faces with an index past the last vertex; left out of everything else.
    pub out_of_range_faces: usize,
    /// Distinct undirected edges of valid faces.
    pub edges: usize,
    /// Edge degree → number of edges.
    pub edge_degrees: BTreeMap<usize, usize>,
    /// Edges of degree 1: an open surface's rim. Zero for a closed surface.
    pub boundary_edges: usize,
    /// Edges of degree 3 or more, where several sheets meet (expected along the curves of a
    /// non-manifold mesh, an error in a manifold one).
    pub non_manifold_edges: usize,
    /// Vertices whose valid faces form more than one fan through manifold edges (cones
    /// touching at their tips, ends of non-manifold edges), over the whole mesh.
    pub non_manifold_vertices: usize,
    /// Largest first (then by first face).
    pub components: Vec<Component>,
    /// Manifold edges whose two faces traverse them the same way.
    pub inconsistent_edges: usize,
    /// No inconsistent edges: every manifold edge is traversed in opposite directions by its
    /// two faces, so normals from the winding agree across it.
    pub consistently_oriented: bool,
    /// Whether every component can be oriented consistently (no Möbius strip).
    pub orientable: bool,
    /// `faces_with_repeated_vertex + zero_area_faces`.
    pub degenerate_faces: usize,
    /// Faces with two equal indices; they are left out of the edge topology.
    pub faces_with_repeated_vertex: usize,
    /// Faces with distinct indices but (nearly) no area: `|(p1 − p0) × (p2 − p0)| ≤ 1e-12 · d²`,
    /// `d` the bounding-box diagonal. They still take part in the edge topology.
    pub zero_area_faces: usize,
    /// Faces with the same vertex set as an earlier face, in any order.
    pub duplicate_faces: usize,
    /// Faces whose three corners lie at the same positions as another face's (extra
    /// copies), whatever their vertex indices or winding: two sheets meshed twice, or a
    /// pair of coincident, oppositely wound triangles that no index comparison sees.
    pub coincident_faces: usize,
    /// Manifold edges where the surface folds back on itself: the normals of the two faces
    /// are more than 175° apart, so the faces lie on top of each other (faces too thin to
    /// have a reliable normal are left out).
    pub folded_edges: usize,
    /// Whether the mesh carries per-vertex normals; without them the renderer shades with
    /// area-weighted face normals and PLY and OBJ files get none.
    pub has_normals: bool,
    /// Triangles per label, sorted by label; empty for an unlabelled mesh.
    pub labels: Vec<LabelCount>,
    /// Curve segments.
    pub curves: usize,
    /// Curve segments per label, and whether each label's curves close up.
    pub curve_labels: Vec<CurveCount>,
    /// Vertices merged into another by [`weld`] before the analysis (`check --weld`).
    pub welded_vertices: Option<usize>,
    /// The box of every vertex position, referenced or not; `None` for a mesh without vertices.
    pub bounds: Option<Bounds>,
    /// Total area of the faces with in-range indices.
    pub area: f64,
    /// The enclosed (signed) volume, when every component is closed and consistently
    /// oriented.
    pub volume: Option<f64>,
    /// Whether that volume is positive (the faces face outward overall), under the same
    /// condition.
    pub outward: Option<bool>,
}

/// One edge-connected component of faces.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Component {
    /// The lowest face index in the component.
    pub first_face: usize,
    /// Valid faces in the component.
    pub faces: usize,
    /// Distinct vertices used by the component's faces.
    pub vertices: usize,
    /// Distinct undirected edges of the component's faces, of any degree.
    pub edges: usize,
    /// V − E + F.
    pub euler: i64,
    /// Edges of degree 1 in the component.
    pub boundary_edges: usize,
    /// Chains of boundary edges joined at shared vertices (closed loops, on a manifold).
    pub boundary_loops: usize,
    /// Edges of degree 3 or more in the component.
    pub non_manifold_edges: usize,
    /// Vertices where this component alone has more than one fan.
    pub non_manifold_vertices: usize,
    /// No boundary and no non-manifold edges.
    pub closed: bool,
    /// Whether the component's faces can be wound consistently at all (a Möbius strip cannot);
    /// false makes `genus` `None`.
    pub orientable: bool,
    /// Manifold edges of the component whose two faces traverse them the same way: faces to flip.
    pub inconsistent_edges: usize,
    /// No inconsistent edges in the component.
    pub consistently_oriented: bool,
    /// `(2 − χ) / 2` for a closed, orientable component without non-manifold vertices.
    pub genus: Option<i64>,
    /// Signed volume, for a closed and consistently oriented component.
    pub volume: Option<f64>,
    /// Whether the volume is positive, i.e. the faces are wound outward.
    pub outward: Option<bool>,
    /// Total area of the component's faces, in squared scene units.
    pub area: f64,
}

impl Component {
    /// Closed, consistently oriented, and without non-manifold vertices.
    pub fn is_closed_manifold(&self) -> bool {
        self.closed && self.consistently_oriented && self.non_manifold_vertices == 0
    }
}

/// Triangles carrying one label.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct LabelCount {
    /// The region pair the triangles separate.
    pub label: RegionPair,
    /// Triangles carrying `label`.
    pub triangles: usize,
}

/// The curve segments carrying one region triple.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct CurveCount {
    /// The three regions meeting along these curves.
    pub label: RegionTriple,
    /// Curve segments carrying `label`.
    pub segments: usize,
    /// Vertices where an odd number of this label's segments end: 0 when the curves are
    /// closed loops (or meet other curves of the label in even numbers).
    pub open_ends: usize,
}

/// [`check`] after [`weld`]ing coincident vertices within `tolerance`.
pub fn check_welded(mesh: &Mesh, tolerance: f32) -> Report {
    let (welded, merged) = weld(mesh, tolerance);
    let mut r = check(&welded);
    r.welded_vertices = Some(merged);
    r
}

fn curve_counts(mesh: &Mesh) -> Vec<CurveCount> {
    let mut per: BTreeMap<RegionTriple, (usize, BTreeMap<u32, usize>)> = BTreeMap::new();
    for c in &mesh.curves {
        let e = per.entry(c.label).or_default();
        e.0 += 1;
        for v in c.v {
            *e.1.entry(v).or_default() += 1;
        }
    }
    per.into_iter()
        .map(|(label, (segments, ends))| CurveCount {
            label,
            segments,
            open_ends: ends.values().filter(|&&n| n % 2 == 1).count(),
        })
        .collect()
}

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Bounds {
    /// Least `x`, `y` and `z` of the vertices, in scene units.
    pub min: [f32; 3],
    /// Greatest `x`, `y` and `z` of the vertices, in scene units.
    pub max: [f32; 3],
}

impl Report {
    /// At least one face, every face valid, no boundary or non-manifold edges, no
    /// non-manifold vertices, and consistently oriented.
    pub fn is_closed_manifold(&self) -> bool {
        self.faces > 0
            && self.out_of_range_faces == 0
            && self.faces_with_repeated_vertex == 0
            && self.boundary_edges == 0
            && self.non_manifold_edges == 0
            && self.non_manifold_vertices == 0
            && self.consistently_oriented
    }

    /// Why the mesh is not a closed manifold, in a few words each; empty when it is one.
    pub fn problems(&self) -> Vec<String> {
        let mut p = Vec::new();
        let mut count = |n: usize, what: &str| {
            if n > 0 {
                p.push(format!("{n} {what}"));
            }
        };
        count(self.out_of_range_faces, "faces with out-of-range indices");
        count(self.faces_with_repeated_vertex, "faces with a repeated vertex");
        count(self.boundary_edges, "boundary edges");
        count(self.non_manifold_edges, "non-manifold edges");
        count(self.non_manifold_vertices, "non-manifold vertices");
        count(self.inconsistent_edges, "inconsistently oriented edges");
        if self.faces == 0 {
            p.push("no faces".to_string());
        }
        p
    }
}

/// Normals of adjacent faces with a dot product below this (more than 175° apart) make a
/// folded edge.
const FOLD_COS: f64 = -0.996_194_698;

/// The unit normal of a face, `None` when the face is too thin for its normal to mean
/// anything (twice its area under 10⁻¹⁰ of its longest edge squared).
fn unit_normal(mesh: &Mesh, t: &[u32; 3]) -> Option<[f64; 3]> {
    let p = t.map(|i| mesh.positions[i as usize].map(f64::from));
    let (u, v, w) = (sub(p[1], p[0]), sub(p[2], p[0]), sub(p[2], p[1]));
    let n = cross(u, v);
    let len = dot(n, n).sqrt();
    let longest = dot(u, u).max(dot(v, v)).max(dot(w, w));
    (len.is_finite() && len > 1e-10 * longest).then(|| n.map(|x| x / len))
}

/// Extra copies of valid faces with the same three corner positions.
fn coincident(mesh: &Mesh, valid: &[bool]) -> usize {
    let mut keys: Vec<[[u32; 3]; 3]> = mesh
        .triangles
        .iter()
        .enumerate()
        .filter(|(f, _)| valid[*f])
        .map(|(_, t)| {
            // Bit patterns, with -0.0 taken as 0.0 so that equal positions compare equal.
            let mut k = t.map(|i| mesh.positions[i as usize].map(|c| (c + 0.0).to_bits()));
            k.sort_unstable();
            k
        })
        .collect();
    keys.sort_unstable();
    keys.windows(2).filter(|w| w[0] == w[1]).count()
}

/// A union-find whose roots are the smallest index of their class.
struct Dsu {
    parent: Vec<usize>,
}

impl Dsu {
    fn new(n: usize) -> Self {
        Dsu { parent: (0..n).collect() }
    }

    fn find(&mut self, mut x: usize) -> usize {
        while self.parent[x] != x {
            let grand = self.parent[self.parent[x]];
            self.parent[x] = grand;
            x = grand;
        }
        x
    }

    fn union(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
            self.parent[hi] = lo;
        }
    }
}

/// A union-find that also keeps the parity (flipped or not) of each element relative to its
/// root, to decide orientability.
struct ParityDsu {
    parent: Vec<usize>,
    parity: Vec<u8>,
}

impl ParityDsu {
    fn new(n: usize) -> Self {
        ParityDsu { parent: (0..n).collect(), parity: vec![0; n] }
    }

    fn find(&mut self, x: usize) -> (usize, u8) {
        let mut root = x;
        let mut p = 0;
        while self.parent[root] != root {
            p ^= self.parity[root];
            root = self.parent[root];
        }
        // Point the path at the root, each with its parity to the root.
        let (mut cur, mut cp) = (x, p);
        while self.parent[cur] != cur {
            let (next, np) = (self.parent[cur], cp ^ self.parity[cur]);
            self.parent[cur] = root;
            self.parity[cur] = cp;
            cur = next;
            cp = np;
        }
        (root, p)
    }

    /// Records that `a` and `b` differ in parity by `rel`; false if that contradicts what is
    /// known.
    fn union(&mut self, a: usize, b: usize, rel: u8) -> bool {
        let ((ra, pa), (rb, pb)) = (self.find(a), self.find(b));
        if ra == rb {
            return pa ^ pb == rel;
        }
        let (lo, hi) = if ra < rb { (ra, rb) } else { (rb, ra) };
        self.parent[hi] = lo;
        self.parity[hi] = pa ^ pb ^ rel;
        true
    }
}

#[derive(Default)]
struct Acc {
    first_face: usize,
    faces: usize,
    vertices: usize,
    edges: usize,
    boundary: usize,
    loops: usize,
    non_manifold: usize,
    pinched: usize,
    inconsistent: usize,
    non_orientable: bool,
    volume: f64,
    area: f64,
}

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: V3, b: V3) -> V3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// The endpoints of an edge key.
fn ends(key: u64) -> (u32, u32) {
    ((key >> 32) as u32, key as u32)
}

/// Checks the topology and geometry of `mesh`; never panics, whatever the indices.
pub fn check(mesh: &Mesh) -> Report {
    let nv = mesh.positions.len();
    let tris = &mesh.triangles;
    let nf = tris.len();

    // Classify faces.
    let mut valid = vec![false; nf];
    let mut referenced = vec![false; nv];
    let (mut out_of_range, mut repeated) = (0, 0);
    for (f, t) in tris.iter().enumerate() {
        if t.iter().any(|&i| i as usize >= nv) {
            out_of_range += 1;
            continue;
        }
        for &i in t {
            referenced[i as usize] = true;
        }
        if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
            repeated += 1;
        } else {
            valid[f] = true;
        }
    }
    let unreferenced_vertices = referenced.iter().filter(|&&r| !r).count();

    // Half-edges: (undirected edge key, face << 1 | whether it runs from low to high).
    let mut half: Vec<(u64, u64)> = Vec::with_capacity(3 * nf);
    for (f, t) in tris.iter().enumerate().filter(|(f, _)| valid[*f]) {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            let key = (u64::from(a.min(b)) << 32) | u64::from(a.max(b));
            half.push((key, ((f as u64) << 1) | u64::from(a < b)));
        }
    }
    half.sort_unstable();
    let face_of = |h: (u64, u64)| (h.1 >> 1) as usize;
    let corner = |f: usize, v: u32| 3 * f + tris[f].iter().position(|&x| x == v).unwrap_or(0);

    // Link faces across edges, fans across manifold edges, and orientations.
    let mut components = Dsu::new(nf);
    let mut fans = Dsu::new(3 * nf);
    let mut orient = ParityDsu::new(nf);
    let mut contradictions = Vec::new();
    let mut edge_degrees = BTreeMap::new();
    let normals: Vec<Option<[f64; 3]>> = tris
        .iter()
        .enumerate()
        .map(|(f, t)| valid[f].then(|| unit_normal(mesh, t)).flatten())
        .collect();
    let mut folded_edges = 0;
    for group in half.chunk_by(|x, y| x.0 == y.0) {
        *edge_degrees.entry(group.len()).or_insert(0) += 1;
        let f0 = face_of(group[0]);
        for &h in &group[1..] {
            components.union(f0, face_of(h));
        }
        if let [h1, h2] = *group {
            let (f1, f2) = (face_of(h1), face_of(h2));
            let (a, b) = ends(h1.0);
            fans.union(corner(f1, a), corner(f2, a));
            fans.union(corner(f1, b), corner(f2, b));
            let same_direction = (h1.1 & 1) == (h2.1 & 1);
            if let (Some(n1), Some(n2)) = (normals[f1], normals[f2]) {
                // Faces that traverse the edge the same way are wound oppositely: compare
                // their normals as if one were flipped.
                let d = dot(n1, n2) * if same_direction { -1.0 } else { 1.0 };
                folded_edges += usize::from(d < FOLD_COS);
            }
            if !orient.union(f1, f2, u8::from(same_direction)) {
                contradictions.push(f1);
            }
        }
    }
    let edges = half.chunk_by(|x, y| x.0 == y.0).count();

    // Number the components in order of their lowest face.
    let mut comp_of = vec![usize::MAX; nf];
    let mut acc: Vec<Acc> = Vec::new();
    for f in (0..nf).filter(|&f| valid[f]) {
        let root = components.find(f);
        let id = if root == f {
            acc.push(Acc { first_face: f, ..Acc::default() });
            acc.len() - 1
        } else {
            comp_of[root]
        };
        comp_of[f] = id;
        acc[id].faces += 1;
    }
    for f in contradictions {
        acc[comp_of[f]].non_orientable = true;
    }

    // Edges per component; boundary edges for the loops.
    let mut boundary = Vec::new();
    for group in half.chunk_by(|x, y| x.0 == y.0) {
        let id = comp_of[face_of(group[0])];
        let c = &mut acc[id];
        c.edges += 1;
        match *group {
            [h] => {
                c.boundary += 1;
                let (a, b) = ends(h.0);
                boundary.push((id, a, b));
            }
            [h1, h2] => c.inconsistent += usize::from((h1.1 & 1) == (h2.1 & 1)),
            _ => c.non_manifold += 1,
        }
    }
    let mut loops = Dsu::new(boundary.len());
    let mut boundary_ends: Vec<(usize, u32, usize)> =
        boundary.iter().enumerate().flat_map(|(e, &(id, a, b))| [(id, a, e), (id, b, e)]).collect();
    boundary_ends.sort_unstable();
    for pair in boundary_ends.windows(2) {
        if pair[0].0 == pair[1].0 && pair[0].1 == pair[1].1 {
            loops.union(pair[0].2, pair[1].2);
        }
    }
    for (e, &(id, _, _)) in boundary.iter().enumerate() {
        if loops.find(e) == e {
            acc[id].loops += 1;
        }
    }

    // Fans per vertex: the root corners.
    let mut fan_count = vec![0u32; nv];
    let mut roots = Vec::new();
    for f in (0..nf).filter(|&f| valid[f]) {
        for (k, &v) in tris[f].iter().enumerate() {
            let c = 3 * f + k;
            if fans.find(c) == c {
                fan_count[v as usize] += 1;
                roots.push((v, comp_of[f]));
            }
        }
    }
    let non_manifold_vertices = fan_count.iter().filter(|&&n| n > 1).count();
    let mut shared: Vec<(u32, usize)> = Vec::new();
    for (v, id) in roots {
        if fan_count[v as usize] == 1 {
            acc[id].vertices += 1;
        } else {
            shared.push((v, id));
        }
    }
    shared.sort_unstable();
    for run in shared.chunk_by(|x, y| x == y) {
        let id = run[0].1;
        acc[id].vertices += 1;
        if run.len() > 1 {
            acc[id].pinched += 1;
        }
    }

    // Geometry.
    let bounds = mesh.bounds();
    let (center, diag2) = bounds.map_or(([0.0; 3], 0.0), |(lo, hi)| {
        let lo = lo.map(f64::from);
        let hi = hi.map(f64::from);
        let d = sub(hi, lo);
        ([0, 1, 2].map(|i| 0.5 * (lo[i] + hi[i])), dot(d, d))
    });
    let zero_limit = 1e-12 * diag2;
    let mut area = 0.0;
    let mut zero_area_faces = 0;
    for (f, t) in tris.iter().enumerate() {
        if t.iter().any(|&i| i as usize >= nv) {
            continue;
        }
        let p = t.map(|i| mesh.positions[i as usize].map(f64::from));
        let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        let twice_area = dot(n, n).sqrt();
        area += 0.5 * twice_area;
        if valid[f] {
            if twice_area <= zero_limit || twice_area == 0.0 {
                zero_area_faces += 1;
            }
            let c = &mut acc[comp_of[f]];
            c.area += 0.5 * twice_area;
            c.volume += dot(sub(p[0], center), n) / 6.0;
        }
    }

    // Duplicate faces.
    let mut keys: Vec<[u32; 3]> = tris
        .iter()
        .filter(|t| t.iter().all(|&i| (i as usize) < nv))
        .map(|t| {
            let mut k = *t;
            k.sort_unstable();
            k
        })
        .collect();
    keys.sort_unstable();
    let duplicate_faces = keys.windows(2).filter(|w| w[0] == w[1]).count();
    let coincident_faces = coincident(mesh, &valid);

    let mut components: Vec<Component> = acc
        .into_iter()
        .map(|c| {
            let euler = c.vertices as i64 - c.edges as i64 + c.faces as i64;
            let closed = c.boundary == 0 && c.non_manifold == 0;
            let orientable = !c.non_orientable;
            let consistently_oriented = c.inconsistent == 0;
            let genus = (closed && orientable && c.pinched == 0 && euler % 2 == 0)
                .then_some((2 - euler) / 2);
            let volume = (closed && consistently_oriented).then_some(c.volume);
            Component {
                first_face: c.first_face,
                faces: c.faces,
                vertices: c.vertices,
                edges: c.edges,
                euler,
                boundary_edges: c.boundary,
                boundary_loops: c.loops,
                non_manifold_edges: c.non_manifold,
                non_manifold_vertices: c.pinched,
                closed,
                orientable,
                inconsistent_edges: c.inconsistent,
                consistently_oriented,
                genus,
                volume,
                outward: volume.map(|v| v > 0.0),
                area: c.area,
            }
        })
        .collect();
    components.sort_by(|a, b| b.faces.cmp(&a.faces).then(a.first_face.cmp(&b.first_face)));

    let inconsistent_edges = components.iter().map(|c| c.inconsistent_edges).sum();
    let volume = (!components.is_empty() && out_of_range == 0)
        .then(|| components.iter().map(|c| c.volume).sum::<Option<f64>>())
        .flatten();
    Report {
        vertices: nv,
        faces: nf,
        unreferenced_vertices,
        out_of_range_faces: out_of_range,
        edges,
        boundary_edges: edge_degrees.get(&1).copied().unwrap_or(0),
        non_manifold_edges: edge_degrees.range(3..).map(|(_, n)| n).sum(),
        edge_degrees,
        non_manifold_vertices,
        orientable: components.iter().all(|c| c.orientable),
        components,
        inconsistent_edges,
        consistently_oriented: inconsistent_edges == 0,
        degenerate_faces: repeated + zero_area_faces,
        faces_with_repeated_vertex: repeated,
        zero_area_faces,
        duplicate_faces,
        coincident_faces,
        folded_edges,
        has_normals: !mesh.normals.is_empty(),
        labels: mesh
            .label_counts()
            .into_iter()
            .map(|(label, triangles)| LabelCount { label, triangles })
            .collect(),
        curves: mesh.curves.len(),
        curve_labels: curve_counts(mesh),
        welded_vertices: None,
        bounds: bounds.map(|(min, max)| Bounds { min, max }),
        area,
        volume,
        outward: volume.map(|v| v > 0.0),
    }
}

/// A number with about six significant digits, without trailing zeros.
fn num(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let magnitude = x.abs().log10().floor();
    if !(-4.0..9.0).contains(&magnitude) {
        return format!("{x:.5e}");
    }
    let decimals = (5.0 - magnitude).max(0.0) as usize;
    let s = format!("{x:.decimals$}");
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.').to_string() } else { s }
}

fn point(p: [f32; 3]) -> String {
    format!("({}, {}, {})", num(p[0].into()), num(p[1].into()), num(p[2].into()))
}

/// How many components the text report lists one by one.
const LISTED_COMPONENTS: usize = 10;

impl fmt::Display for Component {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "faces {}  V {}  E {}  χ {}", self.faces, self.vertices, self.edges, self.euler)?;
        if let Some(g) = self.genus {
            write!(f, "  genus {g}")?;
        }
        let mut parts = Vec::new();
        if self.closed {
            parts.push("closed".to_string());
        }
        if self.boundary_edges > 0 {
            let s = if self.boundary_loops == 1 { "" } else { "s" };
            parts.push(format!(
                "open ({} boundary edges, {} loop{s})",
                self.boundary_edges, self.boundary_loops
            ));
        }
        if self.non_manifold_edges > 0 {
            parts.push(format!("{} non-manifold edges", self.non_manifold_edges));
        }
        if self.non_manifold_vertices > 0 {
            parts.push(format!("{} non-manifold vertices", self.non_manifold_vertices));
        }
        parts.push(if !self.orientable {
            "non-orientable".to_string()
        } else if !self.consistently_oriented {
            format!("inconsistently oriented ({} edges)", self.inconsistent_edges)
        } else {
            match self.outward {
                Some(true) => "oriented (outward)".to_string(),
                Some(false) => "oriented (inward)".to_string(),
                None => "oriented".to_string(),
            }
        });
        write!(f, "  {}", parts.join(", "))
    }
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "vertices      {} ({} unreferenced)",
            self.vertices, self.unreferenced_vertices
        )?;
        if let Some(n) = self.welded_vertices {
            writeln!(f, "welded        {n} coincident vertices merged before the analysis")?;
        }
        write!(f, "faces         {}", self.faces)?;
        if self.out_of_range_faces > 0 {
            write!(f, " ({} with out-of-range indices)", self.out_of_range_faces)?;
        }
        writeln!(f)?;
        let degree = |d: usize| self.edge_degrees.get(&d).copied().unwrap_or(0);
        write!(
            f,
            "edges         {}   degree 1: {}  2: {}  ≥3: {}",
            self.edges,
            degree(1),
            degree(2),
            self.non_manifold_edges
        )?;
        let high: Vec<String> =
            self.edge_degrees.range(3..).map(|(d, n)| format!("{d}: {n}")).collect();
        if !high.is_empty() {
            write!(f, " ({})", high.join("  "))?;
        }
        writeln!(f)?;
        writeln!(
            f,
            "non-manifold  {} edges, {} vertices",
            self.non_manifold_edges, self.non_manifold_vertices
        )?;
        writeln!(f, "components    {}", self.components.len())?;
        for (i, c) in self.components.iter().take(LISTED_COMPONENTS).enumerate() {
            writeln!(f, "  #{i}  {c}")?;
        }
        if self.components.len() > LISTED_COMPONENTS {
            writeln!(f, "  ... and {} more", self.components.len() - LISTED_COMPONENTS)?;
        }
        write!(f, "orientation   ")?;
        if self.consistently_oriented {
            write!(f, "consistent")?;
        } else {
            write!(f, "inconsistent ({} edges)", self.inconsistent_edges)?;
            if !self.orientable {
                write!(f, ", non-orientable")?;
            }
        }
        match self.outward {
            Some(true) => writeln!(f, ", outward")?,
            Some(false) => writeln!(f, ", inward")?,
            None => writeln!(f)?,
        }
        writeln!(
            f,
            "degenerate    {} ({} repeated-vertex, {} zero-area)",
            self.degenerate_faces, self.faces_with_repeated_vertex, self.zero_area_faces
        )?;
        writeln!(f, "duplicates    {}", self.duplicate_faces)?;
        if self.coincident_faces > 0 || self.folded_edges > 0 {
            writeln!(
                f,
                "overlaps      {} coincident faces, {} folded edges",
                self.coincident_faces, self.folded_edges
            )?;
        }
        if !self.labels.is_empty() {
            let labels: Vec<String> =
                self.labels.iter().map(|l| format!("{}: {}", l.label, l.triangles)).collect();
            writeln!(f, "labels        {}", labels.join("  "))?;
        }
        if self.curves > 0 {
            writeln!(f, "curves        {} segments", self.curves)?;
            for c in &self.curve_labels {
                let state = if c.open_ends == 0 {
                    "closed".to_string()
                } else {
                    format!("open ({} ends)", c.open_ends)
                };
                writeln!(f, "  curve {}  {} segments, {state}", c.label, c.segments)?;
            }
        }
        writeln!(f, "normals       {}", if self.has_normals { "yes" } else { "no" })?;
        if let Some(b) = self.bounds {
            writeln!(f, "bounds        {} – {}", point(b.min), point(b.max))?;
        }
        writeln!(f, "area          {}", num(self.area))?;
        if let Some(v) = self.volume {
            writeln!(f, "volume        {}", num(v))?;
        }
        let problems = self.problems();
        if problems.is_empty() {
            writeln!(f, "verdict       closed manifold")
        } else {
            writeln!(f, "verdict       not a closed manifold: {}", problems.join(", "))
        }
    }
}
