//! `skelform render`, `skelform gallery` and `.glb` files as a user meets them: pictures of
//! scenes and meshes, the same picture on any thread count, turntables, glTF files with a
//! material per region pair that the Khronos validator accepts, and one clear error with
//! the right exit code for each kind of bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;
use skelform::mesh::io::{Format, WriteOptions, write_mesh};
use skelform::mesh::{CurveEdge, Mesh, RegionPair, RegionTriple};

mod common;
use common::skelform;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn example(name: &str) -> String {
    root().join("examples").join(name).display().to_string()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// Width, height and RGB bytes of a PNG file.
fn decode(path: &Path) -> (u32, u32, Vec<u8>) {
    let file = std::io::BufReader::new(std::fs::File::open(path).expect("open png"));
    let mut reader = png::Decoder::new(file).read_info().expect("png header");
    let mut buf = vec![0; reader.output_buffer_size().expect("size")];
    let info = reader.next_frame(&mut buf).expect("png frame");
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

fn pixel(img: &(u32, u32, Vec<u8>), x: u32, y: u32) -> [u8; 3] {
    let i = 3 * (y * img.0 + x) as usize;
    [img.2[i], img.2[i + 1], img.2[i + 2]]
}

const BACKGROUND: [u8; 3] = [0xfa, 0xfa, 0xf7];

fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn a_scene_renders_to_a_png() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("torus.png");
    let o = skelform(&[
        "render",
        &example("torus.toml"),
        "-o",
        s(&out),
        "--size",
        "160x120",
        "--resolution",
        "32",
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = decode(&out);
    assert_eq!((img.0, img.1), (160, 120));
    assert_eq!(pixel(&img, 0, 0), BACKGROUND);
    // The torus's hole is seen at a slant: the centre is surface (its far inner wall), the
    // left and right of the middle row are surface, the corners are not.
    assert_ne!(pixel(&img, 40, 60), BACKGROUND);
    assert_ne!(pixel(&img, 120, 60), BACKGROUND);
    assert_eq!(listing(dir.path()), ["torus.png"], "no temporary file is left");
}

#[test]
fn a_mesh_renders_the_same_from_ply_and_from_glb() {
    let dir = tempfile::tempdir().unwrap();
    let mut pictures = Vec::new();
    for ext in ["ply", "glb"] {
        let mesh = dir.path().join(format!("t.{ext}"));
        let o =
            skelform(&["mesh", &example("torus.toml"), "-o", s(&mesh), "--resolution", "24", "-q"]);
        assert!(o.status.success(), "{}", stderr(&o));
        let out = dir.path().join(format!("{ext}.png"));
        let o = skelform(&["render", s(&mesh), "-o", s(&out), "--size", "120x90", "-q"]);
        assert!(o.status.success(), "{ext}: {}", stderr(&o));
        pictures.push(std::fs::read(&out).unwrap());
    }
    // The .glb holds the same positions, normals and triangles in the same order.
    assert_eq!(pictures[0], pictures[1]);
}

#[test]
fn the_same_picture_on_any_thread_count() {
    let dir = tempfile::tempdir().unwrap();
    let mut pictures = Vec::new();
    for threads in ["1", "2", "4"] {
        let out = dir.path().join(format!("{threads}.png"));
        let o = skelform(&[
            "render",
            &example("double-torus.toml"),
            "-o",
            s(&out),
            "--size",
            "150x110",
            "--resolution",
            "40",
            "--threads",
            threads,
            "--transparent",
            "--wireframe",
            "-q",
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        pictures.push(std::fs::read(&out).unwrap());
    }
    assert_eq!(pictures[0], pictures[1]);
    assert_eq!(pictures[0], pictures[2]);
}

#[test]
fn a_turntable_is_an_animated_png() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("turn.png");
    let o = skelform(&[
        "render",
        &example("torus.toml"),
        "-o",
        s(&out),
        "--size",
        "64x48",
        "--resolution",
        "24",
        "--turntable",
        "6",
        "--view",
        "0,-20",
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bytes = std::fs::read(&out).unwrap();
    let count = |tag: &[u8]| bytes.windows(4).filter(|w| *w == tag).count();
    assert_eq!(count(b"acTL"), 1);
    assert_eq!(count(b"fcTL"), 6, "one frame control chunk a frame");
}

/// A mesh with three region pairs, (1, 2), (1, 3) and (2, 3), in known numbers (40, 24
/// and 12 triangles), normals, and a labelled curve: three strips of a fan around the z
/// axis.
///
/// To check the real saucer-and-square scene instead, once it lands, mesh it with
/// `skelform mesh examples/…/saucer-and-square.toml -o X.glb --json` and take the expected
/// counts per label from `skelform check X.glb --json` ("labels"); the checks in
/// `glb_structure` are the same.
fn three_pair_mesh() -> (Mesh, Vec<(RegionPair, usize)>) {
    let mut m = Mesh::default();
    let spec = [
        (RegionPair(1, 2), 20usize, 0.0f32),
        (RegionPair(1, 3), 12, 1.0),
        (RegionPair(2, 3), 6, 2.0),
    ];
    for (label, quads, z) in spec {
        let base = m.positions.len() as u32;
        for k in 0..=quads {
            let a = k as f32 / quads as f32 * std::f32::consts::PI;
            for r in [1.0f32, 2.0] {
                m.positions.push([r * a.cos(), r * a.sin(), z + 0.3 * r]);
                m.normals.push([0.0, -0.29, 0.96]);
            }
        }
        for k in 0..quads as u32 {
            let (i, o, i2, o2) =
                (base + 2 * k, base + 2 * k + 1, base + 2 * k + 2, base + 2 * k + 3);
            m.triangles.push([i, o, o2]);
            m.triangles.push([i, o2, i2]);
            m.labels.extend([label, label]);
        }
        for k in 0..quads as u32 {
            m.curves.push(CurveEdge {
                v: [base + 2 * k, base + 2 * k + 2],
                label: RegionTriple([1, 2, 3]),
            });
        }
    }
    let counts = spec.iter().map(|(l, q, _)| (*l, 2 * q)).collect();
    (m, counts)
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

/// Checks the GLB container and its JSON against the glTF 2.0 rules we rely on; returns
/// the JSON and the triangle count of each triangle primitive.
fn glb_structure(path: &Path) -> (Value, Vec<usize>) {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[0..4], b"glTF", "magic");
    assert_eq!(u32_at(&b, 4), 2, "version");
    assert_eq!(u32_at(&b, 8) as usize, b.len(), "length");
    let jl = u32_at(&b, 12) as usize;
    assert_eq!(&b[16..20], b"JSON");
    assert_eq!(jl % 4, 0, "JSON chunk padded to 4 bytes");
    let doc: Value = serde_json::from_slice(&b[20..20 + jl]).expect("the JSON chunk parses");
    assert_eq!(doc["asset"]["version"], "2.0");
    let bl = u32_at(&b, 20 + jl) as usize;
    assert_eq!(&b[24 + jl..28 + jl], b"BIN\0");
    assert_eq!(bl % 4, 0, "BIN chunk padded to 4 bytes");
    assert_eq!(28 + jl + bl, b.len(), "nothing after the BIN chunk");
    let bin = &b[28 + jl..];
    assert!(doc["buffers"][0]["byteLength"].as_u64().unwrap() as usize <= bl);
    let views = doc["bufferViews"].as_array().unwrap();
    for v in views {
        let off = v["byteOffset"].as_u64().unwrap_or(0) as usize;
        let len = v["byteLength"].as_u64().unwrap() as usize;
        assert_eq!(off % 4, 0, "aligned view");
        assert!(off + len <= bl, "view inside the BIN chunk");
    }
    let accessors = doc["accessors"].as_array().unwrap();
    let f32s = |a: &Value| -> Vec<f32> {
        let v = &views[a["bufferView"].as_u64().unwrap() as usize];
        let off = v["byteOffset"].as_u64().unwrap_or(0) as usize;
        let n = 3 * a["count"].as_u64().unwrap() as usize;
        (0..n)
            .map(|k| f32::from_le_bytes(bin[off + 4 * k..off + 4 * k + 4].try_into().unwrap()))
            .collect()
    };
    for a in accessors {
        let v = &views[a["bufferView"].as_u64().unwrap() as usize];
        let size = match (a["type"].as_str().unwrap(), a["componentType"].as_u64().unwrap()) {
            ("VEC3", 5126) => 12,
            ("SCALAR", 5125) => 4,
            other => panic!("unexpected accessor layout {other:?}"),
        };
        assert_eq!(
            a["count"].as_u64().unwrap() as usize * size,
            v["byteLength"].as_u64().unwrap() as usize
        );
    }
    let mut triangles = Vec::new();
    for mesh in doc["meshes"].as_array().unwrap() {
        for p in mesh["primitives"].as_array().unwrap() {
            let pos = &accessors[p["attributes"]["POSITION"].as_u64().unwrap() as usize];
            let values = f32s(pos);
            for k in 0..3 {
                let lo = values.iter().skip(k).step_by(3).copied().fold(f32::INFINITY, f32::min);
                let hi =
                    values.iter().skip(k).step_by(3).copied().fold(f32::NEG_INFINITY, f32::max);
                assert_eq!(pos["min"][k].as_f64().unwrap() as f32, lo, "POSITION min");
                assert_eq!(pos["max"][k].as_f64().unwrap() as f32, hi, "POSITION max");
            }
            if let Some(n) = p["attributes"].get("NORMAL") {
                let normal = &accessors[n.as_u64().unwrap() as usize];
                assert_eq!(normal["count"], pos["count"]);
                for v in f32s(normal).chunks(3) {
                    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
                    assert!((len - 1.0).abs() < 1e-5, "unit normal");
                }
            }
            let indices = &accessors[p["indices"].as_u64().unwrap() as usize];
            let count = indices["count"].as_u64().unwrap() as usize;
            if p["mode"].as_u64().unwrap_or(4) == 4 {
                assert!(p["material"].is_u64(), "every surface has a material");
                assert_eq!(count % 3, 0);
                triangles.push(count / 3);
            }
        }
    }
    (doc, triangles)
}

fn labelled_glb(dir: &Path) -> (PathBuf, Vec<(RegionPair, usize)>) {
    let (mesh, counts) = three_pair_mesh();
    let path = dir.join("three-pairs.glb");
    write_mesh(&path, &mesh, Format::Glb, &WriteOptions::default()).unwrap();
    (path, counts)
}

#[test]
fn glb_has_a_material_and_primitive_per_region_pair() {
    let dir = tempfile::tempdir().unwrap();
    let (path, counts) = labelled_glb(dir.path());
    let (doc, triangles) = glb_structure(&path);
    let materials = doc["materials"].as_array().unwrap();
    // One per region pair, and one for the curves (lines without one are drawn white).
    assert_eq!(materials.len(), 4);
    let names: Vec<&str> = materials.iter().map(|m| m["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["region 1_2", "region 1_3", "region 2_3", "curves"]);
    assert_eq!(triangles, counts.iter().map(|c| c.1).collect::<Vec<_>>());
    // skelform reads its own .glb back with the labels.
    let o = skelform(&["check", s(&path), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(report["faces"], 76);
    assert_eq!(report["curves"], 38);
    let labels: Vec<(RegionPair, usize)> = report["labels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| {
            (
                serde_json::from_value(l["label"].clone()).unwrap(),
                l["triangles"].as_u64().unwrap() as usize,
            )
        })
        .collect();
    assert_eq!(labels, counts);
    // And draws it, with a legend of the three pairs.
    let out = dir.path().join("pairs.png");
    let o = skelform(&["render", s(&path), "-o", s(&out), "--size", "200x150", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    // A scene written as .glb is one unlabelled primitive with one material.
    let glb = dir.path().join("torus.glb");
    let o = skelform(&["mesh", &example("torus.toml"), "-o", s(&glb), "--resolution", "24", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (doc, triangles) = glb_structure(&glb);
    assert_eq!(doc["materials"].as_array().unwrap().len(), 1);
    assert_eq!(triangles.len(), 1);
}

/// Where the Khronos glTF validator is installed (`.ci/run` puts it in target/npm), if it
/// is, and node with it.
fn validator() -> Option<PathBuf> {
    let dir = std::env::var_os("SKELFORM_GLTF_VALIDATOR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("target/npm/node_modules/gltf-validator"));
    let node = Command::new("node").arg("--version").output().is_ok_and(|o| o.status.success());
    (node && dir.join("package.json").exists()).then_some(dir)
}

#[test]
fn the_khronos_validator_finds_no_errors() {
    let Some(validator) = validator() else {
        assert!(
            std::env::var_os("SKELFORM_REQUIRE_GLTF_VALIDATOR").is_none(),
            "SKELFORM_REQUIRE_GLTF_VALIDATOR is set but node or the gltf-validator package is missing"
        );
        eprintln!("skipped: node or target/npm/node_modules/gltf-validator is missing");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (labelled, _) = labelled_glb(dir.path());
    let torus = dir.path().join("torus.glb");
    let o =
        skelform(&["mesh", &example("torus.toml"), "-o", s(&torus), "--resolution", "32", "-q"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let bare = dir.path().join("bare.glb");
    let o = skelform(&[
        "mesh",
        &example("two-spheres.toml"),
        "-o",
        s(&bare),
        "--resolution",
        "24",
        "--no-normals",
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    // Vertex colours (COLOR_0) from a skeleton's element colours.
    let coloured = dir.path().join("colours.glb");
    let o = skelform(&[
        "mesh",
        &example("skeleton/colours.toml"),
        "-o",
        s(&coloured),
        "--resolution",
        "32",
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::read(&coloured).unwrap().windows(7).any(|w| w == b"COLOR_0"));
    // Texture coordinates (TEXCOORD_0) from a sweep.
    let textured = dir.path().join("horn.glb");
    let o = skelform(&[
        "mesh",
        &example("skeleton/horn.toml"),
        "-o",
        s(&textured),
        "--resolution",
        "32",
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::read(&textured).unwrap().windows(10).any(|w| w == b"TEXCOORD_0"));
    // The leaf's venation texture: an embedded PNG, every surface's baseColorTexture.
    let leaf = dir.path().join("leaf.glb");
    let o = skelform(&[
        "mesh",
        &example("nonmanifold/leaf.toml"),
        "-o",
        s(&leaf),
        "--cell",
        "0.05",
        "-q",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::read(&leaf).unwrap().windows(9).any(|w| w == b"image/png"));
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/gltf-validate.js");
    let o = Command::new("node")
        .arg(&script)
        .arg(&validator)
        .args([&labelled, &torus, &bare, &coloured, &textured, &leaf])
        .output()
        .expect("run node");
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "validator: {out}\n{}", stderr(&o));
    let reports: Vec<Value> = out.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(reports.len(), 6);
    for r in reports {
        assert_eq!(r["errors"], 0, "{r}");
        assert_eq!(r["warnings"], 0, "{r}");
    }
}

#[test]
fn bad_input_gives_one_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let out = d.join("x.png");
    let cases: Vec<(Vec<String>, u8, &str)> = {
        let garbage = d.join("garbage.ply");
        std::fs::write(&garbage, b"ply\nformat ascii 1.0\nelement vertex two\n").unwrap();
        let faceless = d.join("points.obj");
        std::fs::write(&faceless, b"v 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
        let o = s(&out).to_string();
        vec![
            (
                vec!["render".into(), s(&d.join("missing.ply")).into(), "-o".into(), o.clone()],
                2,
                "cannot read",
            ),
            (vec!["render".into(), s(&garbage).into(), "-o".into(), o.clone()], 2, "line 3"),
            (vec!["render".into(), s(&faceless).into(), "-o".into(), o.clone()], 2, "no triangles"),
            (
                vec![
                    "render".into(),
                    example("torus.toml"),
                    "-o".into(),
                    o.clone(),
                    "--size".into(),
                    "0x100".into(),
                ],
                2,
                "empty",
            ),
            (
                vec![
                    "render".into(),
                    example("torus.toml"),
                    "-o".into(),
                    o.clone(),
                    "--size".into(),
                    "20000x100".into(),
                ],
                2,
                "too large",
            ),
            (
                vec![
                    "render".into(),
                    example("torus.toml"),
                    "-o".into(),
                    o.clone(),
                    "--view".into(),
                    "0,120".into(),
                ],
                2,
                "elevation",
            ),
            (
                vec![
                    "render".into(),
                    example("torus.toml"),
                    "-o".into(),
                    s(&d.join("x.jpg")).into(),
                ],
                2,
                ".png",
            ),
            (
                vec![
                    "render".into(),
                    example("torus.toml"),
                    "-o".into(),
                    o.clone(),
                    "--supersample".into(),
                    "9".into(),
                ],
                2,
                "supersample",
            ),
            (
                vec![
                    "render".into(),
                    example("torus.toml"),
                    "-o".into(),
                    s(&d.join("no/such/dir/x.png")).into(),
                    "--resolution".into(),
                    "16".into(),
                ],
                1,
                "cannot write",
            ),
        ]
    };
    for (args, code, says) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = skelform(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(code as i32), "{args:?}: {err}");
        assert!(err.contains(says), "{args:?} should say '{says}': {err}");
        assert!(err.lines().filter(|l| l.starts_with("error")).count() == 1, "{err}");
    }
    assert!(!out.exists());
    assert_eq!(listing(d), ["garbage.ply", "points.obj"], "no picture, no temporary file");
}

#[test]
fn the_gallery_renders_every_scene_with_its_figure() {
    let dir = tempfile::tempdir().unwrap();
    let ex = dir.path().join("examples");
    std::fs::create_dir_all(ex.join("chapter3")).unwrap();
    std::fs::write(
        ex.join("ball.toml"),
        "[scene]\nname = \"ball\"\n[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n[mesh]\nresolution = 16\n[field]\nformula = \"x^2 + y^2 + z^2 - 0.5\"\n",
    )
    .unwrap();
    std::fs::write(
        ex.join("chapter3/cells.toml"),
        "[scene]\nname = \"sphere cells\"\nfigure = \"3.12\"\n[domain]\nmin = [-1.5, -1.5, -1.5]\nmax = [1.5, 1.5, 1.5]\n[mesh]\nmethod = \"continuation\"\ncell = 0.4\nseeds = [[0, 0, 0]]\n[field]\nformula = \"x^2 + y^2 + z^2 - 1\"\n",
    )
    .unwrap();
    let out = dir.path().join("gallery");
    std::fs::create_dir_all(&out).unwrap();
    let run =
        || skelform(&["gallery", "--examples", s(&ex), "--out", s(&out), "--size", "96x72", "-q"]);
    let o = run();
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(listing(&out), ["README.md", "ball.png", "chapter3-cells.png"]);
    assert_eq!(decode(&out.join("ball.png")).0, 96);
    let page = std::fs::read_to_string(out.join("README.md")).unwrap();
    assert!(page.contains("<img src=\"chapter3-cells.png\""), "{page}");
    assert!(page.contains("| sphere cells ([`chapter3/cells.toml`](../examples/chapter3/cells.toml)) | fig. 3.12 | continuation |"), "{page}");
    assert!(page.contains("| ball ([`ball.toml`](../examples/ball.toml)) | — | grid |"), "{page}");
    // The same tree gives the same page and pictures again; a picture whose scene is gone
    // is removed, and a scene that fails is named on the page and fails the command.
    let before = std::fs::read(out.join("ball.png")).unwrap();
    std::fs::rename(ex.join("ball.toml"), ex.join("ball2.toml")).unwrap();
    std::fs::write(ex.join("broken.toml"), "[scene]\nname = 3\n").unwrap();
    let o = run();
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert_eq!(listing(&out), ["README.md", "ball2.png", "chapter3-cells.png"]);
    assert_eq!(std::fs::read(out.join("ball2.png")).unwrap(), before);
    let page = std::fs::read_to_string(out.join("README.md")).unwrap();
    assert!(page.contains("failed: ") && page.contains("broken.toml"), "{page}");
}

/// The gallery touches only files it wrote: a folder it did not make is refused, and a
/// user's picture beside its own survives a rerun, even one that drops pictures.
#[test]
fn the_gallery_leaves_what_it_did_not_write() {
    let dir = tempfile::tempdir().unwrap();
    let ex = dir.path().join("examples");
    std::fs::create_dir_all(&ex).unwrap();
    let ball = "[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n[mesh]\nresolution = 12\n[field]\nformula = \"x^2 + y^2 + z^2 - 0.5\"\n";
    std::fs::write(ex.join("ball.toml"), ball).unwrap();
    std::fs::write(ex.join("orb.toml"), ball).unwrap();
    let run = |out: &Path| {
        skelform(&["gallery", "--examples", s(&ex), "--out", s(out), "--size", "48x36", "-q"])
    };

    // Someone else's folder: refused, nothing written.
    let theirs = dir.path().join("theirs");
    std::fs::create_dir_all(&theirs).unwrap();
    std::fs::write(theirs.join("README.md"), "# my photos\n").unwrap();
    let o = run(&theirs);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("not made by `skelform gallery`"), "{}", stderr(&o));
    assert_eq!(listing(&theirs), ["README.md"]);
    assert_eq!(std::fs::read_to_string(theirs.join("README.md")).unwrap(), "# my photos\n");

    // Our folder with a user's photo in it: the photo stays through reruns.
    let out = dir.path().join("gallery");
    assert!(run(&out).status.success());
    std::fs::write(out.join("photo.png"), b"not ours").unwrap();
    std::fs::remove_file(ex.join("orb.toml")).unwrap();
    let o = run(&out);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(listing(&out), ["README.md", "ball.png", "photo.png"]);
    assert_eq!(std::fs::read(out.join("photo.png")).unwrap(), b"not ours");

    // A new scene whose picture name a user's file already has: refused before drawing.
    std::fs::write(out.join("orb.png"), b"also not ours").unwrap();
    std::fs::write(ex.join("orb.toml"), ball).unwrap();
    let o = run(&out);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert_eq!(std::fs::read(out.join("orb.png")).unwrap(), b"also not ours");

    // Outside the repository, the command says what it needs.
    let o = skelform(&["gallery", "--examples", s(&dir.path().join("nowhere")), "-q"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("give --examples DIR"), "{}", stderr(&o));
}

/// Drawing is bounded like meshing: a mistyped thread count is refused, not started.
#[test]
fn render_refuses_absurd_thread_counts() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("t.ply");
    assert!(
        skelform(&["mesh", &example("torus.toml"), "-o", s(&mesh), "--resolution", "12", "-q"])
            .status
            .success()
    );
    let png = dir.path().join("t.png");
    let o = skelform(&["render", s(&mesh), "-o", s(&png), "--threads", "100000"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--threads must be between 1 and 256"), "{}", stderr(&o));
    assert!(!png.exists());
}
