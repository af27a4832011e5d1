//! Times an edit re-meshed by `skelform::Live` against a fresh run of the edited scene (issue
//! 20's interactive goals; `bench/interactive.sh` runs it).
//!
//! ```sh
//! cargo run --release -p skelform --example live_edit -- SCENE SAMPLES ROUNDS OLD NEW
//! ```
//!
//! The edited scene is SCENE's text with the first OLD replaced by NEW. Each round meshes
//! the edited scene fresh (`Scene::mesh`) and then, with a `Live` that last meshed the other
//! version, incrementally (the `Live` toggles between the two versions, so every timed call
//! is an edit). Prints one JSON line: medians in seconds, vertices, what was sampled again and
//! reused, the mean CPU time of each kind of call (all threads; Linux), and whether the
//! incremental mesh equalled the fresh one in every round.

use std::time::Instant;

use skelform::{Live, Overrides, Resolution, Scene};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// CPU seconds the process has used, all threads (Linux; `None` elsewhere).
fn cpu() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split(' ').collect();
    // utime and stime, fields 14 and 15 of the line (11 and 12 after the name), in ticks
    // of 1/100 s on Linux.
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    Some(ticks / 100.0)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [path, samples, rounds, old, new] = args.as_slice() else {
        return Err("usage: live_edit SCENE SAMPLES ROUNDS OLD NEW".into());
    };
    let text = std::fs::read_to_string(path)?;
    if !text.contains(old.as_str()) {
        return Err(format!("{path} does not contain {old:?}").into());
    }
    let edited = text.replacen(old.as_str(), new, 1);
    let o = Overrides {
        resolution: Some(Resolution::Samples(samples.parse()?)),
        method: Some(skelform::Method::Grid),
        ..Overrides::default()
    };
    let rounds: usize = rounds.parse()?;
    let versions = [Scene::parse(&text, path)?, Scene::parse(&edited, path)?];
    let mut live = Live::new();
    live.mesh(&versions[0], &o)?;
    let (mut fresh, mut inc, mut parse) = (Vec::new(), Vec::new(), Vec::new());
    let mut same = true;
    let (mut fresh_cpu, mut inc_cpu) = (0.0, 0.0);
    let mut run = None;
    let mut vertices = 0;
    let mut phases = String::new();
    for r in 0..rounds {
        // Alternate: edit forward, then back, so every incremental call is an edit.
        let (source, scene) =
            if r % 2 == 0 { (&edited, &versions[1]) } else { (&text, &versions[0]) };
        let t = Instant::now();
        let again = Scene::parse(source, path)?;
        parse.push(t.elapsed().as_secs_f64());
        drop(again);
        let (t, c) = (Instant::now(), cpu());
        let f = scene.mesh(&o)?;
        fresh.push(t.elapsed().as_secs_f64());
        fresh_cpu += cpu().zip(c).map_or(f64::NAN, |(b, a)| b - a);
        let (t, c) = (Instant::now(), cpu());
        let m = live.mesh(scene, &o)?;
        inc.push(t.elapsed().as_secs_f64());
        inc_cpu += cpu().zip(c).map_or(f64::NAN, |(b, a)| b - a);
        same &= m.mesh == f.mesh;
        vertices = m.mesh.vertex_count();
        if let skelform::Stats::Grid(g) = &m.stats {
            phases = format!(
                "{{\"sampling\": {:.5}, \"extraction\": {:.5}, \"refinement\": {:.5}, \"normals\": {:.5}}}",
                g.sampling.as_secs_f64(),
                g.extraction.as_secs_f64(),
                g.refinement.as_secs_f64(),
                g.normals.as_secs_f64()
            );
        }
        run = live.last_run().cloned();
    }
    let run = run.ok_or("no rounds")?;
    let (f, i) = (median(fresh), median(inc));
    println!(
        "{{\"fresh_s\": {f:.5}, \"incremental_s\": {i:.5}, \"ratio\": {:.4}, \"fresh_cpu_s\": {:.4}, \"incremental_cpu_s\": {:.4}, \"parse_s\": {:.5}, \
         \"vertices\": {vertices}, \"incremental\": {}, \"resampled\": {}, \"reused_vertices\": {}, \
         \"placed_vertices\": {}, \"same_mesh\": {same}, \"last_phases_s\": {phases}}}",
        i / f,
        fresh_cpu / rounds as f64,
        inc_cpu / rounds as f64,
        median(parse),
        run.incremental,
        run.reuse.resampled,
        run.reuse.reused_vertices,
        run.reuse.placed_vertices,
    );
    Ok(())
}
