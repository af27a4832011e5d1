//! The HTTP and WebSocket side: the guard (token, origin), the embedded page, and the edit
//! loop that keeps the document, its undo history and the meshing worker in step.

use std::net::SocketAddr;
use std::path::Path;
use std::sync::{Arc, Mutex, MutexGuard};

use axum::Router;
use axum::body::Bytes;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{DefaultBodyLimit, Path as UrlPath, Request, State as AxState};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::serve::ListenerExt;
use serde::Deserialize;
use serde_json::{Value as Json, json};
use skelform::{Control, Mesh, Overrides};
use tokio::sync::broadcast;
use toml_edit::DocumentMut;

use crate::edit::{self, Step};
use crate::mesher::{self, Job, Level, Mesher, Outcome};
use crate::slice::{self, SliceSpec};
use crate::{Place, Settings, Shared, StudioError};

const INDEX: &str = include_str!("../assets/index.html");
const APP_JS: &str = include_str!("../assets/app.js");
const APP_CSS: &str = include_str!("../assets/app.css");

/// The files the page may ask for, by URL name: all embedded, none read from disk.
const ASSETS: &[(&str, &str, &str)] = &[
    ("app.js", "text/javascript; charset=utf-8", APP_JS),
    ("app.css", "text/css; charset=utf-8", APP_CSS),
    (
        "three.module.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/vendor/three.module.js"),
    ),
    (
        "three.core.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/vendor/three.core.js"),
    ),
    (
        "OrbitControls.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/vendor/OrbitControls.js"),
    ),
    (
        "TransformControls.js",
        "text/javascript; charset=utf-8",
        include_str!("../assets/vendor/TransformControls.js"),
    ),
];

/// A message for every open page.
#[derive(Clone, Debug)]
enum Out {
    Text(String),
    Binary(Bytes),
}

/// The document and everything that changes with it, behind one lock so that a state
/// message and a mesh frame can never be published out of order.
struct Doc {
    doc: DocumentMut,
    text: String,
    saved: String,
    undo: Vec<String>,
    redo: Vec<String>,
    revision: u64,
    seq: u64,
    pose: Option<String>,
    /// Playback: the pose shown is `pose` turned this fraction of the way toward another
    /// (DIS §2.8), when set.
    toward: Option<(String, f64)>,
    /// The slice plane the page shows, when it shows one.
    slice: Option<SliceSpec>,
    /// The checked scene of the current document (`None` while the file as opened is
    /// invalid).
    scene: Option<skelform::Scene>,
    /// Why the current document does not check or mesh.
    error: Option<String>,
    /// The newest full surface and the newest frame, for exports and for pages that
    /// connect later.
    full: Option<Arc<Mesh>>,
    frame: Option<Bytes>,
    /// The cancellation flag of the work in flight.
    control: Control,
    /// The revision and level of the surface last published: the two levels run side by
    /// side, and a coarse surface must not replace its revision's full one.
    shown: Option<(u64, Level)>,
    /// The newest revision whose meshing failed: both levels report a failure, the page
    /// needs it once.
    failed: Option<u64>,
}

/// What every request handler shares.
pub struct State {
    settings: Settings,
    place: Place,
    origin_name: String,
    token: String,
    origins: Vec<String>,
    doc: Mutex<Doc>,
    jobs: Mutex<Option<Mesher>>,
    out: broadcast::Sender<Out>,
}

/// A studio bound to its socket, ready to serve.
pub struct Studio {
    listener: tokio::net::TcpListener,
    state: Shared,
    addr: SocketAddr,
}

impl Studio {
    /// Opens `scene` and listens. A file that is not TOML is an error; a scene that does not
    /// check opens with its error shown (edits that fix it are accepted).
    pub async fn bind(scene: &std::path::Path, settings: Settings) -> Result<Studio, StudioError> {
        settings.check()?;
        let place = Place::new(scene)?;
        let shown = scene.display().to_string();
        let text = std::fs::read_to_string(&place.file)
            .map_err(|e| StudioError::Scene { path: shown.clone(), message: e.to_string() })?;
        let doc: DocumentMut = text.parse().map_err(|e: toml_edit::TomlError| {
            StudioError::Scene { path: shown.clone(), message: e.to_string() }
        })?;
        let origin_name = place
            .file
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_else(|| shown.clone());
        let (scene, error) = match check(&text, &doc, &origin_name, None, &place.dir) {
            Ok(s) => (Some(s), None),
            Err(e) => (None, Some(e.to_string())),
        };
        let listener = tokio::net::TcpListener::bind((settings.host, settings.port)).await?;
        let addr = listener.local_addr()?;
        let port = addr.port();
        let mut origins = vec![format!("http://{}", host_port(addr))];
        if addr.ip().is_loopback() {
            origins.push(format!("http://localhost:{port}"));
            origins.push(format!("http://127.0.0.1:{port}"));
            origins.push(format!("http://[::1]:{port}"));
        }
        let (out, _) = broadcast::channel(64);
        let state = Arc::new(State {
            place,
            origin_name,
            token: crate::new_token()?,
            origins,
            doc: Mutex::new(Doc {
                saved: text.clone(),
                text,
                doc,
                undo: Vec::new(),
                redo: Vec::new(),
                revision: 1,
                seq: 0,
                // The pose the file builds (its `pose`, or rest), named, so that joint
                // edits go where the skeleton shown takes its angles from.
                pose: scene.as_ref().and_then(|s| s.articulation.as_ref()).map(|a| a.pose.clone()),
                toward: None,
                slice: None,
                scene,
                error,
                full: None,
                frame: None,
                control: Control::default(),
                shown: None,
                failed: None,
            }),
            jobs: Mutex::new(None),
            out,
            settings,
        });
        let weak = Arc::downgrade(&state);
        let jobs = mesher::start(state.settings.coarse_factor, move |outcome| {
            if let Some(state) = weak.upgrade() {
                state.publish(outcome);
            }
        })?;
        *lock(&state.jobs) = Some(jobs);
        {
            let mut g = lock(&state.doc);
            state.submit(&mut g);
        }
        Ok(Studio { listener, state, addr })
    }

    /// The page's address with the session token.
    pub fn url(&self) -> String {
        format!("http://{}/?token={}", host_port(self.addr), self.state.token)
    }

    /// The session token.
    pub fn token(&self) -> &str {
        &self.state.token
    }

    /// The address listened on.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Serves until the process ends.
    pub async fn serve(self) -> Result<(), StudioError> {
        let limit = self.state.settings.max_message;
        let app = Router::new()
            .route("/", get(page))
            .route("/assets/{name}", get(asset))
            .route("/ws", get(socket))
            .route("/api/mesh/{name}", get(download))
            .layer(middleware::from_fn_with_state(self.state.clone(), guard))
            .layer(DefaultBodyLimit::max(limit))
            .with_state(self.state);
        // No Nagle: a mesh frame written right after a state message would otherwise wait
        // for the page's delayed acknowledgement of it (about 40 ms on Linux) before its last
        // segment leaves, which doubled the edit → first surface time.
        let listener = self.listener.tap_io(|tcp| {
            // Only latency is at stake: a socket that refuses still works.
            let _ = tcp.set_nodelay(true);
        });
        axum::serve(listener, app).await?;
        Ok(())
    }
}

fn host_port(addr: SocketAddr) -> String {
    match addr {
        SocketAddr::V4(a) => format!("{}:{}", a.ip(), a.port()),
        SocketAddr::V6(a) => format!("[{}]:{}", a.ip(), a.port()),
    }
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic while holding the lock leaves data that is still whole (every update is a
    // set of assignments), so the lock is taken back rather than poisoning the server.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// Checks scene text as the library does, in the pose shown, and the lattice it would
/// mesh on (so that a cell too fine for memory is refused as an edit). `doc` is the text
/// as a document (already parsed by every caller: it is not parsed again here).
/// Relative paths in the text are taken from the scene's folder `dir`, and only files in it
/// may be read: a path that leads out of it is refused before anything is opened.
fn check(
    text: &str,
    doc: &DocumentMut,
    origin: &str,
    pose: Option<&str>,
    dir: &Path,
) -> Result<skelform::Scene, skelform::Error> {
    confine(doc, dir)
        .map_err(|message| skelform::Error::Invalid { origin: origin.to_string(), message })?;
    let scene = skelform::Scene::parse_in(text, origin, dir)?;
    let overrides = Overrides { pose: pose.map(str::to_string), ..Overrides::default() };
    scene.lattice(&overrides)?;
    Ok(scene)
}

/// Refuses a file the scene names (every key of [`skelform::FILE_KEYS`]: a sweep's
/// `section_image`, a polygon's `weight_image`, wherever it stands in the document) unless
/// it lies in `dir`: a plain relative path without `..`, and, when it exists, not a link to
/// elsewhere.
fn confine(doc: &DocumentMut, dir: &Path) -> Result<(), String> {
    let mut named = Vec::new();
    files_in_table(doc.as_table(), &mut named);
    for (key, name) in named {
        let path = Path::new(&name);
        let plain = path
            .components()
            .all(|c| matches!(c, std::path::Component::Normal(_) | std::path::Component::CurDir));
        let inside = plain
            && match dir.join(path).canonicalize() {
                Ok(real) => real.starts_with(dir),
                Err(_) => true, // missing: the parse says so
            };
        if !inside {
            return Err(format!(
                "{key} '{name}': the studio reads only files in the scene's folder"
            ));
        }
    }
    Ok(())
}

/// The file keys and their values anywhere in `table`, in document order. A value that is
/// not a string is left to the parse, which refuses it with its position.
fn files_in_table<'a>(table: &'a toml_edit::Table, out: &mut Vec<(&'a str, String)>) {
    for (key, item) in table.iter() {
        match item {
            toml_edit::Item::Value(v) => files_in_value(key, v, out),
            toml_edit::Item::Table(t) => files_in_table(t, out),
            toml_edit::Item::ArrayOfTables(a) => a.iter().for_each(|t| files_in_table(t, out)),
            toml_edit::Item::None => {}
        }
    }
}

fn files_in_value<'a>(key: &'a str, v: &'a toml_edit::Value, out: &mut Vec<(&'a str, String)>) {
    match v {
        toml_edit::Value::String(s) if skelform::FILE_KEYS.contains(&key) => {
            out.push((key, s.value().clone()));
        }
        toml_edit::Value::InlineTable(t) => t.iter().for_each(|(k, v)| files_in_value(k, v, out)),
        toml_edit::Value::Array(a) => a.iter().for_each(|v| files_in_value(key, v, out)),
        _ => {}
    }
}

/// Constant-time comparison, so that the token cannot be guessed a byte at a time.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len() && a.bytes().zip(b.bytes()).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

fn token_of<'r>(query: Option<&'r str>, headers: &'r HeaderMap) -> Option<&'r str> {
    if let Some(t) = headers.get("x-skelform-token").and_then(|v| v.to_str().ok()) {
        return Some(t);
    }
    query?.split('&').find_map(|kv| kv.strip_prefix("token="))
}

/// Every request needs the token, and one with an `Origin` must come from the page's own.
async fn guard(AxState(s): AxState<Shared>, req: Request, next: Next) -> Response {
    if req.uri().path() == "/favicon.ico" {
        // Browsers ask for it unbidden and without the token; there is none.
        return StatusCode::NO_CONTENT.into_response();
    }
    let ok = token_of(req.uri().query(), req.headers()).is_some_and(|t| same(t, &s.token));
    if !ok {
        return (StatusCode::FORBIDDEN, "skelform studio: the session token is missing or wrong (open the URL the studio printed)").into_response();
    }
    if let Some(origin) = req.headers().get(header::ORIGIN) {
        let known = origin.to_str().is_ok_and(|o| s.origins.iter().any(|k| k == o));
        if !known {
            return (StatusCode::FORBIDDEN, "skelform studio: request from another origin")
                .into_response();
        }
    }
    next.run(req).await
}

async fn page(AxState(s): AxState<Shared>) -> Response {
    let html = INDEX.replace("{{TOKEN}}", &s.token);
    (
        [(header::CONTENT_TYPE, "text/html; charset=utf-8"), (header::CACHE_CONTROL, "no-store")],
        html,
    )
        .into_response()
}

async fn asset(UrlPath(name): UrlPath<String>) -> Response {
    match ASSETS.iter().find(|(n, _, _)| *n == name) {
        Some((_, kind, body)) => ([(header::CONTENT_TYPE, *kind)], *body).into_response(),
        None => (StatusCode::NOT_FOUND, "no such asset").into_response(),
    }
}

/// The newest full surface as a file download (`scene.glb`, `scene.ply`).
async fn download(AxState(s): AxState<Shared>, UrlPath(name): UrlPath<String>) -> Response {
    use skelform::mesh::io::{Format, WriteOptions, write_mesh_to};
    let format = match name.as_str() {
        "scene.glb" => Format::Glb,
        "scene.ply" => Format::Ply,
        _ => return (StatusCode::NOT_FOUND, "scene.glb or scene.ply").into_response(),
    };
    let Some(mesh) = lock(&s.doc).full.clone() else {
        return (StatusCode::CONFLICT, "no surface yet").into_response();
    };
    let mut bytes = Vec::new();
    let options = WriteOptions { normals: true, ..WriteOptions::default() };
    if let Err(e) = write_mesh_to(&mut bytes, &mesh, format, &options) {
        return (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response();
    }
    let stem =
        s.place.file.file_stem().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let ext = if format == Format::Glb { "glb" } else { "ply" };
    let disposition = HeaderValue::from_str(&format!("attachment; filename=\"{stem}.{ext}\""))
        .unwrap_or(HeaderValue::from_static("attachment"));
    (
        [
            (header::CONTENT_TYPE, HeaderValue::from_static("application/octet-stream")),
            (header::CONTENT_DISPOSITION, disposition),
        ],
        bytes,
    )
        .into_response()
}

async fn socket(AxState(s): AxState<Shared>, ws: WebSocketUpgrade) -> Response {
    let limit = s.settings.max_message;
    ws.max_message_size(limit).max_frame_size(limit).on_upgrade(move |socket| session(s, socket))
}

/// One page's connection: its edits in, everything published out.
async fn session(s: Shared, mut socket: WebSocket) {
    let mut rx = s.out.subscribe();
    // The page starts from the current state and the newest surface.
    let (hello, frame) = {
        let g = lock(&s.doc);
        (s.state_message(&g), g.frame.clone())
    };
    if socket.send(Message::Text(hello.into())).await.is_err() {
        return;
    }
    if let Some(f) = frame
        && socket.send(Message::Binary(f)).await.is_err()
    {
        return;
    }
    // The page's edits are applied in order on a blocking thread of their own (parsing a
    // scene builds its field: not for the async workers), while this loop goes on
    // forwarding states and surfaces: an edit that arrives during a drag's burst of them
    // does not hold up the state and surface of the one before.
    let (edits, mut replies) = editor(s.clone());
    loop {
        tokio::select! {
            incoming = socket.recv() => {
                let Some(Ok(msg)) = incoming else { break };
                let refused = match msg {
                    Message::Text(t) => edits.try_send(t.to_string()).is_err(),
                    Message::Close(_) => break,
                    _ => false,
                };
                if refused {
                    let busy = error_reply(0, "too many edits waiting: this one was dropped");
                    if socket.send(Message::Text(busy.into())).await.is_err() {
                        break;
                    }
                }
            }
            Some(reply) = replies.recv() => {
                if socket.send(Message::Text(reply.into())).await.is_err() {
                    break;
                }
            }
            out = rx.recv() => {
                let msg = match out {
                    Ok(Out::Text(t)) => Message::Text(t.into()),
                    Ok(Out::Binary(b)) => Message::Binary(b),
                    Err(broadcast::error::RecvError::Lagged(_)) => {
                        // A page too slow for the stream missed messages: it gets the
                        // current state and surface, which is all it needs.
                        let (state, frame) = {
                            let g = lock(&s.doc);
                            (s.state_message(&g), g.frame.clone())
                        };
                        if socket.send(Message::Text(state.into())).await.is_err() {
                            break;
                        }
                        match frame {
                            Some(f) => Message::Binary(f),
                            None => continue,
                        }
                    }
                    Err(broadcast::error::RecvError::Closed) => break,
                };
                if socket.send(msg).await.is_err() {
                    break;
                }
            }
        }
    }
}

/// Edits waiting for their turn, per page: a page that sends faster than they can be
/// applied is told so instead of queueing without bound.
const EDIT_QUEUE: usize = 256;

/// Starts a page's editor: a blocking task that applies the page's messages one after the
/// other, in the order they came, and hands back its replies (errors, saves, exports) for
/// this page alone. It ends when the page's session drops the sender.
fn editor(
    s: Shared,
) -> (tokio::sync::mpsc::Sender<String>, tokio::sync::mpsc::UnboundedReceiver<String>) {
    let (edits, mut incoming) = tokio::sync::mpsc::channel::<String>(EDIT_QUEUE);
    let (replies, outgoing) = tokio::sync::mpsc::unbounded_channel();
    tokio::task::spawn_blocking(move || {
        while let Some(text) = incoming.blocking_recv() {
            if let Some(reply) = s.handle(&text)
                && replies.send(reply).is_err()
            {
                break;
            }
        }
    });
    (edits, outgoing)
}

/// An edit from the page.
#[derive(Deserialize)]
struct Edit {
    #[serde(default)]
    seq: u64,
    op: String,
    #[serde(default)]
    path: Vec<Step>,
    value: Option<Json>,
    kind: Option<String>,
    index: Option<usize>,
    to: Option<[f64; 3]>,
    joint: Option<String>,
    format: Option<String>,
    file: Option<String>,
}

impl State {
    /// The page's picture of the document: revision, settings, skeleton, history.
    fn state_message(&self, g: &Doc) -> String {
        let scene = g.scene.as_ref();
        let shown = shown_scene(g).ok();
        let skeleton = shown
            .as_ref()
            .map(|s| edit::skeleton_json(&g.doc, s, g.pose.as_deref()))
            .unwrap_or(json!({"elements": [], "joints": []}));
        let lattice = scene.and_then(|s| s.lattice(&Overrides::default()).ok());
        let cell = lattice.as_ref().map(|l| l.cell);
        // Samples along the longest side: what `resolution` sets.
        let samples = lattice.as_ref().and_then(|l| l.dims.iter().max().copied());
        json!({
            "type": "state",
            "revision": g.revision,
            "seq": g.seq,
            "file": self.origin_name,
            "dirty": g.text != g.saved,
            "can_undo": !g.undo.is_empty(),
            "can_redo": !g.redo.is_empty(),
            "error": g.error,
            "pose": g.pose.clone().unwrap_or_else(|| "rest".into()),
            "toward": g.toward.as_ref().map(|(p, t)| json!({"pose": p, "t": t})),
            "poses": scene.and_then(|s| s.articulation.as_ref()).map(|a| a.poses.clone()).unwrap_or_default(),
            "method": scene.map(|s| s.method.name()),
            "methods": skelform::Method::ALL.iter().map(|(n, _)| *n).collect::<Vec<_>>(),
            "iso": scene.map(|s| s.iso),
            "cell": cell,
            "samples": samples,
            "domain": scene.map(|s| json!({"min": s.domain.min.to_array(), "max": s.domain.max.to_array()})),
            "skeleton": skeleton,
        })
        .to_string()
    }

    fn broadcast(&self, out: Out) {
        // No page open is not an error.
        let _ = self.out.send(out);
    }

    /// Starts meshing the current document, cancelling the work in flight.
    fn submit(&self, g: &mut MutexGuard<'_, Doc>) {
        g.control.cancel();
        g.control = Control::default();
        // The scene in the pose shown (or between two poses), so the mesher needs no pose.
        let Ok(scene) = shown_scene(g) else { return };
        let job = Job {
            revision: g.revision,
            scene,
            pose: None,
            control: g.control.clone(),
            queued: std::time::Instant::now(),
        };
        if let Some(mesher) = lock(&self.jobs).as_ref() {
            mesher.submit(job);
        }
    }

    /// A result from the worker, published only while its revision is the newest: under the
    /// lock, so no newer state can slip in between the check and the send.
    fn publish(&self, outcome: Outcome) {
        let mut g = lock(&self.doc);
        match outcome {
            Outcome::Mesh { revision, level, mesh, frame, ms, waited_ms, run, phases_ms } => {
                // A coarse surface that comes after its revision's full one is not shown.
                if revision != g.revision
                    || (level == Level::Coarse && g.shown == Some((revision, Level::Full)))
                {
                    return;
                }
                let frame = Bytes::from(frame);
                g.shown = Some((revision, level));
                if level == Level::Full {
                    g.full = Some(mesh.clone());
                }
                g.frame = Some(frame.clone());
                self.broadcast(Out::Binary(frame));
                let run = run.unwrap_or_default();
                self.broadcast(Out::Text(
                    json!({"type": "meshed", "revision": revision, "level": level as u32, "ms": ms,
                           "waited_ms": waited_ms,
                           "vertices": mesh.positions.len(), "triangles": mesh.triangles.len(),
                           "incremental": run.incremental, "full_because": run.full_because,
                           "resampled": run.reuse.resampled,
                           "reused_vertices": run.reuse.reused_vertices,
                           "placed_vertices": run.reuse.placed_vertices,
                           "phases_ms": phases_ms.map(|[s, e, r, n]| json!({"sampling": s,
                               "extraction": e, "refinement": r, "normals": n}))})
                    .to_string(),
                ));
            }
            Outcome::Failed { revision, message } => {
                if revision == g.revision && g.failed != Some(revision) {
                    g.failed = Some(revision);
                    self.broadcast(Out::Text(
                        json!({"type": "error", "revision": revision, "message": message})
                            .to_string(),
                    ));
                }
            }
        }
    }

    /// Applies one message; returns a reply for this page alone (an error), while accepted
    /// changes are broadcast to every page.
    fn handle(&self, text: &str) -> Option<String> {
        let edit: Edit = match serde_json::from_str(text) {
            Ok(e) => e,
            Err(e) => return Some(error_reply(0, &format!("not an edit: {e}"))),
        };
        let seq = edit.seq;
        match self.apply(edit) {
            Ok(reply) => reply,
            Err(e) => Some(error_reply(seq, &e.to_string())),
        }
    }

    fn apply(&self, e: Edit) -> Result<Option<String>, StudioError> {
        let mut g = lock(&self.doc);
        g.seq = g.seq.max(e.seq);
        let value = || {
            e.value.as_ref().ok_or_else(|| StudioError::Edit(format!("'{}' needs a value", e.op)))
        };
        let mut doc = g.doc.clone();
        match e.op.as_str() {
            "set" => edit::set(&mut doc, &e.path, edit::to_toml(value()?)?)?,
            "move" => {
                let to = e.to.ok_or_else(|| StudioError::Edit("'move' needs 'to'".into()))?;
                let scene = shown_scene(&g)?;
                let local =
                    edit::local_point(&doc, &scene, &e.path, skelform::DVec3::from_array(to))?;
                edit::set(&mut doc, &e.path, local)?;
            }
            "add" => {
                let kind = e.kind.as_deref().unwrap_or_default();
                edit::add(&mut doc, kind, value()?)?;
            }
            "delete" => {
                let kind = e.kind.as_deref().unwrap_or_default();
                let index =
                    e.index.ok_or_else(|| StudioError::Edit("'delete' needs 'index'".into()))?;
                edit::delete(&mut doc, kind, index)?;
            }
            "iso" => {
                let key = if doc.contains_key("field") || !doc.contains_key("skeleton") {
                    "field"
                } else {
                    "skeleton"
                };
                edit::set(
                    &mut doc,
                    &[Step::Key(key.into()), Step::Key("iso".into())],
                    edit::to_toml(value()?)?,
                )?;
            }
            "cell" => {
                if !doc.contains_key("mesh") {
                    doc.insert("mesh", toml_edit::Item::Table(toml_edit::Table::new()));
                }
                if let Some(t) = doc.get_mut("mesh").and_then(toml_edit::Item::as_table_mut) {
                    t.remove("resolution");
                }
                edit::set(
                    &mut doc,
                    &[Step::Key("mesh".into()), Step::Key("cell".into())],
                    edit::to_toml(value()?)?,
                )?;
            }
            "resolution" => {
                // Samples along the domain's longest side (the "128-samples cell"),
                // replacing `cell`.
                let n = value()?.as_u64().filter(|n| *n >= 2).ok_or_else(|| {
                    StudioError::Edit(
                        "'resolution' needs a whole number of samples, at least 2".into(),
                    )
                })?;
                if !doc.contains_key("mesh") {
                    doc.insert("mesh", toml_edit::Item::Table(toml_edit::Table::new()));
                }
                if let Some(t) = doc.get_mut("mesh").and_then(toml_edit::Item::as_table_mut) {
                    t.remove("cell");
                }
                let n = i64::try_from(n)
                    .map_err(|_| StudioError::Edit(format!("resolution {n} is too large")))?;
                edit::set(
                    &mut doc,
                    &[Step::Key("mesh".into()), Step::Key("resolution".into())],
                    toml_edit::Value::from(n),
                )?;
            }
            "method" => {
                if !doc.contains_key("mesh") {
                    doc.insert("mesh", toml_edit::Item::Table(toml_edit::Table::new()));
                }
                edit::set(
                    &mut doc,
                    &[Step::Key("mesh".into()), Step::Key("method".into())],
                    edit::to_toml(value()?)?,
                )?;
            }
            "angles" => {
                let joint = e
                    .joint
                    .as_deref()
                    .ok_or_else(|| StudioError::Edit("'angles' needs 'joint'".into()))?;
                let path = edit::angles_path(&doc, joint, g.pose.as_deref())?;
                let v = match value()? {
                    Json::Array(a) if a.len() == 1 => a[0].clone(),
                    v => v.clone(),
                };
                edit::set(&mut doc, &path, edit::to_toml(&v)?)?;
            }
            "pose" => return self.set_pose(&mut g, e.value.as_ref().and_then(Json::as_str)),
            "between" => {
                let to = e.kind.as_deref().ok_or_else(|| {
                    StudioError::Edit("'between' needs the pose to turn toward ('kind')".into())
                })?;
                let t = value()?.as_f64().filter(|t| (0.0..=1.0).contains(t));
                let t = t.ok_or_else(|| {
                    StudioError::Edit("'between' needs a value from 0 to 1".into())
                })?;
                return self.set_between(&mut g, to, t);
            }
            "slice" => {
                let spec = match e.value.as_ref() {
                    None | Some(Json::Null) => None,
                    Some(v) => {
                        let spec: SliceSpec = serde_json::from_value(v.clone())
                            .map_err(|err| StudioError::Edit(format!("not a slice: {err}")))?;
                        spec.check()?;
                        Some(spec)
                    }
                };
                g.slice = spec;
                self.send_slice(&g);
                return Ok(None);
            }
            "undo" | "redo" => return self.history(&mut g, e.op == "undo"),
            "save" => return self.save(&mut g),
            "export" => return self.export(&g, e.format.as_deref(), e.file.as_deref()),
            "state" => return Ok(Some(self.state_message(&g))),
            other => return Err(StudioError::Edit(format!("unknown operation '{other}'"))),
        }
        let text = doc.to_string();
        if text == g.text {
            // Nothing changed (a slider's `change` after its last `input`): no revision, no
            // undo step.
            return Ok(None);
        }
        let scene = match check(&text, &doc, &self.origin_name, g.pose.as_deref(), &self.place.dir)
        {
            Ok(s) => Some(s),
            // A document that did not check when opened takes edits that do not fix it yet.
            Err(err) if g.scene.is_none() => {
                g.error = Some(err.to_string());
                None
            }
            Err(err) => return Err(StudioError::Edit(err.to_string())),
        };
        let old = std::mem::replace(&mut g.text, text);
        g.undo.push(old);
        if g.undo.len() > self.settings.undo_limit {
            g.undo.remove(0);
        }
        g.redo.clear();
        g.doc = doc;
        if scene.is_some() {
            g.error = None;
        }
        g.scene = scene;
        self.changed(&mut g);
        Ok(None)
    }

    /// After the document or the pose changed: a new revision, its state, and meshing.
    fn changed(&self, g: &mut MutexGuard<'_, Doc>) {
        g.revision += 1;
        // Meshing starts before the page's state is built: the state goes out first all the
        // same, since a surface is published under the lock held here.
        self.submit(g);
        self.broadcast(Out::Text(self.state_message(g)));
        self.send_slice(g);
    }

    /// The field on the slice plane of the scene shown, when the page shows one.
    fn send_slice(&self, g: &Doc) {
        if let (Some(spec), Ok(scene)) = (g.slice, shown_scene(g)) {
            self.broadcast(Out::Binary(Bytes::from(slice::frame(&scene, &spec, g.revision))));
        }
    }

    fn set_pose(
        &self,
        g: &mut MutexGuard<'_, Doc>,
        pose: Option<&str>,
    ) -> Result<Option<String>, StudioError> {
        let pose = pose.map(str::to_string);
        if let (Some(scene), Some(p)) = (&g.scene, &pose) {
            scene.posed(p).map_err(|e| StudioError::Edit(e.to_string()))?;
        }
        g.pose = pose;
        g.toward = None;
        self.changed(g);
        Ok(None)
    }

    /// Shows the pose `t` of the way from the current one toward `to` (playback).
    fn set_between(
        &self,
        g: &mut MutexGuard<'_, Doc>,
        to: &str,
        t: f64,
    ) -> Result<Option<String>, StudioError> {
        let scene = g
            .scene
            .as_ref()
            .ok_or_else(|| StudioError::Edit("the scene has an error; fix it first".into()))?;
        let from = g.pose.clone().unwrap_or_else(|| "rest".into());
        scene.posed_between(&from, to, t).map_err(|e| StudioError::Edit(e.to_string()))?;
        g.toward = Some((to.to_string(), t));
        self.changed(g);
        Ok(None)
    }

    fn history(
        &self,
        g: &mut MutexGuard<'_, Doc>,
        undo: bool,
    ) -> Result<Option<String>, StudioError> {
        let from = if undo { g.undo.pop() } else { g.redo.pop() };
        let Some(text) = from else {
            return Err(StudioError::Edit(format!(
                "nothing to {}",
                if undo { "undo" } else { "redo" }
            )));
        };
        let doc: DocumentMut =
            text.parse().map_err(|e: toml_edit::TomlError| StudioError::Edit(e.to_string()))?;
        let scene = check(&text, &doc, &self.origin_name, g.pose.as_deref(), &self.place.dir);
        let old = std::mem::replace(&mut g.text, text);
        if undo {
            g.redo.push(old)
        } else {
            g.undo.push(old)
        }
        g.doc = doc;
        match scene {
            Ok(s) => {
                g.scene = Some(s);
                g.error = None;
            }
            Err(e) => {
                g.scene = None;
                g.error = Some(e.to_string());
            }
        }
        self.changed(g);
        Ok(None)
    }

    fn save(&self, g: &mut MutexGuard<'_, Doc>) -> Result<Option<String>, StudioError> {
        // Through a temporary file renamed over the scene (removed on a signal): the file is
        // the old text or the new, never half-written. The path is canonical: no link.
        skelform::mesh::io::atomic::write(&self.place.file, g.text.as_bytes())?;
        g.saved = g.text.clone();
        self.broadcast(Out::Text(self.state_message(g)));
        Ok(Some(json!({"type": "saved", "file": self.origin_name}).to_string()))
    }

    fn export(
        &self,
        g: &Doc,
        format: Option<&str>,
        file: Option<&str>,
    ) -> Result<Option<String>, StudioError> {
        use skelform::mesh::io::{Format, WriteOptions, write_mesh};
        let (format, ext) = match format.unwrap_or("glb") {
            "glb" => (Format::Glb, "glb"),
            "ply" => (Format::Ply, "ply"),
            other => {
                return Err(StudioError::Edit(format!("cannot export '{other}' (glb or ply)")));
            }
        };
        let stem = self
            .place
            .file
            .file_stem()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let name = file.map(str::to_string).unwrap_or_else(|| format!("{stem}.{ext}"));
        let path = self.place.export_path(&name, ext)?;
        let mesh =
            g.full.clone().ok_or_else(|| StudioError::Edit("no surface to export yet".into()))?;
        let options = WriteOptions { normals: true, ..WriteOptions::default() };
        write_mesh(&path, &mesh, format, &options).map_err(|e| StudioError::Edit(e.to_string()))?;
        Ok(Some(json!({"type": "exported", "file": name}).to_string()))
    }
}

/// The scene in the pose shown, for turning dragged handles back into file coordinates.
fn shown_scene(g: &Doc) -> Result<skelform::Scene, StudioError> {
    let scene = g
        .scene
        .as_ref()
        .ok_or_else(|| StudioError::Edit("the scene has an error; fix it first".into()))?;
    let shown = match (g.pose.as_deref(), &g.toward) {
        (from, Some((to, t))) => scene.posed_between(from.unwrap_or("rest"), to, *t),
        (Some(p), None) => scene.posed(p),
        (None, None) => Ok(scene.clone()),
    };
    shown.map_err(|e| StudioError::Edit(e.to_string()))
}

fn error_reply(seq: u64, message: &str) -> String {
    json!({"type": "error", "seq": seq, "message": message}).to_string()
}
