//! The studio's server as a page sees it: edits in over the WebSocket, states and mesh
//! frames out; the guard (token, origin); refused edits; cancellation; saving; exports.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

use futures_util::{SinkExt, StreamExt};
use serde_json::{Value, json};
use skelform_studio::{Settings, Studio};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio_tungstenite::tungstenite::Message;
use tokio_tungstenite::tungstenite::client::IntoClientRequest;

/// Two segments meeting in a tee, with comments that saving must keep.
const SCENE: &str = "\
# The studio tests' scene: a tee of two segments.
[domain]
min = [-0.75, -0.25, -0.25]
max = [0.75, 0.75, 0.25]

[mesh]
resolution = RES   # samples along x

[skeleton]
radius = 0.1

[[skeleton.segment]]            # the bar
a = [-0.6, 0, 0]
b = [0.6, 0, 0]

[[skeleton.segment]]            # the stem
a = [0, 0, 0]
b = [0, 0.6, 0]
";

struct Running {
    _dir: tempfile::TempDir,
    file: PathBuf,
    addr: SocketAddr,
    token: String,
}

async fn start(resolution: u32) -> Running {
    start_with(&SCENE.replace("RES", &resolution.to_string())).await
}

async fn start_with(scene: &str) -> Running {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("tee.toml");
    std::fs::write(&file, scene).unwrap();
    let studio = Studio::bind(&file, Settings::default()).await.unwrap();
    let (addr, token) = (studio.addr(), studio.token().to_string());
    assert!(studio.url().contains(&token) && token.len() == 32);
    tokio::spawn(studio.serve());
    Running { _dir: dir, file, addr, token }
}

type Ws =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

async fn connect(r: &Running) -> Ws {
    let url = format!("ws://{}/ws?token={}", r.addr, r.token);
    tokio_tungstenite::connect_async(url).await.unwrap().0
}

/// The next message, or a failure after 30 s.
async fn next(ws: &mut Ws) -> Message {
    tokio::time::timeout(Duration::from_secs(30), ws.next())
        .await
        .expect("no message within 30 s")
        .expect("socket closed")
        .unwrap()
}

/// A mesh frame's header: revision, level, vertices, triangles.
fn header(b: &[u8]) -> (u64, u32, u32, u32) {
    assert_eq!(&b[..4], b"SKFM");
    let u32_at = |i: usize| u32::from_le_bytes(b[i..i + 4].try_into().unwrap());
    (u64::from_le_bytes(b[8..16].try_into().unwrap()), u32_at(16), u32_at(20), u32_at(24))
}

/// Reads messages until a full-level frame of `revision` (or newer) arrives; returns the
/// JSON messages and the frames' headers seen on the way.
async fn until_full(ws: &mut Ws, revision: u64) -> (Vec<Value>, Vec<(u64, u32, u32, u32)>) {
    let (mut texts, mut frames) = (Vec::new(), Vec::new());
    loop {
        match next(ws).await {
            Message::Text(t) => texts.push(serde_json::from_str(&t).unwrap()),
            Message::Binary(b) => {
                let h = header(&b);
                frames.push(h);
                if h.1 == 1 && h.0 >= revision {
                    return (texts, frames);
                }
            }
            _ => {}
        }
    }
}

async fn send(ws: &mut Ws, v: Value) {
    ws.send(Message::Text(v.to_string().into())).await.unwrap();
}

/// The state message that follows.
async fn next_state(ws: &mut Ws) -> Value {
    loop {
        if let Message::Text(t) = next(ws).await {
            let v: Value = serde_json::from_str(&t).unwrap();
            if v["type"] == "state" || v["type"] == "error" {
                return v;
            }
        }
    }
}

async fn http_status(addr: SocketAddr, target: &str, origin: Option<&str>) -> u16 {
    let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
    let origin = origin.map(|o| format!("Origin: {o}\r\n")).unwrap_or_default();
    let req = format!("GET {target} HTTP/1.1\r\nHost: {addr}\r\n{origin}Connection: close\r\n\r\n");
    s.write_all(req.as_bytes()).await.unwrap();
    let mut buf = Vec::new();
    s.read_to_end(&mut buf).await.unwrap();
    let text = String::from_utf8_lossy(&buf);
    text.split_whitespace().nth(1).unwrap().parse().unwrap()
}

#[tokio::test]
async fn an_edit_comes_back_as_a_coarse_then_a_full_surface_of_its_revision() {
    let r = start(48).await;
    let mut ws = connect(&r).await;
    let first = next_state(&mut ws).await;
    assert_eq!(first["type"], "state");
    assert_eq!(first["skeleton"]["elements"].as_array().unwrap().len(), 2);
    let (_, frames) = until_full(&mut ws, 1).await;
    let before = frames.last().unwrap().2;
    assert!(before > 100, "{frames:?}");

    send(&mut ws, json!({"seq": 1, "op": "set", "path": ["skeleton", "segment", 1, "b"], "value": [0, 0.7, 0]})).await;
    let state = next_state(&mut ws).await;
    assert_eq!(state["type"], "state", "{state}");
    let rev = state["revision"].as_u64().unwrap();
    assert_eq!(state["skeleton"]["elements"][1]["points"][1]["at"], json!([0.0, 0.7, 0.0]));
    let (_, frames) = until_full(&mut ws, rev).await;
    // The coarse surface comes first, then the full one, both of the new revision.
    let ours: Vec<_> = frames.iter().filter(|f| f.0 == rev).collect();
    assert_eq!(ours.len(), 2, "{frames:?}");
    assert_eq!((ours[0].1, ours[1].1), (0, 1));
    assert!(ours[0].2 < ours[1].2, "the coarse surface has fewer vertices: {frames:?}");
    assert_ne!(ours[1].2, before, "a longer stem changes the surface");

    // A moved handle (world coordinates) lands in the file's coordinates.
    send(&mut ws, json!({"seq": 2, "op": "move", "path": ["skeleton", "segment", 0, "a"], "to": [-0.5, 0.0, 0.0]})).await;
    let state = next_state(&mut ws).await;
    assert_eq!(state["skeleton"]["elements"][0]["points"][0]["at"], json!([-0.5, 0.0, 0.0]));
}

#[tokio::test]
async fn requests_without_the_token_or_from_another_origin_are_refused() {
    let r = start(24).await;
    let t = &r.token;
    assert_eq!(http_status(r.addr, "/", None).await, 403);
    assert_eq!(http_status(r.addr, "/?token=0123", None).await, 403);
    assert_eq!(http_status(r.addr, "/assets/app.js", None).await, 403);
    assert_eq!(http_status(r.addr, &format!("/?token={t}"), None).await, 200);
    assert_eq!(http_status(r.addr, &format!("/assets/three.core.js?token={t}"), None).await, 200);
    assert_eq!(http_status(r.addr, &format!("/assets/..%2Ftee.toml?token={t}"), None).await, 404);
    let served = format!("http://{}", r.addr);
    assert_eq!(http_status(r.addr, &format!("/?token={t}"), Some(&served)).await, 200);
    assert_eq!(
        http_status(r.addr, &format!("/?token={t}"), Some("http://evil.example")).await,
        403
    );

    // The WebSocket: no token, and a page of another origin.
    assert!(tokio_tungstenite::connect_async(format!("ws://{}/ws", r.addr)).await.is_err());
    let mut req = format!("ws://{}/ws?token={t}", r.addr).into_client_request().unwrap();
    req.headers_mut().insert("origin", "http://evil.example".parse().unwrap());
    assert!(tokio_tungstenite::connect_async(req).await.is_err());
    let mut req = format!("ws://{}/ws?token={t}", r.addr).into_client_request().unwrap();
    req.headers_mut().insert("origin", served.parse().unwrap());
    assert!(tokio_tungstenite::connect_async(req).await.is_ok());
}

#[tokio::test]
async fn invalid_edits_are_refused_with_a_message_and_change_nothing() {
    let r = start(24).await;
    let mut ws = connect(&r).await;
    let first = next_state(&mut ws).await;
    let rev = first["revision"].as_u64().unwrap();
    assert_eq!(first["skeleton"]["settings"]["radius"], "0.1");
    let refused = [
        json!({"seq": 1, "op": "set", "path": ["skeleton", "segment", 0, "radius"], "value": -0.2}),
        json!({"seq": 2, "op": "set", "path": ["skeleton", "segment", 0, "radius"], "value": null}),
        json!({"seq": 3, "op": "set", "path": ["skeleton", "segment", 7, "radius"], "value": 0.2}),
        json!({"seq": 4, "op": "set", "path": ["skeleton", "segment", 0, "colour"], "value": 2}),
        json!({"seq": 5, "op": "add", "kind": "blob", "value": {"at": [0, 0, 0]}}),
        json!({"seq": 6, "op": "delete", "kind": "segment", "index": 9}),
        json!({"seq": 7, "op": "cell", "value": 1e-7}),
        json!({"seq": 8, "op": "pose", "value": "grip"}),
        json!({"seq": 9, "op": "undo"}),
        json!({"seq": 10, "op": "set", "path": ["skeleton", "kernel"], "value": "nonsense"}),
    ];
    for (i, edit) in refused.iter().enumerate() {
        send(&mut ws, edit.clone()).await;
        let reply = next_state(&mut ws).await;
        assert_eq!(reply["type"], "error", "{edit} was accepted: {reply}");
        assert_eq!(reply["seq"], json!(i + 1));
        assert!(!reply["message"].as_str().unwrap().is_empty());
    }
    let negative = {
        send(&mut ws, refused[0].clone()).await;
        next_state(&mut ws).await
    };
    assert!(negative["message"].as_str().unwrap().contains("radius"), "{negative}");
    send(&mut ws, json!({"seq": 11, "op": "state"})).await;
    let after = next_state(&mut ws).await;
    assert_eq!(after["revision"].as_u64().unwrap(), rev, "nothing changed");
    assert_eq!(after["can_undo"], false);
    assert_eq!(after["dirty"], false);
    assert_eq!(after["skeleton"], first["skeleton"]);
}

#[tokio::test]
async fn superseded_work_is_cancelled_and_a_stale_surface_never_follows_a_newer_state() {
    let r = start(160).await;
    let mut ws = connect(&r).await;
    next_state(&mut ws).await;
    let edits = 20;
    for i in 0..edits {
        let y = 0.4 + 0.01 * f64::from(i);
        send(&mut ws, json!({"seq": i + 1, "op": "set", "path": ["skeleton", "segment", 1, "b"], "value": [0, y, 0]})).await;
    }
    // Everything until the full surface of the last edit, in order of arrival.
    let (mut newest_state, mut newest_frame) = (0, 0);
    let mut full_frames = 0;
    let last = loop {
        match next(&mut ws).await {
            Message::Text(t) => {
                let v: Value = serde_json::from_str(&t).unwrap();
                if v["type"] == "state" {
                    newest_state = v["revision"].as_u64().unwrap();
                }
            }
            Message::Binary(b) => {
                let (rev, level, ..) = header(&b);
                assert!(
                    rev >= newest_state,
                    "a frame of revision {rev} after the state of {newest_state}"
                );
                assert!(rev >= newest_frame, "frame {rev} after frame {newest_frame}");
                newest_frame = rev;
                if level == 1 {
                    full_frames += 1;
                    if rev == 1 + edits as u64 {
                        break rev;
                    }
                }
            }
            _ => {}
        }
    };
    assert_eq!(last, 1 + edits as u64);
    assert!(
        full_frames < edits,
        "every one of {edits} edits was meshed in full: nothing was cancelled"
    );
}

#[tokio::test]
async fn undo_redo_and_save_keep_the_files_comments_and_write_it_whole() {
    let r = start(24).await;
    let mut ws = connect(&r).await;
    next_state(&mut ws).await;
    send(&mut ws, json!({"seq": 1, "op": "set", "path": ["skeleton", "segment", 0, "b"], "value": [0.5, 0, 0]})).await;
    assert_eq!(next_state(&mut ws).await["can_undo"], true);
    send(&mut ws, json!({"seq": 2, "op": "set", "path": ["skeleton", "segment", 1, "b"], "value": [0, 0.5, 0]})).await;
    next_state(&mut ws).await;
    send(&mut ws, json!({"seq": 3, "op": "undo"})).await;
    let undone = next_state(&mut ws).await;
    assert_eq!(undone["skeleton"]["elements"][1]["points"][1]["at"], json!([0.0, 0.6, 0.0]));
    assert_eq!(undone["can_redo"], true);
    send(&mut ws, json!({"seq": 4, "op": "redo"})).await;
    let redone = next_state(&mut ws).await;
    assert_eq!(redone["skeleton"]["elements"][1]["points"][1]["at"], json!([0.0, 0.5, 0.0]));
    assert_eq!(redone["dirty"], true);
    send(&mut ws, json!({"seq": 5, "op": "add", "kind": "point", "value": {"at": [0, 0.3, 0], "radius": 0.15}})).await;
    assert_eq!(next_state(&mut ws).await["skeleton"]["elements"].as_array().unwrap().len(), 3);

    send(&mut ws, json!({"seq": 6, "op": "save"})).await;
    let saved = loop {
        if let Message::Text(t) = next(&mut ws).await {
            let v: Value = serde_json::from_str(&t).unwrap();
            if v["type"] == "saved" {
                break v;
            }
        }
    };
    assert_eq!(saved["file"], "tee.toml");
    let text = std::fs::read_to_string(&r.file).unwrap();
    for kept in [
        "# The studio tests' scene: a tee of two segments.",
        "resolution = 24   # samples along x",
        "# the bar",
        "# the stem",
    ] {
        assert!(text.contains(kept), "saving lost '{kept}':\n{text}");
    }
    assert!(text.contains("b = [0.5, 0, 0]") && text.contains("b = [0, 0.5, 0]"), "{text}");
    assert!(text.contains("[[skeleton.point]]"), "{text}");
    // The saved file is a scene, and no temporary file is left beside it.
    skelform::Scene::load(&r.file).unwrap();
    assert_eq!(files_in(r.file.parent().unwrap()), vec!["tee.toml".to_string()]);
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[tokio::test]
async fn exports_go_to_the_scenes_folder_only() {
    let r = start(24).await;
    let mut ws = connect(&r).await;
    until_full(&mut ws, 1).await;
    for bad in ["../tee.glb", "/tmp/tee.glb", "sub/tee.glb", ".hidden.glb", "tee.toml", ".."] {
        send(&mut ws, json!({"seq": 1, "op": "export", "format": "glb", "file": bad})).await;
        let reply = next_state(&mut ws).await;
        assert_eq!(reply["type"], "error", "export to {bad} was accepted");
    }
    assert_eq!(files_in(r.file.parent().unwrap()), vec!["tee.toml".to_string()]);
    // A plain name that is a link out of the folder is refused, and the target untouched.
    #[cfg(unix)]
    {
        let outside = tempfile::tempdir().unwrap();
        let target = outside.path().join("victim.glb");
        std::fs::write(&target, b"untouched").unwrap();
        let link = r.file.parent().unwrap().join("link.glb");
        std::os::unix::fs::symlink(&target, &link).unwrap();
        send(&mut ws, json!({"seq": 1, "op": "export", "format": "glb", "file": "link.glb"})).await;
        let reply = next_state(&mut ws).await;
        assert_eq!(reply["type"], "error", "export through a link was accepted");
        assert_eq!(std::fs::read(&target).unwrap(), b"untouched");
        std::fs::remove_file(&link).unwrap();
    }
    send(&mut ws, json!({"seq": 2, "op": "export", "format": "ply"})).await;
    let reply = loop {
        if let Message::Text(t) = next(&mut ws).await {
            let v: Value = serde_json::from_str(&t).unwrap();
            if v["type"] == "exported" || v["type"] == "error" {
                break v;
            }
        }
    };
    assert_eq!(reply["file"], "tee.ply", "{reply}");
    let mesh = skelform::mesh::io::read_mesh(&r.file.with_extension("ply")).unwrap();
    let report = skelform::mesh::check::check(&mesh);
    assert!(report.is_closed_manifold(), "{report:?}");
}

#[tokio::test]
async fn joints_poses_and_playback_between_two_poses() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("finger.toml");
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../examples/skeleton/hand-finger.toml"
    ))
    .unwrap();
    std::fs::write(&file, text.replace("cell = 0.01", "cell = 0.05")).unwrap();
    let studio = Studio::bind(&file, Settings::default()).await.unwrap();
    let r = Running { addr: studio.addr(), token: studio.token().to_string(), file, _dir: dir };
    tokio::spawn(studio.serve());
    let mut ws = connect(&r).await;
    let first = next_state(&mut ws).await;
    // The file builds the curled pose; a joint edit goes into that pose's table.
    assert_eq!(first["pose"], "curled");
    assert_eq!(first["skeleton"]["joints"][1]["angles"], json!([80.0]));
    send(&mut ws, json!({"seq": 1, "op": "angles", "joint": "knuckle2", "value": [70]})).await;
    let bent = next_state(&mut ws).await;
    assert_eq!(bent["skeleton"]["joints"][1]["angles"], json!([70.0]), "{bent}");
    let tip = |s: &Value| s["skeleton"]["joints"][2]["at"].clone();
    assert_ne!(tip(&bent), tip(&first), "the third knuckle moved");

    send(&mut ws, json!({"seq": 2, "op": "pose", "value": "straight"})).await;
    let straight = next_state(&mut ws).await;
    assert_eq!(straight["pose"], "straight");
    send(&mut ws, json!({"seq": 3, "op": "between", "kind": "curled", "value": 0.5})).await;
    let half = next_state(&mut ws).await;
    assert_eq!(half["toward"], json!({"pose": "curled", "t": 0.5}), "{half}");
    let z = |s: &Value| tip(s)[2].as_f64().unwrap();
    // The knuckle goes down (−z) as the finger curls: halfway lies between the two.
    assert!(
        z(&straight) > z(&half) && z(&half) > z(&bent),
        "{} {} {}",
        z(&straight),
        z(&half),
        z(&bent)
    );
    let rev = half["revision"].as_u64().unwrap();
    let (_, frames) = until_full(&mut ws, rev).await;
    assert!(frames.last().unwrap().2 > 100);

    for bad in [
        json!({"seq": 4, "op": "between", "kind": "curled", "value": 2}),
        json!({"seq": 5, "op": "between", "kind": "fist", "value": 0.5}),
    ] {
        send(&mut ws, bad.clone()).await;
        assert_eq!(next_state(&mut ws).await["type"], "error", "{bad} was accepted");
    }
    // The saved file has the edited pose, with the pose table's comment.
    send(&mut ws, json!({"seq": 6, "op": "save"})).await;
    next_state(&mut ws).await;
    tokio::time::sleep(Duration::from_millis(200)).await;
    let saved = std::fs::read_to_string(&r.file).unwrap();
    assert!(saved.contains(
        "[skeleton.poses.curled]          # joints not listed keep their default angles"
    ));
    assert!(saved.contains("knuckle2 = 70"), "{saved}");
}

#[tokio::test]
async fn a_slice_plane_carries_the_field_negative_inside_and_follows_edits() {
    let r = start(24).await;
    let mut ws = connect(&r).await;
    next_state(&mut ws).await;
    // The plane z = 0 (halfway through the domain's z), 61 samples along x.
    send(&mut ws, json!({"seq": 1, "op": "slice", "value": {"axis": 2, "at": 0.5, "size": 61}}))
        .await;
    let (w, h, values) = slice_frame(&mut ws).await;
    // x spans 1.5 and y 1.0: 61 × 41 samples.
    assert_eq!((w, h), (61, 41));
    let at = |x: f64, y: f64| {
        let i = ((x + 0.75) / 1.5 * (w - 1) as f64).round() as usize;
        let j = ((y + 0.25) / 1.0 * (h - 1) as f64).round() as usize;
        values[j * w + i]
    };
    assert!(at(0.0, 0.3) < 0.0, "inside the stem: {}", at(0.0, 0.3));
    assert!(at(0.6, 0.6) > 0.0, "outside: {}", at(0.6, 0.6));
    // An edit that lengthens the stem sends the plane again, with the new field.
    assert!(at(0.0, 0.68) > 0.0);
    send(&mut ws, json!({"seq": 2, "op": "set", "path": ["skeleton", "segment", 1, "b"], "value": [0, 0.7, 0]})).await;
    let (_, _, values) = slice_frame(&mut ws).await;
    let j = ((0.68 + 0.25) / 1.0 * (h - 1) as f64).round() as usize;
    let i = ((0.0 + 0.75) / 1.5 * (w - 1) as f64).round() as usize;
    assert!(values[j * w + i] < 0.0, "the longer stem reaches y = 0.68");
    for bad in [
        json!({"axis": 3, "at": 0.5}),
        json!({"axis": 0, "at": 1.5}),
        json!({"axis": 0, "at": 0.5, "size": 100000}),
    ] {
        send(&mut ws, json!({"seq": 3, "op": "slice", "value": bad})).await;
        assert_eq!(next_state(&mut ws).await["type"], "error", "{bad} was accepted");
    }
}

/// The next slice frame's columns, rows and values.
async fn slice_frame(ws: &mut Ws) -> (usize, usize, Vec<f32>) {
    loop {
        if let Message::Binary(b) = next(ws).await
            && &b[..4] == b"SKSL"
        {
            let u32_at = |i: usize| u32::from_le_bytes(b[i..i + 4].try_into().unwrap()) as usize;
            let (w, h) = (u32_at(20), u32_at(24));
            let values: Vec<f32> = b[56..]
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                .collect();
            assert_eq!(values.len(), w * h);
            return (w, h, values);
        }
    }
}

#[tokio::test]
async fn a_scene_with_an_error_opens_with_it_shown_and_takes_the_edit_that_fixes_it() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("tee.toml");
    let text = SCENE.replace("RES", "24").replace("radius = 0.1", "radius = -0.1");
    std::fs::write(&file, &text).unwrap();
    let studio = Studio::bind(&file, Settings::default()).await.unwrap();
    let r = Running { addr: studio.addr(), token: studio.token().to_string(), file, _dir: dir };
    tokio::spawn(studio.serve());
    let mut ws = connect(&r).await;
    let first = next_state(&mut ws).await;
    assert!(first["error"].as_str().unwrap().contains("radius"), "{first}");
    // An edit that leaves it invalid is taken (there is no good state to keep) and says why.
    send(&mut ws, json!({"seq": 1, "op": "set", "path": ["skeleton", "radius"], "value": -0.2}))
        .await;
    assert!(next_state(&mut ws).await["error"].is_string());
    send(&mut ws, json!({"seq": 2, "op": "set", "path": ["skeleton", "radius"], "value": 0.1}))
        .await;
    let fixed = next_state(&mut ws).await;
    assert!(fixed["error"].is_null(), "{fixed}");
    let (_, frames) = until_full(&mut ws, fixed["revision"].as_u64().unwrap()).await;
    assert!(frames.last().unwrap().2 > 100);
}

/// A sweep's section image is read from the scene's folder (wherever the studio was started
/// from), and an image outside that folder is not read at all.
#[tokio::test]
async fn section_images_come_from_the_scenes_folder_only() {
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/skeleton");
    let text = std::fs::read_to_string(examples.join("star-sweep.toml"))
        .unwrap()
        .replace("resolution = 128", "resolution = 32");
    let image = examples.join("star-section.png");
    let root = tempfile::tempdir().unwrap();
    let dir = root.path().join("scene");
    std::fs::create_dir(&dir).unwrap();
    std::fs::copy(&image, dir.join("star-section.png")).unwrap();
    std::fs::copy(&image, root.path().join("outside.png")).unwrap();

    let open = |text: String| {
        let file = dir.join("star.toml");
        std::fs::write(&file, text).unwrap();
        async move {
            let studio = Studio::bind(&file, Settings::default()).await.unwrap();
            let r = Running {
                addr: studio.addr(),
                token: studio.token().to_string(),
                file,
                _dir: tempfile::tempdir().unwrap(),
            };
            tokio::spawn(studio.serve());
            let mut ws = connect(&r).await;
            let first = next_state(&mut ws).await;
            (ws, first)
        }
    };
    let (mut ws, first) = open(text.clone()).await;
    assert!(first["error"].is_null(), "{first}");
    let (_, frames) = until_full(&mut ws, first["revision"].as_u64().unwrap()).await;
    assert!(frames.last().unwrap().2 > 100, "the star sweep was meshed");

    for outside in ["../outside.png", "/etc/passwd"] {
        let moved = text.replace("\"star-section.png\"", &format!("\"{outside}\""));
        let (_, first) = open(moved).await;
        let error = first["error"].as_str().unwrap_or_default();
        assert!(error.contains("only files in the scene's folder"), "{outside}: {first}");
    }
}

/// A polygon's weight image is a file the scene reads too: one outside the scene's folder is
/// refused as an edit and when the scene is opened, before anything is read.
#[tokio::test]
async fn weight_images_come_from_the_scenes_folder_only() {
    let polygon =
        "\n[[skeleton.polygon]]\nvertices = [[-0.5, -0.2, 0], [0.5, -0.2, 0], [0, 0.5, 0]]\n";
    let r = start_with(&(SCENE.replace("RES", "24") + polygon)).await;
    let mut ws = connect(&r).await;
    let first = next_state(&mut ws).await;
    assert!(first["error"].is_null(), "{first}");
    let outside = r.file.parent().unwrap().parent().unwrap().join("outside.png");
    let outside = outside.to_str().unwrap();
    for (i, bad) in ["../outside.png", outside, "/etc/passwd"].into_iter().enumerate() {
        let seq = i as u64 + 1;
        let path = json!(["skeleton", "polygon", 0, "weight_image"]);
        send(&mut ws, json!({"seq": seq, "op": "set", "path": path, "value": bad})).await;
        let reply = next_state(&mut ws).await;
        assert_eq!(reply["type"], "error", "{bad} was accepted: {reply}");
        let message = reply["message"].as_str().unwrap();
        assert!(
            message.contains("weight_image")
                && message.contains("only files in the scene's folder"),
            "{bad}: {message}"
        );
    }
    let saved = std::fs::read_to_string(&r.file).unwrap();
    assert!(!saved.contains("weight_image"), "the file was not changed");

    let opened =
        start_with(&(SCENE.replace("RES", "24") + polygon + "weight_image = \"../outside.png\"\n"))
            .await;
    let mut ws = connect(&opened).await;
    let first = next_state(&mut ws).await;
    let error = first["error"].as_str().unwrap_or_default();
    assert!(error.contains("only files in the scene's folder"), "{first}");
}

/// Reads messages until the `meshed` report of the full level of `revision` (or newer);
/// returns every `meshed` report seen on the way.
async fn until_meshed(ws: &mut Ws, revision: u64) -> Vec<Value> {
    let mut reports = Vec::new();
    loop {
        if let Message::Text(t) = next(ws).await {
            let v: Value = serde_json::from_str(&t).unwrap();
            if v["type"] == "meshed" {
                let done = v["level"] == 1 && v["revision"].as_u64().unwrap() >= revision;
                reports.push(v);
                if done {
                    return reports;
                }
            }
        }
    }
}

#[tokio::test]
async fn a_drag_is_meshed_incrementally_at_both_levels_and_the_report_says_why_not_otherwise() {
    // The tee, and a ball far from it that no move reaches.
    let scene =
        SCENE.replace("RES", "96").replace("max = [0.75, 0.75, 0.25]", "max = [2.25, 0.75, 0.25]")
            + "\n[[skeleton.point]]\nat = [1.8, 0.2, 0]\nradius = 0.2\n";
    let r = start_with(&scene).await;
    let mut ws = connect(&r).await;
    let opened = until_meshed(&mut ws, 1).await;
    let first = opened.last().unwrap();
    assert_eq!(first["incremental"], false, "{first}");
    assert_eq!(first["full_because"], "nothing kept from a last run", "{first}");
    let total = first["resampled"].as_u64().unwrap();

    // A drag: moves in a burst (each cancels the work of the one before), then one more.
    let drag = 8;
    for i in 0..drag {
        let y = 0.6 - 0.01 * f64::from(i + 1);
        let to = json!([0.05 * f64::from(i), y, 0.0]);
        send(
            &mut ws,
            json!({"seq": i + 1, "op": "move", "path": ["skeleton", "segment", 1, "b"], "to": to}),
        )
        .await;
    }
    let reports = until_meshed(&mut ws, 1 + drag as u64).await;
    send(&mut ws, json!({"seq": 99, "op": "move", "path": ["skeleton", "segment", 1, "b"], "to": [0.3, 0.5, 0.0]})).await;
    let last = until_meshed(&mut ws, 2 + drag as u64).await;
    let moves: Vec<&Value> =
        reports.iter().chain(&last).filter(|m| m["revision"].as_u64().unwrap() > 1).collect();
    assert!(moves.iter().any(|m| m["level"] == 0) && moves.iter().any(|m| m["level"] == 1));
    for m in &moves {
        assert_eq!(m["incremental"], true, "a move re-meshed from scratch: {m}");
        assert_eq!(m["full_because"], Value::Null, "{m}");
    }
    // The full level of the last move re-sampled only what the stem's reach (and the
    // cancelled moves' pending boxes) covers, and reused the ball's vertices.
    let full = last.last().unwrap();
    assert_eq!(full["level"], 1);
    let resampled = full["resampled"].as_u64().unwrap();
    assert!(resampled > 0 && resampled < total, "{resampled} of {total} samples again");
    assert!(full["reused_vertices"].as_u64().unwrap() > 0, "{full}");

    // A new lattice (the samples box) is a run from scratch, and the report says why.
    send(&mut ws, json!({"seq": 100, "op": "resolution", "value": 64})).await;
    let state = next_state(&mut ws).await;
    assert_eq!(state["samples"], 64, "{state}");
    let rev = state["revision"].as_u64().unwrap();
    let reports = until_meshed(&mut ws, rev).await;
    let full = reports.last().unwrap();
    assert_eq!(full["incremental"], false, "{full}");
    assert_eq!(full["full_because"], "the lattice, root finding or normals changed", "{full}");
    let saved = {
        send(&mut ws, json!({"seq": 101, "op": "save"})).await;
        loop {
            if let Message::Text(t) = next(&mut ws).await
                && t.contains("\"saved\"")
            {
                break std::fs::read_to_string(&r.file).unwrap();
            }
        }
    };
    assert!(saved.contains("resolution = 64"), "{saved}");
    // Not a whole number of samples: refused.
    send(&mut ws, json!({"seq": 102, "op": "resolution", "value": 1.5})).await;
    let refused = loop {
        let v = next_state(&mut ws).await;
        if v["type"] == "error" || v["seq"] == 102 {
            break v;
        }
    };
    assert_eq!(refused["type"], "error", "{refused}");
    assert!(refused["message"].as_str().unwrap().contains("whole number"), "{refused}");
}

#[tokio::test]
async fn a_new_edit_does_not_wait_behind_the_last_ones_full_level() {
    // A fine lattice, so that a full level from scratch takes a while.
    let r = start(320).await;
    let mut ws = connect(&r).await;
    let opened = until_meshed(&mut ws, 1).await;
    let scratch_ms = opened.last().unwrap()["ms"].as_f64().unwrap();

    // Edit A changes the lattice (its full level runs from scratch); edit B follows as soon
    // as A's coarse surface is out, while A's full level is at work.
    send(&mut ws, json!({"seq": 1, "op": "resolution", "value": 321})).await;
    let a = next_state(&mut ws).await["revision"].as_u64().unwrap();
    loop {
        if let Message::Text(t) = next(&mut ws).await {
            let v: Value = serde_json::from_str(&t).unwrap();
            if v["type"] == "meshed" && v["revision"] == a && v["level"] == 0 {
                break;
            }
        }
    }
    send(&mut ws, json!({"seq": 2, "op": "move", "path": ["skeleton", "segment", 1, "b"], "to": [0.0, 0.55, 0.0]})).await;
    let reports = until_meshed(&mut ws, a + 1).await;
    assert!(
        !reports.iter().any(|m| m["revision"] == a && m["level"] == 1),
        "A's full level was not cancelled: {reports:?}"
    );
    let coarse = reports.iter().find(|m| m["revision"] == a + 1 && m["level"] == 0).unwrap();
    let waited = coarse["waited_ms"].as_f64().unwrap();
    assert!(
        waited < 0.5 * scratch_ms,
        "B's coarse level waited {waited:.0} ms behind A's full level (a full run takes {scratch_ms:.0} ms)"
    );
}
