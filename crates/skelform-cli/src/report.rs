//! What `skelform mesh` says about a run: `--stats` text, `--json`, warnings.

use std::path::Path;
use std::time::Duration;

use anyhow::anyhow;
use serde_json::json;
use skelform_polygonize::continuation::{self, SeedNote, Stop};
use skelform_polygonize::grid;
use skelform_polygonize::healed::{self, PointKind};
use skelform_polygonize::nonmanifold;
use skelform_scene::{Method, Scene};

/// The statistics of whichever polygonizer ran.
pub enum Run {
    Grid(grid::Stats),
    Continuation(continuation::Stats),
    Healed(Box<healed::Stats>),
    NonManifold(Box<nonmanifold::Stats>),
}

impl Run {
    /// Every field evaluation the run made.
    pub fn evaluations(&self) -> u64 {
        match self {
            Run::Grid(s) => s.evaluations(),
            Run::Continuation(s) => s.evaluations(),
            Run::Healed(s) => s.evaluations(),
            Run::NonManifold(s) => s.region_evaluations,
        }
    }
}

fn secs(d: Duration) -> f64 {
    d.as_secs_f64()
}

fn point(p: skelform_field::DVec3) -> String {
    format!("({}, {}, {})", p.x, p.y, p.z)
}

/// Why there is nothing to write.
pub fn no_surface(scene: &Scene, run: &Run) -> anyhow::Error {
    match run {
        Run::Grid(s) => {
            let where_ = if s.min_sample >= 0.0 { "outside (f ≥ 0)" } else { "inside (f < 0)" };
            anyhow!(
                "{}: no surface in the domain: all {} samples are {where_}, values from {} to {}; \
                 check the formula, the iso value and the domain box",
                scene.origin,
                s.samples,
                s.min_sample,
                s.max_sample
            )
        }
        Run::Continuation(_) => {
            anyhow!(
                "{}: propagation from the seeds made no triangles; check the seeds and the cell size",
                scene.origin
            )
        }
        Run::Healed(s) => healed_no_surface(scene, s),
        Run::NonManifold(_) => anyhow!(
            "{}: the regions of interest make no triangles; check [regions], its interest pairs and the seeds",
            scene.origin
        ),
    }
}

/// Things a user should know even without `--stats`.
pub fn warnings(run: &Run) -> Vec<String> {
    let mut w = Vec::new();
    match run {
        Run::Grid(s) => {
            if s.non_finite_samples > 0 {
                w.push(format!(
                    "{} samples were NaN or infinite (treated as outside/inside)",
                    s.non_finite_samples
                ));
            }
        }
        Run::Continuation(s) => {
            for stop in &s.stops {
                w.push(match stop {
                    Stop::Domain => "propagation reached the domain box; the mesh is open there".to_string(),
                    Stop::Budget => "propagation ran out of cells (--max-cells); the mesh is open where it stopped".to_string(),
                    Stop::Limit => "propagation reached its limit (--limit); the mesh is open there".to_string(),
                });
            }
            for n in &s.seed_notes {
                if let SeedNote::NoSurface { seed } = n {
                    w.push(format!("seed {} found no surface", point(*seed)));
                }
            }
            if s.non_finite > 0 {
                w.push(format!(
                    "{} corner values were NaN or infinite (treated as outside/inside)",
                    s.non_finite
                ));
            }
        }
        Run::Healed(s) => healed_warnings(s, &mut w),
        Run::NonManifold(s) => {
            if s.reached_domain {
                w.push("surfaces reach the domain box; the mesh is open there".into());
            }
            if s.reached_budget {
                w.push(
                    "propagation ran out of cells (--max-cells); the mesh is open where it stopped"
                        .into(),
                );
            }
            if s.face_vertex_fallbacks > 0 {
                w.push(format!(
                    "{} of {} face vertices were not reached by the contour follower (placed at the mean of the face's crossings)",
                    s.face_vertex_fallbacks, s.face_vertices
                ));
            }
        }
    }
    w
}

/// The `--stats` text.
pub fn print(run: &Run, writing: Duration, total: Duration) {
    match run {
        Run::Grid(s) => {
            let [nx, ny, nz] = s.grid_dims;
            println!("grid          {nx} × {ny} × {nz} samples, cell {:.6}", s.cell);
            if s.streamed {
                println!(
                    "samples       {} (streamed in slabs: a layer between slabs run on different threads is sampled twice)",
                    s.samples
                );
            } else {
                println!("samples       {}", s.samples);
            }
            println!(
                "evaluations   {} (samples {}, root finding {}, normals {})",
                s.evaluations(),
                s.samples,
                s.refine_evaluations,
                s.normal_evaluations
            );
            println!(
                "ambiguous     {} faces decided, {} interior tunnels",
                s.ambiguous_faces, s.tunnels
            );
            println!("vertices      {}", s.vertices);
            println!("triangles     {}", s.triangles);
            println!(
                "time          sampling {:.3}s, extraction {:.3}s, refinement {:.3}s, normals {:.3}s, writing {:.3}s, total {:.3}s",
                secs(s.sampling),
                secs(s.extraction),
                secs(s.refinement),
                secs(s.normals),
                secs(writing),
                secs(total)
            );
        }
        Run::Continuation(s) => {
            println!("cell          {:.6}", s.cell);
            println!(
                "evaluations   {} (corners {}, search {}, root finding {}, normals {})",
                s.evaluations(),
                s.corner_evaluations,
                s.search_evaluations,
                s.refine_evaluations,
                s.normal_evaluations
            );
            println!("cells         {} visited", s.cells_visited);
            println!("components    {}", s.components.len());
            for (i, c) in s.components.iter().enumerate().take(10) {
                println!(
                    "  #{i}  seed {}  {} cells  {} triangles",
                    point(c.seed),
                    c.cells,
                    c.triangles
                );
            }
            let stops: Vec<&str> = s
                .stops
                .iter()
                .map(|s| match s {
                    Stop::Domain => "domain box",
                    Stop::Budget => "cell budget",
                    Stop::Limit => "propagation limit",
                })
                .collect();
            println!(
                "stopped by    {}",
                if stops.is_empty() { "nothing (closed)".to_string() } else { stops.join(", ") }
            );
            println!("vertices      {}", s.vertices);
            println!("triangles     {}", s.triangles);
            println!(
                "time          search {:.3}s, propagation {:.3}s, refinement {:.3}s, normals {:.3}s, writing {:.3}s, total {:.3}s",
                secs(s.search),
                secs(s.propagation),
                secs(s.refinement),
                secs(s.normals),
                secs(writing),
                secs(total)
            );
        }
        Run::Healed(s) => healed_print(s, writing, total),
        Run::NonManifold(s) => {
            println!("cell          {:.6} (ε {:.3e})", s.cell, s.epsilon);
            println!(
                "evaluations   {} of the region function (a conventional polygonizer: about {})",
                s.region_evaluations, s.conventional_evaluations
            );
            println!("cells         {} visited", s.cells_visited);
            println!(
                "vertices      {} ({} on edges, {} on faces, {} inside tetrahedra; {} merged)",
                s.vertices,
                s.edge_vertices,
                s.face_vertices,
                s.internal_vertices,
                s.merged_vertices
            );
            println!(
                "post-process  {} merged, {} snapped onto edges, {} triangles dropped",
                s.merged_vertices, s.snapped_to_edges, s.dropped_triangles
            );
            println!(
                "face vertices {} by the contour follower, {} at a crossing, {} fallbacks; {} normals from gradients",
                s.face_vertices - s.face_vertices_at_crossing - s.face_vertex_fallbacks,
                s.face_vertices_at_crossing,
                s.face_vertex_fallbacks,
                s.gradient_normals
            );
            println!("triangles     {}", s.triangles);
            for (p, n) in &s.triangles_per_pair {
                println!("  surface {}_{}  {n} triangles", p.0, p.1);
            }
            for (t, l) in &s.curve_length_per_triple {
                println!("  curve {t}  length {l:.4}");
            }
            println!(
                "time          {:.3}s, writing {:.3}s, total {:.3}s",
                s.time.as_secs_f64(),
                secs(writing),
                secs(total)
            );
        }
    }
}

/// The `--json` document.
pub fn json(
    scene: &Scene,
    out: &Path,
    method: Method,
    run: &Run,
    writing: Duration,
    total: Duration,
) -> serde_json::Value {
    let mut j = match run {
        Run::Grid(s) => json!({
            "grid": { "dims": s.grid_dims, "cell": s.cell },
            "streamed": s.streamed,
            "samples": s.samples,
            "non_finite_samples": s.non_finite_samples,
            "evaluations": {
                "total": s.evaluations(),
                "samples": s.samples,
                "root_finding": s.refine_evaluations,
                "normals": s.normal_evaluations,
            },
            "ambiguous_faces": s.ambiguous_faces,
            "tunnels": s.tunnels,
            "vertices": s.vertices,
            "triangles": s.triangles,
            "seconds": {
                "sampling": secs(s.sampling),
                "extraction": secs(s.extraction),
                "refinement": secs(s.refinement),
                "normals": secs(s.normals),
            },
        }),
        Run::Continuation(s) => json!({
            "cell": s.cell,
            "evaluations": {
                "total": s.evaluations(),
                "corners": s.corner_evaluations,
                "search": s.search_evaluations,
                "root_finding": s.refine_evaluations,
                "normals": s.normal_evaluations,
            },
            "cells_visited": s.cells_visited,
            "non_finite": s.non_finite,
            "components": s.components.iter().map(|c| json!({
                "seed": c.seed.to_array(), "start": c.start.to_array(), "cells": c.cells, "triangles": c.triangles,
            })).collect::<Vec<_>>(),
            "stops": s.stops.iter().map(|s| format!("{s:?}").to_lowercase()).collect::<Vec<_>>(),
            "vertices": s.vertices,
            "triangles": s.triangles,
            "seconds": {
                "search": secs(s.search),
                "propagation": secs(s.propagation),
                "refinement": secs(s.refinement),
                "normals": secs(s.normals),
            },
        }),
        Run::Healed(s) => healed_json(s),
        Run::NonManifold(s) => json!({
            "cell": s.cell,
            "epsilon": s.epsilon,
            "evaluations": { "total": s.region_evaluations, "conventional": s.conventional_evaluations },
            "cells_visited": s.cells_visited,
            "vertices": s.vertices,
            "triangles": s.triangles,
            "surfaces": s.triangles_per_pair.iter().map(|(p, n)| json!({ "pair": [p.0, p.1], "triangles": n })).collect::<Vec<_>>(),
            "curves": s.curve_length_per_triple.iter().map(|(t, l)| json!({ "regions": t.0, "length": l })).collect::<Vec<_>>(),
            "face_vertex_fallbacks": s.face_vertex_fallbacks,
            "face_vertices_at_crossing": s.face_vertices_at_crossing,
            "merged_vertices": s.merged_vertices,
            "snapped_to_edges": s.snapped_to_edges,
            "dropped_triangles": s.dropped_triangles,
            "gradient_normals": s.gradient_normals,
            "seconds": { "polygonize": s.time.as_secs_f64() },
        }),
    };
    j["scene"] = json!(scene.origin);
    j["output"] = json!(out.display().to_string());
    j["method"] = json!(method.name());
    j["seconds"]["writing"] = json!(secs(writing));
    j["seconds"]["total"] = json!(secs(total));
    j
}

/// A computed point to a millionth (the numerical noise of a solve below that is not news).
fn at(p: skelform_field::DVec3) -> String {
    let r = |v: f64| {
        let x = (v * 1e6).round() / 1e6;
        if x == 0.0 { 0.0 } else { x }
    };
    format!("({}, {}, {})", r(p.x), r(p.y), r(p.z))
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

fn healed_no_surface(scene: &Scene, s: &healed::Stats) -> anyhow::Error {
    let where_ = if s.min_sample >= 0.0 { "outside (f ≥ 0)" } else { "inside (f < 0)" };
    let found = if s.singular_lines.is_empty() && s.singular_points.is_empty() {
        String::new()
    } else {
        format!(
            "; the zero set is there but never changes sign ({} bare lines, {} points, see --stats), \
             which no sign-based method can mesh",
            s.singular_lines.len(),
            s.singular_points.len()
        )
    };
    anyhow!(
        "{}: no surface in the domain: all {} samples are {where_}, values from {} to {}{found}; \
         check the formula, the iso value and the domain box",
        scene.origin,
        s.samples,
        s.min_sample,
        s.max_sample
    )
}

fn healed_warnings(s: &healed::Stats, w: &mut Vec<String>) {
    if s.non_finite_samples > 0 {
        w.push(format!(
            "{} samples were NaN or infinite (treated as outside/inside)",
            s.non_finite_samples
        ));
    }
    for u in &s.unresolved {
        w.push(format!(
            "a self-intersection near {} was not healed ({} cubes kept as marching cubes made them): {}",
            at(u.center),
            u.cubes,
            u.reason
        ));
    }
    for l in &s.singular_lines {
        let (a, b) = (l.points[0], l.points[l.points.len() - 1]);
        w.push(format!(
            "the zero set is a bare line from {} to {} (length {:.4}): reported, not meshed",
            at(a),
            at(b),
            l.length
        ));
    }
    for p in &s.singular_points {
        if matches!(p.kind, PointKind::Isolated | PointKind::Degenerate) {
            w.push(format!("{} at {}: reported, not meshed", point_kind(p.kind), at(p.position)));
        }
    }
}

fn healed_print(s: &healed::Stats, writing: Duration, total: Duration) {
    let [nx, ny, nz] = s.grid_dims;
    println!("grid          {nx} × {ny} × {nz} samples, cell {:.6}", s.cell);
    println!("samples       {}", s.samples);
    println!(
        "evaluations   {} (samples {}, root finding {}, normals {}, critical test {}, singular search {})",
        s.evaluations(),
        s.samples,
        s.refine_evaluations,
        s.normal_evaluations,
        s.critical_evaluations,
        s.search_evaluations
    );
    let c = &s.critical_cubes;
    println!(
        "critical      {} vertices; {} cubes (class 10: {}, class 12: {}, class 13: {}, other: {})",
        s.critical_vertices,
        c.total(),
        c.class10,
        c.class12,
        c.class13,
        c.other
    );
    println!(
        "search        {} thesis face points (class 10/12/13 faces), {} seeds tried",
        s.face_points, s.seeds_tried
    );
    // The thesis's table: "triangles by standard MC: …; by HMC: … (correct triangles by MC …,
    // triangles used for healing the critical cubes …)".
    println!(
        "triangles     standard MC {}; HMC {} (kept MC {}, healing {})",
        s.mc_triangles, s.triangles, s.kept_mc_triangles, s.healing_triangles
    );
    let length: f64 = s.curves.iter().map(|c| c.length).sum::<f64>() + 0.0;
    println!(
        "curves        {} self-intersection curves, length {:.4}, {} curve edges (4 triangles each)",
        s.curves.len(),
        length,
        s.curve_edges
    );
    println!(
        "healed        {} regions, {} cubes; {} regions not healed; {} lattice edges and {} faces checked",
        s.zones,
        s.healed_cubes,
        s.unresolved.len(),
        s.edges_checked,
        s.faces_checked
    );
    println!(
        "singular      {} points, {} bare lines",
        s.singular_points.len(),
        s.singular_lines.len()
    );
    for p in s.singular_points.iter().take(20) {
        println!("  {} at {}", point_kind(p.kind), at(p.position));
    }
    for l in s.singular_lines.iter().take(20) {
        let (a, b) = (l.points[0], l.points[l.points.len() - 1]);
        println!("  bare line {} to {}, length {:.4}", at(a), at(b), l.length);
    }
    for u in &s.unresolved {
        println!("  not healed near {}: {} cubes, {}", at(u.center), u.cubes, u.reason);
    }
    println!("vertices      {}", s.vertices);
    println!("triangles     {}", s.triangles);
    println!(
        "time          sampling {:.3}s, extraction {:.3}s, refinement {:.3}s, search {:.3}s, healing {:.3}s, normals {:.3}s, writing {:.3}s, total {:.3}s",
        secs(s.sampling),
        secs(s.extraction),
        secs(s.refinement),
        secs(s.search),
        secs(s.healing),
        secs(s.normals),
        secs(writing),
        secs(total)
    );
}

fn healed_json(s: &healed::Stats) -> serde_json::Value {
    let c = &s.critical_cubes;
    json!({
        "grid": { "dims": s.grid_dims, "cell": s.cell },
        "samples": s.samples,
        "non_finite_samples": s.non_finite_samples,
        "evaluations": {
            "total": s.evaluations(),
            "samples": s.samples,
            "root_finding": s.refine_evaluations,
            "normals": s.normal_evaluations,
            "critical_test": s.critical_evaluations,
            "singular_search": s.search_evaluations,
        },
        "critical": {
            "vertices": s.critical_vertices,
            "cubes": { "class10": c.class10, "class12": c.class12, "class13": c.class13, "other": c.other },
        },
        "seeds_tried": s.seeds_tried,
        "face_points": s.face_points,
        "mc_triangles": s.mc_triangles,
        "kept_mc_triangles": s.kept_mc_triangles,
        "healing_triangles": s.healing_triangles,
        "curve_edges": s.curve_edges,
        "curves": s.curves.iter().map(|c| json!({
            "points": c.points.len(), "closed": c.closed, "length": c.length, "healed": c.healed,
            "start": c.points.first().map(|p| p.to_array()), "end": c.points.last().map(|p| p.to_array()),
        })).collect::<Vec<_>>(),
        "singular_points": s.singular_points.iter().map(|p| json!({
            "kind": point_kind(p.kind), "position": p.position.to_array(),
        })).collect::<Vec<_>>(),
        "singular_lines": s.singular_lines.iter().map(|l| json!({
            "start": l.points.first().map(|p| p.to_array()), "end": l.points.last().map(|p| p.to_array()),
            "length": l.length, "points": l.points.len(),
        })).collect::<Vec<_>>(),
        "healed": { "regions": s.zones, "cubes": s.healed_cubes, "edges_checked": s.edges_checked, "faces_checked": s.faces_checked },
        "unresolved": s.unresolved.iter().map(|u| json!({
            "center": u.center.to_array(), "cubes": u.cubes, "reason": u.reason,
        })).collect::<Vec<_>>(),
        "vertices": s.vertices,
        "triangles": s.triangles,
        "seconds": {
            "sampling": secs(s.sampling),
            "extraction": secs(s.extraction),
            "refinement": secs(s.refinement),
            "search": secs(s.search),
            "healing": secs(s.healing),
            "normals": secs(s.normals),
        },
    })
}
