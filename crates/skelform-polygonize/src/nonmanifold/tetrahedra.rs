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
    pub(super) fn tetrahedron(&mut self, t: [Key; 4]) {
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
}
