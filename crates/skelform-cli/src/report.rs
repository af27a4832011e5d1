//! What `skelform mesh` prints about a run: the statistics' own text for `--stats`, and for
//! `--json` their serialized form with what only the command line knows (the files, the
//! time spent writing), and a leaf's web and texture counts. Nothing here depends on the
//! method that ran.

use std::path::Path;
use std::time::Duration;

use serde_json::json;
use skelform::{Meshed, Scene};

use crate::Failure;

/// The `--stats` text.
pub fn print(
    scene: &Scene,
    meshed: &Meshed,
    writing: Duration,
    total: Duration,
) -> Result<(), Failure> {
    outp!("{}", meshed.stats);
    if let Some(l) = &scene.leaf {
        // The blade's web, to compare with the dissertation's 475 triangles (fig. 7.8).
        let s = &l.stats;
        let texture = l.texture.as_ref().map_or(String::new(), |t| {
            format!(
                "; texture: {} tertiary lines around {} areoles",
                t.tertiary.lines.len(),
                t.tertiary.areoles
            )
        });
        outln!(
            "leaf web      {} polygons refined to {}, {} blade triangles{texture}",
            s.web_polygons,
            s.polygons,
            s.triangles
        );
    }
    if !meshed.painting.is_zero() {
        // Outside the method's phases: colours are blended at the finished vertices.
        outln!("painting      {:.3}s (vertex colours)", meshed.painting.as_secs_f64());
    }
    outln!("writing       {:.3}s (total {:.3}s)", writing.as_secs_f64(), total.as_secs_f64());
    Ok(())
}

/// The `--json` document: the method's statistics, field for field (durations in seconds),
/// with the scene, the output, the method, the warnings and the run's times beside them.
pub fn json(
    scene: &Scene,
    out: &Path,
    meshed: &Meshed,
    writing: Duration,
    total: Duration,
) -> serde_json::Value {
    let mut j = serde_json::to_value(&meshed.stats).unwrap_or_else(|_| json!({}));
    j["scene"] = json!(scene.origin);
    j["output"] = json!(out.display().to_string());
    j["method"] = json!(meshed.method.name());
    j["evaluations"] = json!(meshed.stats.evaluations());
    j["warnings"] = json!(meshed.stats.warnings());
    if let Some(l) = &scene.leaf {
        let s = &l.stats;
        j["leaf"] = json!({
            "web_polygons": s.web_polygons,
            "polygons": s.polygons,
            "unsplit": s.unsplit,
            "triangles": s.triangles,
            "tertiary_lines": l.texture.as_ref().map(|t| t.tertiary.lines.len()),
            "areoles": l.texture.as_ref().map(|t| t.tertiary.areoles),
        });
    }
    j["seconds"] = json!({
        "polygonize": meshed.elapsed.as_secs_f64(),
        "painting": meshed.painting.as_secs_f64(),
        "writing": writing.as_secs_f64(),
        "total": total.as_secs_f64(),
    });
    j
}
