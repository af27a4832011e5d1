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

    /// Sections, bisection, loop removal and vertices for one segment (lo → hi).
    pub(super) fn sample_edge(&mut self, lo: Key, hi: Key) -> Vec<Crossing> {
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
