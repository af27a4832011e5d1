//! Fuzzing the scene parser and builder (`Scene::parse`).
//!
//! Generators: every example scene under `examples/`, damaged: bytes flipped, text cut off,
//! lines deleted, duplicated or swapped, tokens swapped, numbers replaced by extremes (1e308,
//! −0, `nan`, `inf`, integers past 64 bits, 0), values replaced by arrays or inline tables
//! nested thousands deep, and strings (formulas, names) replaced by long ones; and scenes
//! generated from the schema's sections and keys, with values of the right type and of
//! the wrong one, in range and out of it.
//!
//! Properties: no panic, no hang (each case within its limit), no allocation past the
//! harness's 1 GiB; every undamaged example parses; an error names the origin and, where
//! it has a position, a 1-based `file:line:column` inside the text (or just past its end)
//! and a one-line message; a scene that parses can be evaluated at points of its domain
//! (its field, and its region function where it has one).
//!
//! CI runs a few hundred cases per property in a few seconds. A longer run:
//! `SKELFORM_FUZZ_SECONDS=3600 cargo test --release -p skelform-scene --test fuzz_scene -- --nocapture`
//! runs every property for an hour, side by side as the test harness runs them (as many at
//! once as there are cores, or `--test-threads`), with fresh seeds each round
//! (`SKELFORM_FUZZ_CASES=N` sets the cases per round; see `fuzz/harness.rs`).

#[path = "../../../fuzz/harness.rs"]
mod harness;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;

use proptest::prelude::*;
use skelform_field::DVec3;
use skelform_scene::{Scene, SceneError};

#[global_allocator]
static GUARD: harness::Guard = harness::Guard;

const LIMIT: Duration = Duration::from_secs(30);
const ORIGIN: &str = "fuzz.toml";

/// The example scenes: (path relative to examples/, text).
fn examples() -> &'static [(String, String)] {
    static EXAMPLES: OnceLock<Vec<(String, String)>> = OnceLock::new();
    EXAMPLES.get_or_init(|| {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
        let mut out = Vec::new();
        let mut dirs: Vec<PathBuf> = vec![root.clone()];
        while let Some(dir) = dirs.pop() {
            let Ok(entries) = std::fs::read_dir(&dir) else { continue };
            for e in entries.flatten() {
                let p = e.path();
                if p.is_dir() {
                    dirs.push(p);
                } else if p.extension().is_some_and(|x| x == "toml")
                    && let Ok(text) = std::fs::read_to_string(&p)
                {
                    let name = p.strip_prefix(&root).unwrap_or(&p).display().to_string();
                    out.push((name, text));
                }
            }
        }
        out.sort();
        assert!(out.len() >= 10, "examples not found under {}", root.display());
        out
    })
}

/// The checks every verdict of `Scene::parse` must pass.
fn verdict(text: &str) -> Result<Option<Scene>, String> {
    verdict_in(text, None)
}

/// [`verdict`] with relative paths in the text (a sweep's `section_image`) taken from `base`.
fn verdict_in(text: &str, base: Option<&Path>) -> Result<Option<Scene>, String> {
    let options =
        skelform_scene::LoadOptions { base: base.map(Path::to_path_buf), ..Default::default() };
    match Scene::parse_with(text, ORIGIN, &options) {
        Ok(scene) => {
            exercise(&scene)?;
            Ok(Some(scene))
        }
        Err(e) => {
            let shown = e.to_string();
            if !shown.starts_with(ORIGIN) || shown.contains('\n') {
                return Err(format!(
                    "an error that does not start with the origin or is not one line: {shown:?}"
                ));
            }
            match &e {
                SceneError::At { line, column, message, .. } => {
                    let lines: Vec<&str> = text.split('\n').collect();
                    if *line == 0 || *column == 0 || *line > lines.len() + 1 {
                        return Err(format!("position outside the text: {shown}"));
                    }
                    if let Some(l) = lines.get(line - 1)
                        && *column > l.chars().count() + 1
                    {
                        return Err(format!("column past the end of line {line}: {shown}"));
                    }
                    if message.trim().is_empty() {
                        return Err(format!("an error without a message: {shown}"));
                    }
                }
                SceneError::Invalid { message, .. } if !message.trim().is_empty() => {}
                other => return Err(format!("an unexpected kind of error: {other:?}")),
            }
            Ok(None)
        }
    }
}

/// A parsed scene's field (and region function) at a few points of its domain.
fn exercise(scene: &Scene) -> Result<(), String> {
    let (lo, hi) = (scene.domain.min, scene.domain.max);
    let points: Vec<DVec3> = (0..5)
        .map(|k| {
            let t = k as f64 / 4.0;
            lo + (hi - lo) * DVec3::new(t, 1.0 - t, t * t)
        })
        .collect();
    let mut out = vec![0.0; points.len()];
    scene.field.eval_many(&points, &mut out);
    for &p in &points {
        let _ = scene.field.eval(p);
        let _ = scene.field.gradient(p);
    }
    if let Some(setup) = scene.nonmanifold_regions() {
        for &p in &points {
            let _ = setup.field.region(p);
        }
    }
    Ok(())
}

#[test]
fn every_example_parses() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    for (name, text) in examples() {
        // Relative paths from the example's own folder, as a load takes them.
        let base = root.join(name).parent().map(Path::to_path_buf);
        if let Err(e) =
            verdict_in(text, base.as_deref()).and_then(|s| s.ok_or_else(|| "refused".to_string()))
        {
            // The error itself, for a refused example.
            let why = Scene::parse(text, name).err().map_or(e, |e| e.to_string());
            panic!("examples/{name}: {why}");
        }
    }
}

/// A damage to scene text, at positions given as fractions.
#[derive(Clone, Debug)]
enum Damage {
    Flip(f64, u8),
    Cut(f64),
    DeleteLine(f64),
    DuplicateLine(f64, f64),
    SwapLines(f64, f64),
    SwapTokens(f64, f64),
    /// Replace the number at a position.
    Number(f64, &'static str),
    /// Replace the value after an `=` by arrays nested this deep.
    NestArrays(f64, usize),
    /// Replace the value after an `=` by inline tables nested this deep.
    NestTables(f64, usize),
    /// Replace a string by one this long (of this character).
    LongString(f64, usize, char),
    Insert(f64, &'static str),
}

const NUMBERS: &[&str] = &[
    "1e308",
    "-1e308",
    "1.7976931348623157e308",
    "1e309",
    "-0",
    "-0.0",
    "+0",
    "nan",
    "-nan",
    "+nan",
    "inf",
    "-inf",
    "+inf",
    "NaN",
    "0",
    "1",
    "-1",
    "2",
    "1e-320",
    "5e-324",
    "0.5",
    "9223372036854775807",
    "-9223372036854775808",
    "9223372036854775808",
    "99999999999999999999999999999",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "0x7fffffffffffffff",
    "0o777",
    "0b1",
    "1_000",
    "1__0",
    "01",
    "1e",
    "1.",
    ".1",
    "\"1\"",
    "true",
    "[]",
    "{}",
    "1979-05-27",
    "1e+308",
    "2147483648",
    "65536",
    "32768",
    "1024",
];

const INSERTS: &[&str] = &[
    "\n[domain]\n",
    "\n[mesh]\nresolution = 4\n",
    "\n[[skeleton.point]]\n",
    "=",
    "[",
    "]",
    "{",
    "}",
    "\"",
    "'''",
    "\"\"\"",
    "#",
    "\n",
    ",",
    "\\",
    "\u{0}",
    "\u{feff}",
    "é",
    "\r\n",
    "\n[skeleton]\n",
    "\n[field]\nformula = \"x\"\n",
    "\n[regions]\n",
    "\n[leaf]\n",
];

fn damage() -> impl Strategy<Value = Damage> {
    let at = 0.0..1.0f64;
    prop_oneof![
        2 => (at.clone(), any::<u8>()).prop_map(|(a, b)| Damage::Flip(a, b)),
        1 => at.clone().prop_map(Damage::Cut),
        1 => at.clone().prop_map(Damage::DeleteLine),
        1 => (at.clone(), at.clone()).prop_map(|(a, b)| Damage::DuplicateLine(a, b)),
        1 => (at.clone(), at.clone()).prop_map(|(a, b)| Damage::SwapLines(a, b)),
        1 => (at.clone(), at.clone()).prop_map(|(a, b)| Damage::SwapTokens(a, b)),
        5 => (at.clone(), prop::sample::select(NUMBERS)).prop_map(|(a, s)| Damage::Number(a, s)),
        1 => (at.clone(), prop_oneof![1usize..64, 64usize..20_000])
            .prop_map(|(a, n)| Damage::NestArrays(a, n)),
        1 => (at.clone(), prop_oneof![1usize..64, 64usize..20_000])
            .prop_map(|(a, n)| Damage::NestTables(a, n)),
        1 => (at.clone(), prop_oneof![0usize..100, 100usize..500_000], prop::sample::select(vec!['x', '(', 'é', '\\', ' ', '1']))
            .prop_map(|(a, n, c)| Damage::LongString(a, n, c)),
        1 => (at, prop::sample::select(INSERTS)).prop_map(|(a, s)| Damage::Insert(a, s)),
    ]
}

/// Spans of tokens of TOML text: runs of word characters (numbers with their signs), or single
/// punctuation.
fn scene_tokens(text: &str) -> Vec<(usize, usize)> {
    harness::tokens(text, |c| c.is_alphanumeric() || matches!(c, '_' | '.' | '-' | '+'))
}

fn pick(f: f64, len: usize) -> usize {
    ((f * len as f64) as usize).min(len.saturating_sub(1))
}

/// Spans of numbers: tokens that start with a digit or a sign and a digit.
fn numbers(text: &str) -> Vec<(usize, usize)> {
    scene_tokens(text)
        .into_iter()
        .filter(|&(i, j)| {
            let t = text[i..j].trim_start_matches(['-', '+']);
            t.starts_with(|c: char| c.is_ascii_digit())
        })
        .collect()
}

/// The span of the value after the `=` of a line (to the end of the line).
fn values(text: &str) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut at = 0;
    for line in text.split_inclusive('\n') {
        if let Some(eq) = line.find('=') {
            let end = line.trim_end_matches(['\n', '\r']).len();
            if eq < end {
                out.push((at + eq + 1, at + end));
            }
        }
        at += line.len();
    }
    out
}

/// Spans of basic strings `"..."` on one line (contents only).
fn strings(text: &str) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let b = text.as_bytes();
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'"' {
            let s = i + 1;
            let mut j = s;
            while j < b.len() && b[j] != b'"' && b[j] != b'\n' {
                j += 1;
            }
            if j < b.len() && b[j] == b'"' {
                out.push((s, j));
            }
            i = j + 1;
        } else {
            i += 1;
        }
    }
    out
}

fn apply(text: String, d: &Damage) -> String {
    let mut text = text;
    let lines = |t: &str| t.split_inclusive('\n').map(str::to_string).collect::<Vec<_>>();
    match d {
        Damage::Flip(f, b) => {
            let mut bytes = text.into_bytes();
            if !bytes.is_empty() {
                let i = pick(*f, bytes.len());
                bytes[i] ^= b | 1;
            }
            text = String::from_utf8_lossy(&bytes).into_owned();
        }
        Damage::Cut(f) => {
            let i = text.floor_char_boundary(((f * text.len() as f64) as usize).min(text.len()));
            text.truncate(i);
        }
        Damage::DeleteLine(f) => {
            let mut l = lines(&text);
            if !l.is_empty() {
                l.remove(pick(*f, l.len()));
            }
            text = l.concat();
        }
        Damage::DuplicateLine(a, b) => {
            let mut l = lines(&text);
            if !l.is_empty() {
                let line = l[pick(*a, l.len())].clone();
                l.insert(pick(*b, l.len() + 1), line);
            }
            text = l.concat();
        }
        Damage::SwapLines(a, b) => {
            let mut l = lines(&text);
            if !l.is_empty() {
                let (i, j) = (pick(*a, l.len()), pick(*b, l.len()));
                l.swap(i, j);
            }
            text = l.concat();
        }
        Damage::SwapTokens(a, b) => {
            let t = scene_tokens(&text);
            if t.len() >= 2 {
                let (i, j) = (pick(*a, t.len()), pick(*b, t.len()));
                let (i, j) = (i.min(j), i.max(j));
                if i != j {
                    harness::swap_spans(&mut text, t[i], t[j]);
                }
            }
        }
        Damage::Number(f, s) => {
            let n = numbers(&text);
            if !n.is_empty() {
                let (i, j) = n[pick(*f, n.len())];
                text.replace_range(i..j, s);
            }
        }
        Damage::NestArrays(f, n) => {
            let v = values(&text);
            if !v.is_empty() {
                let (i, j) = v[pick(*f, v.len())];
                text.replace_range(i..j, &format!(" {}1{}", "[".repeat(*n), "]".repeat(*n)));
            }
        }
        Damage::NestTables(f, n) => {
            let v = values(&text);
            if !v.is_empty() {
                let (i, j) = v[pick(*f, v.len())];
                text.replace_range(i..j, &format!(" {}1{}", "{a=".repeat(*n), "}".repeat(*n)));
            }
        }
        Damage::LongString(f, n, c) => {
            let s = strings(&text);
            if !s.is_empty() {
                let (i, j) = s[pick(*f, s.len())];
                let long: String = std::iter::repeat_n(*c, *n).collect();
                text.replace_range(i..j, &long);
            }
        }
        Damage::Insert(f, s) => {
            let i = text.floor_char_boundary(((f * text.len() as f64) as usize).min(text.len()));
            text.insert_str(i, s);
        }
    }
    text
}

/// Whether the text asks for polygon images past 256 pixels a side. Building an image is
/// documented to cost the fourth power of its resolution for most kernels: at the largest
/// accepted, 1024, one polygon takes 7 to 15 s to load here (a finding of the long run,
/// reported, not a crash), which would read as a hang.
fn expensive_by_design(text: &str) -> bool {
    text.lines().any(|l| {
        l.trim_start().starts_with("image_resolution")
            && l.split(['=', '#'])
                .nth(1)
                .and_then(|v| v.trim().parse::<f64>().ok())
                .is_some_and(|v| v > 256.0)
    })
}

#[test]
fn damaged_examples_are_errors_or_scenes() {
    let n = examples().len();
    let strategy = (0..n, prop::collection::vec(damage(), 1..5));
    harness::fuzz("scene mutations", 640, LIMIT, strategy, move |(k, damages)| {
        let (name, text) = &examples()[k];
        let text = damages.iter().fold(text.clone(), apply);
        if expensive_by_design(&text) {
            return Ok(());
        }
        verdict(&text).map(|_| ()).map_err(|e| format!("examples/{name}, damaged: {e}"))
    });
}

/// TOML values: of the right shape or not, ordinary or extreme.
fn number() -> BoxedStrategy<String> {
    prop_oneof![
        8 => (-3.0..3.0f64).prop_map(|v| format!("{v}")),
        4 => (-200i64..200).prop_map(|v| v.to_string()),
        2 => prop::sample::select(vec![
            "1e308", "-1e308", "-0", "-0.0", "nan", "inf", "-inf", "0", "1e-320", "5e-324",
            "9223372036854775807", "-9223372036854775808", "4294967296", "1000000000", "65536",
        ])
        .prop_map(str::to_string),
        1 => prop::sample::select(NUMBERS).prop_map(str::to_string),
    ]
    .boxed()
}

fn point() -> BoxedStrategy<String> {
    prop_oneof![
        6 => prop::collection::vec(number(), 3).prop_map(|v| format!("[{}]", v.join(", "))),
        1 => prop::collection::vec(number(), 0..6).prop_map(|v| format!("[{}]", v.join(", "))),
        1 => number(),
    ]
    .boxed()
}

fn value() -> BoxedStrategy<String> {
    prop_oneof![
        3 => number(),
        1 => point(),
        1 => prop::sample::select(vec![
            "true", "false", "\"\"", "\"grid\"", "\"continuation\"", "\"tetra\"",
            "\"nonmanifold\"", "\"healed\"", "\"bisection\"", "\"regula-falsi\"", "\"image\"",
            "\"exact\"", "\"sum\"", "\"max\"", "\"union\"", "\"ply\"", "\"obj\"", "\"out.stl\"",
            "\"x\"", "\"rest\"", "[[0, 0, 0], [1, 0, 0], [0, 1, 0]]",
            "[[0, 0, 0], [1e308, 0, 0], [0, 1, 0], [0, 0, 0]]", "[[0, 0, 0], [0, 0, 0]]", "[[0, 1]]", "[[0, 1, 2]]", "{ R = 0.5 }", "{ x = 1 }", "[]", "{}",
        ])
        .prop_map(str::to_string),
        1 => formula_text(),
    ]
    .boxed()
}

fn formula_text() -> BoxedStrategy<String> {
    prop_oneof![
        prop::sample::select(vec![
            "sqrt(x^2 + y^2 + z^2) - 0.5",
            "x",
            "1",
            "-1",
            "ln(x)",
            "1/0",
            "0/0",
            "R - x",
            "x^2 + y^2 - z^2",
            "max(x, y, z) - 0.5",
            "(",
            "x +",
            "rr - 1",
            "sqrt(",
            "\\u0000",
            "min(x)",
            "pow(x, 1e308)",
            "q = x\\nq^2 - 0.25",
            "sin(x*1e300)",
        ])
        .prop_map(|f| format!("\"{f}\"")),
        "[ -~]{0,30}".prop_map(|f| format!("'''{f}'''")),
    ]
    .boxed()
}

const SECTIONS: &[(&str, &[&str])] = &[
    ("scene", &["name", "description", "figure"]),
    ("domain", &["min", "max"]),
    (
        "mesh",
        &[
            "resolution",
            "cell",
            "method",
            "refine",
            "tolerance",
            "seeds",
            "root",
            "max_cells",
            "limit",
            "search_stride",
            "epsilon",
            "critical_cells",
            "split_sheets",
            "healing",
        ],
    ),
    ("field", &["formula", "iso", "parameters"]),
    (
        "skeleton",
        &[
            "blend",
            "kernel",
            "iso",
            "radius",
            "range",
            "thumbweight",
            "falloff",
            "clamp",
            "angle_scaled",
            "polygon_method",
            "image_resolution",
            "segment_method",
            "blended_normals",
            "combine",
            "pose",
        ],
    ),
    ("regions", &["default", "interest", "curves", "parameters", "full_grid", "loops"]),
    ("output", &["file", "format", "ascii", "normals"]),
    (
        "leaf",
        &[
            "size",
            "lobes",
            "spread",
            "lobe_depth",
            "secondaries",
            "branch_angle",
            "petiole",
            "curvature",
            "jitter",
            "seed",
            "vein_radius",
            "tip_radius",
            "max_area",
            "max_ratio",
            "kernel",
            "fillet",
            "full_grid",
        ],
    ),
];

/// Arrays of tables: the name, how many of the keys are required, the keys.
const ARRAYS: &[(&str, usize, &[&str])] = &[
    ("skeleton.point", 2, &["at", "radius", "strength", "group", "joint"]),
    ("skeleton.segment", 3, &["a", "b", "radius", "strength", "group", "joint"]),
    ("skeleton.polyline", 2, &["points", "radius", "strength", "group", "joint"]),
    (
        "skeleton.triangle",
        2,
        &[
            "vertices",
            "radius",
            "strength",
            "polygon_method",
            "image_resolution",
            "weights",
            "weight_image",
        ],
    ),
    (
        "skeleton.polygon",
        2,
        &[
            "vertices",
            "radius",
            "strength",
            "polygon_method",
            "image_resolution",
            "weights",
            "weight_image",
        ],
    ),
    ("skeleton.curve", 2, &["bezier", "radius", "tolerance", "strength"]),
    ("skeleton.junction", 1, &["at", "direction"]),
    ("skeleton.joint", 2, &["name", "at", "parent", "orient", "axes", "angles"]),
    ("regions.region", 2, &["id", "formula"]),
    ("regions.gradient", 2, &["pair", "formula"]),
];

/// A key's value: usually of the type the key takes (from `typed`, `num` and `pt`), now and
/// then anything (`any`).
fn value_for(key: &str, pick: u8, any: String, num: String, pt: String) -> String {
    if pick < 16 {
        return any;
    }
    let small = (pick % 7) as i64 - 1;
    match key {
        "min" | "max" | "at" | "a" | "b" | "direction" | "orient" | "axes" | "angles" => pt,
        "seeds" | "vertices" | "points" => {
            format!("[{pt}, [0, 0.5, 0], [0.5, 0, {num}]]")
        }
        "interest" => format!("[[0, {}]]", small.max(1)),
        "curves" => "[[0, 1, 2]]".to_string(),
        "pair" => format!("[0, {}]", small),
        "formula" if any.starts_with(['"', '\'']) => any,
        "formula" => "\"sqrt(x^2 + y^2 + z^2) - 0.5\"".to_string(),
        "bezier" => format!("[{pt}, [0, 0.5, 0], [0.5, 0, {num}], [0.5, 0.5, 0.5]]"),
        "method" => ["\"grid\"", "\"continuation\"", "\"tetra\"", "\"healed\"", "\"nonmanifold\""]
            [pick as usize % 5]
            .to_string(),
        "root" => "\"bisection\"".to_string(),
        "blend" | "combine" => {
            ["\"sum\"", "\"union\"", "\"max\"", "\"blend\""][pick as usize % 4].to_string()
        }
        "kernel" => ["\"wyvill\"", "\"gaussian\"", "\"bspline\"", "\"triweight\""]
            [pick as usize % 4]
            .to_string(),
        "falloff" => ["\"linear\"", "\"smooth\""][pick as usize % 2].to_string(),
        "format" => ["\"ply\"", "\"obj\"", "\"stl\"", "\"glb\""][pick as usize % 4].to_string(),
        "file" => "\"out.ply\"".to_string(),
        "healing" => ["\"zone\"", "\"thesis\"", "\"both\""][pick as usize % 3].to_string(),
        "polygon_method" => "\"image\"".to_string(),
        "segment_method" => ["\"separable\"", "\"exact\""][pick as usize % 2].to_string(),
        "weights" => format!("[1, {num}, 0.5]"),
        "weight_image" => "\"no-such-weights.png\"".to_string(),
        "refine" | "split_sheets" | "clamp" | "angle_scaled" | "full_grid" | "loops" | "ascii"
        | "normals" | "blended_normals" => pick.is_multiple_of(2).to_string(),
        "parameters" => format!("{{ R = {num} }}"),
        "name" | "description" | "figure" | "parent" | "joint" | "pose" => "\"a\"".to_string(),
        "resolution" | "id" | "default" | "lobes" | "seed" | "max_cells" | "limit"
        | "search_stride" | "image_resolution" | "secondaries" => match pick % 4 {
            0 => small.to_string(),
            1 => (pick as i64 * 3).to_string(),
            _ => num,
        },
        _ => num,
    }
}

/// The keys and values of one table, each key once (now and then a stray one).
/// The first `required` keys always come, the others when drawn.
fn table(
    keys: &'static [&'static str],
    required: usize,
    kv: Vec<(usize, (u8, String, String, String))>,
) -> String {
    let mut seen = std::collections::HashSet::new();
    let mut t = String::new();
    let first = keys[..required].iter().enumerate().map(|(k, _)| {
        let pt = format!("[{}, 0.2, 0.3]", 0.1 - 0.4 * k as f64);
        (k, (200, String::new(), "0.5".to_string(), pt))
    });
    for (k, (pick, any, num, pt)) in first.chain(kv) {
        let key = if k == 62 { "stray_key" } else { keys[k % keys.len()] };
        if k == 63 || seen.insert(key) {
            t += &format!("{key} = {}\n", value_for(key, pick, any, num, pt));
        }
    }
    t
}

fn entry() -> impl Strategy<Value = (usize, (u8, String, String, String))> {
    (0usize..64, (any::<u8>(), value(), number(), point()))
}

/// A scene: usually a good domain and a formula, then sections (each name once, as a
/// scene would have them; now and then twice) and array-of-tables entries.
fn generated_scene() -> impl Strategy<Value = String> {
    let good = Just("[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n".to_string());
    let domain = prop_oneof![
        6 => good,
        2 => (point(), point()).prop_map(|(a, b)| format!("[domain]\nmin = {a}\nmax = {b}\n")),
        1 => Just(String::new()),
    ];
    let field = prop_oneof![
        2 => formula_text().prop_map(|f| format!("[field]\nformula = {f}\n")),
        1 => Just(String::new()),
    ];
    let sections =
        prop::collection::vec((0..SECTIONS.len(), prop::collection::vec(entry(), 0..6)), 0..5);
    let arrays =
        prop::collection::vec((0..ARRAYS.len(), prop::collection::vec(entry(), 0..5)), 0..5);
    (domain, field, sections, arrays, any::<u8>()).prop_map(
        |(domain, field, sections, arrays, twice)| {
            let mut t = domain;
            let mut names = std::collections::HashSet::new();
            if !t.is_empty() {
                names.insert("domain");
            }
            if !field.is_empty() {
                names.insert("field");
                t += &field;
            }
            for (s, kv) in sections {
                let (name, keys) = SECTIONS[s];
                if names.insert(name) || twice == 0 {
                    t += &format!("[{name}]\n{}", table(keys, usize::from(name == "regions"), kv));
                }
            }
            for (s, kv) in arrays {
                let (name, required, keys) = ARRAYS[s];
                t += &format!("[[{name}]]\n{}", table(keys, required, kv));
            }
            t
        },
    )
}

#[test]
fn generated_scenes_are_errors_or_scenes() {
    harness::fuzz("generated scenes", 768, LIMIT, generated_scene(), |text| {
        if expensive_by_design(&text) {
            return Ok(());
        }
        verdict(&text).map(|_| ())
    });
}

#[test]
fn random_text_is_an_error_or_a_scene() {
    let strategy = prop_oneof![
        "[\\[\\]{}=\"'#., a-z0-9\n-]{0,120}",
        any::<String>(),
        prop::collection::vec(any::<u8>(), 0..200)
            .prop_map(|b| String::from_utf8_lossy(&b).into_owned()),
    ];
    harness::fuzz("scene text", 512, LIMIT, strategy, |text| verdict(&text).map(|_| ()));
}

/// Regression (found by `generated_scenes_are_errors_or_scenes`): a message that quotes a
/// value of the file (here a group name holding a line break) printed the break, so the
/// error ran over two lines, the second without a position.
#[test]
fn a_quoted_line_break_keeps_the_error_on_one_line() {
    let text = "[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n[[skeleton.segment]]\n\
                a = [0.1, 0.2, 0.3]\nb = [-0.3, 0.2, 0.3]\nradius = 0.5\ngroup = \"q\\nr\"\n";
    let e = Scene::parse(text, ORIGIN).expect_err("an unknown group");
    let shown = e.to_string();
    assert!(!shown.contains('\n'), "{shown}");
    assert!(shown.starts_with("fuzz.toml:8:9: unknown group 'q\\nr'"), "{shown}");
}

/// Regression (found by the long run of `generated_scenes_are_errors_or_scenes`): `[leaf]
/// max_area` had no lower bound. `1e-320` overflowed the count of margin samples ("attempt
/// to add with overflow" in `skelform-leaf`'s `margin_splines`, the sample step being
/// `0.5·√max_area·size`), and `1e-8` took four minutes to load. It is now refused below
/// 1e-5 (about the most polygons refinement makes anyway), with its position.
#[test]
fn a_tiny_leaf_max_area_is_refused() {
    for v in ["1e-320", "1e-8", "5e-324", "0.0000099"] {
        let text = format!(
            "[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n[field]\nformula = \"x\"\n\
             [leaf]\nmax_area = {v}\n"
        );
        let t = std::time::Instant::now();
        let e = Scene::parse(&text, ORIGIN).expect_err(v).to_string();
        assert!(e.starts_with("fuzz.toml:7:12: max_area must be"), "{v}: {e}");
        assert!(t.elapsed() < Duration::from_secs(1), "{v}: {:?}", t.elapsed());
    }
}
