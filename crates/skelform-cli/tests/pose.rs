//! `--pose`: meshing, drawing and describing an articulated scene in a named pose.

use std::path::Path;

mod common;
use common::skelform;

fn finger() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/skeleton/hand-finger.toml")
        .display()
        .to_string()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn info_lists_the_joints_and_poses() {
    let o = skelform(&["info", &finger()]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let out = text(&o.stdout);
    assert!(out.contains("joints      3"), "{out}");
    assert!(out.contains("pose        curled (poses: rest, curled, straight)"), "{out}");
    let o = skelform(&["info", &finger(), "--pose", "straight"]);
    assert!(text(&o.stdout).contains("pose        straight"), "{}", text(&o.stdout));
}

#[test]
fn an_unknown_pose_is_bad_input_listing_the_known_ones() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("f.ply");
    for command in ["mesh", "render"] {
        let target = if command == "mesh" { out.clone() } else { dir.path().join("f.png") };
        let o = skelform(&[command, &finger(), "--pose", "fist", "-o", target.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{command}");
        let err = text(&o.stderr);
        assert!(
            err.contains("unknown pose 'fist'; the scene's poses are: rest, curled, straight"),
            "{command}: {err}"
        );
        assert!(!target.exists(), "{command}: nothing written");
    }
}

#[test]
fn each_pose_meshes_where_its_bones_are() {
    let dir = tempfile::tempdir().unwrap();
    let mut extents = Vec::new();
    for pose in ["straight", "curled"] {
        let out = dir.path().join(format!("{pose}.ply"));
        let o = skelform(&[
            "mesh",
            &finger(),
            "--pose",
            pose,
            "--cell",
            "0.025",
            "-o",
            out.to_str().unwrap(),
            "-q",
        ]);
        assert!(o.status.success(), "{pose}: {}", text(&o.stderr));
        let o = skelform(&["check", out.to_str().unwrap(), "--json"]);
        let r: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        assert_eq!(r["boundary_edges"], 0, "{pose}");
        assert_eq!(r["components"].as_array().unwrap().len(), 1, "{pose}");
        let b = &r["bounds"];
        extents.push((b["max"][0].as_f64().unwrap(), b["min"][2].as_f64().unwrap()));
    }
    // Straight, the finger reaches 1.6 along x and stays level; curled, it is short in x
    // and hangs down.
    let ((x_straight, z_straight), (x_curled, z_curled)) = (extents[0], extents[1]);
    assert!((x_straight - 1.6).abs() < 0.03, "{x_straight}");
    assert!(z_straight > -0.16 && x_curled < 0.7 && z_curled < -1.0, "{extents:?}");
}
