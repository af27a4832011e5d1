//! `skelform`: polygonize implicit-surface scenes and check meshes.
//!
//! A thin layer over the library crates: it parses arguments, loads the scene, runs a
//! polygonizer, writes the mesh and prints statistics. Exit codes: 0 success, 1 runtime
//! failure (nothing to mesh, cannot write), 2 bad input or usage.

mod extract;
mod gallery;
mod progress;
mod render;
mod report;
mod run;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::anyhow;
use clap::{Args, Parser, Subcommand};
use skelform_mesh::io::{Format, WriteOptions, read_mesh, write_mesh};
use skelform_polygonize::grid;
use skelform_scene::Scene;

#[derive(Parser)]
#[command(name = "skelform", version, about = "Implicit surfaces, skeletal forms and their meshes")]
#[command(after_help = "Exit codes: 0 success, 1 runtime failure, 2 bad input or usage.")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Polygonize a scene and write the mesh (PLY, OBJ or STL, by the output's extension).
    Mesh(MeshArgs),
    /// Report a mesh's topology: edges, components, genus, orientation, defects.
    Check(CheckArgs),
    /// Show what a scene describes: domain, grid, memory needed, the compiled formula.
    Info(InfoArgs),
    /// Marching cubes on a raw float32 volume (extraction only, no field).
    Extract(extract::ExtractArgs),
    /// Draw a scene (meshed first) or a mesh file as a PNG picture.
    Render(render::RenderArgs),
    /// Render every example scene into docs/gallery, with a page of figures and statistics.
    Gallery(gallery::GalleryArgs),
}

#[derive(Args)]
struct MeshArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Output mesh; the extension picks the format (.ply, .obj, .stl). Defaults to the
    /// scene's [output] file.
    #[arg(short, long)]
    output: Option<PathBuf>,
    #[command(flatten)]
    run: run::RunArgs,
    /// Print statistics: samples, evaluations, vertices, triangles, time per phase.
    #[arg(long)]
    stats: bool,
    /// Print statistics as JSON on standard output.
    #[arg(long)]
    json: bool,
    /// Write PLY as text instead of binary.
    #[arg(long)]
    ascii: bool,
}

#[derive(Args)]
struct CheckArgs {
    /// The mesh (PLY ascii or binary, OBJ, STL).
    mesh: PathBuf,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// Weld vertices within TOL (default 0: coincident) before the analysis, e.g. to see a
    /// non-manifold mesh, whose vertices are duplicated per region pair, as one complex.
    #[arg(long, value_name = "TOL", num_args = 0..=1, default_missing_value = "0")]
    weld: Option<f32>,
}

#[derive(Args)]
struct InfoArgs {
    scene: PathBuf,
    /// Also print the compiled instruction tape.
    #[arg(long)]
    tape: bool,
    /// Describe the scene in this named pose (see `skelform mesh --pose`).
    #[arg(long)]
    pose: Option<String>,
}

/// A failure with its exit code.
struct Failure {
    code: u8,
    error: anyhow::Error,
}

fn input(error: impl Into<anyhow::Error>) -> Failure {
    Failure { code: 2, error: error.into() }
}

fn runtime(error: impl Into<anyhow::Error>) -> Failure {
    Failure { code: 1, error: error.into() }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Mesh(a) => mesh(a),
        Command::Check(a) => check(a),
        Command::Info(a) => info(a),
        Command::Extract(a) => extract::extract(a),
        Command::Render(a) => render::render(a),
        Command::Gallery(a) => gallery::gallery(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("error: {}", f.error);
            ExitCode::from(f.code)
        }
    }
}

fn load_scene(path: &Path) -> Result<Scene, Failure> {
    load_scene_posed(path, None)
}

/// Loads a scene, its skeleton in the named pose when one is given.
fn load_scene_posed(path: &Path, pose: Option<&str>) -> Result<Scene, Failure> {
    let options = skelform_scene::LoadOptions { pose: pose.map(str::to_string) };
    Scene::load_with(path, &options).map_err(input)
}

fn output_format(path: &Path) -> Result<Format, Failure> {
    Format::from_path(path).ok_or_else(|| {
        input(anyhow!(
            "{}: unknown output format; use a .ply, .obj or .stl extension",
            path.display()
        ))
    })
}

fn mesh(a: MeshArgs) -> Result<(), Failure> {
    let scene = load_scene_posed(&a.scene, a.run.pose.as_deref())?;
    let out = a.output.clone().or_else(|| scene.output.file.clone()).ok_or_else(|| {
        input(anyhow!("no output file: give -o OUT.ply (or set [output] file in the scene)"))
    })?;
    let format = output_format(&out)?;
    if let Some(sf) = scene.output.format
        && a.output.is_none()
        && sf != format
    {
        return Err(input(anyhow!(
            "{}: the [output] format does not match the extension of {}",
            scene.origin,
            out.display()
        )));
    }
    let started = Instant::now();
    let (mesh, stats, method) = run::run_scene(&scene, &a.run)?;
    if mesh.is_empty() {
        return Err(runtime(report::no_surface(&scene, &stats)));
    }
    if !a.run.quiet {
        for w in report::warnings(&stats) {
            eprintln!("warning: {w}");
        }
    }
    let t = Instant::now();
    let write_opts =
        WriteOptions { ascii: a.ascii || scene.output.ascii, normals: !a.run.no_normals };
    write_mesh(&out, &mesh, format, &write_opts).map_err(runtime)?;
    let writing = t.elapsed();
    let total = started.elapsed();
    if a.json {
        println!("{}", report::json(&scene, &out, method, &stats, writing, total));
    } else if a.stats {
        report::print(&stats, writing, total);
    }
    if !a.run.quiet && !a.json {
        eprintln!(
            "wrote {} ({} vertices, {} triangles)",
            out.display(),
            mesh.vertex_count(),
            mesh.triangle_count()
        );
    }
    Ok(())
}

fn check(a: CheckArgs) -> Result<(), Failure> {
    let mesh = read_mesh(&a.mesh).map_err(input)?;
    let report = match a.weld {
        Some(t) if !(t.is_finite() && t >= 0.0) => {
            return Err(input(anyhow!("--weld takes a tolerance of 0 or more")));
        }
        Some(t) => skelform_mesh::check::check_welded(&mesh, t),
        None => skelform_mesh::check::check(&mesh),
    };
    if a.json {
        let json = serde_json::to_string_pretty(&report)
            .map_err(|e| runtime(anyhow!("cannot serialise the report: {e}")))?;
        println!("{json}");
    } else {
        println!("{}", a.mesh.display());
        print!("{report}");
    }
    Ok(())
}

fn info(a: InfoArgs) -> Result<(), Failure> {
    let scene = load_scene_posed(&a.scene, a.pose.as_deref())?;
    println!("scene       {}", scene.origin);
    if let Some(n) = &scene.name {
        println!("name        {n}");
    }
    if let Some(d) = &scene.description {
        println!("description {d}");
    }
    let (lo, hi) = (scene.domain.min, scene.domain.max);
    println!("domain      [{}, {}, {}] – [{}, {}, {}]", lo.x, lo.y, lo.z, hi.x, hi.y, hi.z);
    println!("method      {}", scene.method.name());
    let lattice = skelform_polygonize::LatticeOptions {
        domain: scene.domain,
        resolution: scene.resolution,
        ..Default::default()
    };
    let opts = grid::Options { lattice, ..Default::default() };
    match grid::grid_for(&opts) {
        Ok(g) => {
            let [nx, ny, nz] = g.dims;
            println!("grid        {nx} × {ny} × {nz} samples, cell {:.6}", g.cell);
            let streamed = opts.streaming.streams(&g);
            println!(
                "memory      {:.1} MiB before triangles{}",
                grid::memory_needed(&g, streamed) as f64 / (1 << 20) as f64,
                if streamed { " (volume streamed in slabs)" } else { "" }
            );
        }
        Err(e) => println!("grid        invalid: {e}"),
    }
    match &scene.skeleton {
        Some(sk) => println!(
            "skeleton    {} elements in {} blending sets",
            sk.element_count(),
            sk.clique_count()
        ),
        None => {
            println!("iso         {}", scene.iso);
            println!("formula     {} instructions", scene.formula.instruction_count());
        }
    }
    if let Some(art) = &scene.articulation {
        println!("joints      {}", art.joints.len());
        println!("pose        {} (poses: {})", art.pose, art.poses.join(", "));
    }
    if a.tape {
        println!("{}", scene.formula.tape());
    }
    Ok(())
}
