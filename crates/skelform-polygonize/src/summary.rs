//! What each polygonizer's statistics say to a person: the warnings a user should see even
//! without asking for statistics, a why-is-it-empty hint, and the text report.
//!
//! Kept beside the data, not in a front end, so that the command line, the studio and the
//! Python package say the same things without knowing which method ran. Serialization of the
//! same data (the `serde` feature) is derived on the `Stats` types themselves.

use std::fmt;
use std::time::Duration;

use skelform_field::DVec3;

use crate::continuation::{self, SeedNote, Stop};
use crate::healed::{self, PointKind};
use crate::{grid, nonmanifold};

/// Serializes a duration as seconds (a float), as every consumer of the JSON wants it.
#[cfg(feature = "serde")]
pub(crate) fn seconds<S: serde::Serializer>(d: &Duration, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_f64(d.as_secs_f64())
}

/// Triangles per region pair as `[{"pair": [a, b], "triangles": n}, …]`.
#[cfg(feature = "serde")]
pub(crate) fn surfaces<S: serde::Serializer>(
    v: &[(skelform_mesh::RegionPair, usize)],
    s: S,
) -> Result<S::Ok, S::Error> {
    #[derive(serde::Serialize)]
    struct Surface {
        pair: [u32; 2],
        triangles: usize,
    }
    s.collect_seq(v.iter().map(|(p, n)| Surface { pair: [p.0, p.1], triangles: *n }))
}

/// Curve lengths per region triple as `[{"regions": [a, b, c], "length": l}, …]`.
#[cfg(feature = "serde")]
pub(crate) fn curves<S: serde::Serializer>(
    v: &[(skelform_mesh::RegionTriple, f64)],
    s: S,
) -> Result<S::Ok, S::Error> {
    #[derive(serde::Serialize)]
    struct Curve {
        regions: [u32; 3],
        length: f64,
    }
    s.collect_seq(v.iter().map(|(t, l)| Curve { regions: t.0, length: *l }))
}

fn secs(d: Duration) -> f64 {
    d.as_secs_f64()
}

fn point(p: DVec3) -> String {
    format!("({}, {}, {})", p.x, p.y, p.z)
}

/// A computed point to a millionth (the numerical noise of a solve below that is not news).
fn at(p: DVec3) -> String {
    let r = |v: f64| {
        let x = (v * 1e6).round() / 1e6;
        if x == 0.0 { 0.0 } else { x }
    };
    format!("({}, {}, {})", r(p.x), r(p.y), r(p.z))
}

/// The part of an empty run's explanation that the samples give. Non-finite samples are
/// stored as ±`f32::MAX`, so the range alone would report a NaN field as "values from
/// 3.4e38 to 3.4e38".
fn all_samples(samples: u64, non_finite: u64, min: f32, max: f32) -> String {
    if non_finite >= samples {
        return format!(
            "all {samples} samples are NaN or infinite (the field is undefined over the whole domain)"
        );
    }
    let where_ = if min >= 0.0 { "outside (f ≥ 0)" } else { "inside (f < 0)" };
    let range = if non_finite > 0 {
        format!("{non_finite} of them NaN or infinite")
    } else {
        format!("values from {min} to {max}")
    };
    format!("all {samples} samples are {where_}, {range}")
}

fn non_finite(count: u64, what: &str, w: &mut Vec<String>) {
    if count > 0 {
        w.push(format!("{count} {what} were NaN or infinite (treated as outside/inside)"));
    }
}

impl grid::Stats {
    /// Things a user should know even without the statistics.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        non_finite(self.non_finite_samples, "samples", &mut w);
        w
    }

    /// Why a run made no triangles, and what to look at.
    pub fn no_surface(&self) -> String {
        format!(
            "no surface in the domain: {}; check the formula, the iso value and the domain box",
            all_samples(self.samples, self.non_finite_samples, self.min_sample, self.max_sample)
        )
    }
}

impl fmt::Display for grid::Stats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [nx, ny, nz] = self.grid_dims;
        writeln!(f, "grid          {nx} × {ny} × {nz} samples, cell {:.6}", self.cell)?;
        if self.streamed {
            writeln!(
                f,
                "samples       {} (streamed in slabs: a layer between slabs run on different threads is sampled twice)",
                self.samples
            )?;
        } else {
            writeln!(f, "samples       {}", self.samples)?;
        }
        writeln!(
            f,
            "evaluations   {} (samples {}, root finding {}, normals {})",
            self.evaluations(),
            self.samples,
            self.refine_evaluations,
            self.normal_evaluations
        )?;
        writeln!(
            f,
            "ambiguous     {} faces decided, {} interior tunnels",
            self.ambiguous_faces, self.tunnels
        )?;
        writeln!(f, "vertices      {}", self.vertices)?;
        writeln!(f, "triangles     {}", self.triangles)?;
        writeln!(
            f,
            "time          sampling {:.3}s, extraction {:.3}s, refinement {:.3}s, normals {:.3}s",
            secs(self.sampling),
            secs(self.extraction),
            secs(self.refinement),
            secs(self.normals),
        )
    }
}

fn stop_warning(stop: Stop) -> &'static str {
    match stop {
        Stop::Domain => "propagation reached the domain box; the mesh is open there",
        Stop::Budget => {
            "propagation ran out of cells (--max-cells); the mesh is open where it stopped"
        }
        Stop::Limit => "propagation reached its limit (--limit); the mesh is open there",
    }
}

impl continuation::Stats {
    /// Things a user should know even without the statistics: where the mesh is open, and
    /// seeds that found nothing.
    pub fn warnings(&self) -> Vec<String> {
        let mut w: Vec<String> = self.stops.iter().map(|s| stop_warning(*s).to_string()).collect();
        for n in &self.seed_notes {
            if let SeedNote::NoSurface { seed } = n {
                w.push(format!("seed {} found no surface", point(*seed)));
            }
        }
        non_finite(self.non_finite, "corner values", &mut w);
        if self.tetra_disagreements > 0 {
            let first = self.first_disagreement.map(|p| format!(" (the first at {})", at(p)));
            w.push(format!(
                "{} cubes split into tetrahedra join corners the cube method separates (or separate corners it joins){}: \
                 walls or tubes thinner than a cell's diagonal may be cut through or pinched off, so the topology can \
                 differ from --method continuation's; use it, or a smaller cell",
                self.tetra_disagreements,
                first.unwrap_or_default()
            ));
        }
        w
    }

    /// Why a run made no triangles, and what to look at.
    pub fn no_surface(&self) -> String {
        "propagation from the seeds made no triangles; check the seeds and the cell size".into()
    }
}

impl fmt::Display for continuation::Stats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "cell          {:.6}", self.cell)?;
        writeln!(
            f,
            "evaluations   {} (corners {}, search {}, root finding {}, normals {})",
            self.evaluations(),
            self.corner_evaluations,
            self.search_evaluations,
            self.refine_evaluations,
            self.normal_evaluations
        )?;
        writeln!(f, "cells         {} visited", self.cells_visited)?;
        if self.tetra_disagreements > 0 {
            writeln!(
                f,
                "tetrahedra    {} cubes join corners unlike the cube method",
                self.tetra_disagreements
            )?;
        }
        writeln!(f, "components    {}", self.components.len())?;
        for (i, c) in self.components.iter().enumerate().take(10) {
            writeln!(
                f,
                "  #{i}  seed {}  {} cells  {} triangles",
                point(c.seed),
                c.cells,
                c.triangles
            )?;
        }
        let stops: Vec<&str> = self
            .stops
            .iter()
            .map(|s| match s {
                Stop::Domain => "domain box",
                Stop::Budget => "cell budget",
                Stop::Limit => "propagation limit",
            })
            .collect();
        writeln!(
            f,
            "stopped by    {}",
            if stops.is_empty() { "nothing (closed)".to_string() } else { stops.join(", ") }
        )?;
        writeln!(f, "vertices      {}", self.vertices)?;
        writeln!(f, "triangles     {}", self.triangles)?;
        writeln!(
            f,
            "time          search {:.3}s, propagation {:.3}s, refinement {:.3}s, normals {:.3}s",
            secs(self.search),
            secs(self.propagation),
            secs(self.refinement),
            secs(self.normals),
        )
    }
}

impl nonmanifold::Stats {
    /// Things a user should know even without the statistics: where the surfaces are open,
    /// and face vertices the contour follower did not reach.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if self.reached_domain {
            w.push("surfaces reach the domain box; the mesh is open there".into());
        }
        if self.reached_budget {
            w.push(stop_warning(Stop::Budget).into());
        }
        if self.face_vertex_fallbacks > 0 {
            w.push(format!(
                "{} of {} face vertices were not reached by the contour follower (placed at the mean of the face's crossings)",
                self.face_vertex_fallbacks, self.face_vertices
            ));
        }
        w
    }

    /// Why a run made no triangles, and what to look at.
    pub fn no_surface(&self) -> String {
        "the regions of interest make no triangles; check [regions], its interest pairs and the seeds"
            .into()
    }
}

impl fmt::Display for nonmanifold::Stats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "cell          {:.6} (ε {:.3e})", self.cell, self.epsilon)?;
        writeln!(
            f,
            "evaluations   {} of the region function (a conventional polygonizer: about {})",
            self.region_evaluations, self.conventional_evaluations
        )?;
        writeln!(f, "cells         {} visited", self.cells_visited)?;
        writeln!(
            f,
            "vertices      {} ({} on edges, {} on faces, {} inside tetrahedra; {} merged)",
            self.vertices,
            self.edge_vertices,
            self.face_vertices,
            self.internal_vertices,
            self.merged_vertices
        )?;
        writeln!(
            f,
            "post-process  {} merged, {} snapped onto edges, {} triangles dropped, {} curve corners sharpened",
            self.merged_vertices,
            self.snapped_to_edges,
            self.dropped_triangles,
            self.sharpened_corners
        )?;
        writeln!(
            f,
            "face vertices {} by the contour follower, {} at a crossing, {} fallbacks; {} normals from gradients",
            self.face_vertices - self.face_vertices_at_crossing - self.face_vertex_fallbacks,
            self.face_vertices_at_crossing,
            self.face_vertex_fallbacks,
            self.gradient_normals
        )?;
        writeln!(f, "triangles     {}", self.triangles)?;
        for (p, n) in &self.triangles_per_pair {
            writeln!(f, "  surface {}_{}  {n} triangles", p.0, p.1)?;
        }
        for (t, l) in &self.curve_length_per_triple {
            writeln!(f, "  curve {t}  length {l:.4}")?;
        }
        writeln!(f, "time          {:.3}s", secs(self.time))
    }
}

fn point_kind(k: PointKind) -> &'static str {
    match k {
        PointKind::Cone => "cone apex",
        PointKind::Isolated => "isolated point",
        PointKind::Pinch => "pinch point",
        PointKind::Triple => "triple point",
        PointKind::Degenerate => "degenerate point",
    }
}

impl healed::Stats {
    /// Things a user should know even without the statistics: self-intersections left
    /// unhealed, and parts of the zero set that no sign change shows (reported, not meshed).
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        non_finite(self.non_finite_samples, "samples", &mut w);
        for u in &self.unresolved {
            w.push(format!(
                "a self-intersection near {} was not healed ({} cubes kept as marching cubes made them): {}",
                at(u.center),
                u.cubes,
                u.reason
            ));
        }
        for l in &self.singular_lines {
            let (a, b) = (l.points[0], l.points[l.points.len() - 1]);
            w.push(format!(
                "the zero set is a bare line from {} to {} (length {:.4}): reported, not meshed",
                at(a),
                at(b),
                l.length
            ));
        }
        for p in &self.singular_points {
            if matches!(p.kind, PointKind::Isolated | PointKind::Degenerate) {
                w.push(format!(
                    "{} at {}: reported, not meshed",
                    point_kind(p.kind),
                    at(p.position)
                ));
            }
        }
        w
    }

    /// Why a run made no triangles, and what to look at.
    pub fn no_surface(&self) -> String {
        let found = if self.singular_lines.is_empty() && self.singular_points.is_empty() {
            String::new()
        } else {
            format!(
                "; the zero set is there but never changes sign ({} bare lines, {} points, see --stats), \
                 which no sign-based method can mesh",
                self.singular_lines.len(),
                self.singular_points.len()
            )
        };
        format!(
            "no surface in the domain: {}{found}; check the formula, the iso value and the domain box",
            all_samples(self.samples, self.non_finite_samples, self.min_sample, self.max_sample)
        )
    }
}

impl fmt::Display for healed::Stats {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [nx, ny, nz] = self.grid_dims;
        writeln!(f, "grid          {nx} × {ny} × {nz} samples, cell {:.6}", self.cell)?;
        writeln!(f, "samples       {}", self.samples)?;
        writeln!(
            f,
            "evaluations   {} (samples {}, root finding {}, normals {}, critical test {}, singular search {})",
            self.evaluations(),
            self.samples,
            self.refine_evaluations,
            self.normal_evaluations,
            self.critical_evaluations,
            self.search_evaluations
        )?;
        let c = &self.critical_cubes;
        writeln!(
            f,
            "critical      {} vertices; {} cubes (class 10: {}, class 12: {}, class 13: {}, other: {})",
            self.critical_vertices,
            c.total(),
            c.class10,
            c.class12,
            c.class13,
            c.other
        )?;
        if self.mode == healed::Healing::Thesis {
            writeln!(
                f,
                "healing       thesis (per cube): {} critical class 10/12/13 cubes replaced, {} face points, \
                 {} coincident-vertex triangles skipped",
                self.healed_cubes, self.face_points, self.skipped_triangles
            )?;
        } else {
            writeln!(
                f,
                "search        {} thesis face points (class 10/12/13 faces), {} seeds tried",
                self.face_points, self.seeds_tried
            )?;
        }
        // The thesis's table: "triangles by standard MC: …; by HMC: … (correct triangles by
        // MC …, triangles used for healing the critical cubes …)".
        writeln!(
            f,
            "triangles     standard MC {}; HMC {} (kept MC {}, healing {})",
            self.mc_triangles, self.triangles, self.kept_mc_triangles, self.healing_triangles
        )?;
        if self.mode == healed::Healing::Thesis {
            writeln!(
                f,
                "spines        {} self-intersection segments (class 10/12: one per cube, class 13: six)",
                self.curve_edges
            )?;
        } else {
            self.fmt_zones(f)?;
        }
        writeln!(f, "vertices      {}", self.vertices)?;
        writeln!(f, "triangles     {}", self.triangles)?;
        // The thesis's healing spends its search time on the critical test alone.
        let search = if self.mode == healed::Healing::Thesis { "critical test" } else { "search" };
        writeln!(
            f,
            "time          sampling {:.3}s, extraction {:.3}s, refinement {:.3}s, {search} {:.3}s, healing {:.3}s, normals {:.3}s",
            secs(self.sampling),
            secs(self.extraction),
            secs(self.refinement),
            secs(self.search),
            secs(self.healing),
            secs(self.normals),
        )
    }
}

impl healed::Stats {
    /// The zone healing's own lines: its curves, zones and singularities.
    fn fmt_zones(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let length: f64 = self.curves.iter().map(|c| c.length).sum::<f64>() + 0.0;
        writeln!(
            f,
            "curves        {} self-intersection curves, length {:.4}, {} curve edges (4 triangles each)",
            self.curves.len(),
            length,
            self.curve_edges
        )?;
        writeln!(
            f,
            "healed        {} regions, {} cubes; {} regions not healed; {} lattice edges and {} faces checked",
            self.zones,
            self.healed_cubes,
            self.unresolved.len(),
            self.edges_checked,
            self.faces_checked
        )?;
        writeln!(
            f,
            "singular      {} points, {} bare lines",
            self.singular_points.len(),
            self.singular_lines.len()
        )?;
        for p in self.singular_points.iter().take(20) {
            writeln!(f, "  {} at {}", point_kind(p.kind), at(p.position))?;
        }
        for l in self.singular_lines.iter().take(20) {
            let (a, b) = (l.points[0], l.points[l.points.len() - 1]);
            writeln!(f, "  bare line {} to {}, length {:.4}", at(a), at(b), l.length)?;
        }
        for u in &self.unresolved {
            writeln!(f, "  not healed near {}: {} cubes, {}", at(u.center), u.cubes, u.reason)?;
        }
        Ok(())
    }
}
