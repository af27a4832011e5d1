//! What `skelform mesh` prints about a run: the statistics' own text for `--stats`, and for
//! `--json` their serialized form with what only the command line knows (the files, the
//! time spent writing). Nothing here depends on the method that ran.

use std::path::Path;
use std::time::Duration;

use serde_json::json;
use skelform::{Meshed, Scene};

use crate::Failure;

/// The `--stats` text.
pub fn print(meshed: &Meshed, writing: Duration, total: Duration) -> Result<(), Failure> {
    outp!("{}", meshed.stats);
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
    j["seconds"] = json!({
        "polygonize": meshed.elapsed.as_secs_f64(),
        "writing": writing.as_secs_f64(),
        "total": total.as_secs_f64(),
    });
    j
}
