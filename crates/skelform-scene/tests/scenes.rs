//! Scene files: what is accepted, and where each mistake is reported.

use glam::DVec3;
use skelform_polygonize::grid::Resolution;
use skelform_scene::{Method, Scene, SceneError};

const HEAD: &str = "[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n";

fn err(text: &str) -> (usize, usize, String) {
    match Scene::parse(text, "s.toml") {
        Err(SceneError::At { line, column, message, path }) => {
            assert_eq!(path, "s.toml");
            (line, column, message)
        }
        Err(e) => panic!("expected a positioned error, got {e}"),
        Ok(_) => panic!("expected an error for:\n{text}"),
    }
}

#[test]
fn a_full_scene_is_read() {
    let text = format!(
        "[scene]\nname = \"t\"\ndescription = \"d\"\n{HEAD}[mesh]\ncell = 0.05\nmethod = \"grid\"\nrefine = false\n\
         tolerance = 0.001\n[field]\niso = 0.5\nparameters = {{ R = 2 }}\nformula = \"x + R\"\n\
         [output]\nfile = \"o.obj\"\nformat = \"obj\"\nascii = true\nnormals = false\n"
    );
    let s = Scene::parse(&text, "s.toml").unwrap();
    assert_eq!(s.name.as_deref(), Some("t"));
    assert_eq!(s.resolution, Resolution::Cell(0.05));
    assert_eq!(s.method, Method::Grid);
    assert!(!s.refine);
    assert_eq!(s.tolerance, 0.001);
    // The iso value is subtracted: x + 2 - 0.5.
    assert_eq!(s.field.eval(DVec3::new(1.0, 0.0, 0.0)), 2.5);
    assert!(s.output.ascii && !s.output.normals);
    assert_eq!(s.output.format, Some(skelform_mesh::io::Format::Obj));
}

#[test]
fn defaults_apply() {
    let s = Scene::parse(&format!("{HEAD}[field]\nformula = \"x\"\n"), "s.toml").unwrap();
    assert_eq!(s.resolution, Resolution::Samples(128));
    assert!(s.refine && s.output.normals && !s.output.ascii);
    assert_eq!(s.iso, 0.0);
}

#[test]
fn unknown_keys_are_errors_at_their_place() {
    let (l, c, m) = err(&format!("{HEAD}[mesh]\nresolutoin = 5\n[field]\nformula = \"x\"\n"));
    assert_eq!((l, c), (5, 1));
    assert!(m.contains("unknown field `resolutoin`"), "{m}");
    let (l, _, m) = err(&format!("{HEAD}[field]\nformula = \"x\"\ncolour = 1\n"));
    assert_eq!(l, 6);
    assert!(m.contains("colour"), "{m}");
    let (l, _, m) = err(&format!("{HEAD}[feild]\nformula = \"x\"\n"));
    assert_eq!(l, 4);
    assert!(m.contains("feild"), "{m}");
}

#[test]
fn missing_sections_and_wrong_types() {
    let (_, _, m) = err("[field]\nformula = \"x\"\n");
    assert!(m.contains("domain"), "{m}");
    let (l, _, m) =
        err(&format!("{HEAD}[mesh]\nresolution = \"fine\"\n[field]\nformula = \"x\"\n"));
    assert_eq!(l, 5);
    assert!(m.contains("expected a whole number"), "{m}");
    let (l, c, m) = err(&format!("{HEAD}[mesh]\nresolution = 1\n[field]\nformula = \"x\"\n"));
    assert_eq!((l, c), (5, 14));
    assert!(m.contains("from 2"), "{m}");
    let (l, _, m) =
        err(&format!("{HEAD}[mesh]\nresolution = 10\ncell = 0.1\n[field]\nformula = \"x\"\n"));
    assert_eq!(l, 6);
    assert!(m.contains("not both"), "{m}");
    let (l, _, m) = err(&format!("{HEAD}[mesh]\nmethod = \"magic\"\n[field]\nformula = \"x\"\n"));
    assert_eq!(l, 5);
    assert!(m.contains("unknown method 'magic'; expected one of: grid"), "{m}");
    let (_, _, m) = err(&format!("{HEAD}[field]\nformula = \"x\"\n[output]\nformat = \"xyz\"\n"));
    assert!(m.contains("unknown output format"), "{m}");
    let (l, c, m) = err("[domain]\nmin = [0, 0, 0]\nmax = [1, 0, 1]\n[field]\nformula = \"x\"\n");
    assert_eq!((l, c), (3, 7));
    assert!(m.contains("must exceed"), "{m}");
}

#[test]
fn formula_errors_point_into_the_file() {
    // Single-line string: column offset by where the string starts.
    let (l, c, m) = err(&format!("{HEAD}[field]\nformula = \"x + * y\"\n"));
    assert_eq!((l, c), (5, 16), "{m}");
    // Multi-line string: lines offset by the line after the opening quotes.
    let (l, c, m) = err(&format!("{HEAD}[field]\nformula = \"\"\"\na = 1\nb = a +\n\"\"\"\n"));
    assert_eq!((l, c), (8, 1), "{m}");
    // Literal strings too.
    let (l, c, m) = err(&format!("{HEAD}[field]\nformula = '''\nr = 1\nr - rr\n'''\n"));
    assert_eq!((l, c), (7, 5), "{m}");
    assert!(m.contains("unknown name 'rr' (did you mean 'r'?)"), "{m}");
    // A cited second position is translated as well.
    let (l, c, m) =
        err(&format!("{HEAD}[field]\nformula = \"\"\"\nr = 1\nq = (r\n+ 2 2\n\"\"\"\n"));
    assert_eq!((l, c), (8, 5), "{m}");
    assert!(m.contains("opened at line 7, column 5"), "{m}");
    let (_, _, m) = err(&format!("{HEAD}[field]\nformula = \"\"\"\nr = 1\nr = 2\nr\n\"\"\"\n"));
    assert!(m.contains("already defined (at line 6, column 1)"), "{m}");
}

#[test]
fn parameters_are_checked() {
    let (l, _, m) = err(&format!("{HEAD}[field]\nparameters = {{ x = 1 }}\nformula = \"x\"\n"));
    assert_eq!(l, 5);
    assert!(m.contains("reserved"), "{m}");
    let s = Scene::parse(
        &format!("{HEAD}[field]\nparameters = {{ a = 2, b = 3 }}\nformula = \"a * b + x\"\n"),
        "s",
    )
    .unwrap();
    assert_eq!(s.field.eval(DVec3::ZERO), 6.0);
}

#[test]
fn missing_file_is_an_io_error_naming_it() {
    let e = Scene::load(std::path::Path::new("/no/such/scene.toml")).unwrap_err();
    assert!(matches!(e, SceneError::Io { .. }));
    assert!(e.to_string().contains("/no/such/scene.toml"));
}

#[test]
fn output_file_is_relative_to_the_scene() {
    let dir = tempdir();
    let p = dir.join("a.toml");
    std::fs::write(&p, format!("{HEAD}[field]\nformula = \"x\"\n[output]\nfile = \"m.ply\"\n"))
        .unwrap();
    let s = Scene::load(&p).unwrap();
    assert_eq!(s.output.file, Some(dir.join("m.ply")));
}

fn tempdir() -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!("skelform-scene-test-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Region ids are written as 32-bit signed integers, so the scene check refuses larger ones
/// where they are given (not at writing time).
#[test]
fn region_ids_fit_the_files_they_are_written_to() {
    let scene = |id: &str| {
        format!("{HEAD}[regions]\ndefault = 0\n[[regions.region]]\nid = {id}\nformula = \"x\"\n")
    };
    assert!(Scene::parse(&scene("2147483647"), "s.toml").is_ok());
    let (line, col, m) = err(&scene("2147483648"));
    assert_eq!((line, col), (7, 6), "{m}");
    assert!(m.contains("from 0 to 2147483647 (got 2147483648)"), "{m}");
}

/// `[mesh] healing` picks the zone healing (default) or the thesis's own; anything else is
/// an error at the value, and the thesis's healing takes the thesis's critical test unless
/// the scene gives one.
#[test]
fn healed_healing_is_zone_or_thesis() {
    use skelform_polygonize::healed::Healing;
    let with = |v: &str| {
        format!("{HEAD}[mesh]\nmethod = \"healed\"\nhealing = {v}\n[field]\nformula = \"x*y*z\"\n")
    };
    let s = Scene::parse(&with("\"thesis\""), "s.toml").unwrap();
    assert_eq!(s.healed.healing, Healing::Thesis);
    assert_eq!(s.healed.epsilon, None);
    let s = Scene::parse(&with("\"zone\""), "s.toml").unwrap();
    assert_eq!(s.healed.healing, Healing::Zone);
    assert_eq!(skelform_scene::Healed::default().healing, Healing::Zone);
    let line = HEAD.lines().count() + 3;
    let (l, c, m) = err(&with("\"nguyen\""));
    assert_eq!((l, c), (line, 11), "{m}");
    assert!(m.contains("unknown healing 'nguyen'; expected zone or thesis"), "{m}");
    let (l, c, m) = err(&with("2"));
    assert_eq!(l, line, "{m}");
    assert!(c >= 11, "{m}");
}

/// Healed meshes give each sheet its own curve vertices (and normals) unless the scene asks
/// for shared ones; a scene built in code has the same default as one read from a file.
#[test]
fn healed_sheets_are_split_unless_asked() {
    let mesh = "[mesh]\nmethod = \"healed\"\n[field]\nformula = \"x*y*z\"\n";
    let s = Scene::parse(&format!("{HEAD}{mesh}"), "s.toml").unwrap();
    assert!(s.healed.split_sheets);
    assert_eq!(s.healed, skelform_scene::Healed::default());
    let shared =
        "[mesh]\nmethod = \"healed\"\nsplit_sheets = false\n[field]\nformula = \"x*y*z\"\n";
    let s = Scene::parse(&format!("{HEAD}{shared}"), "s.toml").unwrap();
    assert!(!s.healed.split_sheets);
}
