//! `--pose`: meshing, drawing and describing an articulated scene in a named pose.

use std::path::Path;

mod common;
use common::{check_json, skelform};

fn finger() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/skeleton/hand-finger.toml")
        .display()
        .to_string()
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// Meshes the finger in `pose` into `out`, with `lattice` (a resolution or cell option).
fn mesh_in_pose(pose: &str, out: &Path, lattice: &[&str]) {
    let f = finger();
    let mut args = vec!["mesh", f.as_str(), "--pose", pose, "-o", out.to_str().unwrap(), "-q"];
    args.extend(lattice);
    let o = skelform(&args);
    assert!(o.status.success(), "{pose}: {}", text(&o.stderr));
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
        mesh_in_pose(pose, &out, &["--cell", "0.025"]);
        let r = check_json(&out);
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

fn closed_components(mesh: &Path) -> Vec<(bool, i64)> {
    check_json(mesh)["components"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| (c["closed"].as_bool().unwrap(), c["genus"].as_i64().unwrap_or(-1)))
        .collect()
}

/// Animates the finger from straight to curled into `out` with `options`.
fn animate_finger(out: &Path, options: &[&str]) {
    let f = finger();
    let mut args = vec![
        "animate",
        f.as_str(),
        "--from",
        "straight",
        "--to",
        "curled",
        "-o",
        out.to_str().unwrap(),
        "-q",
    ];
    args.extend(options);
    let o = skelform(&args);
    assert!(o.status.success(), "{}", text(&o.stderr));
}

#[test]
fn animate_turns_the_skeleton_from_one_pose_to_the_other() {
    let dir = tempfile::tempdir().unwrap();
    let frames = dir.path().join("frames/");
    animate_finger(&frames, &["--frames", "5", "--resolution", "32"]);
    let mut names: Vec<String> = std::fs::read_dir(&frames)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        ["frame-0000.ply", "frame-0001.ply", "frame-0002.ply", "frame-0003.ply", "frame-0004.ply"]
    );
    // The ends are the two poses themselves, byte for byte.
    for (pose, frame) in [("straight", "frame-0000.ply"), ("curled", "frame-0004.ply")] {
        let own = dir.path().join(format!("{pose}.ply"));
        mesh_in_pose(pose, &own, &["--resolution", "32"]);
        assert!(
            std::fs::read(&own).unwrap() == std::fs::read(frames.join(frame)).unwrap(),
            "{pose}"
        );
    }
    // Every frame is the finger, one closed surface of genus 0, and each differs from the
    // last: the joints turn a little at a time.
    let mut last = Vec::new();
    for name in &names {
        let path = frames.join(name);
        assert_eq!(closed_components(&path), [(true, 0)], "{name}");
        let bytes = std::fs::read(&path).unwrap();
        assert!(bytes != last, "{name} repeats the frame before it");
        last = bytes;
    }

    // An animated picture: one frame control chunk a frame.
    let png = dir.path().join("finger.png");
    animate_finger(&png, &["--frames", "4", "--resolution", "24", "--size", "80x60"]);
    let bytes = std::fs::read(&png).unwrap();
    let count = |tag: &[u8]| bytes.windows(4).filter(|w| *w == tag).count();
    assert_eq!((count(b"acTL"), count(b"fcTL")), (1, 4));
}

#[test]
fn animate_refuses_what_it_cannot_do_before_writing_anything() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("a.png");
    let p = png.to_str().unwrap();
    let f = finger();
    for (args, says) in [
        (vec!["--from", "straight", "--to", "nope"], "unknown pose 'nope'"),
        (vec!["--from", "nope", "--to", "curled"], "unknown pose 'nope'"),
        (vec!["--from", "straight", "--to", "curled", "--frames", "0"], "--frames"),
        (vec!["--from", "straight", "--to", "curled", "--pose", "curled"], "--pose"),
    ] {
        let mut all = vec!["animate", f.as_str(), "-o", p];
        all.extend(args);
        let o = skelform(&all);
        assert_eq!(o.status.code(), Some(2), "{all:?}: {}", text(&o.stderr));
        assert!(text(&o.stderr).contains(says), "{all:?}: {}", text(&o.stderr));
        assert!(!png.exists());
    }
    let o = skelform(&["animate", &f, "--from", "straight", "--to", "curled", "-o", "x.ply"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o.stderr).contains("(.png) or a folder"), "{}", text(&o.stderr));
}
