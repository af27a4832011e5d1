//! The `skelform` command as a user runs it: meshes from the example scenes, the checker's
//! report, and one clear error with the right exit code for every kind of bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

mod common;
use common::{check_json, example, skelform};

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Writes a scene into a temporary folder.
fn scene(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn torus_in_every_format_is_a_closed_genus_one_surface() {
    let dir = tempfile::tempdir().unwrap();
    for ext in ["ply", "obj", "stl"] {
        let out = dir.path().join(format!("torus.{ext}"));
        let o = skelform(&[
            "mesh",
            &example("torus.toml"),
            "-o",
            out.to_str().unwrap(),
            "--resolution",
            "64",
        ]);
        assert!(o.status.success(), "{ext}: {}", stderr(&o));
        let r = check_json(&out);
        assert_eq!(r["boundary_edges"], 0, "{ext}");
        assert_eq!(r["non_manifold_edges"], 0, "{ext}");
        assert_eq!(r["consistently_oriented"], true, "{ext}");
        assert_eq!(r["outward"], true, "{ext}");
        assert_eq!(r["components"].as_array().unwrap().len(), 1, "{ext}");
        assert_eq!(r["components"][0]["genus"], 1, "{ext}");
    }
}

#[test]
fn every_example_scene_meshes_closed() {
    let dir = tempfile::tempdir().unwrap();
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let mut count = 0;
    for entry in std::fs::read_dir(examples).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let out = dir.path().join("out.ply");
        let o = skelform(&[
            "mesh",
            path.to_str().unwrap(),
            "-o",
            out.to_str().unwrap(),
            "--resolution",
            "48",
        ]);
        assert!(o.status.success(), "{}: {}", path.display(), stderr(&o));
        let r = check_json(&out);
        assert_eq!(r["boundary_edges"], 0, "{}", path.display());
        assert_eq!(r["non_manifold_edges"], 0, "{}", path.display());
        assert_eq!(r["outward"], true, "{}", path.display());
        count += 1;
    }
    assert!(count >= 5);
}

#[test]
fn stats_and_json_report_the_run() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("s.ply");
    let o = skelform(&[
        "mesh",
        &example("sphere.toml"),
        "-o",
        out.to_str().unwrap(),
        "--stats",
        "--resolution",
        "33",
    ]);
    assert!(o.status.success());
    let text = stdout(&o);
    for key in
        ["samples       35937", "vertices", "triangles", "sampling", "extraction", "refinement"]
    {
        assert!(text.contains(key), "--stats lacks {key}:\n{text}");
    }
    let o = skelform(&[
        "mesh",
        &example("sphere.toml"),
        "-o",
        out.to_str().unwrap(),
        "--json",
        "--cell",
        "0.0625",
    ]);
    assert!(o.status.success());
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["samples"], 33 * 33 * 33);
    assert!(j["triangles"].as_u64().unwrap() > 1000);
    assert!(j["seconds"]["total"].as_f64().unwrap() >= 0.0);
}

#[test]
fn output_is_the_same_for_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for t in ["1", "2", "4"] {
        let out = dir.path().join(format!("g{t}.ply"));
        let o = skelform(&[
            "mesh",
            &example("gyroid.toml"),
            "-o",
            out.to_str().unwrap(),
            "--threads",
            t,
            "--resolution",
            "64",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        files.push(std::fs::read(out).unwrap());
    }
    assert!(files.windows(2).all(|w| w[0] == w[1]), "meshes differ between thread counts");
}

#[test]
fn check_reads_ascii_ply_and_reports_text() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("t.ply");
    let o = skelform(&[
        "mesh",
        &example("sphere.toml"),
        "-o",
        out.to_str().unwrap(),
        "--ascii",
        "--resolution",
        "20",
    ]);
    assert!(o.status.success());
    assert!(std::fs::read_to_string(&out).unwrap().starts_with("ply\nformat ascii 1.0"));
    let o = skelform(&["check", out.to_str().unwrap()]);
    assert!(o.status.success());
    let text = stdout(&o);
    assert!(text.contains("genus 0"), "{text}");
    assert!(text.contains("closed manifold"), "{text}");
}

/// Runs a failing command; checks the exit code, that stderr is one line naming `needle`,
/// and that no output file was left.
fn fails(args: &[&str], code: i32, needle: &str, out: Option<&Path>) {
    let o = skelform(args);
    assert_eq!(o.status.code(), Some(code), "{args:?}: {}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains(needle), "{args:?}: expected '{needle}' in: {err}");
    assert_eq!(err.trim_end().lines().count(), 1, "one line: {err}");
    assert!(!err.contains("panicked"), "{err}");
    if let Some(out) = out {
        assert!(!out.exists(), "{args:?} left {}", out.display());
    }
}

#[test]
fn bad_input_gets_one_clear_line_and_exit_code() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("out.ply");
    let o = out.to_str().unwrap();
    let head = "[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n";

    let missing = d.join("missing.toml");
    fails(&["mesh", missing.to_str().unwrap(), "-o", o], 2, "missing.toml", Some(&out));

    // A thread count far beyond any machine is refused before a thread starts.
    let p = scene(d, "ball.toml", &format!("{head}[field]\nformula = \"x^2 + y^2 + z^2 - 0.5\"\n"));
    fails(
        &["mesh", p.to_str().unwrap(), "-o", o, "--threads", "100000"],
        2,
        "threads must be between 1 and 256",
        Some(&out),
    );

    let p = scene(
        d,
        "badtoml.toml",
        "[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1\n[field]\nformula = \"x\"\n",
    );
    fails(&["mesh", p.to_str().unwrap(), "-o", o], 2, "badtoml.toml:4:1", Some(&out));

    let p = scene(
        d,
        "unknown.toml",
        &format!("{head}[mesh]\nresolutoin = 5\n[field]\nformula = \"x\"\n"),
    );
    fails(
        &["mesh", p.to_str().unwrap(), "-o", o],
        2,
        "unknown.toml:5:1: unknown field `resolutoin`",
        Some(&out),
    );

    let p = scene(
        d,
        "syntax.toml",
        &format!("{head}[field]\nformula = \"\"\"\nr = sqrt(x^2 + y^2)\nr - * z\n\"\"\"\n"),
    );
    fails(&["mesh", p.to_str().unwrap(), "-o", o], 2, "syntax.toml:7:5", Some(&out));

    let p = scene(
        d,
        "name.toml",
        &format!("{head}[field]\nformula = \"sqrt(x^2 + y^2 + z^2) - radius\"\n"),
    );
    fails(
        &["mesh", p.to_str().unwrap(), "-o", o],
        2,
        "name.toml:5:36: unknown name 'radius'",
        Some(&out),
    );

    let p = scene(
        d,
        "huge.toml",
        &format!("{head}[mesh]\nresolution = 5000\n[field]\nformula = \"x\"\n"),
    );
    fails(&["mesh", p.to_str().unwrap(), "-o", o], 2, "GiB", Some(&out));
    fails(
        &["mesh", &example("sphere.toml"), "-o", o, "--resolution", "400", "--max-memory", "64M"],
        2,
        "limit",
        Some(&out),
    );

    let p = scene(d, "empty.toml", &format!("{head}[field]\nformula = \"x^2 + y^2 + z^2 + 1\"\n"));
    fails(&["mesh", p.to_str().unwrap(), "-o", o], 1, "no surface in the domain", Some(&out));

    let unwritable = d.join("no/such/dir/out.ply");
    fails(
        &["mesh", &example("sphere.toml"), "-o", unwritable.to_str().unwrap()],
        1,
        "cannot write",
        None,
    );
    fails(
        &["mesh", &example("sphere.toml"), "-o", d.join("out.xyz").to_str().unwrap()],
        2,
        "unknown output format",
        None,
    );
    // Lattices too large to count are refused with the per-axis limit, by every method.
    for m in ["grid", "healed", "tetra", "continuation"] {
        fails(
            &["mesh", &example("sphere.toml"), "-o", o, "--cell", "1e-19", "--method", m],
            2,
            "at most 32768 are allowed along one axis",
            Some(&out),
        );
    }
    // A mistyped thread count once hung a machine starting threads.
    fails(
        &["mesh", &example("sphere.toml"), "-o", o, "--threads", "100000"],
        2,
        "threads must be between 1 and 256 (got 100000)",
        Some(&out),
    );
    fails(
        &["mesh", &example("sphere.toml"), "-o", o, "--method", "magic"],
        2,
        "invalid value 'magic' for '--method <METHOD>' [possible values: grid, continuation, tetra, healed, nonmanifold]",
        Some(&out),
    );

    let garbage = scene(d, "garbage.ply", "this is not a mesh\n");
    fails(&["check", garbage.to_str().unwrap()], 2, "garbage.ply", None);
    fails(&["check", d.join("nothing.ply").to_str().unwrap()], 2, "nothing.ply", None);
}

#[test]
fn usage_errors_exit_with_two() {
    let o = skelform(&["mesh"]);
    assert_eq!(o.status.code(), Some(2));
    let o = skelform(&["--help"]);
    assert!(o.status.success());
    assert!(stdout(&o).contains("mesh"));
}

/// A full disk is a clear runtime failure; a reader that has gone ends the run quietly. Neither
/// panics ("failed printing to stdout").
#[test]
fn standard_output_that_fails_is_not_a_panic() {
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_skelform"))
        .args(["info", &example("gyroid.toml")])
        .stdout(full)
        .output()
        .unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("cannot write to standard output"), "{err}");
    assert!(!err.contains("panicked"), "{err}");

    let mut child = Command::new(env!("CARGO_BIN_EXE_skelform"))
        .args(["info", &example("gyroid.toml"), "--tape"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let o = child.wait_with_output().unwrap();
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(0), "{err}");
    assert!(err.is_empty(), "a closed pipe ends quietly: {err}");
}

/// A scene names output files in its own folder only: `..` or an absolute path in
/// `[output] file` is refused (exit 2, nothing written); `-o` may name any path.
#[test]
fn a_scene_cannot_write_outside_its_folder() {
    let dir = tempfile::tempdir().unwrap();
    let inner = dir.path().join("a/b");
    std::fs::create_dir_all(&inner).unwrap();
    let victim = dir.path().join("victim.ply");
    std::fs::write(&victim, b"keep me").unwrap();
    let body = "[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n[mesh]\nresolution = 12\n[field]\nformula = \"x^2 + y^2 + z^2 - 0.5\"\n";
    for file in ["../../victim.ply".to_string(), victim.display().to_string()] {
        let scene = inner.join("s.toml");
        std::fs::write(&scene, format!("{body}[output]\nfile = \"{file}\"\n")).unwrap();
        let o = skelform(&["mesh", scene.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{file}: {}", stderr(&o));
        assert!(stderr(&o).contains("outside the scene's folder"), "{}", stderr(&o));
        assert_eq!(std::fs::read(&victim).unwrap(), b"keep me");
        let info = skelform(&["info", scene.to_str().unwrap()]);
        assert!(stdout(&info).contains("output      refused"), "{}", stdout(&info));
    }
    let scene = inner.join("s.toml");
    std::fs::write(&scene, format!("{body}[output]\nfile = \"out/m.ply\"\n")).unwrap();
    std::fs::create_dir_all(inner.join("out")).unwrap();
    let o = skelform(&["mesh", scene.to_str().unwrap(), "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(inner.join("out/m.ply").exists());
    let o = skelform(&["mesh", scene.to_str().unwrap(), "-q", "-o", victim.to_str().unwrap()]);
    assert!(o.status.success(), "the command line may name any path: {}", stderr(&o));
}

/// A field that is NaN everywhere is said to be so (not "values from 3.4e38 to 3.4e38"); a
/// memory limit above the machine's is held to the machine's, with a warning, so the check
/// still refuses what the machine cannot hold.
#[test]
fn undefined_fields_and_impossible_limits_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("nan.toml");
    std::fs::write(
        &scene,
        "[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n[mesh]\nresolution = 12\n[field]\nformula = \"ln(-1 - x^2)\"\n",
    )
    .unwrap();
    let out = dir.path().join("m.ply");
    let o = out.to_str().unwrap();
    fails(
        &["mesh", scene.to_str().unwrap(), "-o", o],
        1,
        "all 1728 samples are NaN or infinite",
        Some(&out),
    );
    let r = skelform(&[
        "mesh",
        &example("sphere.toml"),
        "-o",
        o,
        "--max-memory",
        "1000T",
        "--resolution",
        "30000",
    ]);
    assert_eq!(r.status.code(), Some(2), "{}", stderr(&r));
    let err = stderr(&r);
    assert!(err.contains("more than this machine has"), "{err}");
    assert!(err.contains("over the limit"), "{err}");
    assert!(!err.contains("panicked") && !out.exists(), "{err}");
}

/// `info --json` describes the scene as data; `check --strict` turns defects into exit
/// status 3 (a clean mesh passes), for scripts and print pipelines.
#[test]
fn info_as_json_and_a_strict_check() {
    let o = skelform(&["info", &example("skeleton/hand.toml"), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(j["method"], "grid");
    assert_eq!(j["grid"]["dims"].as_array().unwrap().len(), 3);
    assert!(j["poses"].as_array().unwrap().iter().any(|p| p == "grip"), "{j}");

    let dir = tempfile::tempdir().unwrap();
    let closed = dir.path().join("t.ply");
    let r = skelform(&[
        "mesh",
        &example("torus.toml"),
        "-o",
        closed.to_str().unwrap(),
        "--resolution",
        "20",
        "-q",
    ]);
    assert!(r.status.success());
    assert!(skelform(&["check", "--strict", closed.to_str().unwrap()]).status.success());
    // The same surface cut open by the domain box: boundary edges.
    let open = dir.path().join("open.ply");
    let scene = dir.path().join("open.toml");
    std::fs::write(&scene, "[domain]\nmin = [-1, -1, 0]\nmax = [1, 1, 1]\n[mesh]\nresolution = 20\n[field]\nformula = \"x^2 + y^2 + z^2 - 0.5\"\n").unwrap();
    assert!(
        skelform(&["mesh", scene.to_str().unwrap(), "-o", open.to_str().unwrap(), "-q"])
            .status
            .success()
    );
    let r = skelform(&["check", "--strict", open.to_str().unwrap()]);
    assert_eq!(r.status.code(), Some(3), "{}", stderr(&r));
    assert!(stderr(&r).contains("boundary edges"), "{}", stderr(&r));
    assert!(stdout(&r).contains("boundary"), "the report is still printed");
}

/// Completion scripts for the usual shells, knowing the subcommands and the method names.
#[test]
fn shell_completions_know_the_commands() {
    for shell in ["bash", "zsh", "fish"] {
        let o = skelform(&["completions", shell]);
        assert!(o.status.success(), "{shell}: {}", stderr(&o));
        let script = stdout(&o);
        for word in ["mesh", "extract", "nonmanifold", "regula-falsi"] {
            assert!(script.contains(word), "{shell} completion lacks {word}");
        }
    }
}

/// `-` is standard output for `mesh -o` (with --format) and standard input for `check`
/// (format from --format or the first bytes): pipelines without temporary files.
#[test]
fn a_dash_is_a_standard_stream() {
    use std::io::Write as _;
    for format in ["ply", "obj", "stl", "glb"] {
        let o = skelform(&[
            "mesh",
            &example("torus.toml"),
            "-o",
            "-",
            "--format",
            format,
            "--resolution",
            "16",
            "-q",
        ]);
        assert!(o.status.success(), "{format}: {}", stderr(&o));
        assert!(o.stdout.len() > 1000, "{format}: the mesh on standard output");
        let mut check = Command::new(env!("CARGO_BIN_EXE_skelform"))
            .args(["check", "-", "--json", "--strict"])
            .stdin(std::process::Stdio::piped())
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        check.stdin.take().unwrap().write_all(&o.stdout).unwrap();
        let c = check.wait_with_output().unwrap();
        assert!(c.status.success(), "{format}: {}", stderr(&c));
        let j: serde_json::Value = serde_json::from_slice(&c.stdout).unwrap();
        assert_eq!(j["components"][0]["genus"], 1, "{format}");
    }
    let o = skelform(&["mesh", &example("torus.toml"), "-o", "-"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("give its --format"), "{}", stderr(&o));
    assert!(o.stdout.is_empty());
}

#[test]
fn image_polygons_too_costly_to_build_are_refused_at_their_place_with_the_memory_need_in_info() {
    let dir = tempfile::tempdir().unwrap();
    // Two polygons at the largest image resolution with a kernel that is not separable:
    // hundreds of billions of pixel operations, refused before any image is built.
    let text = std::fs::read_to_string(example("skeleton/image-polygons.toml"))
        .unwrap()
        .replace("image_resolution = 80 ", "image_resolution = 1024")
        .replace("[skeleton]\n", "[skeleton]\nkernel = \"wyvill\"\n");
    let p = scene(dir.path(), "costly.toml", &text);
    let out = dir.path().join("costly.ply");
    let o = skelform(&["mesh", p.to_str().unwrap(), "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("costly.toml:") && e.contains("pixel operations"), "{e}");
    assert!(e.contains("polygon_method = \"exact\""), "{e}");
    assert!(!out.exists());
    // `info` names what each method holds up front.
    let o = skelform(&["info", &example("nonmanifold/sphere-and-square.toml")]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stdout(&o).contains("MiB: every cube, region and cache of the full grid"),
        "{}",
        stdout(&o)
    );
    let o = skelform(&["info", &example("healed/diabolo.toml"), "--json"]);
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(j["grid"]["memory_bytes"].as_u64().unwrap() > 0, "{j}");
    assert_eq!(j["grid"]["memory_for"], "the sampled volume, before triangles");
}

#[test]
fn check_measures_vertices_against_a_scenes_surface() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sphere.ply");
    let sphere = example("sphere.toml");
    let o = skelform(&["mesh", &sphere, "-o", out.to_str().unwrap(), "--resolution", "32", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Against its own scene: every vertex on the surface (root finding to 10⁻⁴ of a cell).
    let o = skelform(&["check", out.to_str().unwrap(), "--field", &sphere, "--json", "--strict"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let d = &j["surface_distance"];
    assert_eq!(d["over"], 0, "{d}");
    assert!(d["max"].as_f64().unwrap() < 1e-5, "{d}");
    assert_eq!(d["vertices"], j["vertices"]);
    // Against a sphere of radius 0.81 (the mesh's is 0.8): every vertex 0.01 off, past the
    // default tolerance of 1% of that scene's cell; --strict makes it a defect.
    let bigger = scene(
        dir.path(),
        "bigger.toml",
        &std::fs::read_to_string(&sphere).unwrap().replace("- 0.8\"", "- 0.81\""),
    );
    let o = skelform(&["check", out.to_str().unwrap(), "--field", bigger.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("off surface   max 1.00"), "{text}");
    let o = skelform(&[
        "check",
        out.to_str().unwrap(),
        "--field",
        bigger.to_str().unwrap(),
        "--strict",
    ]);
    assert_eq!(o.status.code(), Some(3), "{}", stderr(&o));
    assert!(stderr(&o).contains("vertices off the surface by more than"), "{}", stderr(&o));
    // A looser tolerance accepts it.
    let o = skelform(&[
        "check",
        out.to_str().unwrap(),
        "--field",
        bigger.to_str().unwrap(),
        "--field-tolerance",
        "0.02",
        "--strict",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // A scene of regions has no surface to measure against; a bad tolerance is refused.
    let regions = example("nonmanifold/saucer-and-square.toml");
    let o = skelform(&["check", out.to_str().unwrap(), "--field", &regions]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("no [field]"), "{}", stderr(&o));
    let o = skelform(&["check", out.to_str().unwrap(), "--field", &sphere, "--field-tolerance=-1"]);
    assert_eq!(o.status.code(), Some(2));
}
