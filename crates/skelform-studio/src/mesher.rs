//! Meshing for the page: a coarse surface first, then the full one, on a thread of its own;
//! a newer edit cancels the work in flight, and a result is published only while its
//! revision is still the newest.

use std::sync::Arc;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::time::Instant;

use skelform::{Control, LiveRun, Mesh, Overrides, Resolution};

/// Which surface of an edit a frame carries.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    /// The quick one, at [`Settings::coarse_factor`](crate::Settings::coarse_factor) times
    /// the scene's cell.
    Coarse = 0,
    /// The scene's own resolution.
    Full = 1,
}

/// Meshes `scene` at one level: the one call the studio makes into the library. `live`
/// keeps what the last run of this level made, so that an edit that moves, reshapes or
/// re-angles a few skeletal elements re-meshes only what their influence reaches
/// ([`skelform::Live`]: the same mesh as a fresh run, bit for bit); other edits, and other
/// methods than the grid, run in full. Vertex colours are left out: the page shades by
/// region. A cancelled run returns an error for which [`skelform::Error::is_cancelled`]
/// holds; a cancelled incremental run leaves its changed boxes to the next (which stays
/// incremental), a cancelled run from scratch leaves nothing. [`skelform::Live::last_run`]
/// says how the run went; the studio reports it with every surface.
pub fn mesh_scene(
    live: &mut skelform::Live,
    scene: &skelform::Scene,
    pose: Option<&str>,
    level: Level,
    coarse_factor: f64,
    control: &Control,
) -> Result<skelform::Meshed, skelform::Error> {
    let mut overrides = Overrides {
        pose: pose.map(str::to_string),
        colors: Some(false),
        control: control.clone(),
        ..Overrides::default()
    };
    if level == Level::Coarse {
        let lattice = scene.lattice(&overrides)?;
        overrides.resolution = Some(Resolution::Cell(lattice.cell * coarse_factor));
        // Linear interpolation along lattice edges: the coarse surface is a preview.
        overrides.refine = Some(false);
    }
    live.mesh(scene, &overrides)
}

/// The grid run's phases in milliseconds (sampling, extraction, root finding and
/// projection, normals), for the report: where an edit's time went.
fn phases(stats: &skelform::Stats) -> Option<[f64; 4]> {
    let skelform::Stats::Grid(s) = stats else { return None };
    Some([s.sampling, s.extraction, s.refinement, s.normals].map(|d| d.as_secs_f64() * 1e3))
}

/// The magic that opens every mesh frame.
pub const MAGIC: &[u8; 4] = b"SKFM";
/// The frame layout's version.
pub const VERSION: u32 = 1;
/// Bytes before the arrays.
pub const HEADER: usize = 32;

/// A mesh as a binary WebSocket frame (little-endian): `SKFM`, version (u32), revision
/// (u64), level (u32: 0 coarse, 1 full), vertex count V (u32), triangle count T (u32),
/// flags (u32: 1 normals, 2 labels); then V×3 f32 positions, V×3 f32 normals when flagged,
/// T×3 u32 indices, T×2 u32 region labels when flagged. Every array starts 4-aligned.
pub fn encode(revision: u64, level: Level, mesh: &Mesh) -> Vec<u8> {
    let v = mesh.positions.len();
    let t = mesh.triangles.len();
    let normals = mesh.normals.len() == v && v > 0;
    let labels = mesh.labels.len() == t && t > 0;
    let flags = u32::from(normals) | (u32::from(labels) << 1);
    let mut out = Vec::with_capacity(
        HEADER + v * 12 * (1 + usize::from(normals)) + t * (12 + 8 * usize::from(labels)),
    );
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&revision.to_le_bytes());
    out.extend_from_slice(&(level as u32).to_le_bytes());
    // Mesh sizes fit u32: triangles index vertices with u32.
    out.extend_from_slice(&(v as u32).to_le_bytes());
    out.extend_from_slice(&(t as u32).to_le_bytes());
    out.extend_from_slice(&flags.to_le_bytes());
    for p in &mesh.positions {
        p.iter().for_each(|c| out.extend_from_slice(&c.to_le_bytes()));
    }
    if normals {
        for n in &mesh.normals {
            n.iter().for_each(|c| out.extend_from_slice(&c.to_le_bytes()));
        }
    }
    for tri in &mesh.triangles {
        tri.iter().for_each(|i| out.extend_from_slice(&i.to_le_bytes()));
    }
    if labels {
        for l in &mesh.labels {
            out.extend_from_slice(&l.0.to_le_bytes());
            out.extend_from_slice(&l.1.to_le_bytes());
        }
    }
    out
}

/// What the worker is asked to mesh.
pub struct Job {
    /// The document revision the scene is of.
    pub revision: u64,
    /// The checked scene.
    pub scene: skelform::Scene,
    /// The pose shown.
    pub pose: Option<String>,
    /// Cancelled when a newer job arrives.
    pub control: Control,
    /// When the edit was handed to the worker: the coarse level's wait is measured from here
    /// (a new edit must not wait behind the last one's full level).
    pub queued: Instant,
}

/// What the worker hands back for publication.
pub enum Outcome {
    /// A surface.
    Mesh {
        /// The revision meshed.
        revision: u64,
        /// Coarse or full.
        level: Level,
        /// The surface.
        mesh: Arc<Mesh>,
        /// The surface as a frame ([`encode`]), made on the meshing thread: a full surface
        /// is a megabyte, and the studio publishes under its document's lock.
        frame: Vec<u8>,
        /// Milliseconds the call took.
        ms: f64,
        /// Milliseconds from the job's hand-over to the start of this level's run.
        waited_ms: f64,
        /// How [`skelform::Live`] ran it: incrementally, or from scratch and why.
        run: Option<LiveRun>,
        /// The grid run's phases: sampling, extraction, root finding, normals (ms).
        phases_ms: Option<[f64; 4]>,
    },
    /// The run failed (cancellation is not reported).
    Failed {
        /// The revision meshed.
        revision: u64,
        /// Why.
        message: String,
    },
}

/// The two meshing threads, one per level: the coarse surface of a new edit never waits
/// behind the full level of an older one, whose cancellation may take a moment to be seen.
pub struct Mesher {
    coarse: Sender<Arc<Job>>,
    full: Sender<Arc<Job>>,
}

impl Mesher {
    /// Hands `job` to both levels (a closed channel means the studio is shutting down).
    pub fn submit(&self, job: Job) {
        let job = Arc::new(job);
        let _ = self.coarse.send(job.clone());
        let _ = self.full.send(job);
    }
}

/// Starts the meshing threads; `publish` is called with each result and decides (under the
/// studio's lock) whether it is still current.
pub fn start(
    coarse_factor: f64,
    publish: impl Fn(Outcome) + Send + Sync + 'static,
) -> std::io::Result<Mesher> {
    let publish = Arc::new(publish);
    let spawn = |level: Level| -> std::io::Result<Sender<Arc<Job>>> {
        let (tx, rx) = channel::<Arc<Job>>();
        // Each level has a rayon pool of its own: in the global pool the coarse run's tasks
        // would queue behind the full run's.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(std::thread::available_parallelism().map_or(2, |n| n.get()))
            .thread_name(move |i| format!("skelform-studio-{}-{i}", level.name()))
            .start_handler(move |_| {
                if level == Level::Full {
                    yield_to_the_coarse_level();
                }
            })
            .build()
            .map_err(std::io::Error::other)?;
        let publish = publish.clone();
        std::thread::Builder::new()
            .name(format!("skelform-studio-{}", level.name()))
            .spawn(move || worker(rx, level, coarse_factor, &pool, &*publish))?;
        Ok(tx)
    };
    Ok(Mesher { coarse: spawn(Level::Coarse)?, full: spawn(Level::Full)? })
}

/// The full level is the dissertation's refinement in idle time: its threads (its pool's and
/// the one that encodes its frames) run at a lower priority, so that while both levels are at work (the first moments after every edit of
/// a drag) the cores go to the coarse surface the designer is waiting for. Alone, the full
/// level still has every core.
#[cfg(target_os = "linux")]
fn yield_to_the_coarse_level() {
    // SAFETY: setpriority only reads its integer arguments. On Linux, PRIO_PROCESS with id 0
    // sets the nice value of the calling thread alone. A refusal leaves the normal priority,
    // which is only slower, so its result is not needed.
    unsafe {
        libc::setpriority(libc::PRIO_PROCESS, 0, 10);
    }
}

#[cfg(not(target_os = "linux"))]
fn yield_to_the_coarse_level() {}

impl Level {
    fn name(self) -> &'static str {
        match self {
            Level::Coarse => "coarse",
            Level::Full => "full",
        }
    }
}

fn worker(
    rx: Receiver<Arc<Job>>,
    level: Level,
    coarse_factor: f64,
    pool: &rayon::ThreadPool,
    publish: &(impl Fn(Outcome) + ?Sized),
) {
    // The full level's own thread encodes its megabyte frames: at its pool's priority too.
    if level == Level::Full {
        yield_to_the_coarse_level();
    }
    // The incremental re-mesher of this level: it keeps the lattice of its own resolution.
    let mut live = skelform::Live::default();
    while let Ok(mut job) = rx.recv() {
        // Only the newest of the jobs that queued up meanwhile is worth doing.
        while let Ok(newer) = rx.try_recv() {
            job = newer;
        }
        if job.control.is_cancelled() {
            continue;
        }
        let start = Instant::now();
        let waited_ms = start.duration_since(job.queued).as_secs_f64() * 1e3;
        let result = pool.install(|| {
            mesh_scene(
                &mut live,
                &job.scene,
                job.pose.as_deref(),
                level,
                coarse_factor,
                &job.control,
            )
        });
        let ms = start.elapsed().as_secs_f64() * 1e3;
        match result {
            Ok(meshed) => publish(Outcome::Mesh {
                revision: job.revision,
                level,
                frame: encode(job.revision, level, &meshed.mesh),
                phases_ms: phases(&meshed.stats),
                mesh: Arc::new(meshed.mesh),
                ms,
                waited_ms,
                run: live.last_run().cloned(),
            }),
            Err(e) if e.is_cancelled() => {}
            Err(e) => publish(Outcome::Failed { revision: job.revision, message: e.to_string() }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_has_the_documented_layout() {
        let mesh = Mesh {
            positions: vec![[0.0, 1.0, 2.0], [3.0, 4.0, 5.0], [6.0, 7.0, 8.0]],
            normals: vec![[0.0, 0.0, 1.0]; 3],
            triangles: vec![[0, 1, 2]],
            ..Mesh::default()
        };
        let f = encode(7, Level::Full, &mesh);
        assert_eq!(&f[..4], MAGIC);
        assert_eq!(u64::from_le_bytes(f[8..16].try_into().unwrap()), 7);
        assert_eq!(u32::from_le_bytes(f[16..20].try_into().unwrap()), 1);
        assert_eq!(u32::from_le_bytes(f[20..24].try_into().unwrap()), 3);
        assert_eq!(u32::from_le_bytes(f[24..28].try_into().unwrap()), 1);
        assert_eq!(u32::from_le_bytes(f[28..32].try_into().unwrap()), 1);
        assert_eq!(f.len(), HEADER + 36 + 36 + 12);
        assert_eq!(f32::from_le_bytes(f[HEADER + 16..HEADER + 20].try_into().unwrap()), 4.0);
    }
}
