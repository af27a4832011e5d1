//! Edge sampling: the regions at lattice points, and the crossings on each lattice segment
//! (the chapter's sections, each bisected to ε, looped pairs removed or kept), each crossing
//! a vertex shared by every tetrahedron on the segment.

use glam::DVec3;

use super::Run;
use super::faces::Walked;
use crate::lattice::cubes::Key;

#[derive(Clone, Copy, Debug)]
pub(super) struct Crossing {
    /// Regions before and after, in that direction.
    pub(super) from: u32,
    pub(super) to: u32,
    pub(super) vertex: u32,
}

impl Run<'_> {
    /// Regions at lattice points, cached.
    pub(super) fn lattice_regions(&mut self, keys: &[Key]) {
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
    pub(super) fn edge(&mut self, a: Key, b: Key) -> Vec<Walked> {
        let (lo, hi) = if a < b { (a, b) } else { (b, a) };
        if !self.edges.contains_key(&(lo, hi)) {
            let c = self.sample_edge(lo, hi);
            self.inner_bytes += crate::lattice::memory::vec_bytes(&c);
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

    /// Sections, bisection, loop removal and vertices for one segment (lo → hi). Without
    /// `Options::loops`, a segment whose ends lie in one region is not sectioned: what
    /// sectioning finds there is a surface poking in and out, a looped pair that would be
    /// dropped anyway, and sampling it was more than half of a run's evaluations.
    pub(super) fn sample_edge(&mut self, lo: Key, hi: Key) -> Vec<Crossing> {
        let (pa, pb) = (self.point(lo), self.point(hi));
        let (ra, rb) = (self.point_region[&lo], self.point_region[&hi]);
        let n = self.opts.sections as usize;
        if ra != rb {
            self.stats.conventional_evaluations += 8;
        }
        let len = (pb - pa).length();
        let tol = (2.0 * self.eps / len).max(f64::EPSILON);
        let mut found: Vec<(f64, u32, u32)> = Vec::new();
        if self.opts.loops {
            // Kept loops need every section: a surface poking through the edge between two
            // section points of one region is seen only there.
            let inner: Vec<DVec3> = (1..n).map(|i| pa.lerp(pb, i as f64 / n as f64)).collect();
            let mut rs = vec![ra];
            rs.extend(self.regions_of(&inner));
            rs.push(rb);
            for i in 0..n {
                if rs[i] != rs[i + 1] {
                    let (t0, t1) = (i as f64 / n as f64, (i + 1) as f64 / n as f64);
                    self.bisect(pa, pb, t0, rs[i], t1, rs[i + 1], 0, tol, &mut found);
                }
            }
        } else if ra != rb {
            self.sections(pa, pb, [0, n], [ra, rb], tol, &mut found);
        }
        if !found.is_empty() {
            self.inner_bytes += crate::lattice::memory::vec_bytes(&found);
            self.samples.insert((lo, hi), found.clone());
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

    /// The region at `p`, a point of the lattice segment that holds the edge vertex `at`, as
    /// the segment's sampling already says, without evaluating: the region between the
    /// crossings bisected on it (looped ones included) where `p` lies more than 1.5ε from
    /// every one of them (a bracket reaches ε either side). `None` where it does not say
    /// (`p` off the segment or near a crossing, `at` not an edge vertex). What the sampling
    /// missed between its samples (a region poking through between two of them) the
    /// contour follower's own evaluation would see; for the follower's first triangle, 2ε
    /// from the crossing beside the bisection's last samples, that is a sliver thinner than
    /// ε. Farther out it is not: taking the coarse strip's base (8ε out) from the samples
    /// too moved face vertices next to a sheet a hair off a lattice plane on the three-lobed
    /// leaf, and folded it there.
    pub(super) fn known_region(&self, at: u32, p: DVec3) -> Option<u32> {
        let &(lo, hi) = self.on_edge.get(&at)?;
        let (pa, pb) = (self.point(lo), self.point(hi));
        let d = pb - pa;
        let len2 = d.length_squared();
        let t = (p - pa).dot(d) / len2;
        let len = len2.sqrt();
        if !(0.0..=1.0).contains(&t) || (p - pa.lerp(pb, t)).length() > 1e-9 * len {
            return None;
        }
        let margin = 1.5 * self.eps / len;
        let mut region = *self.point_region.get(&lo)?;
        for &(tc, _, to) in self.samples.get(&(lo, hi))? {
            if (t - tc).abs() <= margin {
                return None;
            }
            if tc < t {
                region = to;
            }
        }
        Some(region)
    }

    /// The region at a point next to the edge vertex `at` on its segment: known from the
    /// segment's sampling where it says ([`Run::known_region`]), else evaluated.
    pub(super) fn region_beside(&mut self, at: u32, p: DVec3) -> u32 {
        match self.known_region(at, p) {
            Some(r) => r,
            None => self.region_at(p),
        }
    }

    /// The section changes between section points `i[0] < i[1]` (regions `r[0] != r[1]`),
    /// found by bisecting over the section points, each change then bisected within its
    /// section ([`Run::bisect`]).
    ///
    /// Why not sample every section point, as the chapter does: that costs `sections − 1`
    /// evaluations on every segment, most of them on segments with one crossing or none, and
    /// was most of the run's cost (five to eight times a conventional polygonizer's). The
    /// points this search visits are section points, and wherever the regions along the
    /// segment are each one interval (every region met once), it finds the same changing
    /// sections as sampling them all: the bracket always holds the run of regions between
    /// its ends, a sample in a third region splits it in two, and a bracket narrower than
    /// twice such a run must sample inside it. So the crossings, and the vertices bisected
    /// from them, are the same. What it can miss is a region met twice (a surface poking
    /// through and back between two samples of one region), which the chapter removes
    /// anyway as a looped pair unless `Options::loops` keeps it; with loops every section is
    /// sampled. A conventional polygonizer's single crossing costs the same four section
    /// levels and four refinements.
    fn sections(
        &mut self,
        pa: DVec3,
        pb: DVec3,
        i: [usize; 2],
        r: [u32; 2],
        tol: f64,
        out: &mut Vec<(f64, u32, u32)>,
    ) {
        let n = self.opts.sections as f64;
        if i[1] - i[0] == 1 {
            let (t0, t1) = (i[0] as f64 / n, i[1] as f64 / n);
            self.bisect(pa, pb, t0, r[0], t1, r[1], 0, tol, out);
            return;
        }
        let m = (i[0] + i[1]) / 2;
        let rm = self.region_at(pa.lerp(pb, m as f64 / n));
        if rm == r[0] {
            self.sections(pa, pb, [m, i[1]], [rm, r[1]], tol, out);
        } else if rm == r[1] {
            self.sections(pa, pb, [i[0], m], [r[0], rm], tol, out);
        } else {
            self.sections(pa, pb, [i[0], m], [r[0], rm], tol, out);
            self.sections(pa, pb, [m, i[1]], [rm, r[1]], tol, out);
        }
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn bisect(
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
}
