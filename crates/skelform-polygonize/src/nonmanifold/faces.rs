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

/// A face vertex: where contours of the face meet (a junction), with the crossings joined
/// to it.
#[derive(Clone, Debug, Default)]
pub(super) struct Hub {
    pub(super) vertex: u32,
    /// Crossings joined to the face vertex, with their pair.
    pub(super) spokes: Vec<(u32, RegionPair)>,
    /// The regions meeting at the face vertex, sorted: its curve's label.
    pub(super) regions: Vec<u32>,
}

#[derive(Clone, Debug, Default)]
pub(super) struct FaceInfo {
    /// Lines between two crossings (disjoint lines), between a crossing and a loop vertex,
    /// or between two face vertices (a contour joining two junctions of the face), with
    /// their pair.
    pub(super) lines: Vec<(u32, u32, RegionPair)>,
    /// The face vertices of interest, one per separate junction of the face's contours.
    pub(super) hubs: Vec<Hub>,
}

impl FaceInfo {
    /// Every pair drawn on the face (lines and spokes).
    pub(super) fn pairs(&self) -> impl Iterator<Item = RegionPair> + '_ {
        self.lines
            .iter()
            .map(|l| l.2)
            .chain(self.hubs.iter().flat_map(|h| h.spokes.iter().map(|s| s.1)))
    }
}

/// Where the contour follower got to ([`Run::follow`]): the face vertex's place, whether a
/// third region was already at the crossing's first triangle, and the region foreign to
/// the contour that it met there.
#[derive(Clone, Copy, Debug)]
struct End {
    at: DVec3,
    at_crossing: bool,
    foreign: u32,
}

/// Crossings left unpaired on a face, split into the junctions they run to (see
/// [`Run::junctions`]): each group with the point its contours were followed to, when known,
/// and the contours joining groups (group, group, pair).
struct Junctions {
    groups: Vec<(Vec<Walked>, Option<DVec3>)>,
    links: Vec<(usize, usize, RegionPair)>,
    /// For each link, which side of it lies which region: a direction across it within the
    /// face, from a point of the face on one side towards one on the other, and the region
    /// it points into ([`Run::orient`] winds the sheet's triangles on the link by it).
    sides: Vec<(DVec3, u32)>,
    /// Where the contour of each followed crossing (by its vertex) ended, and the foreign
    /// region it met there ([`Run::four_region_ends`]).
    ends: Vec<(u32, DVec3, u32)>,
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
            let split = self.junctions(sorted, unmatched, &mut info.lines);
            // A group gets a face vertex when one of its contours (or a contour to another
            // group) is of interest.
            let mut vertex_of: Vec<Option<u32>> = Vec::with_capacity(split.groups.len());
            for (gi, (group, end)) in split.groups.iter().enumerate() {
                let links: Vec<RegionPair> =
                    split.links.iter().filter(|l| l.0 == gi || l.1 == gi).map(|l| l.2).collect();
                let interesting: Vec<&Walked> = group
                    .iter()
                    .filter(|w| self.interesting(RegionPair::new(w.from, w.to)))
                    .collect();
                if interesting.is_empty() && !links.iter().any(|&p| self.interesting(p)) {
                    vertex_of.push(None);
                    continue;
                }
                let mut regions: Vec<u32> = group.iter().flat_map(|w| [w.from, w.to]).collect();
                regions.extend(links.iter().flat_map(|p| [p.0, p.1]));
                regions.sort_unstable();
                regions.dedup();
                let (p, followed) = match end {
                    Some(p) => (*p, None),
                    None => {
                        let starts = if interesting.is_empty() {
                            group.iter().collect()
                        } else {
                            interesting
                        };
                        self.face_vertex(sorted, group, &starts)
                    }
                };
                let split_four = if split.groups.len() == 1 {
                    self.four_region_split(group, followed)
                } else {
                    None
                };
                if let Some((mine, other, short)) = split_four {
                    let centre = |run: &Self, ws: &[Walked; 2]| {
                        ws.iter().map(|w| run.positions[w.vertex as usize]).sum::<DVec3>() * 0.5
                    };
                    let towards = (centre(self, &other) - centre(self, &mine)).normalize_or_zero();
                    let mut hub = |run: &mut Self, at: DVec3, ws: &[Walked; 2]| {
                        run.positions.push(at);
                        run.crossing.push(None);
                        run.stats.face_vertices += 1;
                        let v = run.positions.len() as u32 - 1;
                        let mut regions: Vec<u32> =
                            ws.iter().flat_map(|w| [w.from, w.to]).collect();
                        regions.extend([short.0, short.1]);
                        regions.sort_unstable();
                        regions.dedup();
                        info.hubs.push(Hub {
                            vertex: v,
                            spokes: ws
                                .iter()
                                .map(|w| (w.vertex, RegionPair::new(w.from, w.to)))
                                .collect(),
                            regions,
                        });
                        v
                    };
                    let found = four_region_ends(&split.ends, &mine, &other, self.eps);
                    let (pa, pb) =
                        found.unwrap_or((p - towards * self.eps, p + towards * self.eps));
                    let a = hub(self, pa, &mine);
                    let b = hub(self, pb, &other);
                    info.lines.push((a, b, short));
                    // The cap's triangles have no edge vertex of their pair to be wound
                    // by: give its first vertex the direction across the short contour,
                    // from one of its regions to the other, as an edge vertex has.
                    // Region r_k touches the face's sides between crossings k - 1 and k.
                    let side = |run: &Self, r: u32| {
                        let k = group.iter().position(|w| w.from == r).unwrap_or(0);
                        let before = group[(k + 3) % 4];
                        (run.positions[before.vertex as usize]
                            + run.positions[group[k].vertex as usize])
                            * 0.5
                    };
                    let across = side(self, short.1) - side(self, short.0);
                    let dir = across - towards * across.dot(towards);
                    let [fa, fb, fc] = sorted.map(|k| self.point(k));
                    let normal = (fb - fa).cross(fc - fa);
                    let by_spokes = found.and_then(|_| {
                        [(a, &mine), (b, &other)]
                            .into_iter()
                            .find_map(|(v, ws)| self.across_cap(v, a, b, normal, ws, short))
                    });
                    self.crossing[a as usize] = Some(by_spokes.unwrap_or((dir, short.0, short.1)));
                    vertex_of.push(Some(a));
                    continue;
                }
                self.positions.push(p);
                self.crossing.push(None);
                self.stats.face_vertices += 1;
                let v = self.positions.len() as u32 - 1;
                vertex_of.push(Some(v));
                info.hubs.push(Hub {
                    vertex: v,
                    spokes: group
                        .iter()
                        .map(|w| (w.vertex, RegionPair::new(w.from, w.to)))
                        .collect(),
                    regions,
                });
            }
            for (&(a, b, pair), &(across, region)) in split.links.iter().zip(&split.sides) {
                if let (Some(u), Some(v)) = (vertex_of[a], vertex_of[b]) {
                    info.lines.push((u, v, pair));
                    self.link_sides.insert((u.min(v), u.max(v)), (across, region, pair));
                }
            }
        }
        let kept = info.clone();
        self.inner_bytes += vec_bytes(&kept.lines)
            + vec_bytes(&kept.hubs)
            + kept.hubs.iter().map(|h| vec_bytes(&h.spokes) + vec_bytes(&h.regions)).sum::<u64>();
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
    ) -> (DVec3, Option<(Walked, u32)>) {
        for pass in [false, true] {
            for s in starts {
                if let Some(end) = self.follow(corners, s, pass) {
                    self.stats.face_vertices_at_crossing += usize::from(end.at_crossing);
                    return (end.at, Some((**s, end.foreign)));
                }
            }
        }
        self.stats.face_vertex_fallbacks += 1;
        let n = crossings.len() as f64;
        (crossings.iter().map(|w| self.positions[w.vertex as usize]).sum::<DVec3>() / n, None)
    }

    /// Which way a cap's short contour `a`–`b` (both ends at their junctions, see
    /// [`four_region_ends`]) is crossed, from the side of its junction `v` whose spokes go
    /// to the crossings `ws`: round a junction the two spokes and the cap part three
    /// regions, and the region between the cap and a spoke is the one that spoke's crossing
    /// has on the cap's side (`x.from` for the first, `y.to` for the second, the middle
    /// region `x.to = y.from` lying between the spokes). When the spokes leave on opposite
    /// sides of the cap's line within the face, the direction across it towards the second
    /// spoke's side goes from `x.from` to `y.to`, as an edge vertex's crossing does; `None`
    /// when they leave on one side (a contour too curved for its crossings to tell).
    ///
    /// Why: with the junctions more than 2ε apart, the direction between the regions'
    /// touching points on the face's sides, less its part along the cap, could be short
    /// and point either way (a slab's two regions touch the sides far from its end), and
    /// the cap's triangles were wound against their neighbours (inconsistent edges).
    fn across_cap(
        &self,
        v: u32,
        a: u32,
        b: u32,
        normal: DVec3,
        ws: &[Walked; 2],
        short: RegionPair,
    ) -> Option<(DVec3, u32, u32)> {
        let [x, y] = *ws;
        if x.to != y.from || RegionPair::new(x.from, y.to) != short {
            return None;
        }
        let p = |u: u32| self.positions[u as usize];
        let perp = normal.cross(p(b) - p(a)).normalize_or_zero();
        let (sx, sy) = (perp.dot(p(x.vertex) - p(v)), perp.dot(p(y.vertex) - p(v)));
        (sx * sy < 0.0).then(|| (perp * sy.signum(), x.from, y.to))
    }

    /// The two junctions of a face vertex of four regions, without following another
    /// contour: four regions r0..r3 round the face (crossing k from r_k to r_k+1) never
    /// meet at one point generically, but at two junctions joined by a short contour,
    /// (r0, r1, r2) and (r2, r3, r0) or (r3, r0, r1) and (r1, r2, r3). The contour that was
    /// followed (`followed`: from crossing `s`, it met `foreign`) says which: `s` and its
    /// neighbour towards `foreign` end at one junction, the other two crossings at the
    /// other. Only a way whose short contour is a cap (drawn, between two drawn sheets) is
    /// made; where the contour says the other way, or none was followed, the cap is made
    /// when it is the only way that is one. Returns the two groups of crossings (the first
    /// with `s`) and the short contour's pair, or `None` when the crossings do not go round
    /// four regions or no cap is made.
    ///
    /// Why: with one face vertex for all four, the two sheets on either side of a thin
    /// slab (where a leaf's vein reaches the margin, a few hundredths of a cell thick)
    /// ended at the same point on both faces of a tetrahedron and met along one line at a
    /// hairline angle, folded (issue 18). Two vertices ε either side of the followed end,
    /// towards the crossings of each, give the slab a cap, the short contour's sheet, which
    /// the sheets meet at an angle; the junctions' true distance is not sought, since that
    /// takes another walk along a contour (evaluations, issue 18's cost limit).
    fn four_region_split(
        &self,
        group: &[Walked],
        followed: Option<(Walked, u32)>,
    ) -> Option<([Walked; 2], [Walked; 2], RegionPair)> {
        if group.len() != 4 || (0..4).any(|k| group[k].to != group[(k + 1) % 4].from) {
            return None;
        }
        let mut regions: Vec<u32> = group.iter().map(|w| w.from).collect();
        regions.sort_unstable();
        regions.dedup();
        if regions.len() != 4 {
            return None;
        }
        let g = |k: usize| group[k % 4];
        let r = |k: usize| group[k % 4].from;
        // The two ways: (r0, r1, r2) and (r2, r3, r0) joined by (r0 | r2), or (r3, r0, r1)
        // and (r1, r2, r3) joined by (r3 | r1).
        let ways = [
            ([g(0), g(1)], [g(2), g(3)], RegionPair::new(r(0), r(2))),
            ([g(3), g(0)], [g(1), g(2)], RegionPair::new(r(3), r(1))),
        ];
        // A cap: the short contour is drawn and each junction keeps a drawn sheet beside
        // it, so the cap joins two sheets (the sides of a slab). Otherwise one junction
        // would end a lone sheet (a margin, a boundary where there was none), or the two
        // would be left apart with nothing between them (a slit).
        let drawn = |w: &Walked| self.interesting(RegionPair::new(w.from, w.to));
        let caps = ways.map(|(mine, other, short)| {
            self.interesting(short) && mine.iter().any(drawn) && other.iter().any(drawn)
        });
        // The way the followed contour says: from crossing i, meeting r_(i+2) it ends at
        // (r_i, r_i+1, r_i+2), meeting r_(i+3) at (r_i+3, r_i, r_i+1).
        let said = followed.and_then(|(s, foreign)| {
            let i = group.iter().position(|w| *w == s)?;
            if foreign == r(i + 2) {
                Some(i % 2)
            } else if foreign == r(i + 3) {
                Some((i + 1) % 2)
            } else {
                None
            }
        });
        // Where the contour says the way that is no cap, the cap is made all the same:
        // the junctions then lie closer than the follower's triangles can tell apart or
        // the slab pinches off on this face, and one face vertex for the four (as the
        // chapter has it) folds the slab's two sides onto each other.
        let way = match said {
            Some(w) if caps[w] => w,
            _ => (0..2).find(|&w| caps[w] && !caps[1 - w])?,
        };
        let (mut mine, mut other, short) = ways[way];
        // The first group holds the followed crossing (its junction is where it ended).
        if let Some((s, _)) = followed
            && other.contains(&s)
        {
            std::mem::swap(&mut mine, &mut other);
        }
        Some((mine, other, short))
    }

    /// One try of [`Run::face_vertex`]: the contour from the crossing `s` followed into the
    /// face (`back` false) or the other way, to where it meets a foreign region, moved at
    /// least 2ε into the face, and whether a third region was already at the first
    /// triangle; `None` when the walk does not get there.
    fn follow(&mut self, corners: [Key; 3], s: &Walked, back: bool) -> Option<End> {
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
        if inside(mid + w * side) == back {
            w = -w;
        }
        let (rx, ry) = (self.region_beside(s.vertex, px), self.region_beside(s.vertex, py));
        let (x, y) = (s.from, s.to);
        if ![rx, ry].iter().all(|&r| r == x || r == y) {
            // The first triangle already has a corner in a third region (the crossing is
            // within 2ε of it along the edge): it is the final triangle.
            let apex = mid + w * side * 3f64.sqrt() * 0.5;
            let foreign = if rx == x || rx == y { ry } else { rx };
            return Some(End { at: clamp((px + py + apex) / 3.0), at_crossing: true, foreign });
        }
        if !(rx == x && ry == y) {
            if !(rx == y && ry == x) {
                return None;
            }
            std::mem::swap(&mut px, &mut py);
        }
        // Into the face, the coarse stride first; the fine strip from the crossing
        // when that fails, and for the other way (a few triangles at most).
        if !back
            && let Some((p, foreign)) =
                self.coarse_then_fine(s.vertex, edge_dir, w, (x, y), side, max_steps, &outside)
        {
            return Some(End { at: clamp(p), at_crossing: false, foreign });
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
                return Some(End {
                    at: clamp((px + py + apex) / 3.0),
                    at_crossing: false,
                    foreign: r,
                });
            }
        }
        None
    }
}

impl Run<'_> {
    /// Splits the crossings that `pair_off` left on a face into the junctions their
    /// contours run to, beyond the chapter's one face vertex per face (its fig. 4.14 and
    /// future work): with one vertex, two junctions on one face (two curves leaving a
    /// tetrahedron through the same face, as near a point where four regions meet) were
    /// fused into one vertex of four regions, and the curves through it came out as short
    /// spurious pieces with a wrong label.
    ///
    /// With three crossings or fewer (one junction: the usual case) nothing is followed.
    /// With four, the region the first contour meets says which two junctions there can be
    /// (see below), and one contour of the other is followed; otherwise the contour from
    /// every crossing is followed to its junction. Crossings whose contours end within
    /// [`JUNCTION`] fine triangles of each other share one. A
    /// junction whose crossings are consecutive round the face and enclose one region
    /// (before the first and after the last) is separate: it is taken out, and what is left
    /// paired off again (a line may then join crossings that it separated). What is left at
    /// the end is one junction, or several when it falls into consecutive runs, one per
    /// junction: then contours join them (`linked_runs`: one between two, the sides of a
    /// polygon or a path between three or more). Anything else (a contour that cannot be
    /// followed, junctions interleaved round the face) keeps one face vertex for what is
    /// left, as the chapter does. One face vertex for three junctions had fused the three
    /// points where three walls cross a face near their common point into one of seven
    /// regions, and left a spurious short curve there.
    fn junctions(
        &mut self,
        corners: [Key; 3],
        mut unmatched: Vec<Walked>,
        lines: &mut Vec<(u32, u32, RegionPair)>,
    ) -> Junctions {
        let any_interest =
            unmatched.iter().any(|w| self.interesting(RegionPair::new(w.from, w.to)));
        if unmatched.len() < 4 || !any_interest || !self.opts.junctions {
            return Junctions {
                groups: vec![(unmatched, None)],
                links: Vec::new(),
                sides: Vec::new(),
                ends: Vec::new(),
            };
        }
        let n = unmatched.len();
        let near = JUNCTION * 4.0 * self.eps;
        // From a crossing of interest: where there is one junction, its vertex is where
        // that contour ends.
        let first = (0..n)
            .find(|&i| self.interesting(RegionPair::new(unmatched[i].from, unmatched[i].to)))
            .unwrap_or(0);
        unmatched.rotate_left(first);
        let follow = |run: &mut Self, i: usize| match run.follow(corners, &unmatched[i], false) {
            Some(p) => Some(p),
            None => run.follow(corners, &unmatched[i], true),
        };
        let mut found: Vec<Option<End>> = vec![None; n];
        found[0] = follow(self, 0);
        // Four crossings, of four regions r0..r3 round the face, meet at one junction or at
        // two: (r0, r1, r2) and (r2, r3, r0), or (r3, r0, r1) and (r1, r2, r3). The region
        // the first contour (r0 | r1) meets says which pair it is, so the contour of the
        // other junction is the only other one followed: its end is the second vertex, or
        // the same point when all four meet there.
        let to = |i: usize| unmatched[i % n].to;
        let from = |i: usize| unmatched[i % n].from;
        let pairing = match found[0] {
            Some(e) if n == 4 && e.foreign == to(1) => Some(0),
            Some(e) if n == 4 && e.foreign == from(3) => Some(3),
            _ => None,
        };
        let mut followed = vec![true; n];
        if let Some(j) = pairing {
            // The crossings j and j + 1 (0 and its partner p) meet at found[0]; q = j + 2
            // and j + 3 where the contour of q ends, which must meet the region after j + 3.
            let (p, q) = (if j == 0 { 1 } else { 3 }, (j + 2) % 4);
            found[p] = found[0];
            found[q] = follow(self, q);
            if found[q].is_some_and(|e| e.foreign == to(q + 1)) {
                found[(q + 1) % 4] = found[q];
            } else {
                found[(q + 1) % 4] = follow(self, (q + 1) % 4);
                followed[p] = false;
            }
        }
        for i in 1..n {
            if pairing.is_none() || !followed[i] {
                found[i] = follow(self, i);
            }
        }
        let followed_ends: Vec<(u32, DVec3, u32)> = (0..n)
            .filter_map(|i| found[i].map(|e| (unmatched[i].vertex, e.at, e.foreign)))
            .collect();
        let ends: Vec<Option<DVec3>> = found.iter().map(|f| f.map(|e| e.at)).collect();
        // Single linkage of the ends closer than JUNCTION fine triangles.
        let mut cluster: Vec<usize> = (0..n).collect();
        for i in 0..n {
            for j in i + 1..n {
                if let (Some(p), Some(q)) = (ends[i], ends[j])
                    && p.distance(q) < near
                {
                    let (ci, cj) = (cluster[i], cluster[j]);
                    for c in cluster.iter_mut() {
                        if *c == cj {
                            *c = ci;
                        }
                    }
                }
            }
        }
        let cluster: Vec<Option<usize>> = (0..n).map(|i| ends[i].map(|_| cluster[i])).collect();
        let mean = |members: &[usize]| {
            members.iter().filter_map(|&i| ends[i]).sum::<DVec3>() / members.len() as f64
        };
        let mut groups: Vec<(Vec<Walked>, Option<DVec3>)> = Vec::new();
        let mut ring: Vec<usize> = (0..n).collect();
        while let Some(run) = closed_run(&ring, &cluster, &unmatched) {
            let members: Vec<usize> = run.iter().map(|&k| ring[k]).collect();
            groups.push((members.iter().map(|&i| unmatched[i]).collect(), Some(mean(&members))));
            let rest: Vec<Walked> =
                ring.iter().filter(|i| !members.contains(i)).map(|&i| unmatched[i]).collect();
            let left = pair_off(&rest, lines);
            ring.retain(|&i| left.iter().any(|w| w.vertex == unmatched[i].vertex));
        }
        if ring.is_empty() {
            return Junctions { groups, links: Vec::new(), sides: Vec::new(), ends: followed_ends };
        }
        // What is left: junctions each of one run of consecutive crossings, joined by
        // contours (see `linked_runs`), or one junction.
        if let Some(runs) = runs(&ring, &cluster) {
            let members: Vec<Vec<usize>> =
                runs.iter().map(|run| run.iter().map(|&k| ring[k]).collect()).collect();
            let centre = (members.len() > 2)
                .then(|| members.iter().map(|m| mean(m)).sum::<DVec3>() / members.len() as f64);
            let inside = centre.map(|c| self.region_at(c));
            let walked: Vec<Vec<Walked>> =
                members.iter().map(|m| m.iter().map(|&i| unmatched[i]).collect()).collect();
            if let Some(links) = linked_runs(&walked, inside) {
                // The region a link's first run is followed by touches the face's sides
                // between that run's last crossing and the next run's first: the link has it
                // on the side of a point of the boundary between them (their midpoint when
                // they lie on one side of the face, else the corner that ends the first
                // one's side), and on the other side the region across (the other gap
                // between two runs, or the polygon's inside at its centre).
                let [ca, cb, cc] = corners.map(|k| self.point(k));
                let walk = [(ca, cb), (cb, cc), (cc, ca)];
                let off = |p: DVec3, i: usize| {
                    let (q0, q1) = walk[i];
                    (p - q0).cross((q1 - q0).normalize()).length()
                };
                let side_of =
                    |p: DVec3| (0..3).min_by(|&i, &j| off(p, i).total_cmp(&off(p, j))).unwrap_or(0);
                let at = |i: usize| self.positions[unmatched[i].vertex as usize];
                let gap = |i: usize, j: usize| {
                    let (last, first) = (members[i][members[i].len() - 1], members[j][0]);
                    let (p0, p1) = (at(last), at(first));
                    let s0 = side_of(p0);
                    let (q0, q1) = walk[s0];
                    let between = if s0 == side_of(p1) && (p1 - p0).dot(q1 - q0) > 0.0 {
                        (p0 + p1) * 0.5
                    } else {
                        q1
                    };
                    (between, unmatched[last].to)
                };
                let sides = links
                    .iter()
                    .map(|&(a, b, _)| {
                        let (p, r) = gap(a, b);
                        let q = match centre {
                            Some(c) => c,
                            None => gap(b, a).0,
                        };
                        (p - q, r)
                    })
                    .collect();
                let base = groups.len();
                for (m, w) in members.iter().zip(walked) {
                    groups.push((w, Some(mean(m))));
                }
                let links = links.into_iter().map(|(a, b, p)| (base + a, base + b, p)).collect();
                return Junctions { groups, links, sides, ends: followed_ends };
            }
        }
        // One junction: its vertex where the first contour of interest that was followed
        // ends (as the chapter's follower puts it), not followed again.
        let end = ring
            .iter()
            .filter(|&&i| {
                let w = unmatched[i];
                self.interesting(RegionPair::new(w.from, w.to))
            })
            .find_map(|&i| found[i]);
        if let Some(e) = end
            && e.at_crossing
        {
            self.stats.face_vertices_at_crossing += 1;
        }
        groups.push((ring.iter().map(|&i| unmatched[i]).collect(), end.map(|e| e.at)));
        Junctions { groups, links: Vec::new(), sides: Vec::new(), ends: followed_ends }
    }
}

/// The two junctions of a face vertex of four regions split in two
/// ([`Run::four_region_split`]), where the contours followed to find them say where they
/// are: each pair of crossings' contours ended at its junction (meeting the pair's third
/// region, within a fine triangle of each other when both were followed), and the two
/// junctions lie more than 2ε apart. `None` otherwise (the split then puts its vertices ε
/// either side of the one end known).
///
/// Why: junctions closer than [`JUNCTION`] fine triangles are one group, so a slab up to a
/// sixteenth of a cell thick ending at the margin had both ends of its cap put ε either
/// side of one of them; on a face cutting the slab obliquely the other end lay ten ε or
/// more off its curve, and the cap's triangles folded onto the slab's side along it. The
/// ends are already known (no more evaluations), only not used.
fn four_region_ends(
    ends: &[(u32, DVec3, u32)],
    mine: &[Walked; 2],
    other: &[Walked; 2],
    eps: f64,
) -> Option<(DVec3, DVec3)> {
    let junction = |ws: &[Walked; 2]| {
        let mut regions: Vec<u32> = ws.iter().flat_map(|w| [w.from, w.to]).collect();
        regions.sort_unstable();
        regions.dedup();
        let at: Vec<DVec3> = ws
            .iter()
            .filter_map(|w| {
                let &(_, p, foreign) = ends.iter().find(|e| e.0 == w.vertex)?;
                let third = foreign != w.from && foreign != w.to && regions.contains(&foreign);
                third.then_some(p)
            })
            .collect();
        match at[..] {
            [p] => Some(p),
            [p, q] if p.distance(q) < 4.0 * eps => Some((p + q) * 0.5),
            _ => None,
        }
    };
    let (a, b) = (junction(mine)?, junction(other)?);
    (a.distance(b) > 2.0 * eps).then_some((a, b))
}

/// Fine triangles within which followed contour ends are one junction ([`Run::junctions`]):
/// the follower stops within about one fine triangle of the junction it reaches, so four
/// leave room for its error; two junctions closer than that (a sixteenth of a cell at
/// the default ε) stay one face vertex.
const JUNCTION: f64 = 4.0;

/// A junction that can be taken out of a face's ring of unpaired crossings (positions in
/// `ring`, which holds indices into `walked`): all the crossings of one cluster, at least
/// three, consecutive round the ring but not the whole of it, with one region before the
/// first and after the last.
fn closed_run(ring: &[usize], cluster: &[Option<usize>], walked: &[Walked]) -> Option<Vec<usize>> {
    let len = ring.len();
    for start in 0..len {
        let Some(c) = cluster[ring[start]] else { continue };
        // Start at the first of a run: the one before belongs to another cluster.
        if cluster[ring[(start + len - 1) % len]] == Some(c) {
            continue;
        }
        let run: Vec<usize> = (0..len)
            .map(|k| (start + k) % len)
            .take_while(|&k| cluster[ring[k]] == Some(c))
            .collect();
        let total = ring.iter().filter(|&&i| cluster[i] == Some(c)).count();
        if run.len() >= 3 && run.len() == total && run.len() < len {
            let (first, last) = (walked[ring[run[0]]], walked[ring[run[run.len() - 1]]]);
            if first.from == last.to {
                return Some(run);
            }
        }
    }
    None
}

/// The ring (positions) as two or more consecutive runs, one per cluster, every crossing's
/// contour followed.
fn runs(ring: &[usize], cluster: &[Option<usize>]) -> Option<Vec<Vec<usize>>> {
    let len = ring.len();
    if len < 2 || ring.iter().any(|&i| cluster[i].is_none()) {
        return None;
    }
    // The first position whose predecessor is in another cluster.
    let start = (0..len).find(|&k| cluster[ring[k]] != cluster[ring[(k + len - 1) % len]])?;
    let mut runs: Vec<Vec<usize>> = Vec::new();
    for k in (0..len).map(|k| (start + k) % len) {
        match runs.last_mut() {
            Some(run) if cluster[ring[run[0]]] == cluster[ring[k]] => run.push(k),
            _ => runs.push(vec![k]),
        }
    }
    let mut seen: Vec<Option<usize>> = runs.iter().map(|r| cluster[ring[r[0]]]).collect();
    seen.sort_unstable();
    seen.dedup();
    (seen.len() == runs.len()).then_some(runs)
}

/// The contours joining junctions that each hold one run of consecutive crossings round a
/// face (`runs`, in ring order), as (run, run, pair); `None` when the runs do not make such
/// a picture. Between the last crossing of a run and the first of the next lies a region
/// that touches the face's side there; inside the face it is bounded by a contour between
/// the two junctions. Two junctions: one contour, between the regions on either side.
/// Three or more: the junctions are the corners of a polygon of contours round the region
/// `inside` (asked at their centre). Where that is a region of none of the crossings (an
/// enclosed region, as where three walls cross near a face), every side of the polygon is a
/// contour between it and the region outside that side; where it is the region between two
/// runs (the junctions lie on a path), that side is missing and the others border it. Each
/// junction must have three contours at least.
fn linked_runs(
    runs: &[Vec<Walked>],
    inside: Option<u32>,
) -> Option<Vec<(usize, usize, RegionPair)>> {
    let k = runs.len();
    // The region after each run, which is the one before the next.
    let after: Vec<u32> = runs.iter().map(|r| r[r.len() - 1].to).collect();
    let links: Vec<(usize, usize, RegionPair)> = match inside {
        None if k == 2 && after[0] != after[1] => {
            vec![(0, 1, RegionPair::new(after[0], after[1]))]
        }
        Some(c) if k > 2 => {
            let on_side = after.iter().filter(|&&a| a == c).count();
            let elsewhere =
                runs.iter().flatten().any(|w| (w.from == c || w.to == c) && !after.contains(&c));
            if on_side > 1 || elsewhere {
                return None;
            }
            (0..k)
                .filter(|&i| after[i] != c)
                .map(|i| (i, (i + 1) % k, RegionPair::new(after[i], c)))
                .collect()
        }
        _ => return None,
    };
    let degree = |i: usize| runs[i].len() + links.iter().filter(|l| l.0 == i || l.1 == i).count();
    (0..k).all(|i| degree(i) >= 3).then_some(links)
}

/// How many times longer the sides of the contour follower's coarse triangles are than
/// its fine ones (a power of two: the coarse base is halved down to a fine side).
const COARSE: f64 = 4.0;

impl Run<'_> {
    /// The face vertex's contour walk in two strides: a strip of triangles [`COARSE`] times
    /// the fine side follows the contour (x, y) from the crossing `at` (on a face side of
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
        at: u32,
        d: DVec3,
        w: DVec3,
        (x, y): (u32, u32),
        side: f64,
        max_steps: usize,
        outside: &dyn Fn(DVec3) -> f64,
    ) -> Option<(DVec3, u32)> {
        // The fine strip's lattice: its first triangle is (o, o + e1, o + e2). The coarse
        // triangles are made of its points (four fine sides to a coarse one), the first with
        // its base along the face side through the crossing, so the fine walk resumed on a
        // coarse base walks the same fine triangles as the fine walk from the crossing.
        let v = self.positions[at as usize];
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
                    return Some(((px + py + apex) / 3.0, r));
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

    #[test]
    fn three_junctions_round_an_enclosed_region_are_joined_as_a_triangle() {
        // Three walls crossing near a face: each junction has two crossings, the regions
        // 10, 11, 12 lie between the runs, 20, 21, 22 in them, and 7 is enclosed.
        let runs = vec![
            vec![w(0, 10, 20), w(1, 20, 11)],
            vec![w(2, 11, 21), w(3, 21, 12)],
            vec![w(4, 12, 22), w(5, 22, 10)],
        ];
        let links = linked_runs(&runs, Some(7)).unwrap();
        assert_eq!(
            links,
            vec![
                (0, 1, RegionPair::new(11, 7)),
                (1, 2, RegionPair::new(12, 7)),
                (2, 0, RegionPair::new(10, 7))
            ]
        );
        // The centre in a region of a run's own crossings: no such picture.
        assert_eq!(linked_runs(&runs, Some(21)), None);
    }

    #[test]
    fn junctions_on_a_path_miss_the_side_across_the_region_they_border() {
        // Three junctions of three regions on a path, all bordering region 12 (between the
        // last run and the first): the middle one has one crossing and two contours.
        let runs = vec![
            vec![w(0, 12, 20), w(1, 20, 10)],
            vec![w(2, 10, 11)],
            vec![w(3, 11, 21), w(4, 21, 12)],
        ];
        let links = linked_runs(&runs, Some(12)).unwrap();
        assert_eq!(links, vec![(0, 1, RegionPair::new(10, 12)), (1, 2, RegionPair::new(11, 12))]);
        // Two junctions: one contour between the regions on either side.
        let two = vec![vec![w(0, 1, 2), w(1, 2, 3)], vec![w(2, 3, 4), w(3, 4, 1)]];
        assert_eq!(linked_runs(&two, None), Some(vec![(0, 1, RegionPair::new(3, 1))]));
        // A junction of one crossing and one contour is not one.
        let thin = vec![vec![w(0, 1, 2)], vec![w(1, 2, 3), w(2, 3, 1)]];
        assert_eq!(linked_runs(&thin, None), None);
    }

    #[test]
    fn runs_need_every_cluster_in_one_piece() {
        let ring: Vec<usize> = (0..6).collect();
        let c = |v: [usize; 6]| v.map(Some).to_vec();
        let r = runs(&ring, &c([0, 0, 1, 1, 2, 2])).unwrap();
        assert_eq!(r.len(), 3);
        // A run wrapping round the ring's start is one run.
        assert_eq!(runs(&ring, &c([0, 1, 1, 2, 2, 0])).unwrap().len(), 3);
        // Interleaved clusters are not runs.
        assert_eq!(runs(&ring, &c([0, 1, 0, 1, 2, 2])), None);
    }
}
