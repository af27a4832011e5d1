//! `skelform animate`: an articulated scene turned from one pose to another (DIS §2.8),
//! each frame meshed and drawn into an animated PNG, or written as a mesh file.

use std::path::PathBuf;

use anyhow::anyhow;
use clap::Args;
use skelform::mesh::io::{Format, WriteOptions, write_mesh};
use skelform::render::{Image, RenderError, Renderer, write_animation};

use crate::{Failure, FormatArg, input, render, run, runtime};

#[derive(Args)]
pub struct AnimateArgs {
    /// An articulated scene (.toml with joints and poses).
    pub scene: PathBuf,
    /// The pose the animation starts in.
    #[arg(long)]
    pub from: String,
    /// The pose it ends in. Each joint's rotation is interpolated between the two
    /// (spherically), never the elements' positions, so limbs keep their lengths.
    #[arg(long)]
    pub to: String,
    /// Frames, the two poses included (1 to 3600).
    #[arg(long, default_value_t = 24)]
    pub frames: u32,
    /// An animated picture (.png), or a folder (ending in `/`, or an existing folder) that
    /// receives one mesh per frame, `frame-0000.ply`, `frame-0001.ply`, … (only those names
    /// are written).
    #[arg(short, long)]
    pub output: PathBuf,
    /// The mesh format of the frames written to a folder.
    #[arg(long, value_enum, default_value = "ply")]
    pub format: FormatArg,
    /// Picture size in pixels, WIDTHxHEIGHT.
    #[arg(long, value_parser = render::parse_size, default_value = "640x480")]
    pub size: (u32, u32),
    /// Where the camera looks from: azimuth,elevation in degrees (as `render --view`).
    #[arg(long, value_parser = render::parse_view, allow_hyphen_values = true, default_value = "30,25")]
    pub view: (f64, f64),
    /// Milliseconds each frame is shown.
    #[arg(long, default_value_t = 80)]
    pub frame_ms: u16,
    #[command(flatten)]
    pub run: run::RunArgs,
}

/// Where the frames go.
enum Target {
    Picture(PathBuf),
    Meshes(PathBuf, Format),
}

pub fn animate(a: AnimateArgs) -> Result<(), Failure> {
    if a.run.pose.is_some() {
        return Err(input(anyhow!("animate takes its poses from --from and --to, not --pose")));
    }
    if !(1..=skelform::render::MAX_FRAMES).contains(&a.frames) {
        return Err(input(anyhow!(
            "--frames must be from 1 to {} (got {})",
            skelform::render::MAX_FRAMES,
            a.frames
        )));
    }
    let out = &a.output;
    let is_dir = out.is_dir() || out.as_os_str().to_string_lossy().ends_with('/');
    let target = if is_dir {
        Target::Meshes(out.clone(), a.format.into())
    } else if out.extension().is_some_and(|e| e.eq_ignore_ascii_case("png")) {
        Target::Picture(out.clone())
    } else {
        return Err(input(anyhow!(
            "{}: give an animated picture (.png) or a folder for meshes (ending in /)",
            out.display()
        )));
    };
    // Both poses are checked (and the scene read) before any frame is made.
    let scene = run::load_scene(&a.scene, Some(&a.from))?;
    scene.posed(&a.to).map_err(run::failure)?;
    let at = |k: u32| if a.frames > 1 { f64::from(k) / f64::from(a.frames - 1) } else { 0.0 };
    let mesh_frame = |k: u32| -> Result<skelform::Mesh, Failure> {
        let posed = scene.posed_between(&a.from, &a.to, at(k)).map_err(run::failure)?;
        let meshed = run::run_scene(&posed, &a.run)?;
        run::surface(&posed, &meshed, true)?;
        if !a.run.quiet {
            errln!("frame {}/{}: {} triangles", k + 1, a.frames, meshed.mesh.triangle_count());
        }
        Ok(meshed.mesh)
    };
    let pool = run::pool(&a.run)?;
    match target {
        Target::Meshes(dir, format) => {
            std::fs::create_dir_all(&dir)
                .map_err(|e| runtime(anyhow!("cannot make {}: {e}", dir.display())))?;
            let options = WriteOptions { normals: !a.run.no_normals, ..WriteOptions::default() };
            for k in 0..a.frames {
                let mesh = mesh_frame(k)?;
                let path = dir.join(format!("frame-{k:04}.{}", format.extension()));
                pool.install(|| write_mesh(&path, &mesh, format, &options)).map_err(runtime)?;
            }
            if !a.run.quiet {
                errln!("wrote {} meshes into {}", a.frames, dir.display());
            }
        }
        Target::Picture(path) => {
            let settings = skelform::render::Settings {
                width: a.size.0,
                height: a.size.1,
                view: skelform::render::View { azimuth: a.view.0, elevation: a.view.1 },
                // One camera for every frame: the scene's domain, which every pose lies in.
                fit: Some((
                    scene.domain.min.as_vec3().to_array(),
                    scene.domain.max.as_vec3().to_array(),
                )),
                ..skelform::render::Settings::default()
            };
            settings.validate().map_err(render::failure)?;
            let mut failed = None;
            let frame = |k: u32| -> Result<Image, RenderError> {
                let made = mesh_frame(k).and_then(|mesh| {
                    pool.install(|| Renderer::new(&mesh)?.render(&settings))
                        .map_err(render::failure)
                });
                made.map_err(|f| {
                    let message = f.error.as_ref().map_or(String::new(), |e| e.to_string());
                    failed = Some(f);
                    RenderError::Frame { frame: k, message }
                })
            };
            let result = write_animation(&path, a.size, a.frames, a.frame_ms, frame);
            if let Some(f) = failed {
                return Err(f);
            }
            result.map_err(render::failure)?;
            if !a.run.quiet {
                errln!("wrote {} ({} frames, {}×{})", path.display(), a.frames, a.size.0, a.size.1);
            }
        }
    }
    Ok(())
}
