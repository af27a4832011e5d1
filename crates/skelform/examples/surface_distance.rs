//! How far a mesh's vertices lie from its scene's surface: `|f|/|∇f|` (the first-order
//! distance) at every vertex, for checking that a change to root finding leaves vertices no
//! farther from the surface.
//!
//! `cargo run --release -p skelform --example surface_distance -- SCENE MESH...`
//! prints, for each mesh, its vertex count and the mean, 99th percentile and largest
//! distance.

use std::path::Path;

use skelform::{DVec3, Field, Scene};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some((scene, meshes)) = args.split_first() else {
        return Err("usage: surface_distance SCENE MESH...".into());
    };
    let scene = Scene::load(scene)?;
    let field = &scene.description().field;
    println!("| mesh | vertices | mean distance | 99th percentile | largest |");
    println!("|---|---|---|---|---|");
    for path in meshes {
        let mesh = skelform::mesh::io::read_mesh(Path::new(path))?;
        let pts: Vec<DVec3> =
            mesh.positions.iter().map(|p| DVec3::from(p.map(f64::from))).collect();
        let mut values = vec![0.0; pts.len()];
        let mut grads = vec![DVec3::ZERO; pts.len()];
        field.eval_grad_many(&pts, &mut values, &mut grads);
        let mut d: Vec<f64> =
            values.iter().zip(&grads).map(|(f, g)| f.abs() / g.length()).collect();
        d.sort_by(f64::total_cmp);
        let mean = d.iter().sum::<f64>() / d.len().max(1) as f64;
        let p99 = d.get(d.len() * 99 / 100).copied().unwrap_or(0.0);
        let max = d.last().copied().unwrap_or(0.0);
        println!("| {path} | {} | {mean:.3e} | {p99:.3e} | {max:.3e} |", d.len());
    }
    Ok(())
}
