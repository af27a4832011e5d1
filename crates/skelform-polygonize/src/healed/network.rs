//! The self-intersection network: the traced crossing curves cut into segments at lattice
//! faces, joined at triple points, ended at pinch points and at the domain box.
//!
//! The nodes where a curve crosses a lattice face are the thesis's face self-intersection
//! points (where, on a face whose four edges all cross the surface, the two segments joining
//! opposite edge points intersect; here they are solved for exactly on the field). Between
//! two such nodes the network edge is the straight spine through one cube, as in the thesis.

use glam::DVec3;
use rustc_hash::FxHashMap;
use skelform_field::grid::Grid;

use super::trace::{End, LineKind, PointKind, SingularPoint, Tracer};

/// What a network node is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum NodeKind {
    /// Where a crossing curve meets a lattice face.
    Face,
    /// Where a crossing curve leaves the domain box (on its boundary).
    Exit,
    /// Where a march lost the curve: an end the method could not explain.
    End,
    /// Where a march ran into a curve traced before, going the same way.
    Join,
    /// Where a crossing curve becomes a bare line.
    Pinch,
    /// Where crossing curves meet.
    Junction,
    /// A cone apex (no edges).
    Cone,
}

#[derive(Clone, Copy, Debug)]
pub(crate) struct Node {
    pub p: DVec3,
    pub kind: NodeKind,
}

/// A crossing run: a stretch of a traced curve where two sheets cross.
#[derive(Clone, Debug)]
pub(crate) struct Run {
    /// The traced points, about a quarter of a cell apart.
    pub fine: Vec<DVec3>,
    /// Its nodes in order.
    pub nodes: Vec<u32>,
    pub closed: bool,
}

/// The whole network, and the bare lines found on the way.
#[derive(Clone, Debug, Default)]
pub(crate) struct Network {
    pub nodes: Vec<Node>,
    pub edges: Vec<[u32; 2]>,
    /// Per node: `(neighbour, edge)`.
    pub adj: Vec<Vec<(u32, u32)>>,
    pub runs: Vec<Run>,
    /// Stretches of curves where the zero set is the line alone.
    pub lines: Vec<Vec<DVec3>>,
    /// Singular points to report: cones, isolated and degenerate points from the search, and
    /// the pinch and triple points of the network.
    pub points: Vec<SingularPoint>,
}

impl Network {
    pub fn degree(&self, n: u32) -> usize {
        self.adj[n as usize].len()
    }

    pub fn edge_between(&self, a: u32, b: u32) -> Option<u32> {
        self.adj[a as usize].iter().find(|x| x.0 == b).map(|x| x.1)
    }
}

/// One end of a run.
#[derive(Clone, Copy, Debug)]
enum RunEnd {
    Curve(End),
    Pinch(DVec3),
}

struct RawRun {
    curve: usize,
    /// Inclusive point range in the curve (for a rotated closed curve, indices wrap).
    idx: Vec<usize>,
    kind: LineKind,
    closed: bool,
    ends: [RunEnd; 2],
}

/// Lattice planes crossed going from `a` to `b`: `(axis, plane index, fraction)`, sorted by
/// fraction. A point exactly on a plane counts for the segment that arrives at it.
fn planes_crossed(grid: &Grid, a: DVec3, b: DVec3) -> Vec<(usize, i64, f64)> {
    let mut out = Vec::new();
    for axis in 0..3 {
        let la = (a[axis] - grid.origin[axis]) / grid.cell;
        let lb = (b[axis] - grid.origin[axis]) / grid.cell;
        if (la - lb).abs() < 1e-9 {
            continue;
        }
        let last = grid.dims[axis] as i64 - 1;
        let (lo, hi) = if la < lb { (la, lb) } else { (lb, la) };
        // Planes k with lo < k <= hi going up, lo <= k < hi going down (arrival counts).
        let (first, end) = if la < lb {
            (lo.floor() as i64 + 1, hi.floor() as i64)
        } else {
            (lo.ceil() as i64, hi.ceil() as i64 - 1)
        };
        for k in first.max(0)..=end.min(last) {
            let u = (k as f64 - la) / (lb - la);
            if (0.0..=1.0).contains(&u) {
                out.push((axis, k, u));
            }
        }
    }
    out.sort_by(|x, y| x.2.total_cmp(&y.2));
    out
}

/// Where the segment from `anchor` (inside) to `outside` leaves the lattice's box: the first
/// boundary plane it meets (`anchor` may lie on it already), as `(axis, plane, fraction)`.
fn box_exit(grid: &Grid, anchor: DVec3, outside: DVec3) -> Option<(usize, i64, f64)> {
    let bounds = grid.bounds();
    let mut exit: Option<(usize, i64, f64)> = None;
    for axis in 0..3 {
        let (plane, k) = if outside[axis] > bounds.max[axis] {
            (bounds.max[axis], grid.dims[axis] as i64 - 1)
        } else if outside[axis] < bounds.min[axis] {
            (bounds.min[axis], 0)
        } else {
            continue;
        };
        let u = ((plane - anchor[axis]) / (outside[axis] - anchor[axis])).clamp(0.0, 1.0);
        if exit.is_none_or(|e| u < e.2) {
            exit = Some((axis, k, u));
        }
    }
    exit
}

/// Builds the network from the tracer's curves (solving the face crossings, pinch and triple
/// points on the field).
pub(crate) fn build(tracer: &mut Tracer) -> Network {
    let grid = *tracer.grid();
    let h = grid.cell;
    let curves = tracer.curves.clone();
    let mut net = Network::default();

    // 1. Runs of one kind.
    let mut raw: Vec<RawRun> = Vec::new();
    for (ci, c) in curves.iter().enumerate() {
        let n = c.points.len();
        let uniform = c.kinds.iter().all(|k| *k == c.kinds[0]);
        if c.closed() && uniform {
            raw.push(RawRun {
                curve: ci,
                idx: (0..n).collect(),
                kind: c.kinds[0],
                closed: true,
                ends: [RunEnd::Curve(End::Closed), RunEnd::Curve(End::Closed)],
            });
            continue;
        }
        // Order of points; a closed curve of mixed kinds starts just after a change of kind.
        let (order, mut ends): (Vec<usize>, [RunEnd; 2]) = if c.closed() {
            let s = (1..n).find(|&i| c.kinds[i] != c.kinds[i - 1]).unwrap_or(0);
            let mut o: Vec<usize> = (s..n).chain(0..s).collect();
            o.push(s);
            let a = c.points[(s + n - 1) % n];
            let pinch = tracer.pinch_between(a, c.points[s]);
            (o, [RunEnd::Pinch(pinch), RunEnd::Pinch(pinch)])
        } else {
            ((0..n).collect(), [RunEnd::Curve(c.ends[0]), RunEnd::Curve(c.ends[1])])
        };
        let mut start = 0;
        for i in 1..=order.len() {
            let change = i == order.len() || c.kinds[order[i]] != c.kinds[order[i - 1]];
            if !change {
                continue;
            }
            let end = if i == order.len() {
                ends[1]
            } else {
                RunEnd::Pinch(tracer.pinch_between(c.points[order[i - 1]], c.points[order[i]]))
            };
            raw.push(RawRun {
                curve: ci,
                idx: order[start..i].to_vec(),
                kind: c.kinds[order[i - 1]],
                closed: false,
                ends: [ends[0], end],
            });
            ends[0] = end;
            start = i;
        }
    }

    // 2. Nodes of the crossing runs, keyed by position along the run.
    let mut nodes: Vec<Node> = Vec::new();
    let mut keyed: Vec<Vec<(f64, u32)>> = Vec::new();
    let mut crossing_runs: Vec<usize> = Vec::new();
    let mut joins: Vec<(usize, usize, u32)> = Vec::new(); // (curve, point index, node)
    let add = |nodes: &mut Vec<Node>, p: DVec3, kind: NodeKind| {
        nodes.push(Node { p, kind });
        nodes.len() as u32 - 1
    };
    for (ri, r) in raw.iter().enumerate() {
        let c = &curves[r.curve];
        let fine: Vec<DVec3> = r.idx.iter().map(|&i| c.points[i]).collect();
        if r.kind == LineKind::Isolated {
            let mut line = fine.clone();
            for (e, at_start) in [(r.ends[0], true), (r.ends[1], false)] {
                let anchor = if at_start { fine[0] } else { fine[fine.len() - 1] };
                let p = match e {
                    RunEnd::Pinch(p) => p,
                    RunEnd::Curve(End::Domain { outside }) => {
                        match box_exit(&grid, anchor, outside) {
                            Some((axis, k, _)) => tracer.on_plane(anchor, outside, axis, k),
                            None => continue,
                        }
                    }
                    _ => continue,
                };
                if at_start {
                    line.insert(0, p);
                } else {
                    line.push(p);
                }
            }
            net.lines.push(line);
            continue;
        }
        let mut list: Vec<(f64, u32)> = Vec::new();
        let last = fine.len() - 1;
        for w in 0..fine.len().saturating_sub(1) {
            for (axis, k, u) in planes_crossed(&grid, fine[w], fine[w + 1]) {
                let p = tracer.on_plane(fine[w], fine[w + 1], axis, k);
                list.push((w as f64 + u, add(&mut nodes, p, NodeKind::Face)));
            }
        }
        if r.closed {
            for (axis, k, u) in planes_crossed(&grid, fine[last], fine[0]) {
                let p = tracer.on_plane(fine[last], fine[0], axis, k);
                list.push((last as f64 + u, add(&mut nodes, p, NodeKind::Face)));
            }
        }
        for (side, e) in [(0usize, r.ends[0]), (1, r.ends[1])] {
            let (anchor, key_base, sign) =
                if side == 0 { (fine[0], 0.0, -1.0) } else { (fine[last], last as f64, 1.0) };
            match e {
                RunEnd::Curve(End::Closed) => {}
                RunEnd::Curve(End::Domain { outside }) => {
                    let exit = box_exit(&grid, anchor, outside);
                    for (axis, k, u) in planes_crossed(&grid, anchor, outside) {
                        if exit.is_some_and(|e| u >= e.2) {
                            continue;
                        }
                        let p = tracer.on_plane(anchor, outside, axis, k);
                        list.push((key_base + sign * u, add(&mut nodes, p, NodeKind::Face)));
                    }
                    if let Some((axis, k, u)) = exit {
                        let p = tracer.on_plane(anchor, outside, axis, k);
                        list.push((
                            key_base + sign * (u + 1e-6),
                            add(&mut nodes, p, NodeKind::Exit),
                        ));
                    }
                }
                RunEnd::Curve(End::Lost | End::Budget) => {
                    list.push((key_base + sign * 1e-3, add(&mut nodes, anchor, NodeKind::End)));
                }
                RunEnd::Curve(End::Join { curve, index }) => {
                    let p = curves[curve].points[index];
                    let id = add(&mut nodes, p, NodeKind::Join);
                    list.push((key_base + sign * 0.5, id));
                    joins.push((curve, index, id));
                }
                RunEnd::Pinch(p) => {
                    list.push((key_base + sign * 0.5, add(&mut nodes, p, NodeKind::Pinch)));
                }
            }
        }
        keyed.push(list);
        crossing_runs.push(ri);
        net.runs.push(Run { fine, nodes: Vec::new(), closed: r.closed });
    }

    // Joins: the node also goes into the run that holds the point joined.
    for (curve, index, id) in joins {
        for (k, &ri) in crossing_runs.iter().enumerate() {
            let r = &raw[ri];
            if r.curve == curve
                && let Some(pos) = r.idx.iter().position(|&i| i == index)
            {
                keyed[k].push((pos as f64, id));
            }
        }
    }

    // 3. Triple points: fine segments of different runs (or far apart on one) that meet.
    let bucket = |p: DVec3| {
        let r = (p - grid.origin) / h;
        [r.x.floor() as i64, r.y.floor() as i64, r.z.floor() as i64]
    };
    let mut segs: FxHashMap<[i64; 3], Vec<(usize, usize)>> = FxHashMap::default();
    for (k, r) in net.runs.iter().enumerate() {
        let n = r.fine.len();
        let count = if r.closed { n } else { n.saturating_sub(1) };
        for w in 0..count {
            let (a, b) = (r.fine[w], r.fine[(w + 1) % n]);
            let mut keys = vec![bucket(a), bucket(b)];
            keys.dedup();
            for key in keys {
                segs.entry(key).or_default().push((k, w));
            }
        }
    }
    let mut keys: Vec<&[i64; 3]> = segs.keys().collect();
    keys.sort_unstable();
    let mut junctions: Vec<u32> = Vec::new();
    let mut candidates: Vec<(usize, usize, f64, usize, usize, f64, DVec3)> = Vec::new();
    for key in keys {
        let mut near: Vec<(usize, usize)> = Vec::new();
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(l) = segs.get(&[key[0] + dx, key[1] + dy, key[2] + dz]) {
                        near.extend_from_slice(l);
                    }
                }
            }
        }
        near.sort_unstable();
        near.dedup();
        for &(k1, w1) in segs.get(key).into_iter().flatten() {
            for &(k2, w2) in &near {
                if (k2, w2) <= (k1, w1) {
                    continue;
                }
                if k1 == k2 && w1.abs_diff(w2) < 8 {
                    continue;
                }
                let r1 = &net.runs[k1];
                let r2 = &net.runs[k2];
                let (a, b) = (r1.fine[w1], r1.fine[(w1 + 1) % r1.fine.len()]);
                let (c, d) = (r2.fine[w2], r2.fine[(w2 + 1) % r2.fine.len()]);
                let (u, v, dist) = segment_distance(a, b, c, d);
                let (da, dc) = ((b - a).normalize_or_zero(), (d - c).normalize_or_zero());
                if dist < 0.05 * h && da.dot(dc).abs() < 0.94 {
                    let mid = (a.lerp(b, u) + c.lerp(d, v)) * 0.5;
                    candidates.push((k1, w1, u, k2, w2, v, mid));
                }
            }
        }
    }
    candidates.sort_by_key(|x| (x.0, x.1, x.3, x.4));
    candidates.dedup_by(|x, y| (x.0, x.1, x.3, x.4) == (y.0, y.1, y.3, y.4));
    for (k1, w1, u, k2, w2, v, mid) in candidates {
        let existing =
            junctions.iter().copied().find(|&j| (nodes[j as usize].p - mid).length() < 0.2 * h);
        let id = match existing {
            Some(j) => j,
            None => {
                let p = tracer.junction_near(mid);
                let id = add(&mut nodes, p, NodeKind::Junction);
                junctions.push(id);
                id
            }
        };
        for (k, key) in [(k1, w1 as f64 + u), (k2, w2 as f64 + v)] {
            if !keyed[k].iter().any(|x| x.1 == id) {
                keyed[k].push((key, id));
            }
        }
    }

    // 4. Merge nodes at the same place (a curve through a lattice edge crosses two planes at
    // once; a triple point may sit on a face), keeping the most specific kind.
    let tol = 1e-6 * h;
    let mut rep: Vec<u32> = (0..nodes.len() as u32).collect();
    let mut by_bucket: FxHashMap<[i64; 3], Vec<u32>> = FxHashMap::default();
    for i in 0..nodes.len() {
        let p = nodes[i].p;
        let b = bucket(p);
        let mut found = None;
        'search: for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    if let Some(l) = by_bucket.get(&[b[0] + dx, b[1] + dy, b[2] + dz]) {
                        for &j in l {
                            if (nodes[j as usize].p - p).length() <= tol {
                                found = Some(j);
                                break 'search;
                            }
                        }
                    }
                }
            }
        }
        match found {
            Some(j) => {
                rep[i] = j;
                if nodes[i].kind > nodes[j as usize].kind {
                    nodes[j as usize].kind = nodes[i].kind;
                }
            }
            None => by_bucket.entry(b).or_default().push(i as u32),
        }
    }
    // Compact to the representatives.
    let mut new_id = vec![u32::MAX; nodes.len()];
    for i in 0..nodes.len() {
        if rep[i] == i as u32 {
            new_id[i] = net.nodes.len() as u32;
            net.nodes.push(nodes[i]);
        }
    }
    let map = |i: u32| new_id[rep[i as usize] as usize];
    let bounds = grid.bounds();
    for n in net.nodes.iter_mut() {
        let on_box = (0..3).any(|a| {
            (n.p[a] - bounds.min[a]).abs() <= 1e-7 * h || (n.p[a] - bounds.max[a]).abs() <= 1e-7 * h
        });
        if on_box && n.kind == NodeKind::Face {
            n.kind = NodeKind::Exit;
        }
    }

    // 5. Edges along each run.
    let mut edges: Vec<[u32; 2]> = Vec::new();
    for (k, list) in keyed.iter_mut().enumerate() {
        list.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        let mut ids: Vec<u32> = list.iter().map(|x| map(x.1)).collect();
        ids.dedup();
        if net.runs[k].closed && ids.len() > 1 && ids.first() == ids.last() {
            ids.pop();
        }
        let n = ids.len();
        let count = if net.runs[k].closed && n > 2 { n } else { n.saturating_sub(1) };
        for w in 0..count {
            let (a, b) = (ids[w], ids[(w + 1) % n]);
            if a != b {
                edges.push([a.min(b), a.max(b)]);
            }
        }
        net.runs[k].nodes = ids;
    }
    edges.sort_unstable();
    edges.dedup();
    net.adj = vec![Vec::new(); net.nodes.len()];
    for (e, &[a, b]) in edges.iter().enumerate() {
        net.adj[a as usize].push((b, e as u32));
        net.adj[b as usize].push((a, e as u32));
    }
    net.edges = edges;

    // 6. Point singularities: the search's cones and isolated points become nodes (cones
    // are healed, by fanning each nappe to the apex); pinch and triple points are reported.
    for sp in &tracer.points {
        let on_network = net.nodes.iter().any(|n| {
            matches!(n.kind, NodeKind::Junction | NodeKind::Pinch)
                && (n.p - sp.position).length() < h
        });
        let on_curve = net
            .runs
            .iter()
            .any(|r| r.fine.iter().any(|q| (*q - sp.position).length() < 0.5 * h))
            || net.lines.iter().any(|l| l.iter().any(|q| (*q - sp.position).length() < 0.5 * h));
        if sp.kind == PointKind::Degenerate && (on_network || on_curve) {
            continue;
        }
        if sp.kind == PointKind::Cone {
            net.nodes.push(Node { p: sp.position, kind: NodeKind::Cone });
            net.adj.push(Vec::new());
        }
        net.points.push(*sp);
    }
    for n in &net.nodes {
        let kind = match n.kind {
            NodeKind::Pinch => PointKind::Pinch,
            NodeKind::Junction => PointKind::Triple,
            _ => continue,
        };
        net.points.push(SingularPoint { position: n.p, kind });
    }
    net
}

/// Closest points of segments `ab` and `cd`: fractions along each and the distance.
fn segment_distance(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> (f64, f64, f64) {
    let (u, v) = (b - a, d - c);
    let w = a - c;
    let (aa, bb, cc, dd, ee) = (u.dot(u), u.dot(v), v.dot(v), u.dot(w), v.dot(w));
    let den = aa * cc - bb * bb;
    let mut s = if den > 1e-300 { ((bb * ee - cc * dd) / den).clamp(0.0, 1.0) } else { 0.0 };
    let mut t = if cc > 1e-300 { ((bb * s + ee) / cc).clamp(0.0, 1.0) } else { 0.0 };
    if aa > 1e-300 {
        s = ((bb * t - dd) / aa).clamp(0.0, 1.0);
    }
    if cc > 1e-300 {
        t = ((bb * s + ee) / cc).clamp(0.0, 1.0);
    }
    let dist = ((a + u * s) - (c + v * t)).length();
    (s, t, dist)
}

#[cfg(test)]
mod tests {
    use super::*;
    use skelform_field::{Aabb, FnField};

    use super::super::local::Probe;
    use super::super::trace::TraceOptions;

    #[test]
    fn planes_between_points() {
        let grid = Grid::with_cell(&Aabb::cube(1.0), 0.5).unwrap();
        // Lattice planes at -1, -0.5, 0, 0.5, 1 on each axis.
        let got = planes_crossed(&grid, DVec3::new(-0.7, 0.1, 0.1), DVec3::new(0.2, 0.1, 0.1));
        assert_eq!(got.iter().map(|x| (x.0, x.1)).collect::<Vec<_>>(), vec![(0, 1), (0, 2)]);
        // A point exactly on a plane counts once, for the segment arriving at it.
        let a = planes_crossed(&grid, DVec3::new(-0.2, 0.1, 0.1), DVec3::new(0.0, 0.1, 0.1));
        let b = planes_crossed(&grid, DVec3::new(0.0, 0.1, 0.1), DVec3::new(0.2, 0.1, 0.1));
        assert_eq!((a.len(), b.len()), (1, 0));
        let a = planes_crossed(&grid, DVec3::new(0.2, 0.1, 0.1), DVec3::new(0.0, 0.1, 0.1));
        let b = planes_crossed(&grid, DVec3::new(0.0, 0.1, 0.1), DVec3::new(-0.2, 0.1, 0.1));
        assert_eq!((a.len(), b.len()), (1, 0));
    }

    #[test]
    fn the_three_axes_meet_at_one_triple_point() {
        let f = FnField(|p: DVec3| p.x * p.y * p.z);
        let grid =
            Grid::with_cell(&Aabb::new(DVec3::splat(-1.0), DVec3::splat(0.95)), 0.15).unwrap();
        let mut t =
            Tracer::new(Probe::new(&f, 0.15), grid, TraceOptions { step: 0.25, max_steps: 10_000 });
        let all = [DVec3::X, DVec3::Y, DVec3::Z];
        for s in [
            DVec3::new(0.5, 0.01, -0.02),
            DVec3::new(0.02, -0.6, 0.01),
            DVec3::new(-0.01, 0.02, 0.7),
        ] {
            assert!(t.seed(s, &all));
        }
        let net = build(&mut t);
        let triples: Vec<_> = net.points.iter().filter(|p| p.kind == PointKind::Triple).collect();
        assert_eq!(triples.len(), 1, "{:?}", net.points);
        assert!(triples[0].position.length() < 1e-6);
        let j = net.nodes.iter().position(|n| n.kind == NodeKind::Junction).unwrap();
        assert_eq!(net.degree(j as u32), 6);
        // Every other node is on an axis, on a lattice plane across it or on the box.
        for n in &net.nodes {
            let on = [n.p.x, n.p.y, n.p.z].iter().filter(|c| c.abs() < 1e-9).count();
            assert!(on >= 2, "{:?}", n);
        }
        let exits = net.nodes.iter().filter(|n| n.kind == NodeKind::Exit).count();
        assert_eq!(exits, 6);
        // One network edge per cube along each axis (13 cubes), two in the cube of the triple
        // point.
        assert_eq!(net.edges.len(), 3 * 14);
    }
}
