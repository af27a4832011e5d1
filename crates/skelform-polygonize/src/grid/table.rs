//! The marching-cubes case table, generated from first principles rather than typed in.
//!
//! For each of the 256 sign configurations and each resolution of its ambiguous faces, the
//! table holds the closed loops in which the surface meets the cube's boundary. A loop is
//! made of one segment per face that the surface crosses; on a face with four crossings
//! (an ambiguous face) the asymptotic decider picks which crossings pair up, and since that
//! choice depends only on the face's four values, the two cubes that share a face always
//! pick alike. That is what makes the mesh closed and manifold at any resolution.
//!
//! Orientation: on every face the segment runs from the crossing where the face boundary
//! (counter-clockwise from outside) leaves the inside to where it comes back; the loops are
//! then reversed so that a fan over a loop has its right-hand normal pointing outward
//! (towards `f > 0`). Adjacent faces traverse their shared edge in opposite directions, so
//! every crossing ends exactly one segment and starts exactly one, and the loops close.

use super::cube::{EDGES, FACES, edge_between, edge_point};

/// The pseudo-edge that stands for a cube's interior vertex in triangles.
pub const CENTER: u8 = 12;

/// Most loops one cube can have (four isolated corners give four).
pub const MAX_LOOPS: usize = 4;
/// Longest loop (a hexagon-like ring can reach twelve crossings).
pub const MAX_LOOP_LEN: usize = 12;

/// One cube configuration after its ambiguous faces are decided.
#[derive(Clone, Copy, Debug, Default)]
pub struct Entry {
    /// Triangles as cube-edge triples, a fan over each loop: `tris[start..start + count]`.
    pub tri_start: u32,
    pub tri_count: u8,
    /// Loops: `loop_edges[loop_start..]`, with `loop_len[i]` edges in loop `i`.
    pub loop_start: u32,
    pub loop_count: u8,
    pub loop_len: [u8; MAX_LOOPS],
    /// Whether the caps cut off by the loops (the regions of the cube boundary that are disks)
    /// are inside; meaningful when `loop_count == 2`.
    pub caps_inside: bool,
    /// The loop fanned from an interior vertex ([`CENTER`]), if any (at most one: such
    /// loops have eight or more of the twelve edges).
    pub center_loop: Option<u8>,
    /// For three loops whose corner groups form a path (two groups of each sign: MC33's
    /// configuration 13.5), the loop left as a disk when the interior joins the two groups
    /// of one side, per side (`[inside, outside]`): the interpolant can join them by a tube
    /// through the interior (13.5.2), and that tube runs between the two loops that bound
    /// the other side's middle group, leaving the loop around the other side's end group.
    pub path_end: Option<[u8; 2]>,
}

/// The whole table.
pub struct CaseTable {
    /// Faces with four crossings, per case, as a bit mask over face numbers.
    pub ambiguous: [u8; 256],
    /// `entries[case * 64 + decisions]`; `decisions` has bit `f` set when the inside corners
    /// of face `f` are joined across it (only ambiguous faces' bits are ever set).
    pub entries: Vec<Entry>,
    pub tris: Vec<[u8; 3]>,
    pub loop_edges: Vec<u8>,
}

impl CaseTable {
    /// The entry for a sign configuration and face decisions.
    #[inline]
    pub fn entry(&self, case: usize, decisions: usize) -> &Entry {
        &self.entries[case * 64 + decisions]
    }

    #[inline]
    pub fn triangles(&self, e: &Entry) -> &[[u8; 3]] {
        &self.tris[e.tri_start as usize..e.tri_start as usize + e.tri_count as usize]
    }

    /// Loop `i` of an entry, as cube edges in order.
    #[inline]
    pub fn loop_edges(&self, e: &Entry, i: usize) -> &[u8] {
        let start =
            e.loop_start as usize + e.loop_len[..i].iter().map(|&l| l as usize).sum::<usize>();
        &self.loop_edges[start..start + e.loop_len[i] as usize]
    }
}

/// The loops of one configuration: `inside` has bit `c` set for corners with `f < 0`.
pub fn loops_for(inside: u8, decisions: u8) -> Vec<Vec<u8>> {
    let is_in = |c: usize| inside & (1 << c) != 0;
    // next[e] = the crossing that follows crossing e along its loop.
    let mut next = [u8::MAX; 12];
    for (f, q) in FACES.iter().enumerate() {
        let side = |k: usize| edge_between(q[k % 4], q[(k + 1) % 4]);
        let crossings = (0..4).filter(|&k| is_in(q[k]) != is_in(q[(k + 1) % 4])).count();
        for k in 0..4 {
            // An exit: the boundary walk leaves the inside along side k.
            if !is_in(q[k]) || is_in(q[(k + 1) % 4]) {
                continue;
            }
            let entry = if crossings == 2 {
                (1..4).map(|d| (k + d) % 4).find(|&j| !is_in(q[j]) && is_in(q[(j + 1) % 4]))
            } else if decisions & (1 << f) != 0 {
                Some((k + 1) % 4) // inside corners joined: cut off the outside corner q[k+1]
            } else {
                Some((k + 3) % 4) // inside corners apart: cut off the inside corner q[k]
            };
            let entry = entry.expect("a face with an exit has an entry");
            next[side(k)] = side(entry) as u8;
        }
    }
    let mut seen = [false; 12];
    let mut loops = Vec::new();
    for start in 0..12 {
        if next[start] == u8::MAX || seen[start] {
            continue;
        }
        let mut l = Vec::new();
        let mut e = start;
        while !seen[e] {
            seen[e] = true;
            l.push(e as u8);
            e = next[e] as usize;
        }
        debug_assert_eq!(e, start, "segments chain into closed loops");
        l.reverse();
        loops.push(l);
    }
    loops
}

/// Whether two cube edges lie on a common face.
pub fn share_face(a: u8, b: u8) -> bool {
    FACES.iter().any(|q| {
        let on = |e: u8| (0..4).any(|k| edge_between(q[k], q[(k + 1) % 4]) == e as usize);
        on(a) && on(b)
    })
}

/// Triangles over a loop, as cube-edge triples wound like the loop.
///
/// No diagonal may join two crossings on a common face: the cube across that face could
/// draw the same diagonal, and the edge would then have four triangles. Among the
/// triangulations that obey this, the one with the shortest diagonals (between edge
/// midpoints) is taken, which also avoids the slivers of a plain fan.
///
/// Some long loops (8, 9 or 12 crossings, in 116 of the table's entries) have no such
/// triangulation; for them this returns `None` and the table fans the loop from a vertex
/// inside the cube ([`CENTER`]), whose spokes no other cube can share.
pub fn triangulate(l: &[u8]) -> Option<Vec<[u8; 3]>> {
    let n = l.len();
    let mid = |e: u8| edge_point(e as usize, 0.5);
    let len = |a: u8, b: u8| {
        let (p, q) = (mid(a), mid(b));
        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
    };
    // cost of a chord (i, j): 0 for a loop side, its length for an allowed diagonal.
    let chord = |i: usize, j: usize| -> Option<f64> {
        if j == i + 1 || (i == 0 && j == n - 1) {
            Some(0.0)
        } else if share_face(l[i], l[j]) {
            None
        } else {
            Some(len(l[i], l[j]))
        }
    };
    // best[i][j]: cheapest triangulation of the sub-polygon i..=j, with its apex choice.
    let mut best = vec![vec![(f64::INFINITY, usize::MAX); n]; n];
    for i in 0..n - 1 {
        best[i][i + 1] = (0.0, usize::MAX);
    }
    for span in 2..n {
        for i in 0..n - span {
            let j = i + span;
            for k in i + 1..j {
                let (Some(a), Some(b)) = (chord(i, k), chord(k, j)) else { continue };
                let c = best[i][k].0 + best[k][j].0 + a + b;
                if c < best[i][j].0 {
                    best[i][j] = (c, k);
                }
            }
        }
    }
    if !best[0][n - 1].0.is_finite() {
        return None;
    }
    let mut tris = Vec::with_capacity(n - 2);
    let mut stack = vec![(0, n - 1)];
    while let Some((i, j)) = stack.pop() {
        if j - i < 2 {
            continue;
        }
        let k = best[i][j].1;
        tris.push([l[i], l[k], l[j]]);
        stack.push((i, k));
        stack.push((k, j));
    }
    Some(tris)
}

/// The faces of a configuration with four crossings.
pub fn ambiguous_faces(inside: u8) -> u8 {
    let is_in = |c: usize| inside & (1 << c) != 0;
    let mut mask = 0;
    for (f, q) in FACES.iter().enumerate() {
        if is_in(q[0]) == is_in(q[2]) && is_in(q[1]) == is_in(q[3]) && is_in(q[0]) != is_in(q[1]) {
            mask |= 1 << f;
        }
    }
    mask
}

/// Whether the caps (disk regions of the cube boundary outside the loop annulus) are inside,
/// for a configuration with two loops: the side with two connected groups of corners.
fn caps_inside(inside: u8, decisions: u8) -> bool {
    corner_groups(inside, decisions, true) > corner_groups(inside, decisions, false)
}

/// For three loops on a cube whose corner groups form a path (two groups of each sign), the
/// loop around each side's end group, indexed by the *other* side (`[inside, outside]`):
/// the loop that stays a disk when that other side's two groups join through the interior.
/// `None` for three loops in a star (one group of one sign), which never join.
fn path_ends(inside: u8, decisions: u8, loops: &[Vec<u8>]) -> Option<[u8; 2]> {
    let mut ends = [0u8; 2];
    for (k, joining_inside) in [true, false].into_iter().enumerate() {
        let other = corner_group_labels(inside, decisions, !joining_inside);
        let mine = corner_group_labels(inside, decisions, joining_inside);
        let count = |l: &[u8; 8]| l.iter().filter(|&&g| g != u8::MAX).max().map_or(0, |&m| m + 1);
        if count(&other) != 2 || count(&mine) != 2 {
            return None;
        }
        // A loop borders a group when one of its crossing edges has an end in that group.
        let borders =
            |l: &[u8], g: u8| l.iter().any(|&e| EDGES[e as usize].iter().any(|&c| other[c] == g));
        let end = (0..2u8).find_map(|g| {
            let b: Vec<usize> = (0..loops.len()).filter(|&i| borders(&loops[i], g)).collect();
            (b.len() == 1).then(|| b[0] as u8)
        })?;
        ends[k] = end;
    }
    Some(ends)
}

/// Connected groups of corners on the given side, over cube edges and across decided faces.
pub fn corner_groups(inside: u8, decisions: u8, side_inside: bool) -> usize {
    let labels = corner_group_labels(inside, decisions, side_inside);
    labels.iter().filter(|&&g| g != u8::MAX).max().map_or(0, |&m| m as usize + 1)
}

/// The group of each corner on the given side (numbered from 0 in corner order), `u8::MAX`
/// for corners of the other side.
pub fn corner_group_labels(inside: u8, decisions: u8, side_inside: bool) -> [u8; 8] {
    let on = |c: usize| (inside & (1 << c) != 0) == side_inside;
    let mut parent: Vec<usize> = (0..8).collect();
    fn root(p: &mut [usize], mut c: usize) -> usize {
        while p[c] != c {
            c = p[c];
        }
        c
    }
    let join = |a: usize, b: usize, p: &mut Vec<usize>| {
        let (ra, rb) = (root(p, a), root(p, b));
        p[ra] = rb;
    };
    for [a, b] in EDGES {
        if on(a) && on(b) {
            join(a, b, &mut parent);
        }
    }
    let amb = ambiguous_faces(inside);
    for (f, q) in FACES.iter().enumerate() {
        if amb & (1 << f) == 0 {
            continue;
        }
        let joined_inside = decisions & (1 << f) != 0;
        // Diagonal corners of this side are joined when the decision favours this side.
        if joined_inside == side_inside {
            for k in 0..2 {
                if on(q[k]) {
                    join(q[k], q[k + 2], &mut parent);
                }
            }
        }
    }
    let (mut labels, mut of_root) = ([u8::MAX; 8], [u8::MAX; 8]);
    let mut next = 0u8;
    for c in (0..8).filter(|&c| on(c)) {
        let r = root(&mut parent, c);
        if of_root[r] == u8::MAX {
            of_root[r] = next;
            next += 1;
        }
        labels[c] = of_root[r];
    }
    labels
}

impl CaseTable {
    /// Builds the table (a few milliseconds; callers keep one in a `OnceLock`).
    pub fn build() -> CaseTable {
        let mut t = CaseTable {
            ambiguous: [0; 256],
            entries: vec![Entry::default(); 256 * 64],
            tris: Vec::new(),
            loop_edges: Vec::new(),
        };
        for case in 0..256usize {
            let amb = ambiguous_faces(case as u8);
            t.ambiguous[case] = amb;
            for decisions in 0..64u8 {
                if decisions & !amb != 0 {
                    continue;
                }
                let loops = loops_for(case as u8, decisions);
                assert!(loops.len() <= MAX_LOOPS);
                let mut e = Entry {
                    tri_start: t.tris.len() as u32,
                    loop_start: t.loop_edges.len() as u32,
                    loop_count: loops.len() as u8,
                    ..Entry::default()
                };
                for (i, l) in loops.iter().enumerate() {
                    assert!(l.len() <= MAX_LOOP_LEN);
                    e.loop_len[i] = l.len() as u8;
                    t.loop_edges.extend_from_slice(l);
                    match triangulate(l) {
                        Some(tris) => t.tris.extend(tris),
                        None => {
                            assert!(e.center_loop.is_none(), "one interior vertex per cube");
                            e.center_loop = Some(i as u8);
                            let n = l.len();
                            t.tris.extend((0..n).map(|k| [CENTER, l[k], l[(k + 1) % n]]));
                        }
                    }
                }
                e.tri_count = (t.tris.len() - e.tri_start as usize) as u8;
                if loops.len() == 2 {
                    e.caps_inside = caps_inside(case as u8, decisions);
                }
                if loops.len() == 3 {
                    e.path_end = path_ends(case as u8, decisions, &loops);
                }
                t.entries[case * 64 + decisions as usize] = e;
            }
        }
        t
    }
}

/// The table, built on first use. (Inlined: it is looked up for every cube, and the check
/// that it is built is one load and compare.)
#[inline]
pub fn table() -> &'static CaseTable {
    static TABLE: std::sync::OnceLock<CaseTable> = std::sync::OnceLock::new();
    TABLE.get_or_init(CaseTable::build)
}

#[cfg(test)]
mod tests {
    use super::super::cube::CORNERS;
    use super::*;

    fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }
    fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    }

    #[test]
    fn single_corner_gives_one_outward_triangle() {
        for (c, corner) in CORNERS.iter().enumerate() {
            let t = table();
            let e = t.entry(1 << c, 0);
            assert_eq!(e.loop_count, 1);
            let tris = t.triangles(e);
            assert_eq!(tris.len(), 1);
            let p = tris[0].map(|ed| edge_point(ed as usize, 0.5));
            let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            let away = sub(p[0], corner.map(|v| v as f64));
            let dot: f64 = (0..3).map(|i| n[i] * away[i]).sum();
            assert!(dot > 0.0, "corner {c}: normal must point away from the inside corner");
        }
    }

    #[test]
    fn complement_swaps_orientation_and_decisions() {
        // Flipping every sign turns inside-joined into outside-joined: same loops, reversed.
        let t = table();
        for case in 0..256usize {
            let amb = t.ambiguous[case];
            assert_eq!(amb, t.ambiguous[255 - case]);
            for d in 0..64usize {
                if d & !(amb as usize) != 0 {
                    continue;
                }
                let a = t.entry(case, d);
                let b = t.entry(255 - case, !d & amb as usize);
                assert_eq!(a.loop_count, b.loop_count, "case {case} decisions {d}");
                let mut ea: Vec<u8> = t.tris[a.tri_start as usize..][..a.tri_count as usize]
                    .iter()
                    .flatten()
                    .copied()
                    .collect();
                let mut eb: Vec<u8> = t.tris[b.tri_start as usize..][..b.tri_count as usize]
                    .iter()
                    .flatten()
                    .copied()
                    .collect();
                ea.sort();
                eb.sort();
                ea.dedup();
                eb.dedup();
                assert_eq!(ea, eb);
            }
        }
    }

    #[test]
    fn no_diagonal_joins_two_crossings_on_one_face() {
        let t = table();
        for case in 0..256usize {
            for d in 0..64usize {
                if d & !(t.ambiguous[case] as usize) != 0 {
                    continue;
                }
                let e = t.entry(case, d);
                for i in 0..e.loop_count as usize {
                    let l = t.loop_edges(e, i);
                    let sides: Vec<(u8, u8)> =
                        (0..l.len()).map(|k| (l[k], l[(k + 1) % l.len()])).collect();
                    let Some(tris) = triangulate(l) else {
                        assert_eq!(e.center_loop, Some(i as u8));
                        assert!(l.len() >= 8);
                        continue;
                    };
                    assert_eq!(tris.len(), l.len() - 2);
                    for tri in &tris {
                        for k in 0..3 {
                            let (a, b) = (tri[k], tri[(k + 1) % 3]);
                            let side = sides.contains(&(a, b)) || sides.contains(&(b, a));
                            assert!(side || !share_face(a, b), "case {case}: diagonal {a}-{b}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn every_crossing_is_on_exactly_one_loop() {
        let t = table();
        for case in 0..256usize {
            let crossings: Vec<u8> = (0..12u8)
                .filter(|&e| {
                    let [a, b] = EDGES[e as usize];
                    ((case >> a) & 1) != ((case >> b) & 1)
                })
                .collect();
            let e = t.entry(case, 0);
            let mut on_loops: Vec<u8> =
                (0..e.loop_count as usize).flat_map(|i| t.loop_edges(e, i).to_vec()).collect();
            on_loops.sort();
            assert_eq!(on_loops, crossings, "case {case}");
        }
    }
}
