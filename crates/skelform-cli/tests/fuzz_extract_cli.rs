//! Fuzzing `skelform extract`'s command line (the binary itself): the raw file and every
//! argument that sizes or places the lattice. `crates/skelform/tests/fuzz_extract.rs`
//! fuzzes the library beneath it with far more cases.
//!
//! Generators: `--dims` (ordinary, 0 or 1 sample, past the per-axis limit, past 64 bits,
//! malformed), `--iso`, `--origin`, `--spacing` and `--max-memory` (ordinary, extreme, NaN,
//! infinite, malformed), `--threads` (one count, several, 0, 100 000), `--stream`,
//! `--ascii`, `--json`, the output's extension; raw files of exactly the declared size or a
//! few bytes off, of spheres or of extreme samples.
//!
//! Properties: the process ends within its limit with exit code 0, 1 or 2 and never a
//! panic; an error is one `error: ...` line on standard error saying what is wrong; exit 0 leaves a
//! mesh that reads back, any other leaves no output file.
//!
//! CI runs a few dozen processes. A longer run:
//! `SKELFORM_FUZZ_SECONDS=3600 cargo test --release -p skelform-cli --test fuzz_extract_cli -- --nocapture`
//! runs the property for an hour, with fresh seeds each round (see `fuzz/harness.rs`).

#[path = "../../../fuzz/harness.rs"]
mod harness;

use std::process::Command;
use std::time::Duration;

use proptest::prelude::*;

#[global_allocator]
static GUARD: harness::Guard = harness::Guard;

const LIMIT: Duration = Duration::from_secs(60);

#[derive(Clone, Debug)]
struct Args {
    dims: String,
    /// The samples the file holds along x, y, z (the declared dims, when they parse).
    file_dims: [usize; 3],
    /// Bytes added to (or, negative, removed from) the file.
    off_by: i64,
    extreme_samples: bool,
    flags: Vec<(String, String)>,
    extension: &'static str,
}

fn args() -> impl Strategy<Value = Args> {
    let side = 2usize..7;
    let dims = prop_oneof![
        6 => (side.clone(), side.clone(), side).prop_map(|(x, y, z)| (format!("{x},{y},{z}"), [x, y, z])),
        1 => prop::sample::select(vec![
            "0,3,3", "1,3,3", "3,3", "3,3,3,3", "32769,2,2", "4294967296,4294967296,4294967296",
            "18446744073709551616,2,2", "-1,3,3", " 3 , 3 , 3 ", "x,y,z", "", "3,,3", "1e3,2,2",
            "30000,30000,30000",
        ])
        .prop_map(|d| (d.to_string(), [3, 3, 3])),
    ];
    let flag = prop_oneof![
        (
            "--iso",
            prop::sample::select(vec![
                "0", "0.3", "-0.2", "nan", "NaN", "inf", "-inf", "1e300", "-1e300", "1e-320", "x",
                "", "1,2"
            ])
        ),
        (
            "--origin",
            prop::sample::select(vec![
                "0,0,0",
                "-1,-1,-1",
                "1e38,0,0",
                "3.4e38,0,0",
                "1e39,0,0",
                "nan,0,0",
                "inf,0,0",
                "1,2",
                "0,0,0,0",
                "a,b,c"
            ])
        ),
        (
            "--spacing",
            prop::sample::select(vec![
                "1", "0.1", "0", "-1", "nan", "inf", "1e-300", "5e-324", "1e38", "2e38", "x"
            ])
        ),
        (
            "--max-memory",
            prop::sample::select(vec![
                "4G",
                "1K",
                "0",
                "1",
                "16E",
                "18446744073709551615",
                "99999999999999999999T",
                "1.5G",
                "-1",
                "x"
            ])
        ),
        ("--threads", prop::sample::select(vec!["1", "2", "1,2", "0", "100000", "1,0", "", "x"])),
        ("--stream", Just("")),
        ("--ascii", Just("")),
        ("--json", Just("")),
        ("--repeat", prop::sample::select(vec!["1", "2", "0", "x"])),
    ]
    .prop_map(|(f, v)| (f.to_string(), v.to_string()));
    (
        dims,
        prop_oneof![8 => Just(0i64), 1 => -8i64..8],
        any::<bool>(),
        prop::collection::vec(flag, 0..5),
        prop::sample::select(vec!["ply", "obj", "stl", "glb", "xyz"]),
    )
        .prop_map(|((dims, file_dims), off_by, extreme_samples, flags, extension)| Args {
            dims,
            file_dims,
            off_by,
            extreme_samples,
            flags,
            extension,
        })
}

fn raw(a: &Args) -> Vec<u8> {
    let [nx, ny, nz] = a.file_dims;
    let extremes =
        [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, f32::MAX, -f32::MAX, 0.0, -1.0, 1.0, 1e-45];
    let mut out = Vec::new();
    let mut n = 0;
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let t = |a: usize, m: usize| -1.0 + 2.0 * a as f32 / (m - 1) as f32;
                let v = if a.extreme_samples {
                    extremes[(n * 7 + k) % extremes.len()]
                } else {
                    (t(i, nx).powi(2) + t(j, ny).powi(2) + t(k, nz).powi(2)).sqrt() - 0.6
                };
                out.extend_from_slice(&v.to_le_bytes());
                n += 1;
            }
        }
    }
    if a.off_by < 0 {
        out.truncate(out.len().saturating_sub(a.off_by.unsigned_abs() as usize));
    } else {
        out.extend(std::iter::repeat_n(0x3F, a.off_by as usize));
    }
    out
}

fn run(a: &Args) -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(|e| format!("no temporary folder: {e}"))?;
    let vol = dir.path().join("v.raw");
    std::fs::write(&vol, raw(a)).map_err(|e| format!("cannot write the volume: {e}"))?;
    let out = dir.path().join(format!("out.{}", a.extension));
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_skelform"));
    cmd.arg("extract").arg(&vol).arg("-o").arg(&out).arg(format!("--dims={}", a.dims));
    for (flag, value) in &a.flags {
        if value.is_empty() && !matches!(flag.as_str(), "--iso" | "--threads") {
            cmd.arg(flag);
        } else {
            cmd.arg(format!("{flag}={value}"));
        }
    }
    let o = cmd.output().map_err(|e| format!("cannot run skelform: {e}"))?;
    let err = String::from_utf8_lossy(&o.stderr);
    if err.contains("panicked") || err.contains("RUST_BACKTRACE") {
        return Err(format!("a panic: {err}"));
    }
    match o.status.code() {
        Some(0) => {
            let mesh = skelform::mesh::io::read_mesh(&out)
                .map_err(|e| format!("exit 0, but the output does not read back: {e}"))?;
            mesh.validate().map_err(|e| format!("exit 0, but an invalid mesh: {e}"))?;
        }
        Some(1 | 2) => {
            // One line says `error: ...` (after any warnings; clap's usage errors add the
            // usage and a hint).
            let said = err.lines().filter(|l| l.starts_with("error: ")).count();
            if said != 1 || err.lines().any(|l| l.trim() == "error:") {
                return Err(format!("exit {:?} with an unclear message: {err:?}", o.status.code()));
            }
            if out.exists() {
                return Err(format!("exit {:?}, but an output file was left", o.status.code()));
            }
        }
        other => return Err(format!("exit {other:?}: {err}")),
    }
    Ok(())
}

#[test]
fn extract_ends_with_a_mesh_or_a_clear_error() {
    harness::fuzz("extract command line", 48, LIMIT, args(), |a| run(&a));
}

/// Regression (found while writing this fuzzer): `extract --threads` took any count and
/// built a pool of that many threads (`--threads 100000` started a hundred thousand), where
/// `mesh --threads` refuses counts outside 1 ..= 256.
#[test]
fn extract_refuses_thread_counts_past_the_limit() {
    let dir = tempfile::tempdir().expect("a temporary folder");
    let vol = dir.path().join("v.raw");
    std::fs::write(&vol, vec![0u8; 4 * 27]).expect("write the volume");
    let out = dir.path().join("o.ply");
    for threads in ["100000", "0", "1,257"] {
        let o = Command::new(env!("CARGO_BIN_EXE_skelform"))
            .arg("extract")
            .arg(&vol)
            .args(["--dims", "3,3,3", "--threads", threads, "-o"])
            .arg(&out)
            .output()
            .expect("run skelform");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "--threads {threads}: {err}");
        assert!(err.contains("--threads must be between 1 and 256"), "--threads {threads}: {err}");
    }
}
