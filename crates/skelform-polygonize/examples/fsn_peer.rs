//! A peer for `bench/peers`: Naive Surface Nets from the `fast-surface-nets` crate on a raw
//! float32 volume (x fastest), timing the extraction alone.
//!
//! `cargo run --release -p skelform-polygonize --example fsn_peer -- VOLUME NX NY NZ [REPEAT]`
//! prints `{"seconds": […], "vertices": …, "triangles": …}`: the time of each of REPEAT
//! extractions (default 1) in this process, each into a new buffer.

use std::time::Instant;

use fast_surface_nets::ndshape::RuntimeShape;
use fast_surface_nets::{SurfaceNetsBuffer, surface_nets};

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().collect();
    let (path, nx, ny, nz, repeat) = match args.as_slice() {
        [_, path, nx, ny, nz] => (path, nx, ny, nz, 1),
        [_, path, nx, ny, nz, r] => {
            (path, nx, ny, nz, r.parse::<usize>().map_err(|e| e.to_string())?)
        }
        _ => return Err("usage: fsn_peer VOLUME NX NY NZ [REPEAT]".into()),
    };
    let dims: Vec<u32> = [nx, ny, nz]
        .iter()
        .map(|s| s.parse::<u32>().map_err(|e| e.to_string()))
        .collect::<Result<_, _>>()?;
    let bytes = std::fs::read(path).map_err(|e| format!("{path}: {e}"))?;
    let sdf: Vec<f32> =
        bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
    if sdf.len() != dims.iter().map(|&d| d as usize).product::<usize>() {
        return Err(format!("{path}: size does not match {dims:?}"));
    }
    let shape = RuntimeShape::<u32, 3>::new([dims[0], dims[1], dims[2]]);
    let mut seconds = Vec::new();
    let mut extract = || {
        let mut buffer = SurfaceNetsBuffer::default();
        let t = Instant::now();
        surface_nets(&sdf, &shape, [0; 3], [dims[0] - 1, dims[1] - 1, dims[2] - 1], &mut buffer);
        seconds.push(t.elapsed().as_secs_f64().to_string());
        buffer
    };
    let mut buffer = extract();
    for _ in 1..repeat {
        drop(buffer);
        buffer = extract();
    }
    println!(
        "{{\"seconds\": [{}], \"vertices\": {}, \"triangles\": {}}}",
        seconds.join(", "),
        buffer.positions.len(),
        buffer.indices.len() / 3
    );
    Ok(())
}
