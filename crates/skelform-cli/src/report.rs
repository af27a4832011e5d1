//! What `skelform mesh` says about a run: `--stats` text, `--json`, warnings.

use std::path::Path;
use std::time::Duration;

use anyhow::anyhow;
use serde_json::json;
use skelform_polygonize::continuation::{self, SeedNote, Stop};
use skelform_polygonize::grid;
use skelform_scene::{Method, Scene};

/// The statistics of whichever polygonizer ran.
pub enum Run {
    Grid(grid::Stats),
    Continuation(continuation::Stats),
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
    }
    w
}

/// The `--stats` text.
pub fn print(run: &Run, writing: Duration, total: Duration) {
    match run {
        Run::Grid(s) => {
            let [nx, ny, nz] = s.grid_dims;
            println!("grid          {nx} × {ny} × {nz} samples, cell {:.6}", s.cell);
            println!("samples       {}", s.samples);
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
    };
    j["scene"] = json!(scene.origin);
    j["output"] = json!(out.display().to_string());
    j["method"] = json!(method.name());
    j["seconds"]["writing"] = json!(secs(writing));
    j["seconds"]["total"] = json!(secs(total));
    j
}
