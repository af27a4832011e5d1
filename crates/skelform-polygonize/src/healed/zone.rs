//! Healing zones: the cubes around the self-intersection network whose marching-cubes
//! triangles are replaced.
//!
//! The thesis replaces the triangles of each critical cube by hand-made patterns fanned onto
//! the self-intersection segment of that cube. Here the same is done for a connected set of
//! cubes at once, which is what lets one cell hold more than one segment, curves that turn,
//! pinch points and cone apexes:
//!
//! 1. The zone starts as every cube within a twentieth of a cell of the network, and grows
//!    until marching cubes is right on its boundary: no boundary lattice edge crosses the
//!    surface twice between its samples where two sheets meet (found from the field: the
//!    sign of `f` at the extremum along the edge; a pair of crossings with nearly the same
//!    normal is one sheet grazing the edge, missed the same way outside, and does not make
//!    the zone grow), and every boundary face with four crossings pairs them as
//!    the field does (the sign of `f` at the face's saddle, where the decider uses the
//!    bilinear interpolant; where `f` has no saddle on the face, the contour `f = 0`
//!    followed across it). A saddle with `f = 0` on a boundary face is a curve point the
//!    search missed: it becomes a seed and the network is traced again. It grows for these
//!    only within six cells of the network (farther, what marching cubes misses is one
//!    sheet's own, shared with the cubes outside), and it takes in any small patch of
//!    outside polygons that its boundary closes round.
//! 2. On the zone's boundary the surface meets the faces in segments that marching cubes
//!    shares with the cubes outside, and on the domain box in segments where the mesh ends
//!    (but not on box faces where a curve leaves the box, or whose edges hide crossings:
//!    there marching cubes pairs the crossings wrongly). They chain into loops, and into
//!    paths that end where curves leave the box: the traces of the sheets that leave the
//!    network. A loop that no curve explains (a sheet grazing the zone) is a disk.
//! 3. Each trace is mapped onto the network (each vertex to its nearest node, joined by
//!    shortest network paths, back-and-forth moves removed except at the ends of curves, where
//!    a sheet folds round as on the Whitney umbrella) and the band between the trace and that
//!    walk is triangulated by zipping the two. A loop round a cone apex is fanned to it.
//!    A band whose zip folds (consecutive triangles turned back, or slivers) is zipped again
//!    by the order that keeps its triangles facing as the field's gradient at the trace
//!    does (`Band::rezip`).
//! 4. The zone is accepted only if every network edge in it gets exactly four triangles (two
//!    sheets crossing), every trace was explained, and every cone was fanned. Otherwise its
//!    marching-cubes triangles are kept and the zone is reported: never worse than marching
//!    cubes, never a hole.
//!
//! Every boundary segment is traversed as the zone-side cube traverses it in marching cubes,
//! so the bands are oriented like the triangles they meet: towards `f > 0`, which flips from
//! one side of a crossing to the other.

use std::collections::BinaryHeap;

use glam::DVec3;
use rustc_hash::{FxHashMap, FxHashSet};
use skelform_field::grid::{Grid, Volume};

use super::local::Probe;
use super::network::{Network, NodeKind};
use crate::grid::cell::{case_of, face_decisions};
use crate::grid::cube::{CORNERS, EDGES, FACES, edge_axis, other_axes};
use crate::grid::table::{Entry, table};
use crate::grid::{GridVertex, Place};

/// A zone whose marching-cubes triangles were kept, and why.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize))]
pub struct Unresolved {
    /// The centre of its cubes.
    pub center: DVec3,
    /// How many cubes it has: how much of the mesh stays as marching cubes made it.
    pub cubes: usize,
    /// The first check it failed, in words (e.g. a curve edge without four sheet pieces).
    pub reason: String,
}

/// The replacement triangles. Vertex ids below `mc_vertices` are marching-cubes vertices;
/// `mc_vertices + k` is network node `k`.
#[derive(Clone, Debug, Default)]
pub(crate) struct Healing {
    /// Cubes whose marching-cubes triangles are replaced (accepted zones only).
    pub cubes: FxHashSet<usize>,
    pub triangles: Vec<[u32; 3]>,
    /// Network edges that carry bands (node ids).
    pub curve_edges: Vec<[u32; 2]>,
    /// For each band triangle, the band (sheet piece) it belongs to.
    pub band_of: Vec<u32>,
    pub zones: usize,
    pub unresolved: Vec<Unresolved>,
    /// Lattice edges and faces checked on the field while growing the zones.
    pub edges_checked: usize,
    pub faces_checked: usize,
}

/// What healing needs to know.
pub(crate) struct Input<'a> {
    pub grid: Grid,
    pub volume: &'a Volume,
    pub vertices: &'a [GridVertex],
    pub positions: &'a [DVec3],
    /// The marching-cubes triangles and the cube of each.
    pub triangles: &'a [[u32; 3]],
    pub cube_of_tri: &'a [Option<usize>],
    pub net: &'a Network,
    /// Most cubes in all zones together.
    pub max_cubes: usize,
}

/// Either new seeds (curve points the search missed), or the healing.
pub(crate) enum Outcome {
    Seeds(Vec<(DVec3, usize)>),
    Healed(Healing),
}

/// Cube and lattice indexing: the shared lattice, with what healing adds to it below.
pub(crate) use crate::lattice::cubes::CubeLattice as Lattice;

impl Lattice {
    /// The key of a lattice point given in healing's `usize` coordinates.
    pub fn point_index(&self, p: [usize; 3]) -> u64 {
        self.key(p.map(|x| x as u32))
    }

    /// Key of the lattice edge from point `p` along `axis`.
    pub fn edge_key(&self, p: [usize; 3], axis: usize) -> u64 {
        self.point_index(p) * 3 + axis as u64
    }

    /// The four cubes round a lattice edge, in cyclic order (`None` outside the lattice).
    pub fn around_edge(&self, p: [usize; 3], axis: usize) -> [Option<usize>; 4] {
        let (b, c) = other_axes(axis);
        [(0, 0), (1, 0), (1, 1), (0, 1)].map(|(db, dc): (usize, usize)| {
            let mut q = p;
            if q[b] < db || q[c] < dc {
                return None;
            }
            q[b] -= db;
            q[c] -= dc;
            (q[0] < self.cubes[0] && q[1] < self.cubes[1] && q[2] < self.cubes[2])
                .then(|| self.cube(q))
        })
    }

    pub fn corner_values(&self, volume: &Volume, c: [usize; 3]) -> [f32; 8] {
        CORNERS.map(|o| volume.get(c[0] + o[0], c[1] + o[1], c[2] + o[2]))
    }

    pub fn add_near(&self, p: DVec3, margin: f64, out: &mut FxHashSet<usize>) {
        let r = (p - self.grid.origin) / self.grid.cell;
        let range = |a: usize| {
            let lo = (r[a] - margin).floor().max(0.0) as usize;
            let hi = ((r[a] + margin).floor().max(0.0) as usize).min(self.cubes[a] - 1);
            lo.min(self.cubes[a] - 1)..=hi
        };
        for k in range(2) {
            for j in range(1) {
                for i in range(0) {
                    out.insert(self.cube([i, j, k]));
                }
            }
        }
    }
}

/// Lattice edge key → marching-cubes vertex, for the edges of the given cubes that cross the
/// surface (found through those cubes' triangles, so that no map of every vertex is kept).
pub(crate) fn edge_vertices(
    lat: &Lattice,
    vertices: &[GridVertex],
    triangles: &[[u32; 3]],
    cube_of_tri: &[Option<usize>],
    cubes: &FxHashSet<usize>,
) -> FxHashMap<u64, u32> {
    let mut map = FxHashMap::default();
    if cubes.is_empty() {
        return map;
    }
    for (t, c) in triangles.iter().zip(cube_of_tri) {
        if c.is_some_and(|c| cubes.contains(&c)) {
            for &v in t {
                if let Place::Edge { dir, .. } = vertices[v as usize].place {
                    let base = vertices[v as usize].base.map(|x| x as usize);
                    map.insert(lat.edge_key(base, dir.trailing_zeros() as usize), v);
                }
            }
        }
    }
    map
}

/// The face two cube edges share, if any.
fn common_face(a: usize, b: usize) -> Option<usize> {
    let on = |f: usize, e: usize| {
        let q = FACES[f];
        let [c0, c1] = EDGES[e];
        q.contains(&c0) && q.contains(&c1)
    };
    (0..6).find(|&f| on(f, a) && on(f, b))
}

/// Heals around the network, or asks for more seeds first.
pub(crate) fn heal(inp: &Input, probe: &mut Probe) -> Outcome {
    heal_with(inp, probe, true)
}

/// Heals around the network, trusting the decider on boundary faces whose saddle is on the
/// surface (when tracing from there found nothing new).
pub(crate) fn heal_ignoring_seeds(inp: &Input, probe: &mut Probe) -> Healing {
    match heal_with(inp, probe, false) {
        Outcome::Healed(h) => h,
        Outcome::Seeds(_) => Healing::default(),
    }
}

fn heal_with(inp: &Input, probe: &mut Probe, accept_seeds: bool) -> Outcome {
    let lat = Lattice::new(inp.grid);
    let h = inp.grid.cell;
    let mut out = Healing::default();

    // 1. The initial zone: cubes near the network.
    let mut zone: FxHashSet<usize> = FxHashSet::default();
    for r in &inp.net.runs {
        let n = r.fine.len();
        let count = if r.closed { n } else { n.saturating_sub(1) };
        for &p in &r.fine {
            lat.add_near(p, 0.05, &mut zone);
        }
        for w in 0..count {
            let (a, b) = (r.fine[w], r.fine[(w + 1) % n]);
            for s in 1..4 {
                lat.add_near(a.lerp(b, s as f64 / 4.0), 0.05, &mut zone);
            }
        }
    }
    for (k, node) in inp.net.nodes.iter().enumerate() {
        let margin = if node.kind == NodeKind::Cone { 1.0 } else { 0.05 };
        lat.add_near(node.p, margin, &mut zone);
        for &(m, _) in &inp.net.adj[k] {
            let q = inp.net.nodes[m as usize].p;
            for s in 1..8 {
                lat.add_near(node.p.lerp(q, s as f64 / 8.0), 0.05, &mut zone);
            }
        }
    }
    if zone.is_empty() {
        return Outcome::Healed(out);
    }

    // 2. Grow until marching cubes is right on the boundary, near the network.
    let near = NearNetwork::new(inp.net, &lat);
    let mut edge_memo: FxHashMap<u64, Hidden> = FxHashMap::default();
    let mut face_memo: FxHashMap<u64, FaceVerdict> = FxHashMap::default();
    let t = table();
    let mut overflow = false;
    loop {
        let mut sorted: Vec<usize> = zone.iter().copied().collect();
        sorted.sort_unstable();
        let mut add: Vec<usize> = Vec::new();
        let mut seeds: Vec<(DVec3, usize)> = Vec::new();
        for &ci in &sorted {
            let c = lat.coords(ci);
            for (e, &[c0, _]) in EDGES.iter().enumerate() {
                let o = CORNERS[c0];
                let p = [c[0] + o[0], c[1] + o[1], c[2] + o[2]];
                let axis = edge_axis(e);
                let around = lat.around_edge(p, axis);
                let inz = around.map(|x| x.map(|x| zone.contains(&x)));
                // Two zone cubes touching along this edge only: the zone's boundary would not
                // be a surface there.
                let diag = |a: usize, b: usize| {
                    inz[a] == Some(true)
                        && inz[b] == Some(true)
                        && inz[(a + 1) % 4] == Some(false)
                        && inz[(b + 1) % 4] == Some(false)
                };
                if diag(0, 2) || diag(1, 3) {
                    add.extend(around.iter().flatten());
                    continue;
                }
                if !inz.contains(&Some(false)) {
                    continue;
                }
                let key = lat.edge_key(p, axis);
                let hidden = *edge_memo.entry(key).or_insert_with(|| {
                    out.edges_checked += 1;
                    edge_hides_crossings(probe, inp.volume, &lat, p, axis)
                });
                // A sheet's own graze is missed the same way outside (see `Hidden`).
                if hidden == Hidden::Sheets {
                    add.extend(around.iter().flatten().filter(|&&x| near.holds(&lat, x)));
                }
            }
            let v = lat.corner_values(inp.volume, c);
            let case = case_of(&v);
            let amb = t.ambiguous[case];
            for f in 0..6 {
                let Some(nb) = lat.neighbour(c, f) else { continue };
                if zone.contains(&nb) {
                    continue;
                }
                // A small patch of polygons outside whose outer sides all lie on the zone's
                // boundary would be closed off by the zone's trace alone: its cubes belong
                // to the zone.
                if let Some(cubes) = enclosed_patch(inp.volume, &lat, &zone, nb) {
                    add.extend(cubes);
                    continue;
                }
                if amb & (1 << f) == 0 {
                    continue;
                }
                let o = CORNERS[FACES[f][0]];
                let key =
                    lat.point_index([c[0] + o[0], c[1] + o[1], c[2] + o[2]]) * 3 + (f / 2) as u64;
                let verdict = *face_memo.entry(key).or_insert_with(|| {
                    out.faces_checked += 1;
                    face_verdict(probe, &lat, &v, c, f)
                });
                match verdict {
                    FaceVerdict::Agree => {}
                    FaceVerdict::Disagree if near.holds(&lat, nb) => add.push(nb),
                    FaceVerdict::Disagree => {}
                    FaceVerdict::Singular(p) if accept_seeds => seeds.push((p, f / 2)),
                    FaceVerdict::Singular(_) => {}
                }
            }
        }
        if !seeds.is_empty() {
            return Outcome::Seeds(seeds);
        }
        add.retain(|x| !zone.contains(x));
        if add.is_empty() {
            break;
        }
        zone.extend(add);
        if zone.len() > inp.max_cubes {
            overflow = true;
            break;
        }
    }

    // 3. Connected components, each healed or kept.
    let edge_vertex = edge_vertices(&lat, inp.vertices, inp.triangles, inp.cube_of_tri, &zone);
    let mut sorted: Vec<usize> = zone.iter().copied().collect();
    sorted.sort_unstable();
    let mut seen: FxHashSet<usize> = FxHashSet::default();
    for &start in &sorted {
        if !seen.insert(start) {
            continue;
        }
        let mut comp = vec![start];
        let mut k = 0;
        while k < comp.len() {
            let c = lat.coords(comp[k]);
            k += 1;
            for f in 0..6 {
                if let Some(nb) = lat.neighbour(c, f)
                    && zone.contains(&nb)
                    && seen.insert(nb)
                {
                    comp.push(nb);
                }
            }
        }
        comp.sort_unstable();
        let set: FxHashSet<usize> = comp.iter().copied().collect();
        let center = comp.iter().fold(DVec3::ZERO, |s, &c| {
            let q = lat.coords(c);
            s + inp.grid.point(q[0], q[1], q[2]) + DVec3::splat(0.5 * h)
        }) / comp.len() as f64;
        let result = if overflow {
            Err("the zone grew past the limit on healed cubes".to_string())
        } else {
            heal_component(inp, &lat, &set, &comp, &edge_vertex, probe, &mut edge_memo)
        };
        match result {
            Ok(bands) => {
                out.zones += 1;
                out.cubes.extend(comp.iter().copied());
                let base = out.band_of.iter().max().map_or(0, |b| b + 1);
                out.triangles.extend(bands.triangles);
                out.band_of.extend(bands.band_of.iter().map(|b| b + base));
                out.curve_edges.extend(bands.edges);
            }
            Err(reason) => out.unresolved.push(Unresolved { center, cubes: comp.len(), reason }),
        }
    }
    Outcome::Healed(out)
}

/// The case-table entry that marching cubes uses for these corner values, with its
/// ambiguous faces decided; `None` for a cube the surface does not enter.
fn cube_entry(v: &[f32; 8]) -> Option<&'static Entry> {
    let case = case_of(v);
    if case == 0 || case == 255 {
        return None;
    }
    let t = table();
    Some(t.entry(case, face_decisions(v, t.ambiguous[case]) as usize))
}

/// How far from the network (in cells) a zone grows for edges that hide crossings and faces
/// whose decider is wrong.
const GROWTH_REACH: f64 = 6.0;

/// Which cubes lie within [`GROWTH_REACH`] of the network's curves and nodes.
///
/// Beyond that, what marching cubes gets wrong on a zone's boundary is one sheet's own,
/// which the cubes outside share, so the boundary's trace is still consistent; growing there
/// only joins zones round different curves, and a sheet piece between two curves is not a
/// band along one. (A sheet tangent to a lattice plane, which hides pairs of crossings in the
/// plane's edges all along the tangency, is told apart by its normals at any distance:
/// [`Hidden::OneSheet`].)
struct NearNetwork {
    /// Network points by coarse bucket (`GROWTH_REACH` cells a side).
    buckets: FxHashMap<[i64; 3], Vec<DVec3>>,
    size: f64,
}

impl NearNetwork {
    fn new(net: &Network, lat: &Lattice) -> Self {
        let size = GROWTH_REACH * lat.grid.cell;
        let mut buckets: FxHashMap<[i64; 3], Vec<DVec3>> = FxHashMap::default();
        let points =
            net.runs.iter().flat_map(|r| r.fine.iter()).chain(net.nodes.iter().map(|n| &n.p));
        for &p in points {
            buckets.entry(Self::key(p, lat, size)).or_default().push(p);
        }
        NearNetwork { buckets, size }
    }

    fn key(p: DVec3, lat: &Lattice, size: f64) -> [i64; 3] {
        let r = (p - lat.grid.origin) / size;
        [r.x.floor() as i64, r.y.floor() as i64, r.z.floor() as i64]
    }

    /// Whether the centre of cube `ci` is within reach of a network point.
    fn holds(&self, lat: &Lattice, ci: usize) -> bool {
        let c = lat.coords(ci);
        let centre = lat.grid.point(c[0], c[1], c[2]) + DVec3::splat(0.5 * lat.grid.cell);
        let k = Self::key(centre, lat, self.size);
        (0..27).any(|d| {
            let b = [k[0] + d % 3 - 1, k[1] + d / 3 % 3 - 1, k[2] + d / 9 - 1];
            self.buckets
                .get(&b)
                .is_some_and(|l| l.iter().any(|q| (*q - centre).length() <= self.size))
        })
    }
}

/// The most marching-cubes polygons outside the zone that [`enclosed_patch`] gathers.
const PATCH_POLYGONS: usize = 8;

/// The global key of cube edge `e` of cube `c`.
fn cube_edge_key(lat: &Lattice, c: [usize; 3], e: usize) -> u64 {
    let o = CORNERS[EDGES[e][0]];
    lat.edge_key([c[0] + o[0], c[1] + o[1], c[2] + o[2]], edge_axis(e))
}

/// The cubes of a small patch of marching-cubes polygons outside the zone, starting from a
/// polygon of cube `ci`, whose outer sides all lie on faces shared with zone cubes or with
/// the domain box (and at least one with the zone); `None` when there is no such patch of at
/// most [`PATCH_POLYGONS`] polygons.
///
/// Such a patch would be closed off by the zone's trace alone: the zone would fan that loop
/// as a disk on top of the kept polygons (duplicate faces), or read the sheet through it as
/// two pieces. Its cubes belong to the zone. One polygon is the common case (a zone that
/// wraps round an outside cube); two or three arise where a sheet passes within a hair of a
/// lattice point on the zone's border, its tiny polygons round that point split between
/// zone and outside cubes.
fn enclosed_patch(
    volume: &Volume,
    lat: &Lattice,
    zone: &FxHashSet<usize>,
    ci: usize,
) -> Option<Vec<usize>> {
    let t = table();
    // The polygons of an outside cube: for each, its sides as pairs of global edge keys,
    // each with the face it lies on.
    let polygons = |c: [usize; 3]| -> Vec<Vec<(u64, u64, usize)>> {
        let Some(entry) = cube_entry(&lat.corner_values(volume, c)) else {
            return Vec::new();
        };
        (0..entry.loop_count as usize)
            .map(|l| {
                let edges = t.loop_edges(entry, l);
                let n = edges.len();
                (0..n)
                    .map(|k| {
                        let (a, b) = (edges[k] as usize, edges[(k + 1) % n] as usize);
                        let f = common_face(a, b).unwrap_or(usize::MAX);
                        let (ka, kb) = (cube_edge_key(lat, c, a), cube_edge_key(lat, c, b));
                        (ka.min(kb), ka.max(kb), f)
                    })
                    .collect()
            })
            .collect()
    };
    let first = polygons(lat.coords(ci));
    'start: for (l0, polygon) in first.iter().enumerate() {
        let mut patch: Vec<(usize, usize)> = vec![(ci, l0)];
        let mut sides: Vec<Vec<(u64, u64, usize)>> = vec![polygon.clone()];
        let mut touches_zone = false;
        let mut k = 0;
        while k < patch.len() {
            let c = lat.coords(patch[k].0);
            let own = sides[k].clone();
            k += 1;
            for (ka, kb, f) in own {
                if f == usize::MAX {
                    continue 'start;
                }
                let Some(nb) = lat.neighbour(c, f) else { continue };
                if zone.contains(&nb) {
                    touches_zone = true;
                    continue;
                }
                // The polygon across this side, in the outside cube there.
                let theirs = polygons(lat.coords(nb));
                let Some(l) = theirs.iter().position(|p| p.iter().any(|s| s.0 == ka && s.1 == kb))
                else {
                    continue 'start;
                };
                if patch.contains(&(nb, l)) {
                    continue;
                }
                if patch.len() == PATCH_POLYGONS {
                    continue 'start;
                }
                patch.push((nb, l));
                sides.push(theirs[l].clone());
            }
        }
        if touches_zone {
            let mut cubes: Vec<usize> = patch.iter().map(|x| x.0).collect();
            cubes.sort_unstable();
            cubes.dedup();
            return Some(cubes);
        }
    }
    None
}

/// What the field does between the samples of a lattice edge that their signs do not show.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Hidden {
    /// Nothing: the samples' signs show every crossing.
    No,
    /// More crossings, all of one smooth sheet grazing the edge: the unit normals at
    /// consecutive crossings are within 25° of each other (a sheet tangent to the edge, or
    /// to a lattice plane the edge lies in).
    OneSheet,
    /// More crossings, of sheets meeting at an angle: the thin wedge between two crossing
    /// sheets (its two faces' normals are the wedge's opening short of opposite), a thin
    /// tube or slab.
    Sheets,
}

/// Below this cosine (25°) between the normals at two consecutive crossings along an edge,
/// they are not of one sheet grazing it. A sheet whose radius of curvature is `R` cells turns
/// by at most `1/R` radians between crossings within one cell (14° at four cells); a wedge
/// is taken for one sheet only if its opening is over 155°, when the crossing's other wedge
/// is under 25°, thinner than the sweeps' crossings.
const ONE_SHEET_COS: f64 = 0.9;

/// Whether the field crosses zero between the samples of a lattice edge more often than
/// their signs show, and if so whether those crossings are of one sheet grazing the edge.
///
/// Why tell them apart: the crossings a wedge between two sheets hides (near a
/// self-intersection) are what a zone must grow over, as marching cubes would join the two
/// sheets through them on its boundary; a single sheet tangent to a lattice plane hides
/// pairs of crossings all along the tangency, which marching cubes misses the same way in
/// the cubes outside, so a boundary there is consistent, and growing along it joins the
/// zones of different curves (the torus whose bottom lies in a lattice plane, crossed by a
/// sphere in two loops). The crossings are told apart by the normals: a sheet grazing an
/// edge has nearly the same normal at its two crossings; the two faces of a wedge of opening
/// `θ` have normals `180° - θ` apart.
fn edge_hides_crossings(
    probe: &mut Probe,
    volume: &Volume,
    lat: &Lattice,
    p: [usize; 3],
    axis: usize,
) -> Hidden {
    let grid = &lat.grid;
    let mut q = p;
    q[axis] += 1;
    let p0 = grid.point(p[0], p[1], p[2]);
    let p1 = grid.point(q[0], q[1], q[2]);
    let s0 = volume.get(p[0], p[1], p[2]) < 0.0;
    let s1 = volume.get(q[0], q[1], q[2]) < 0.0;
    let us = [0.0, 0.25, 0.5, 0.75, 1.0];
    let pts: Vec<DVec3> = us.iter().map(|&u| p0.lerp(p1, u)).collect();
    let Some((vals, grads)) = probe.grads(&pts) else { return Hidden::No };
    let signs = [s0, vals[1] < 0.0, vals[2] < 0.0, vals[3] < 0.0, s1];
    let d: Vec<f64> = grads.iter().map(|g| g[axis]).collect();
    // Brackets of single crossings along the edge, in order.
    let mut brackets: Vec<(f64, f64, bool)> = Vec::new();
    for k in 0..4 {
        if signs[k] != signs[k + 1] {
            brackets.push((us[k], us[k + 1], signs[k]));
            continue;
        }
        if d[k] * d[k + 1] >= 0.0 {
            continue;
        }
        // An extremum inside: bisect on the derivative.
        let (mut a, mut b, da) = (us[k], us[k + 1], d[k]);
        let mut value = 0.0;
        let mut m = 0.5 * (a + b);
        for _ in 0..24 {
            m = 0.5 * (a + b);
            let Some((f, g)) = probe.grad(p0.lerp(p1, m)) else { return Hidden::No };
            value = f;
            if (g[axis] < 0.0) == (da < 0.0) {
                a = m;
            } else {
                b = m;
            }
        }
        if (value < 0.0) != signs[k] {
            brackets.push((us[k], m, signs[k]));
            brackets.push((m, us[k + 1], !signs[k]));
        }
    }
    if brackets.len() == usize::from(s0 != s1) {
        return Hidden::No;
    }
    // The normal at each crossing, by bisection on the sign.
    let mut normals: Vec<DVec3> = Vec::with_capacity(brackets.len());
    for &(mut a, mut b, neg_a) in &brackets {
        for _ in 0..30 {
            let m = 0.5 * (a + b);
            let Some((f, _)) = probe.grad(p0.lerp(p1, m)) else { return Hidden::Sheets };
            if (f < 0.0) == neg_a {
                a = m;
            } else {
                b = m;
            }
        }
        let Some((_, g)) = probe.grad(p0.lerp(p1, 0.5 * (a + b))) else { return Hidden::Sheets };
        normals.push(g.normalize_or_zero());
    }
    let one_sheet = normals.windows(2).all(|w| w[0].dot(w[1]) > ONE_SHEET_COS);
    if one_sheet { Hidden::OneSheet } else { Hidden::Sheets }
}

/// Whether an edge of face `f` of cube `c` crosses the surface between its samples.
fn box_face_hides(
    probe: &mut Probe,
    volume: &Volume,
    lat: &Lattice,
    memo: &mut FxHashMap<u64, Hidden>,
    c: [usize; 3],
    f: usize,
) -> bool {
    let q = FACES[f];
    (0..4).any(|k| {
        let e = crate::grid::cube::edge_between(q[k], q[(k + 1) % 4]);
        let o = CORNERS[EDGES[e][0]];
        let p = [c[0] + o[0], c[1] + o[1], c[2] + o[2]];
        let axis = edge_axis(e);
        *memo
            .entry(lat.edge_key(p, axis))
            .or_insert_with(|| edge_hides_crossings(probe, volume, lat, p, axis))
            != Hidden::No
    })
}

/// What the field says about a boundary face with four crossings.
#[derive(Clone, Copy, Debug, PartialEq)]
enum FaceVerdict {
    /// It pairs the crossings as the decider does (or has no saddle to say otherwise).
    Agree,
    Disagree,
    /// Its saddle is on the surface: a self-intersection point the search missed.
    Singular(DVec3),
}

/// Finds the saddle of `f` restricted to face `f` of cube `c` by Newton's method from the
/// bilinear interpolant's saddle, and compares the sign there with the asymptotic decider.
fn face_verdict(
    probe: &mut Probe,
    lat: &Lattice,
    v: &[f32; 8],
    c: [usize; 3],
    f: usize,
) -> FaceVerdict {
    let grid = &lat.grid;
    let h = grid.cell;
    let axis = f / 2;
    let (b, cax) = other_axes(axis);
    let decided_inside = face_decisions(v, 1 << f) & (1 << f) != 0;
    let o = CORNERS[FACES[f][0]];
    let lo = grid.point(c[0] + o[0], c[1] + o[1], c[2] + o[2]);
    // Corner values by in-face coordinates (s along b, t along c).
    let mut val = [[0.0f64; 2]; 2];
    for &k in &FACES[f] {
        let q = CORNERS[k];
        val[q[b]][q[cax]] = v[k] as f64;
    }
    let den = val[0][0] - val[1][0] - val[0][1] + val[1][1];
    let (mut s, mut t) = if den.abs() > 1e-300 {
        (
            ((val[0][0] - val[0][1]) / den).clamp(0.05, 0.95),
            ((val[0][0] - val[1][0]) / den).clamp(0.05, 0.95),
        )
    } else {
        (0.5, 0.5)
    };
    let at = |s: f64, t: f64| {
        let mut p = lo;
        p[b] += s * h;
        p[cax] += t * h;
        p
    };
    let Some(scale) = probe.gradient_scale(at(s, t), h) else { return FaceVerdict::Agree };
    if scale <= 0.0 {
        return FaceVerdict::Agree;
    }
    for _ in 0..30 {
        let Some(j) = probe.jet(at(s, t)) else { return FaceVerdict::Agree };
        let (gb, gc) = (j.g[b], j.g[cax]);
        if (gb * gb + gc * gc).sqrt() <= 1e-8 * scale {
            let tiny = 1e-6 * scale * h;
            if j.f.abs() <= tiny {
                return FaceVerdict::Singular(at(s, t));
            }
            let inside_joined = j.f < 0.0;
            return if inside_joined == decided_inside {
                FaceVerdict::Agree
            } else {
                FaceVerdict::Disagree
            };
        }
        let (hbb, hbc, hcc) = (j.h.col(b)[b], j.h.col(cax)[b], j.h.col(cax)[cax]);
        let det = hbb * hcc - hbc * hbc;
        if det.abs() < 1e-300 {
            return contour_verdict(probe, lat, v, c, f, scale);
        }
        let mut ds = -(hcc * gb - hbc * gc) / det / h;
        let mut dt = -(hbb * gc - hbc * gb) / det / h;
        let len = (ds * ds + dt * dt).sqrt();
        if len > 0.25 {
            ds *= 0.25 / len;
            dt *= 0.25 / len;
        }
        s += ds;
        t += dt;
        if !(-0.01..=1.01).contains(&s) || !(-0.01..=1.01).contains(&t) {
            return contour_verdict(probe, lat, v, c, f, scale);
        }
    }
    contour_verdict(probe, lat, v, c, f, scale)
}

/// The pairing of a face's four crossings where the field has no saddle on the face to
/// show it (Newton from the interpolant's saddle left the face or did not settle): the
/// contour `f = 0` is followed across the face from the crossing on its first side, and the
/// corner it cuts off says which corners are joined. Without a saddle the bilinear
/// interpolant's guess is just a guess: two sheets crossing just beyond the face (a thin
/// wedge of one sign between them, running across it) are read as a saddle, the zone stops
/// there, and its boundary trace joins two sheet pieces that never meet (so the curve there
/// gets two bands, not four). `Agree` when the contour cannot be followed (it comes near a
/// point where the gradient on the face vanishes, or returns to its own side).
fn contour_verdict(
    probe: &mut Probe,
    lat: &Lattice,
    v: &[f32; 8],
    c: [usize; 3],
    f: usize,
    scale: f64,
) -> FaceVerdict {
    let decided_inside = face_decisions(v, 1 << f) & (1 << f) != 0;
    match contour_joins_inside(probe, lat, v, c, f, scale) {
        Some(joined) if joined != decided_inside => FaceVerdict::Disagree,
        _ => FaceVerdict::Agree,
    }
}

/// Whether the inside corners of face `f` of cube `c` (four crossings) are joined, by
/// following the contour from the crossing on the side `FACES[f][0]`–`FACES[f][1]`; `None`
/// when it cannot be followed.
fn contour_joins_inside(
    probe: &mut Probe,
    lat: &Lattice,
    v: &[f32; 8],
    c: [usize; 3],
    f: usize,
    scale: f64,
) -> Option<bool> {
    let grid = &lat.grid;
    let h = grid.cell;
    let (b, cax) = other_axes(f / 2);
    let q = FACES[f];
    let corner = |k: usize| {
        let o = CORNERS[q[k]];
        grid.point(c[0] + o[0], c[1] + o[1], c[2] + o[2])
    };
    // In-face coordinates, in cells from corner 0.
    let origin = corner(0);
    let to_uv = |p: DVec3| glam::DVec2::new((p[b] - origin[b]) / h, (p[cax] - origin[cax]) / h);
    let at = |u: glam::DVec2| {
        let mut p = origin;
        p[b] += u.x * h;
        p[cax] += u.y * h;
        p
    };
    let eval = |probe: &mut Probe, u: glam::DVec2| {
        probe.grad(at(u)).map(|(val, g)| (val, glam::DVec2::new(g[b], g[cax]) * h))
    };
    let corners: [glam::DVec2; 4] = std::array::from_fn(|k| to_uv(corner(k)));
    // The crossing on each side (corner k to corner k + 1), by bisection on the field between
    // the samples' signs (the face has four crossings, one a side).
    let mut crossings = [glam::DVec2::ZERO; 4];
    for (k, x) in crossings.iter_mut().enumerate() {
        let (a0, a1) = (corners[k], corners[(k + 1) % 4]);
        let inside0 = v[q[k]] < 0.0;
        let (mut lo, mut hi) = (0.0f64, 1.0f64);
        for _ in 0..40 {
            let m = 0.5 * (lo + hi);
            let (val, _) = eval(probe, a0.lerp(a1, m))?;
            if (val < 0.0) == inside0 {
                lo = m;
            } else {
                hi = m;
            }
        }
        *x = a0.lerp(a1, 0.5 * (lo + hi));
    }
    let mut p = crossings[0];
    // Into the face from side 0: towards corners 2 and 3.
    let inward = (corners[3] - corners[0]).normalize_or_zero();
    let tiny = 1e-6 * scale * h;
    let (_, g) = eval(probe, p)?;
    if g.length() <= tiny {
        return None;
    }
    // The contour direction is the gradient turned by a fixed quarter turn, so that a step
    // onto another branch of the contour shows as a reversal.
    let turn = if g.perp().dot(inward) >= 0.0 { 1.0 } else { -1.0 };
    let mut dir = g.perp().normalize() * turn;
    let mut step = 1.0 / 16.0;
    let inside = |u: glam::DVec2| (0.0..=1.0).contains(&u.x) && (0.0..=1.0).contains(&u.y);
    let mut steps = 0;
    loop {
        steps += 1;
        if steps > 2000 || step < 1e-5 {
            return None;
        }
        // Predict along the contour, correct back onto it along the gradient.
        let mut u = p + dir * step;
        let mut settled = false;
        let mut grad = glam::DVec2::ZERO;
        for _ in 0..12 {
            let (val, g) = eval(probe, u)?;
            if g.length() <= tiny {
                return None;
            }
            grad = g;
            let d = g * (val / g.length_squared());
            u -= d;
            if d.length() <= 1e-7 {
                settled = true;
                break;
            }
        }
        let nd = grad.perp().normalize() * turn;
        if !settled || (u - p).length() > 1.5 * step || nd.dot(dir) < 0.5 {
            step *= 0.5;
            continue;
        }
        if !inside(u) {
            // Left the face between p and u, so through the side whose crossing is nearest
            // that step (where the contour leaves close to a corner, which side the step's
            // segment cuts first is a coin toss; the crossings are exact). Cutting off one
            // corner separates the corners of its sign.
            return match exit_side(&crossings, p, u)? {
                1 => Some(v[q[1]] >= 0.0),
                3 => Some(v[q[0]] >= 0.0),
                _ => None,
            };
        }
        p = u;
        dir = nd;
        step = (step * 1.5).min(1.0 / 16.0);
    }
}

/// Which side `k` (from corner `k` to corner `k + 1`) of the face a contour step from `p`
/// (inside) to `u` (outside) leaves through: the side other than side 0 (where the contour
/// started) whose crossing is nearest the step, if within a tenth of a cell of it.
fn exit_side(crossings: &[glam::DVec2; 4], p: glam::DVec2, u: glam::DVec2) -> Option<usize> {
    let d = u - p;
    let dist = |x: glam::DVec2| {
        let s = if d.length_squared() > 0.0 {
            ((x - p).dot(d) / d.length_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (p + d * s - x).length()
    };
    (1..4)
        .map(|k| (dist(crossings[k]), k))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .filter(|x| x.0 <= 0.1)
        .map(|x| x.1)
}

/// The bands of one zone.
struct Bands {
    triangles: Vec<[u32; 3]>,
    band_of: Vec<u32>,
    edges: Vec<[u32; 2]>,
}

/// Whether a marching-cubes vertex lies on the domain box.
fn on_box(v: &GridVertex, dims: [usize; 3]) -> bool {
    match v.place {
        Place::Edge { dir, .. } => {
            let axis = dir.trailing_zeros() as usize;
            (0..3).any(|a| a != axis && (v.base[a] == 0 || v.base[a] as usize == dims[a] - 1))
        }
        Place::Cell { .. } => false,
    }
}

#[derive(Clone, Copy, PartialEq)]
struct Dist(f64, u32);
impl Eq for Dist {}
impl PartialOrd for Dist {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Dist {
    // Reversed, for a min-heap.
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        o.0.total_cmp(&self.0).then(o.1.cmp(&self.1))
    }
}

/// Shortest network path from `a` to `b` (both included), within `limit` length.
fn shortest_path(net: &Network, a: u32, b: u32, limit: f64) -> Option<Vec<u32>> {
    if a == b {
        return Some(vec![a]);
    }
    let mut dist: FxHashMap<u32, (f64, u32)> = FxHashMap::default();
    let mut heap = BinaryHeap::new();
    dist.insert(a, (0.0, u32::MAX));
    heap.push(Dist(0.0, a));
    while let Some(Dist(d, n)) = heap.pop() {
        if n == b {
            break;
        }
        if d > dist.get(&n).map_or(f64::INFINITY, |x| x.0) || d > limit {
            continue;
        }
        let mut adj = net.adj[n as usize].clone();
        adj.sort_unstable();
        for (m, _) in adj {
            let nd = d + (net.nodes[m as usize].p - net.nodes[n as usize].p).length();
            if nd < dist.get(&m).map_or(f64::INFINITY, |x| x.0) {
                dist.insert(m, (nd, n));
                heap.push(Dist(nd, m));
            }
        }
    }
    dist.get(&b)?;
    let mut path = vec![b];
    let mut n = b;
    while n != a {
        n = dist.get(&n)?.1;
        path.push(n);
    }
    path.reverse();
    Some(path)
}

/// Builds and checks the bands of one zone: the zone boundary's trace (its segments chained
/// into paths and loops), each piece mapped onto the network walk it follows and zipped to
/// it, then the check that two sheets cross along every curve edge and every cone is fanned.
fn heal_component(
    inp: &Input,
    lat: &Lattice,
    set: &FxHashSet<usize>,
    comp: &[usize],
    edge_vertex: &FxHashMap<u64, u32>,
    probe: &mut Probe,
    edge_memo: &mut FxHashMap<u64, Hidden>,
) -> Result<Bands, String> {
    let net = inp.net;
    let h = inp.grid.cell;
    let exits = exit_faces(inp, lat);
    let boundary = Boundary { set, comp, edge_vertex, exits: &exits };
    let trace = boundary_trace(inp, lat, &boundary, probe, edge_memo)?;
    let zone = ZoneNetwork::new(net, lat, set)?;
    let components = trace.components()?;

    let mut bands = Bands { triangles: Vec::new(), band_of: Vec::new(), edges: Vec::new() };
    let mut usage: FxHashMap<u32, u32> = FxHashMap::default();
    let mut cone_fans: FxHashMap<u32, u32> = FxHashMap::default();
    for (band, (trace, closed)) in components.iter().enumerate() {
        let band = band as u32;
        let (mut walk, mut w) = walk_along(inp, &zone, trace)?;
        // A loop's seam must not be where its walk turns (see `loop_seam`).
        let rotated: Vec<u32>;
        let trace: &[u32] = match loop_seam(net, &walk, &w).filter(|_| *closed) {
            Some(k) => {
                rotated = trace[k..].iter().chain(&trace[1..=k]).copied().collect();
                (walk, w) = walk_along(inp, &zone, &rotated)?;
                &rotated
            }
            None => trace,
        };
        remove_wiggles(net, &mut walk, &mut w, h, *closed);
        if !closed {
            extend_to_exits(inp, trace, &mut walk, &mut w);
        }
        if walk.len() == 1 {
            let n = walk[0];
            if !closed {
                return Err("an open trace along no self-intersection curve".into());
            }
            if net.nodes[n as usize].kind != NodeKind::Cone {
                // A sheet piece that enters the zone and leaves it without reaching a curve
                // (a tangential graze, a corner cut off): a disk, fanned from its first
                // vertex. Were it really a piece round a curve, that curve's edges would lack
                // it, and the check below would refuse the zone.
                for k in 1..trace.len().saturating_sub(2) {
                    bands.triangles.push([trace[0], trace[k], trace[k + 1]]);
                    bands.band_of.push(band);
                }
                continue;
            }
            *cone_fans.entry(n).or_insert(0) += 1;
        } else if walk.iter().any(|&n| net.nodes[n as usize].kind == NodeKind::Cone) {
            return Err("a trace runs through a cone apex".into());
        }
        let (steps, tris) = zip_band(inp, trace, &walk, &w, *closed, probe);
        for t in tris {
            bands.triangles.push(t);
            bands.band_of.push(band);
        }
        let mut j = 0usize;
        for &along_trace in &steps {
            if !along_trace {
                let Some(e) = net.edge_between(walk[j], walk[j + 1]) else {
                    return Err("a walk step is not a network edge".into());
                };
                *usage.entry(e).or_insert(0) += 1;
                j += 1;
            }
        }
    }
    check_sheets(net, &zone, &usage, &cone_fans, &mut bands)?;
    Ok(bands)
}

/// Faces of the domain box where a curve leaves it: there marching cubes pairs the four
/// crossings of the two sheets wrongly, so their segments are not used; the traces end on
/// those faces' edges and the bands on the exit node. As `(cube, face)`.
fn exit_faces(inp: &Input, lat: &Lattice) -> FxHashSet<(usize, usize)> {
    let h = inp.grid.cell;
    let bounds = inp.grid.bounds();
    let mut exit_faces: FxHashSet<(usize, usize)> = FxHashSet::default();
    for n in inp.net.nodes.iter().filter(|n| n.kind == NodeKind::Exit) {
        let mut cubes = FxHashSet::default();
        lat.add_near(n.p, 1e-6, &mut cubes);
        for c in cubes {
            for a in 0..3 {
                if (n.p[a] - bounds.min[a]).abs() <= 1e-6 * h {
                    exit_faces.insert((c, 2 * a));
                }
                if (n.p[a] - bounds.max[a]).abs() <= 1e-6 * h {
                    exit_faces.insert((c, 2 * a + 1));
                }
            }
        }
    }
    exit_faces
}

/// What decides which of a zone's marching-cubes segments lie on its boundary.
struct Boundary<'z> {
    /// The zone's cubes, as a set and in order.
    set: &'z FxHashSet<usize>,
    comp: &'z [usize],
    /// Lattice edge key → marching-cubes vertex.
    edge_vertex: &'z FxHashMap<u64, u32>,
    /// Box faces where a curve leaves the domain ([`exit_faces`]).
    exits: &'z FxHashSet<(usize, usize)>,
}

/// The zone boundary's segments, chained: each marching-cubes vertex to the next along its
/// sheet's trace.
struct Trace {
    next: FxHashMap<u32, u32>,
    /// Vertices some segment ends at (the rest of `next`'s keys start paths).
    has_prev: FxHashSet<u32>,
}

/// Trace segments on the zone's boundary, directed as the zone-side cube has them: on faces
/// shared with cubes outside, and on the domain box (where the bands end with the mesh),
/// except where curves leave it.
fn boundary_trace(
    inp: &Input,
    lat: &Lattice,
    zone: &Boundary,
    probe: &mut Probe,
    edge_memo: &mut FxHashMap<u64, Hidden>,
) -> Result<Trace, String> {
    let t = table();
    let mut next: FxHashMap<u32, u32> = FxHashMap::default();
    let mut has_prev: FxHashSet<u32> = FxHashSet::default();
    for &ci in zone.comp {
        let c = lat.coords(ci);
        let Some(entry) = cube_entry(&lat.corner_values(inp.volume, c)) else {
            continue;
        };
        let vid = |e: u8| -> Result<u32, String> {
            let e = e as usize;
            let o = CORNERS[EDGES[e][0]];
            let p = [c[0] + o[0], c[1] + o[1], c[2] + o[2]];
            zone.edge_vertex
                .get(&lat.edge_key(p, edge_axis(e)))
                .copied()
                .ok_or_else(|| "a boundary crossing has no marching-cubes vertex".to_string())
        };
        for l in 0..entry.loop_count as usize {
            let edges = t.loop_edges(entry, l);
            let n = edges.len();
            for k in 0..n {
                let (ea, eb) = (edges[k], edges[(k + 1) % n]);
                let Some(f) = common_face(ea as usize, eb as usize) else {
                    return Err("a loop side on no face".into());
                };
                match lat.neighbour(c, f) {
                    Some(nb) if zone.set.contains(&nb) => continue,
                    None if zone.exits.contains(&(ci, f)) => continue,
                    // A box face where the lattice misses crossings (near where a curve
                    // leaves) is left out like an exit face.
                    None if box_face_hides(probe, inp.volume, lat, edge_memo, c, f) => continue,
                    _ => {}
                }
                let (a, b) = (vid(ea)?, vid(eb)?);
                if next.insert(a, b).is_some() || !has_prev.insert(b) {
                    return Err(
                        "the zone's boundary is not a surface where the sheets cross it".into()
                    );
                }
            }
        }
    }
    Ok(Trace { next, has_prev })
}

impl Trace {
    /// The trace's pieces: paths from their first vertex (in vertex order), then loops
    /// (closed: the first vertex repeated at the end), each with whether it is closed.
    fn components(&self) -> Result<Vec<(Vec<u32>, bool)>, String> {
        let next = &self.next;
        let mut starts: Vec<u32> =
            next.keys().copied().filter(|v| !self.has_prev.contains(v)).collect();
        starts.sort_unstable();
        let mut used: FxHashSet<u32> = FxHashSet::default();
        let mut components: Vec<(Vec<u32>, bool)> = Vec::new();
        for s in starts {
            let mut path = vec![s];
            let mut v = s;
            used.insert(s);
            while let Some(&w) = next.get(&v) {
                if !used.insert(w) {
                    return Err("a trace path runs into itself".into());
                }
                path.push(w);
                v = w;
            }
            components.push((path, false));
        }
        let mut rest: Vec<u32> = next.keys().copied().filter(|v| !used.contains(v)).collect();
        rest.sort_unstable();
        for s in rest {
            if used.contains(&s) {
                continue;
            }
            let mut path = vec![s];
            used.insert(s);
            let mut v = s;
            loop {
                let Some(&w) = next.get(&v) else {
                    return Err("a trace loop does not close".into());
                };
                if w == s {
                    break;
                }
                if !used.insert(w) {
                    return Err("a trace loop runs into another".into());
                }
                path.push(w);
                v = w;
            }
            path.push(s);
            components.push((path, true));
        }
        Ok(components)
    }
}

/// The network inside one zone: its nodes and the edges touching them, with the nodes
/// bucketed by cube for nearest-node queries.
struct ZoneNetwork<'n> {
    net: &'n Network,
    lat: Lattice,
    nodes: Vec<u32>,
    edges: Vec<u32>,
    buckets: FxHashMap<[usize; 3], Vec<u32>>,
}

impl<'n> ZoneNetwork<'n> {
    /// The network of the zone of cubes `set`; an error when no curve passes through it.
    fn new(net: &'n Network, lat: &Lattice, set: &FxHashSet<usize>) -> Result<Self, String> {
        let node_in = |k: usize| set.contains(&lat.cube(lat.cube_of(net.nodes[k].p)));
        let nodes: Vec<u32> =
            (0..net.nodes.len()).filter(|&k| node_in(k)).map(|k| k as u32).collect();
        let node_set: FxHashSet<u32> = nodes.iter().copied().collect();
        let edges: Vec<u32> = (0..net.edges.len() as u32)
            .filter(|&e| {
                let [a, b] = net.edges[e as usize];
                node_set.contains(&a) || node_set.contains(&b)
            })
            .collect();
        if nodes.is_empty() {
            return Err("no self-intersection in the zone".into());
        }
        let mut buckets: FxHashMap<[usize; 3], Vec<u32>> = FxHashMap::default();
        for &k in &nodes {
            buckets.entry(lat.cube_of(net.nodes[k as usize].p)).or_default().push(k);
        }
        Ok(ZoneNetwork { net, lat: *lat, nodes, edges, buckets })
    }

    /// The zone's node nearest `p` (the lowest-numbered of equally near ones), searched in
    /// rings of cubes outward until no farther ring can hold a nearer one.
    fn nearest(&self, p: DVec3) -> Option<u32> {
        let (lat, net) = (&self.lat, self.net);
        let h = lat.grid.cell;
        let reach = lat.cubes.iter().copied().max().unwrap_or(1);
        let c = lat.cube_of(p);
        let mut best: Option<(f64, u32)> = None;
        for r in 0..=reach {
            // Nothing in ring r can beat a distance below (r - 1) cells.
            if let Some((d, _)) = best
                && d < (r as f64 - 1.0) * h
            {
                break;
            }
            let lo = |a: usize| c[a].saturating_sub(r);
            let hi = |a: usize| (c[a] + r).min(lat.cubes[a] - 1);
            for k in lo(2)..=hi(2) {
                for j in lo(1)..=hi(1) {
                    for i in lo(0)..=hi(0) {
                        let ring = [i.abs_diff(c[0]), j.abs_diff(c[1]), k.abs_diff(c[2])];
                        if ring.iter().copied().max().unwrap_or(0) != r {
                            continue;
                        }
                        for &n in self.buckets.get(&[i, j, k]).into_iter().flatten() {
                            let d = (net.nodes[n as usize].p - p).length();
                            if best.is_none_or(|b| d < b.0 || (d == b.0 && n < b.1)) {
                                best = Some((d, n));
                            }
                        }
                    }
                }
            }
        }
        best.map(|b| b.1)
    }
}

/// The walk a trace piece follows on the network: each trace vertex's nearest node, joined
/// by shortest network paths. Returns the walk and, for each trace vertex, the walk position
/// it maps to.
///
/// A path may be four cells long, or twice as long as the way from one trace vertex through
/// the next to their nodes: where two sheets cross at a shallow angle the zone grows wide
/// (its edges hide crossings far from the curve), the trace runs cells away from the curve,
/// and two neighbouring trace vertices may have nearest nodes far apart along it.
fn walk_along(
    inp: &Input,
    zone: &ZoneNetwork,
    trace: &[u32],
) -> Result<(Vec<u32>, Vec<usize>), String> {
    let mut walk: Vec<u32> = Vec::new();
    let mut w: Vec<usize> = Vec::with_capacity(trace.len());
    let node = |n: u32| zone.net.nodes[n as usize].p;
    let mut prev: Option<DVec3> = None;
    for &v in trace {
        let p = inp.positions[v as usize];
        let Some(n) = zone.nearest(p) else {
            return Err("no node near a trace".into());
        };
        let last_vertex = prev.replace(p);
        match (walk.last(), last_vertex) {
            (Some(&last), Some(q)) if last != n => {
                let around = (q - node(last)).length() + (p - q).length() + (p - node(n)).length();
                let limit = (4.0 * inp.grid.cell).max(2.0 * around);
                let Some(path) = shortest_path(zone.net, last, n, limit) else {
                    return Err("a trace jumps between unconnected curves".into());
                };
                walk.extend_from_slice(&path[1..]);
            }
            (None, _) => walk.push(n),
            _ => {}
        }
        w.push(walk.len() - 1);
    }
    Ok((walk, w))
}

/// Where a closed trace should start: a vertex whose walk node the walk passes straight
/// through (the nodes before and after it differ), as far along the walk as can be from
/// every place where it turns; `None` when the walk's seam does not turn, or turns at the end
/// of a curve (where the walk does reach the end).
///
/// A loop's first vertex is its last, and its walk's first node its last: a back-and-forth
/// move there (the walk leaves node `n` for `m` at its start and comes back from `m` at its
/// end) is not seen by [`remove_wiggles`], which looks at interior nodes. Round a pinch
/// point that move is a fold: the cross-cap's trace is one loop that runs along the curve
/// four times, folding twice at the pinch, and when its first vertex lay at one of those
/// folds the walk was never taken on to the pinch there, so the curve's last edge got two
/// bands, not four, and the whole curve was left as marching cubes made it. Far from the
/// turns, because a fold taken on to the pinch needs trace vertices after it to zip with: a
/// seam just past one left the way back from the pinch to the loop's last vertex alone, and
/// its two triangles there were one triangle twice.
fn loop_seam(net: &Network, walk: &[u32], w: &[usize]) -> Option<usize> {
    let n = walk.len();
    if n < 3 || walk[1] != walk[n - 2] || net.degree(walk[0]) <= 1 {
        return None;
    }
    let turns: Vec<usize> =
        std::iter::once(0).chain((1..n - 1).filter(|&m| walk[m - 1] == walk[m + 1])).collect();
    // Walk positions from the nearest turn, round the loop (its last position is its first).
    let period = n - 1;
    let away = |j: usize| {
        turns.iter().map(|&m| j.abs_diff(m).min(period - j.abs_diff(m))).min().unwrap_or(0)
    };
    (1..w.len() - 1)
        .filter(|&k| {
            let j = w[k];
            j > 0
                && j + 1 < n
                && w[k - 1] < j
                && w[k + 1] > j
                && walk[j - 1] != walk[j + 1]
                && net.degree(walk[j]) == 2
        })
        .max_by_key(|&k| (away(w[k]), std::cmp::Reverse(k)))
}

/// Removes a walk's back-and-forth moves, which are wiggles of the nearest-node mapping,
/// except round the end of a curve: a sheet that folds round a pinch point turns there, and
/// the nearest nodes may turn one node early, so the walk is taken on to the end and back.
/// Keeps `w` (trace vertex → walk position) pointing at the same nodes.
///
/// A closed trace may also fold round a curve's exit from the domain: a loop cannot end on
/// the box, so a sheet that turns there wraps round the curve's end, which is a pinch point
/// on the box (the cross-cap's upper end on `[-1, 1]³`); its trace turns on the cap, short
/// of the exit node, and would otherwise be taken for a wiggle and the walk emptied.
fn remove_wiggles(net: &Network, walk: &mut Vec<u32>, w: &mut [usize], h: f64, closed: bool) {
    let is_leaf = |n: u32| net.degree(n) <= 1;
    let mut from = 1;
    while let Some(j) = (from..walk.len().saturating_sub(1))
        .find(|&j| walk[j - 1] == walk[j + 1] && !is_leaf(walk[j]))
    {
        if let Some(path) = path_to_end(net, walk[j], walk[j - 1], 2.5 * h, closed) {
            // Go on to the end and back.
            let extra = 2 * (path.len() - 1);
            let mut round: Vec<u32> = path[1..].to_vec();
            round.extend(path[..path.len() - 1].iter().rev());
            walk.splice(j + 1..j + 1, round);
            for x in w.iter_mut() {
                if *x > j {
                    *x += extra;
                }
            }
            from = j + extra + 1;
            continue;
        }
        walk.drain(j..j + 2);
        for x in w.iter_mut() {
            if *x == j || *x == j + 1 {
                *x = j - 1;
            } else if *x > j + 1 {
                *x -= 2;
            }
        }
        from = 1;
    }
}

/// Open traces end on the domain box, as do the curves they follow: a walk whose trace
/// starts (or ends) on the box is extended to the curve's exit node there.
fn extend_to_exits(inp: &Input, trace: &[u32], walk: &mut Vec<u32>, w: &mut [usize]) {
    let (net, h) = (inp.net, inp.grid.cell);
    let first = trace[0];
    let last = *trace.last().unwrap_or(&first);
    if on_box(&inp.vertices[first as usize], inp.grid.dims)
        && let Some(path) = path_to_exit(net, walk[0], 2.5 * h)
    {
        let extra = path.len() - 1;
        let mut nw: Vec<u32> = path.into_iter().rev().collect();
        nw.extend_from_slice(&walk[1..]);
        *walk = nw;
        for x in w.iter_mut() {
            *x += extra;
        }
    }
    let end = *walk.last().unwrap_or(&0);
    if on_box(&inp.vertices[last as usize], inp.grid.dims)
        && let Some(path) = path_to_exit(net, end, 2.5 * h)
    {
        walk.extend_from_slice(&path[1..]);
    }
}

/// Zips a trace piece (marching-cubes vertices) with its walk (network nodes) into a band:
/// a sequence of steps, each one triangle, `true` for a step along the trace. Returns the
/// steps and the triangles (node `k` numbered `mc_vertices + k`).
fn zip_band(
    inp: &Input,
    trace: &[u32],
    walk: &[u32],
    w: &[usize],
    closed: bool,
    probe: &mut Probe,
) -> (Vec<bool>, Vec<[u32; 3]>) {
    let net = inp.net;
    let n_mc = inp.vertices.len() as u32;
    let pos = |v: u32| inp.positions[v as usize];
    let (nt, nw) = (trace.len() - 1, walk.len() - 1);
    let mut steps: Vec<bool> = Vec::with_capacity(nt + nw);
    let (mut i, mut j) = (0usize, 0usize);
    let mut turned_at: Option<usize> = None;
    while i < nt || j < nw {
        // Round the end of a curve the walk comes straight back: the trace must move on
        // between the two steps, or the second triangle would fold onto the first.
        let folds = j >= 1 && j < nw && walk[j + 1] == walk[j - 1] && turned_at == Some(i);
        let advance_trace = if i == nt {
            false
        } else if j == nw || j >= w[i + 1] || folds {
            true
        } else if j < w[i] {
            false
        } else {
            // The shorter rung.
            let (ti, tn) = (pos(trace[i]), pos(trace[i + 1]));
            let (wj, wn) = (net.nodes[walk[j] as usize].p, net.nodes[walk[j + 1] as usize].p);
            (tn - wj).length() <= (ti - wn).length()
        };
        if advance_trace {
            i += 1;
        } else {
            turned_at = Some(i);
            j += 1;
        }
        steps.push(advance_trace);
    }
    let tri_of = |steps: &[bool], k: usize, i: usize, j: usize| -> [u32; 3] {
        if steps[k] {
            [trace[i], trace[i + 1], n_mc + walk[j]]
        } else {
            [trace[i], n_mc + walk[j + 1], n_mc + walk[j]]
        }
    };
    let place = |v: u32| {
        if v < n_mc { inp.positions[v as usize] } else { net.nodes[(v - n_mc) as usize].p }
    };
    let normal = |t: [u32; 3]| {
        let q = t.map(place);
        (q[1] - q[0]).cross(q[2] - q[0])
    };
    let flat = |t: [u32; 3]| {
        let q = t.map(place);
        let e = (q[1] - q[0]).length_squared()
            + (q[2] - q[1]).length_squared()
            + (q[0] - q[2]).length_squared();
        normal(t).length() <= 1e-6 * e
    };
    let emit = |steps: &[bool]| {
        let (mut i, mut j) = (0, 0);
        let mut out = Vec::with_capacity(steps.len());
        for k in 0..steps.len() {
            out.push(tri_of(steps, k, i, j));
            if steps[k] {
                i += 1;
            } else {
                j += 1;
            }
        }
        out
    };
    // A triangle whose three points are on one line (a curve crossing the lattice plane a
    // trace runs in) is flipped with a neighbour: swapping two unlike steps moves the rung
    // between them to the quad's other diagonal.
    let mut tris = emit(&steps);
    for k in 0..steps.len() {
        if !flat(tris[k]) {
            continue;
        }
        for m in [k.wrapping_sub(1), k + 1] {
            if m >= steps.len() || steps[m] == steps[k] {
                continue;
            }
            let (a, b) = (k.min(m), k.max(m));
            let mut trial = steps.clone();
            trial.swap(a, b);
            let t2 = emit(&trial);
            let (x, y) = (t2[a], t2[b]);
            let distinct = |t: [u32; 3]| t[0] != t[1] && t[1] != t[2] && t[0] != t[2];
            if distinct(x) && distinct(y) && !flat(x) && !flat(y) && normal(x).dot(normal(y)) > 0.0
            {
                steps = trial;
                tris = t2;
                break;
            }
        }
    }
    let band = Band { inp, trace, walk, closed };
    let (before, bad) = band.folding(&tris);
    if bad && let Some(better) = band.rezip(w, &steps, probe) {
        let t2 = emit(&better);
        if band.folding(&t2).0 < before {
            tris = t2;
            steps = better;
        }
    }
    (steps, tris)
}

/// Below this cosine (about 160°) between the normals of two band triangles that share a
/// rung, the band folds there: well short of the 175° at which `skelform check` counts a
/// folded edge, so that the float rounding of the output cannot push one over.
const BAND_FOLD_COS: f64 = -0.94;

/// The cosine of 170°: past it a fold in a band is sharp (see `Band::fold`).
const SHARP_COS: f64 = -0.984_807_753;

/// A band being zipped: its trace piece and walk, for the re-zip of a folded band.
struct Band<'a, 'i> {
    inp: &'a Input<'i>,
    trace: &'a [u32],
    walk: &'a [u32],
    closed: bool,
}

impl Band<'_, '_> {
    /// Where vertex `v` of a band triangle is (marching-cubes vertex or network node).
    fn place(&self, v: u32) -> DVec3 {
        let n_mc = self.inp.vertices.len() as u32;
        if v < n_mc {
            self.inp.positions[v as usize]
        } else {
            self.inp.net.nodes[(v - n_mc) as usize].p
        }
    }

    /// Twice the area times the unit normal.
    fn normal(&self, t: [u32; 3]) -> DVec3 {
        let q = t.map(|v| self.place(v));
        (q[1] - q[0]).cross(q[2] - q[0])
    }

    /// Whether triangle `t` is too thin for its normal to mean anything (its points nearly on
    /// a line: twice its area under a thousandth of its longest side squared).
    fn degenerate(&self, t: [u32; 3]) -> bool {
        let q = t.map(|v| self.place(v));
        let longest = (q[1] - q[0])
            .length_squared()
            .max((q[2] - q[1]).length_squared())
            .max((q[0] - q[2]).length_squared());
        self.normal(t).length() <= 1e-3 * longest
    }

    /// The cosine between the normals of two triangles; `None` when either is degenerate
    /// (its normal, once the positions are rounded to `f32`, could point either way).
    fn cos(&self, a: [u32; 3], b: [u32; 3]) -> Option<f64> {
        (!self.degenerate(a) && !self.degenerate(b))
            .then(|| self.normal(a).normalize_or_zero().dot(self.normal(b).normalize_or_zero()))
    }

    /// How far two triangles that share a rung fold onto each other: 0 while their normals
    /// are within 90°, 1 when they are 170° apart, up to 6 at 180° or when either is
    /// degenerate. Steep past 170° because that is where a fold gets near the 175° at which
    /// `skelform check` counts it, and a sheet that folds round a pinch point on the domain
    /// box has a crest sharper than any triangle, so some fold there is unavoidable and only
    /// its angle can be chosen.
    fn fold(&self, a: [u32; 3], b: [u32; 3]) -> f64 {
        match self.cos(a, b) {
            None => 6.0,
            Some(c) => (-c).max(0.0) + 5.0 * ((SHARP_COS - c) / (1.0 + SHARP_COS)).max(0.0),
        }
    }

    /// How much the band folds: the sum of [`Band::fold`] over consecutive triangles (sharing
    /// a rung, round the seam of a loop too), and whether any of them is degenerate or folds
    /// by more than [`BAND_FOLD_COS`].
    fn folding(&self, tris: &[[u32; 3]]) -> (f64, bool) {
        let mut pairs: Vec<([u32; 3], [u32; 3])> = tris.windows(2).map(|p| (p[0], p[1])).collect();
        if self.wraps()
            && let (Some(&a), Some(&b)) = (tris.last(), tris.first())
            && tris.len() > 2
        {
            pairs.push((a, b));
        }
        let mut bad = tris.iter().any(|&t| self.degenerate(t));
        let mut sum = 0.0;
        for (a, b) in pairs {
            sum += self.fold(a, b);
            bad |= self.cos(a, b).is_none_or(|c| c < BAND_FOLD_COS);
        }
        (sum, bad)
    }

    /// Whether the band is a closed loop whose last triangle meets its first on the rung
    /// from the first trace vertex to the first walk node.
    fn wraps(&self) -> bool {
        self.closed
            && self.trace.first() == self.trace.last()
            && self.walk.first() == self.walk.last()
    }

    /// A zip of the band without folds where the greedy one folds: the steps that minimise,
    /// over all zips that keep each trace vertex within [`REZIP_REACH`] walk steps of its
    /// node, how far each triangle turns from the surface's normal at its trace vertices, how
    /// much consecutive triangles fold, and (to break ties) the rungs' lengths; `None` when
    /// the field cannot be evaluated.
    ///
    /// Why: the greedy zip pairs each trace vertex with its nearest node, which fails where
    /// the trace runs straight away from a node: a trace in the lattice plane that a curve
    /// crosses at that node (next to a pinch point, where the zone is wide below the plane
    /// and narrow above it), whose vertices all have that node nearest, so the band fans
    /// them from it, a fan of slivers as flat as the trace is straight, which fold at random;
    /// and a trace that passes within a cell of a pinch point, where the order of the nearest
    /// nodes does not follow the trace's. Along such a trace the sheet runs from the trace
    /// down the curve, so its vertices are zipped with the nodes a few steps on, and the
    /// triangles' normals, compared with the field's gradient at the trace (which is the
    /// sheet's normal, however small, on a point of one sheet), say which zip lies in the
    /// sheet. `greedy` is the zip along the nearest nodes.
    fn rezip(&self, w: &[usize], greedy: &[bool], probe: &mut Probe) -> Option<Vec<bool>> {
        let (trace, walk) = (self.trace, self.walk);
        let (nt, nw) = (trace.len() - 1, walk.len() - 1);
        let n_mc = self.inp.vertices.len() as u32;
        let h = self.inp.grid.cell;
        let pts: Vec<DVec3> = trace.iter().map(|&v| self.place(v)).collect();
        let (_, grads) = probe.grads(&pts)?;
        let g: Vec<DVec3> = grads.iter().map(|g| g.normalize_or_zero()).collect();
        let tri_trace = |i: usize, j: usize| [trace[i], trace[i + 1], n_mc + walk[j]];
        let tri_walk = |i: usize, j: usize| [trace[i], n_mc + walk[j + 1], n_mc + walk[j]];
        // Which way the band's triangles face the gradient: as most of the band's area does
        // in the zip along the nearest nodes (a sheet's pieces all face `f > 0` or all away).
        let mut facing = 0.0;
        let (mut i, mut j) = (0, 0);
        for &along_trace in greedy {
            if along_trace {
                facing += self.normal(tri_trace(i, j)).dot(g[i] + g[i + 1]);
                i += 1;
            } else {
                facing += self.normal(tri_walk(i, j)).dot(g[i]);
                j += 1;
            }
        }
        let s = if facing < 0.0 { -1.0 } else { 1.0 };
        let cost = |t: [u32; 3], gt: DVec3, rung: f64| -> f64 {
            let turn = if self.degenerate(t) {
                1.0
            } else {
                0.5 * (1.0 - s * self.normal(t).normalize_or_zero().dot(gt.normalize_or_zero()))
            };
            turn + REZIP_RUNG * rung / h
        };
        // The walk positions a state at trace vertex `i` may be at.
        let lo = |i: usize| if i == 0 { 0 } else { w[i].saturating_sub(REZIP_REACH) };
        let hi = |i: usize| if i == nt { nw } else { (w[i + 1] + REZIP_REACH).min(nw) };
        let allowed = |i: usize, j: usize| lo(i) <= j && j <= hi(i);
        // Costs by state (trace position, walk position, last step: 0 trace, 1 walk), and the
        // step that led there.
        let idx = |i: usize, j: usize, l: usize| (i * (nw + 1) + j) * 2 + l;
        let size = (nt + 1).checked_mul(nw + 1)?.checked_mul(2)?;
        let mut best_steps: Option<(f64, Vec<bool>)> = None;
        let firsts: &[bool] = if self.wraps() { &[true, false] } else { &[true] };
        for &first_forced in firsts {
            let mut best = vec![f64::INFINITY; size];
            let mut from: Vec<u8> = vec![u8::MAX; size];
            let prev_tri = |i: usize, j: usize, l: usize| {
                if l == 0 { tri_trace(i - 1, j) } else { tri_walk(i, j - 1) }
            };
            // The first step, with or without the wrap round the seam in mind.
            let starts: Vec<bool> =
                if self.wraps() { vec![first_forced] } else { vec![true, false] };
            for step_trace in starts {
                if step_trace && nt > 0 && allowed(1, 0) {
                    let t = tri_trace(0, 0);
                    let c = cost(t, g[0] + g[1], (pts[1] - self.place(n_mc + walk[0])).length());
                    best[idx(1, 0, 0)] = c;
                    from[idx(1, 0, 0)] = 2;
                }
                if !step_trace && nw > 0 && allowed(0, 1) {
                    let t = tri_walk(0, 0);
                    let c = cost(t, g[0], (pts[0] - self.place(n_mc + walk[1])).length());
                    best[idx(0, 1, 1)] = c;
                    from[idx(0, 1, 1)] = 2;
                }
            }
            for i in 0..=nt {
                for j in lo(i)..=hi(i) {
                    for l in 0..2 {
                        let here = best[idx(i, j, l)];
                        if !here.is_finite() {
                            continue;
                        }
                        let prev = prev_tri(i, j, l);
                        if i < nt && allowed(i + 1, j) {
                            let t = tri_trace(i, j);
                            let rung = (pts[i + 1] - self.place(n_mc + walk[j])).length();
                            let c = here
                                + cost(t, g[i] + g[i + 1], rung)
                                + REZIP_FOLD * self.fold(prev, t);
                            let k = idx(i + 1, j, 0);
                            if c < best[k] {
                                best[k] = c;
                                from[k] = l as u8;
                            }
                        }
                        // Round the end of a curve the walk comes straight back: two walk steps
                        // in a row there would be one triangle twice.
                        let turn = l == 1 && j >= 1 && j < nw && walk[j + 1] == walk[j - 1];
                        if j < nw && allowed(i, j + 1) && !turn {
                            let t = tri_walk(i, j);
                            let rung = (pts[i] - self.place(n_mc + walk[j + 1])).length();
                            let c = here + cost(t, g[i], rung) + REZIP_FOLD * self.fold(prev, t);
                            let k = idx(i, j + 1, 1);
                            if c < best[k] {
                                best[k] = c;
                                from[k] = l as u8;
                            }
                        }
                    }
                }
            }
            for l in 0..2 {
                let mut total = best[idx(nt, nw, l)];
                if !total.is_finite() {
                    continue;
                }
                // Walk back to the start.
                let mut steps = Vec::with_capacity(nt + nw);
                let (mut i, mut j, mut ll) = (nt, nw, l);
                loop {
                    let f = from[idx(i, j, ll)];
                    steps.push(ll == 0);
                    if ll == 0 {
                        i -= 1
                    } else {
                        j -= 1
                    }
                    if f == 2 {
                        break;
                    }
                    ll = f as usize;
                }
                steps.reverse();
                if self.wraps() {
                    let last = prev_tri(nt, nw, l);
                    let first = if steps[0] { tri_trace(0, 0) } else { tri_walk(0, 0) };
                    total += REZIP_FOLD * self.fold(last, first);
                }
                if best_steps.as_ref().is_none_or(|b| total < b.0) {
                    best_steps = Some((total, steps));
                }
            }
        }
        best_steps.map(|b| b.1)
    }
}

/// How many walk steps beyond the ones between its nearest nodes a trace vertex may be
/// zipped with in [`Band::rezip`]: the curve's nodes are about a cell apart (one per lattice
/// face it crosses), and a trace that runs straight away from a node next to a pinch point
/// needs the nodes down to the pinch.
const REZIP_REACH: usize = 3;

/// The weight of a fold between consecutive triangles in [`Band::rezip`], against at most 1
/// for a triangle turned away from the surface's normal.
const REZIP_FOLD: f64 = 4.0;

/// The weight of a rung's length (in cells) in [`Band::rezip`]: small, only to choose among
/// zips that lie in the sheet equally well.
const REZIP_RUNG: f64 = 0.02;

/// The zone's acceptance test: two sheets cross along every curve, so each network edge in
/// the zone carries four bands (then it goes into `bands.edges`), and every cone apex in it
/// got at least one fan.
fn check_sheets(
    net: &Network,
    zone: &ZoneNetwork,
    usage: &FxHashMap<u32, u32>,
    cone_fans: &FxHashMap<u32, u32>,
    bands: &mut Bands,
) -> Result<(), String> {
    for &e in &zone.edges {
        let n = usage.get(&e).copied().unwrap_or(0);
        if n != 4 {
            let [a, b] = net.edges[e as usize];
            let mid = (net.nodes[a as usize].p + net.nodes[b as usize].p) * 0.5;
            return Err(format!(
                "{n} sheet pieces (not 4) meet the self-intersection near ({:.3}, {:.3}, {:.3})",
                mid.x, mid.y, mid.z
            ));
        }
        bands.edges.push(net.edges[e as usize]);
    }
    for &k in &zone.nodes {
        if net.nodes[k as usize].kind == NodeKind::Cone
            && cone_fans.get(&k).copied().unwrap_or(0) == 0
        {
            return Err("no sheet reaches the cone apex".into());
        }
    }
    Ok(())
}

/// A path from `a` (not back through `not`) to the end of a curve inside the domain (a pinch
/// point or a lost end), or also on the box (an exit) when `exits` is set, within `limit`.
fn path_to_end(net: &Network, a: u32, not: u32, limit: f64, exits: bool) -> Option<Vec<u32>> {
    let mut best: Option<(f64, Vec<u32>)> = None;
    let mut frontier = vec![(a, 0.0, vec![a])];
    while let Some((n, d, path)) = frontier.pop() {
        for &(m, _) in &net.adj[n as usize] {
            if m == not || path.contains(&m) {
                continue;
            }
            let nd = d + (net.nodes[m as usize].p - net.nodes[n as usize].p).length();
            if nd > limit {
                continue;
            }
            let mut np = path.clone();
            np.push(m);
            let kind = net.nodes[m as usize].kind;
            let end = matches!(kind, NodeKind::Pinch | NodeKind::End)
                || (exits && kind == NodeKind::Exit);
            if net.degree(m) <= 1 && end {
                if best.as_ref().is_none_or(|b| nd < b.0) {
                    best = Some((nd, np));
                }
            } else {
                frontier.push((m, nd, np));
            }
        }
    }
    best.map(|b| b.1)
}

/// The shortest network path from `a` to a node on the domain box within `limit`, if `a` is
/// not one already.
fn path_to_exit(net: &Network, a: u32, limit: f64) -> Option<Vec<u32>> {
    if net.nodes[a as usize].kind == NodeKind::Exit {
        return None;
    }
    let mut best: Option<(f64, Vec<u32>)> = None;
    let mut frontier = vec![(a, 0.0, vec![a])];
    while let Some((n, d, path)) = frontier.pop() {
        for &(m, _) in &net.adj[n as usize] {
            if path.contains(&m) {
                continue;
            }
            let nd = d + (net.nodes[m as usize].p - net.nodes[n as usize].p).length();
            if nd > limit {
                continue;
            }
            let mut np = path.clone();
            np.push(m);
            if net.nodes[m as usize].kind == NodeKind::Exit {
                if best.as_ref().is_none_or(|b| nd < b.0) {
                    best = Some((nd, np));
                }
            } else {
                frontier.push((m, nd, np));
            }
        }
    }
    best.map(|b| b.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lattice_indexing_round_trips() {
        let grid = Grid::with_cell(&skelform_field::Aabb::cube(1.0), 0.25).unwrap();
        let lat = Lattice::new(grid);
        assert_eq!(lat.cubes, [8, 8, 8]);
        for i in [0, 7, 63, 100, 511] {
            assert_eq!(lat.cube(lat.coords(i)), i);
        }
        let around = lat.around_edge([3, 4, 5], 2);
        let got: Vec<[usize; 3]> = around.iter().map(|c| lat.coords(c.unwrap())).collect();
        assert_eq!(got, vec![[3, 4, 5], [2, 4, 5], [2, 3, 5], [3, 3, 5]]);
        assert_eq!(lat.around_edge([0, 0, 5], 2).iter().flatten().count(), 1);
        assert_eq!(lat.neighbour([0, 0, 0], 0), None);
        assert_eq!(lat.neighbour([0, 0, 0], 1), Some(lat.cube([1, 0, 0])));
    }

    #[test]
    fn edges_share_the_faces_they_should() {
        for a in 0..12 {
            let count = (0..12).filter(|&b| b != a && common_face(a, b).is_some()).count();
            // Each edge is on two faces, each with three other edges.
            assert_eq!(count, 6, "edge {a}");
        }
    }

    #[test]
    fn hidden_crossings_on_an_edge() {
        use skelform_field::{FnField, control::Control, grid::sample};
        // A slab |x| < 0.05 around x = 0 between samples at x = -0.125 and 0.125.
        let f = FnField(|p: DVec3| p.x * p.x - 0.0025);
        let grid = Grid::with_cell(
            &skelform_field::Aabb::new(DVec3::splat(-0.125), DVec3::splat(0.125)),
            0.25,
        )
        .unwrap();
        let vol = sample(&f, &grid, &Control::default()).unwrap();
        let lat = Lattice::new(grid);
        let mut probe = Probe::new(&f, 0.25);
        assert_eq!(edge_hides_crossings(&mut probe, &vol, &lat, [0, 0, 0], 0), Hidden::Sheets);
        assert_eq!(edge_hides_crossings(&mut probe, &vol, &lat, [0, 0, 0], 1), Hidden::No);
        // Two planes crossing at 60° a fiftieth of a cell off the edge (along y at x = z =
        // -0.125): the edge runs through the thin wedge between them.
        let (n1, n2) = (DVec3::new(0.0, 1.0, 0.0), DVec3::new(0.0, 0.5, 0.75f64.sqrt()));
        let f = FnField(move |p: DVec3| {
            let q = p - DVec3::new(0.0, 0.01, -0.12);
            n1.dot(q) * n2.dot(q)
        });
        let vol = sample(&f, &grid, &Control::default()).unwrap();
        let mut probe = Probe::new(&f, 0.25);
        assert_eq!(edge_hides_crossings(&mut probe, &vol, &lat, [0, 0, 0], 1), Hidden::Sheets);
        // A sphere of radius 1 dipping 0.001 across the edge: one sheet grazing it.
        let f = FnField(|p: DVec3| (p - DVec3::new(-1.124, 0.0, -0.125)).length() - 1.0);
        let vol = sample(&f, &grid, &Control::default()).unwrap();
        let mut probe = Probe::new(&f, 0.25);
        assert_eq!(edge_hides_crossings(&mut probe, &vol, &lat, [0, 0, 0], 1), Hidden::OneSheet);
    }
}
