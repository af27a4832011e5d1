//! Faces: the crossings round each triangular lattice face paired off into disjoint lines,
//! and where they do not pair, the face vertex placed by the contour follower (and, with
//! `Options::loops`, the vertices of looped crossings).

use glam::DVec3;
use skelform_mesh::RegionPair;

use super::Run;
use crate::lattice::cubes::Key;
use crate::lattice::memory::vec_bytes;

/// A crossing met while walking a face boundary in one direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Walked {
    pub(super) vertex: u32,
    pub(super) from: u32,
    pub(super) to: u32,
}

#[derive(Clone, Debug, Default)]
pub(super) struct FaceInfo {
    /// Lines between two crossings (disjoint lines), with their pair.
    pub(super) lines: Vec<(u32, u32, RegionPair)>,
    /// Crossings joined to the face vertex, with their pair.
    pub(super) spokes: Vec<(u32, RegionPair)>,
    pub(super) face_vertex: Option<u32>,
    /// The regions meeting at the face vertex.
    pub(super) regions: Vec<u32>,
}

impl Run<'_> {
    /// Lines and the face vertex of a triangular face of lattice points.
    pub(super) fn face(&mut self, corners: [Key; 3]) -> FaceInfo {
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
        let kept = info.clone();
        self.inner_bytes +=
            vec_bytes(&kept.lines) + vec_bytes(&kept.spokes) + vec_bytes(&kept.regions);
        self.faces.insert(sorted, kept);
        info
    }

    /// The vertex of a loop on a face: the contour leaves the face's side at crossing `u`
    /// and comes back at `v`; follow it from `u` in small triangles (as for face vertices)
    /// until it returns to that side, and take the triangle centre farthest from the side.
    /// If the walk does not come back (the loop is thinner than the triangles), the vertex
    /// goes half the gap between the crossings into the face from their midpoint.
    pub(super) fn loop_vertex(&mut self, corners: [Key; 3], u: u32, v: u32) -> u32 {
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
    pub(super) fn face_vertex(
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
        // Every start into the face first; then every start the other way, for a crossing
        // within a triangle of a corner where the contour runs along the face's side (a wall
        // in the plane of that side, as a sheet on a lattice plane): there the first way can
        // lead off the face at once, and the contour lies the other way.
        for (pass, s) in [false, true].into_iter().flat_map(|p| starts.iter().map(move |s| (p, s)))
        {
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
            if inside(mid + w * side) == pass {
                w = -w;
            }
            let (rx, ry) = (self.region_at(px), self.region_at(py));
            let (x, y) = (s.from, s.to);
            if ![rx, ry].iter().all(|&r| r == x || r == y) {
                // The first triangle already has a corner in a third region (the crossing is
                // within 2ε of it along the edge): it is the final triangle.
                self.stats.face_vertices_at_crossing += 1;
                let apex = mid + w * side * 3f64.sqrt() * 0.5;
                return clamp((px + py + apex) / 3.0);
            }
            if !(rx == x && ry == y) {
                if !(rx == y && ry == x) {
                    continue;
                }
                std::mem::swap(&mut px, &mut py);
            }
            // Into the face, the coarse stride first; the fine strip from the crossing
            // when that fails, and for the other way (a few triangles at most).
            if !pass
                && let Some(p) =
                    self.coarse_then_fine(v, edge_dir, w, (x, y), side, max_steps, &outside)
            {
                return clamp(p);
            }
            let mut apex = mid + w * side * 3f64.sqrt() * 0.5;
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
}

/// How many times longer the sides of the contour follower's coarse triangles are than
/// its fine ones (a power of two: the coarse base is halved down to a fine side).
const COARSE: f64 = 4.0;

impl Run<'_> {
    /// The face vertex's contour walk in two strides: a strip of triangles [`COARSE`] times
    /// the fine side follows the contour (x, y) from the crossing at `v` (on a face side of
    /// direction `d`, the walk heading into the face along `w`) to the first triangle that
    /// meets a foreign region or leaves the face; its base, which straddles the contour,
    /// is bisected down to a fine side and the fine strip walks on from there to the
    /// foreign region, whose last triangle's centre is returned. `None` when the coarse
    /// start does not straddle the contour or the fine walk fails: the caller then walks
    /// the fine strip all the way, as before.
    ///
    /// Why: the fine strip's side is 4ε (a 64th of a cell), so reaching a meeting point
    /// half a face away took some fifty evaluations per face vertex, as much as sectioning
    /// every edge once cost. The coarse stride covers the way in a quarter of the steps and
    /// the fine one still ends at a fine triangle touching the foreign region, so the
    /// vertex is placed where the fine walk alone puts it, unless a foreign region touches
    /// the contour only between the coarse triangles' corners (a feature finer than a coarse
    /// side, 16ε, where the fine walk stops earlier).
    #[allow(clippy::too_many_arguments)]
    fn coarse_then_fine(
        &mut self,
        v: DVec3,
        d: DVec3,
        w: DVec3,
        (x, y): (u32, u32),
        side: f64,
        max_steps: usize,
        outside: &dyn Fn(DVec3) -> f64,
    ) -> Option<DVec3> {
        // The fine strip's lattice: its first triangle is (o, o + e1, o + e2). The coarse
        // triangles are made of its points (four fine sides to a coarse one), the first with
        // its base along the face side through the crossing, so the fine walk resumed on a
        // coarse base walks the same fine triangles as the fine walk from the crossing.
        let (e1, e2) = (d * side, d * side * 0.5 + w * side * 3f64.sqrt() * 0.5);
        let o = v - e1 * 0.5;
        let (mut px, mut py) = (o - e1 * (COARSE * 0.5), o + e1 * (COARSE * 0.5));
        let mut apex = px + e2 * COARSE;
        let (rx, ry) = (self.region_at(px), self.region_at(py));
        if (rx, ry) == (y, x) {
            std::mem::swap(&mut px, &mut py);
        } else if (rx, ry) != (x, y) {
            return None;
        }
        let coarse_steps = max_steps / COARSE as usize + 16;
        // The last few coarse triangles, newest last: each base straddles the contour.
        let mut trail: Vec<(DVec3, DVec3, DVec3)> = Vec::with_capacity(TRAIL);
        // The coarse strip stops at the face's sides: beyond them, where the fine strip may
        // still go a little way, the fine one decides.
        for _ in 0..coarse_steps {
            if outside(apex) > 0.0 {
                break;
            }
            if trail.len() == TRAIL {
                trail.remove(0);
            }
            trail.push((px, py, apex));
            let r = self.region_at(apex);
            if !flip_strip(r, x, y, &mut px, &mut py, &mut apex) {
                break;
            }
        }
        // Resume the fine strip on the last coarse base. Where the foreign region also
        // reaches into that base (the meeting point lies on it), resume on the one before:
        // the fine strip crosses every coarse base the contour crosses once, so it walks the
        // same fine triangles from there. Restarting from the crossing instead cost about
        // three times the evaluations, on over a quarter of the leaf's face vertices.
        'base: while let Some((mut px, mut py, apex)) = trail.pop() {
            let ahead = (apex - (px + py) * 0.5) / COARSE;
            while px.distance(py) > side * (1.0 + 1e-9) {
                let m = (px + py) * 0.5;
                match self.region_at(m) {
                    r if r == x => px = m,
                    r if r == y => py = m,
                    _ => continue 'base,
                }
            }
            let mut apex = (px + py) * 0.5 + ahead;
            for _ in 0..(4.0 * COARSE * COARSE) as usize * (TRAIL - trail.len()) + 16 {
                if outside(apex) > 2.0 * side {
                    return None;
                }
                let r = self.region_at(apex);
                if !flip_strip(r, x, y, &mut px, &mut py, &mut apex) {
                    return Some((px + py + apex) / 3.0);
                }
            }
            return None;
        }
        None
    }
}

/// How many coarse triangles back the fine strip may resume (see
/// [`Run::coarse_then_fine`]).
const TRAIL: usize = 3;

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
