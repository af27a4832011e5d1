//! `skelform extract` on raw float32 volumes.

mod common;
use common::skelform;

/// A sphere of radius `r` sampled on n³ points of [-1, 1]³, x fastest, as raw bytes.
fn sphere(n: usize, r: f32) -> Vec<u8> {
    let mut out = Vec::with_capacity(n * n * n * 4);
    let at = |i: usize| -1.0 + 2.0 * i as f32 / (n - 1) as f32;
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let v = (at(i).powi(2) + at(j).powi(2) + at(k).powi(2)).sqrt() - r;
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    out
}

#[test]
fn extracts_a_closed_surface_from_a_raw_volume() {
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("s.raw");
    std::fs::write(&vol, sphere(40, 0.7)).unwrap();
    let out = dir.path().join("s.ply");
    let o = skelform(&[
        "extract",
        vol.to_str().unwrap(),
        "--dims",
        "40,40,40",
        "-o",
        out.to_str().unwrap(),
        "--json",
        "--spacing",
        "0.05128205",
        "--origin",
        "-1,-1,-1",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(j["triangles"].as_u64().unwrap() > 1000);
    let c = skelform(&["check", out.to_str().unwrap(), "--json"]);
    let r: serde_json::Value = serde_json::from_slice(&c.stdout).unwrap();
    assert_eq!(r["boundary_edges"], 0);
    assert_eq!(r["components"][0]["genus"], 0);
    assert_eq!(r["outward"], true);
    // The iso value moves the surface: the level 0.1 of the distance is a larger sphere.
    let o = skelform(&[
        "extract",
        vol.to_str().unwrap(),
        "--dims",
        "40,40,40",
        "-o",
        out.to_str().unwrap(),
        "--iso",
        "0.1",
    ]);
    assert!(o.status.success());
}

#[test]
fn streaming_the_file_gives_the_same_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("s.raw");
    std::fs::write(&vol, sphere(37, 0.6)).unwrap();
    let run = |out: &str, extra: &[&str]| {
        let out = dir.path().join(out);
        let mut args = vec!["extract", vol.to_str().unwrap(), "--dims", "37,37,37", "--json"];
        args.extend_from_slice(&["-o", out.to_str().unwrap()]);
        args.extend_from_slice(extra);
        let o = skelform(&args);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        (std::fs::read(out).unwrap(), j)
    };
    let (whole, jw) = run("whole.ply", &[]);
    let (streamed, js) = run("streamed.ply", &["--stream", "--threads", "3"]);
    assert_eq!(js["streamed"], true);
    assert_eq!(jw["triangles"], js["triangles"]);
    assert!(whole == streamed, "the streamed mesh differs");
    // Repeated extractions (for benchmarks) time each run and write the same mesh.
    for extra in [&["--repeat", "3"][..], &["--repeat", "2", "--stream"][..]] {
        let (again, j) = run("again.ply", extra);
        let times = j["seconds"]["extractions"].as_array().unwrap();
        assert_eq!(times.len().to_string(), extra[1], "{j}");
        assert!(times.contains(&j["seconds"]["extraction"]), "the median is one of the runs: {j}");
        assert!(again == whole, "a repeated extraction differs: {extra:?}");
    }
    // Several thread counts: each round runs every count; each gets its times and its
    // speed-ups over the first, round by round, and the mesh is the same.
    for stream in [&[][..], &["--stream"][..]] {
        let (again, j) =
            run("scaling.ply", &[&["--threads", "1,3", "--repeat", "4"], stream].concat());
        let scaling = j["scaling"].as_array().unwrap();
        assert_eq!(scaling.len(), 2, "{j}");
        assert_eq!(
            (scaling[0]["threads"].as_u64(), scaling[1]["threads"].as_u64()),
            (Some(1), Some(3))
        );
        for s in scaling {
            assert_eq!(s["extractions"].as_array().unwrap().len(), 4, "{j}");
            let ups: Vec<f64> =
                s["speedups"].as_array().unwrap().iter().map(|u| u.as_f64().unwrap()).collect();
            assert_eq!(ups.len(), 4, "{j}");
            assert!(ups.iter().all(|u| u.is_finite() && *u > 0.0), "{j}");
            assert!(ups.contains(&s["speedup"].as_f64().unwrap()), "the median is a round's: {j}");
        }
        assert!(scaling[0]["speedups"].as_array().unwrap().iter().all(|u| u == 1.0), "{j}");
        assert_eq!(j["seconds"]["extractions"], scaling[0]["extractions"]);
        assert!(again == whole, "the mesh of a scaling run differs");
    }
}

#[test]
fn bad_volumes_are_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("s.raw");
    std::fs::write(&vol, sphere(10, 0.5)).unwrap();
    let out = dir.path().join("o.ply");
    let (v, o) = (vol.to_str().unwrap(), out.to_str().unwrap());
    for (args, code, needle) in [
        (vec!["extract", v, "--dims", "10,10,11", "-o", o], 2, "bytes"),
        (vec!["extract", v, "--dims", "10,10", "-o", o], 2, "sample counts"),
        (vec!["extract", "/no/such.raw", "--dims", "10,10,10", "-o", o], 2, "/no/such.raw"),
        (vec!["extract", v, "--dims", "10,10,10", "-o", o, "--iso", "5"], 1, "no surface"),
        (vec!["extract", v, "--dims", "10000,10000,10000", "-o", o], 2, "GiB"),
    ] {
        let r = skelform(&args);
        let err = String::from_utf8_lossy(&r.stderr).to_string();
        assert_eq!(r.status.code(), Some(code), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!out.exists());
    }
}

/// Sizes from the command line are checked before anything is read or allocated: counts
/// whose byte size would wrap, axes over the lattice limit, coordinates past f32.
#[test]
fn hostile_sizes_are_refused_up_front() {
    let dir = tempfile::tempdir().unwrap();
    let vol = dir.path().join("v.raw");
    std::fs::write(&vol, sphere(4, 0.5)).unwrap();
    let out = dir.path().join("v.ply");
    let (v, o) = (vol.to_str().unwrap(), out.to_str().unwrap());
    for (args, needle) in [
        (vec!["--dims", "4294967296,4294967296,4294967296"], "at most 32768 samples"),
        (vec!["--dims", "30000,30000,30000"], "over the limit"),
        (vec!["--dims", "4,4,4", "--origin", "1e39,0,0"], "32-bit coordinates"),
        (vec!["--dims", "4,4,4", "--spacing", "2e38"], "32-bit coordinates"),
    ] {
        let mut all = vec!["extract", v, "-o", o];
        all.extend(&args);
        let r = skelform(&all);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!out.exists());
    }
}
