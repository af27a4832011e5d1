//! `skelform`: polygonize implicit-surface scenes and check meshes.
//!
//! A thin layer over the library crates: it parses arguments, loads the scene, runs a
//! polygonizer, writes the mesh and prints statistics. Exit codes: 0 success, 1 runtime
//! failure (nothing to mesh, cannot write), 2 bad input or usage.

mod progress;
mod report;

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::anyhow;
use clap::{Args, Parser, Subcommand};
use skelform_field::DVec3;
use skelform_mesh::io::{Format, WriteOptions, read_mesh, write_mesh};
use skelform_polygonize::grid::{self, Resolution};
use skelform_polygonize::{continuation, refine::RootMethod};
use skelform_scene::{Method, Scene};

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
}

#[derive(Args)]
struct MeshArgs {
    /// The scene file (TOML).
    scene: PathBuf,
    /// Output mesh; the extension picks the format (.ply, .obj, .stl). Defaults to the
    /// scene's [output] file.
    #[arg(short, long)]
    output: Option<PathBuf>,
    /// Samples along the domain's longest side (overrides the scene).
    #[arg(long, conflicts_with = "cell")]
    resolution: Option<usize>,
    /// Cell size (overrides the scene).
    #[arg(long)]
    cell: Option<f64>,
    /// Polygonizer (overrides the scene): grid, continuation or tetra.
    #[arg(long)]
    method: Option<String>,
    /// continuation/tetra: start from this point on or near the surface (repeatable;
    /// replaces the scene's seeds), e.g. --seed 0.6,0,0.
    #[arg(long, value_parser = parse_point, allow_hyphen_values = true)]
    seed: Vec<[f64; 3]>,
    /// continuation/tetra: root finder, regula-falsi or bisection (overrides the scene).
    #[arg(long)]
    root: Option<String>,
    /// Root-finding tolerance as a fraction of the cell (overrides the scene).
    #[arg(long)]
    tolerance: Option<f64>,
    /// continuation/tetra: stop after visiting this many cubes.
    #[arg(long)]
    max_cells: Option<u64>,
    /// continuation/tetra: stop this many cubes from each start, in every direction.
    #[arg(long)]
    limit: Option<u32>,
    /// Worker threads (default: all cores). The mesh is the same for any count.
    #[arg(long)]
    threads: Option<usize>,
    /// Print statistics: samples, evaluations, vertices, triangles, time per phase.
    #[arg(long)]
    stats: bool,
    /// Print statistics as JSON on standard output.
    #[arg(long)]
    json: bool,
    /// Write PLY as text instead of binary.
    #[arg(long)]
    ascii: bool,
    /// Leave out vertex normals.
    #[arg(long)]
    no_normals: bool,
    /// Place vertices by linear interpolation only (no root finding on the field).
    #[arg(long)]
    no_refine: bool,
    /// Refuse grids that would need more memory than this, e.g. 512M, 4G (default 4G).
    #[arg(long, value_parser = parse_bytes, default_value = "4G")]
    max_memory: u64,
    /// No progress bar.
    #[arg(short, long)]
    quiet: bool,
}

#[derive(Args)]
struct CheckArgs {
    /// The mesh (PLY ascii or binary, OBJ, STL).
    mesh: PathBuf,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Args)]
struct InfoArgs {
    scene: PathBuf,
    /// Also print the compiled instruction tape.
    #[arg(long)]
    tape: bool,
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
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("error: {}", f.error);
            ExitCode::from(f.code)
        }
    }
}

fn parse_bytes(s: &str) -> Result<u64, String> {
    let s = s.trim();
    let (num, mult) = match s.char_indices().find(|(_, c)| c.is_ascii_alphabetic()) {
        Some((i, _)) => {
            let unit = s[i..].to_ascii_uppercase();
            let m = match unit.trim_end_matches("IB").trim_end_matches('B') {
                "" => 1u64,
                "K" => 1 << 10,
                "M" => 1 << 20,
                "G" => 1 << 30,
                "T" => 1 << 40,
                _ => return Err(format!("unknown unit '{}' (use K, M, G or T)", &s[i..])),
            };
            (&s[..i], m)
        }
        None => (s, 1),
    };
    let n: f64 = num.trim().parse().map_err(|_| format!("'{s}' is not a size like 512M or 4G"))?;
    if !(n.is_finite() && n > 0.0) {
        return Err(format!("'{s}' must be a positive size"));
    }
    Ok((n * mult as f64) as u64)
}

fn parse_point(s: &str) -> Result<[f64; 3], String> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let nums: Vec<f64> = parts.iter().filter_map(|p| p.parse().ok()).collect();
    match <[f64; 3]>::try_from(nums) {
        Ok(p) if parts.len() == 3 && p.iter().all(|x| x.is_finite()) => Ok(p),
        _ => Err(format!("'{s}' is not a point like 0.5,0,-1")),
    }
}

fn load_scene(path: &Path) -> Result<Scene, Failure> {
    Scene::load(path).map_err(input)
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
    let scene = load_scene(&a.scene)?;
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
    let method = match &a.method {
        Some(m) => m.parse::<Method>().map_err(input)?,
        None => scene.method,
    };
    let resolution = match (a.resolution, a.cell) {
        (Some(n), _) if n < 2 => return Err(input(anyhow!("--resolution must be at least 2"))),
        (Some(n), _) => Resolution::Samples(n),
        (None, Some(c)) if !(c.is_finite() && c > 0.0) => {
            return Err(input(anyhow!("--cell must be a positive length")));
        }
        (None, Some(c)) => Resolution::Cell(c),
        (None, None) => scene.resolution,
    };
    let threads = a.threads.unwrap_or(0);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| runtime(anyhow!("cannot start {threads} threads: {e}")))?;

    let show_progress = !a.quiet && std::io::stderr().is_terminal();
    let control = progress::control(show_progress);
    let refine = scene.refine && !a.no_refine;
    let tolerance = match a.tolerance {
        Some(t) if !(t > 0.0 && t < 1.0) => {
            return Err(input(anyhow!("--tolerance is a fraction of the cell, between 0 and 1")));
        }
        Some(t) => t,
        None => scene.tolerance,
    };
    let normals = scene.output.normals && !a.no_normals;
    let started = Instant::now();
    let field = scene.field.as_ref();
    let result = match method {
        Method::Grid => {
            let options = grid::Options {
                domain: scene.domain,
                resolution,
                refine,
                tolerance,
                normals,
                max_memory: a.max_memory,
                control,
            };
            pool.install(|| grid::polygonize(field, &options))
                .map(|(m, s)| (m, report::Run::Grid(s)))
        }
        Method::Continuation | Method::Tetra => {
            let cell = grid::grid_for(&grid::Options {
                domain: scene.domain,
                resolution,
                ..Default::default()
            })
            .map_err(|e| input(anyhow!("{}: {e}", scene.origin)))?
            .cell;
            let c = &scene.continuation;
            let defaults = continuation::Options::default();
            let root = match a.root.as_deref() {
                None => c.root,
                Some("regula-falsi") => RootMethod::RegulaFalsi,
                Some("bisection") => RootMethod::Bisection,
                Some(other) => {
                    return Err(input(anyhow!(
                        "unknown root finder '{other}'; expected regula-falsi or bisection"
                    )));
                }
            };
            let options = continuation::Options {
                domain: scene.domain,
                cell,
                seeds: if a.seed.is_empty() {
                    c.seeds.clone()
                } else {
                    a.seed.iter().map(|p| DVec3::from_array(*p)).collect()
                },
                search_stride: c.search_stride.unwrap_or(defaults.search_stride),
                cells: if method == Method::Tetra {
                    continuation::Cells::Tetrahedra
                } else {
                    continuation::Cells::Cubes
                },
                root,
                tolerance,
                refine,
                normals,
                max_cells: a.max_cells.or(c.max_cells).unwrap_or(defaults.max_cells),
                limit: a.limit.or(c.limit),
                control,
            };
            pool.install(|| continuation::polygonize(field, &options))
                .map(|(m, s)| (m, report::Run::Continuation(s)))
        }
    };
    progress::finish();
    let (mesh, stats) = result.map_err(|e| {
        use skelform_polygonize::Error as E;
        match e {
            E::TooMuchMemory { .. } | E::Grid(_) | E::BadSeed { .. } | E::BadOption(_) => {
                input(anyhow!("{}: {e}", scene.origin))
            }
            E::NoSurfaceFound { .. } => runtime(anyhow!("{}: {e}", scene.origin)),
            e => runtime(e),
        }
    })?;
    if mesh.is_empty() {
        return Err(runtime(report::no_surface(&scene, &stats)));
    }
    if !a.quiet {
        for w in report::warnings(&stats) {
            eprintln!("warning: {w}");
        }
    }
    let t = Instant::now();
    let write_opts = WriteOptions { ascii: a.ascii || scene.output.ascii, normals: !a.no_normals };
    write_mesh(&out, &mesh, format, &write_opts).map_err(runtime)?;
    let writing = t.elapsed();
    let total = started.elapsed();
    if a.json {
        println!("{}", report::json(&scene, &out, method, &stats, writing, total));
    } else if a.stats {
        report::print(&stats, writing, total);
    }
    if !a.quiet && !a.json {
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
    let report = skelform_mesh::check::check(&mesh);
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
    let scene = load_scene(&a.scene)?;
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
    let opts =
        grid::Options { domain: scene.domain, resolution: scene.resolution, ..Default::default() };
    match grid::grid_for(&opts) {
        Ok(g) => {
            let [nx, ny, nz] = g.dims;
            println!("grid        {nx} × {ny} × {nz} samples, cell {:.6}", g.cell);
            println!(
                "memory      {:.1} MiB before triangles",
                grid::memory_needed(&g) as f64 / (1 << 20) as f64
            );
        }
        Err(e) => println!("grid        invalid: {e}"),
    }
    println!("iso         {}", scene.iso);
    println!("formula     {} instructions", scene.formula.instruction_count());
    if a.tape {
        println!("{}", scene.formula.tape());
    }
    Ok(())
}
