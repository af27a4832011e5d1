// The studio page: draws the surface and the skeleton, turns clicks, drags and form
// changes into edit messages, and shows what the server sends back. The server holds the
// scene; this page holds nothing but what it is shown (see docs/STUDIO.md for the protocol).
import * as THREE from 'three';
import { OrbitControls } from 'three/addons/OrbitControls.js';
import { TransformControls } from 'three/addons/TransformControls.js';

const token = new URLSearchParams(location.search).get('token') ?? '';
const $ = (id) => document.getElementById(id);

// What tests (and curious people, from the console) can read.
const studio = (window.studio = {
    revision: 0, frameRevision: 0, level: -1, vertices: 0, triangles: 0,
    timings: [], meshed: [], errors: [], state: null, handles: [], ready: false,
    // Where an edit's time goes on this side: edit → state arrival, and the page's own
    // handling of each state, frame and render (ms).
    stateTimings: [], handling: [],
});
// The timings kept: the newest few thousand, so a long session does not grow without bound.
const KEPT = 4000;
function record(list, entry) {
    list.push(entry);
    if (list.length > KEPT) list.splice(0, list.length - KEPT);
}

// --- three.js -------------------------------------------------------------------------
const view = $('view');
// A software renderer (no GPU: SwiftShader, llvmpipe) draws on the cores the server meshes
// on, and there a multisampled frame of the hand costs about four times a plain one: such a
// page is drawn without antialiasing. A GPU draws with it.
function softwareRenderer() {
    const gl = document.createElement('canvas').getContext('webgl2');
    if (!gl) return false;
    const software = /swiftshader|llvmpipe|softpipe|software/i;
    let name = String(gl.getParameter(gl.RENDERER));
    // Chromium names only itself there; its unmasked name is behind an extension (which
    // other browsers, naming the renderer plainly, warn about).
    if (/^webkit/i.test(name)) {
        const info = gl.getExtension('WEBGL_debug_renderer_info');
        if (info) name = String(gl.getParameter(info.UNMASKED_RENDERER_WEBGL));
    }
    gl.getExtension('WEBGL_lose_context')?.loseContext();
    return software.test(name);
}
studio.software = softwareRenderer();
const renderer = new THREE.WebGLRenderer({ antialias: !studio.software, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
view.appendChild(renderer.domElement);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0xf4f4f2);
const camera = new THREE.PerspectiveCamera(35, 1, 0.01, 1000);
scene.add(new THREE.HemisphereLight(0xffffff, 0x888877, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
camera.add(sun);
sun.position.set(1, 1, 2);
scene.add(camera);
const orbit = new OrbitControls(camera, renderer.domElement);
const gizmo = new TransformControls(camera, renderer.domElement);
gizmo.setSize(0.8);
scene.add(gizmo.getHelper());
gizmo.addEventListener('dragging-changed', (e) => {
    orbit.enabled = !e.value;
    if (!e.value) sendMove(true);
});
gizmo.addEventListener('objectChange', () => sendMove(false));

const surfaceMaterial = new THREE.MeshStandardMaterial({
    color: 0xd9b38c, roughness: 0.6, metalness: 0.0, side: THREE.DoubleSide,
});
const labelMaterial = new THREE.MeshStandardMaterial({
    vertexColors: true, roughness: 0.6, side: THREE.DoubleSide,
});
let surface = null;
const skeletonGroup = new THREE.Group();
scene.add(skeletonGroup);
// Handles are a few pixels across: 8×6 segments look as round as 12×8, and the hand has 254
// of them, more vertices than its coarse surface (a software renderer pays for each).
const handleGeometry = new THREE.SphereGeometry(1, 8, 6);
const handleMaterial = new THREE.MeshBasicMaterial({ color: 0x1060d0, depthTest: false, transparent: true, opacity: 0.85 });
const selectedMaterial = new THREE.MeshBasicMaterial({ color: 0xe03010, depthTest: false, transparent: true });
const jointMaterial = new THREE.MeshBasicMaterial({ color: 0x20a040, depthTest: false, transparent: true });
const lineMaterial = new THREE.LineBasicMaterial({ color: 0x1040a0, depthTest: false, transparent: true, opacity: 0.7 });

// Drawn only when something changed: the view, the gizmo, the selection, a state, surface
// or slice from the server. A picture drawn every frame kept a core busy (with a software
// renderer, all of it) that the server's meshing and this page's messages were waiting for.
// A state's skeleton is drawn with its revision's surface: while that surface is on its
// way (at most HOLD ms), nothing is drawn, so that a frame the next message replaces does
// not take the cores from the meshing of it. With a software renderer, whose frames cost
// the hand's coarse meshing several times over, the hold starts when an edit is sent: the
// gizmo dragged is then drawn with the surface it made.
let stale = true;
const redraw = () => { stale = true; };
const HOLD = 100;
let awaiting = null; // {revision, since}: a state whose surface has not arrived
function resize() {
    const w = view.clientWidth, h = view.clientHeight;
    renderer.setSize(w, h, false);
    renderer.domElement.style.width = w + 'px';
    renderer.domElement.style.height = h + 'px';
    camera.aspect = w / Math.max(h, 1);
    camera.updateProjectionMatrix();
    redraw();
}
window.addEventListener('resize', resize);
resize();
orbit.addEventListener('change', redraw);
gizmo.addEventListener('change', redraw);
renderer.setAnimationLoop(() => {
    orbit.update();
    if (!stale) return;
    if (awaiting && performance.now() - awaiting.since < HOLD) return;
    awaiting = null;
    stale = false;
    const start = performance.now();
    renderer.render(scene, camera);
    record(studio.handling, { kind: 'render', ms: performance.now() - start });
});

let framed = false;
function frameDomain(domain) {
    const min = new THREE.Vector3(...domain.min), max = new THREE.Vector3(...domain.max);
    const centre = min.clone().add(max).multiplyScalar(0.5);
    const size = max.clone().sub(min).length();
    orbit.target.copy(centre);
    camera.position.copy(centre).add(new THREE.Vector3(0, 0, 1.3 * size));
    camera.near = size / 100; camera.far = size * 20;
    camera.updateProjectionMatrix();
    handleScale = size / 150;
}
let handleScale = 0.02;

// --- messages ---------------------------------------------------------------------------
let seq = 0;
const sentAt = new Map(); // seq → time sent
const revisionSeq = new Map(); // revision → the newest seq it includes
let socket = null;

function send(msg) {
    if (!socket || socket.readyState !== WebSocket.OPEN) return;
    msg.seq = ++seq;
    sentAt.set(msg.seq, performance.now());
    if (sentAt.size > KEPT) sentAt.delete(sentAt.keys().next().value);
    socket.send(JSON.stringify(msg));
    if (studio.software && !QUIET.has(msg.op)) awaiting = { revision: studio.revision + 1, since: sentAt.get(msg.seq) };
}
// The edits that make no new surface.
const QUIET = new Set(['save', 'export', 'state', 'slice']);
studio.send = send;

function message(text, info = false) {
    const m = $('message');
    m.textContent = text;
    m.className = info ? 'info' : '';
    if (!info) studio.errors.push(text);
}

function connect() {
    socket = new WebSocket(`ws://${location.host}/ws?token=${encodeURIComponent(token)}`);
    socket.binaryType = 'arraybuffer';
    socket.onopen = () => { $('status').textContent = 'connected'; };
    socket.onclose = () => { $('status').textContent = 'disconnected: restart the studio and reload'; };
    socket.onmessage = (e) => {
        // Text messages redraw only when they change the view (a state); reports do not.
        if (typeof e.data === 'string') onText(JSON.parse(e.data));
        else if (new TextDecoder().decode(new Uint8Array(e.data, 0, 4)) === 'SKSL') { onSlice(e.data); redraw(); }
        else {
            const start = performance.now();
            onFrame(e.data);
            record(studio.handling, { kind: 'frame', ms: performance.now() - start });
        }
    };
}

function onText(m) {
    if (m.type === 'state') {
        const start = performance.now();
        if (m.revision > studio.revision && sentAt.has(m.seq)) {
            record(studio.stateTimings, { seq: m.seq, revision: m.revision, ms: start - sentAt.get(m.seq) });
        }
        onState(m);
        redraw();
        // A checked scene is meshed: hold its skeleton for its surface (a scene with an error
        // has none coming).
        if (m.error) awaiting = null;
        else if (m.revision > studio.frameRevision) awaiting = { revision: m.revision, since: awaiting?.since ?? start };
        record(studio.handling, { kind: 'state', revision: m.revision, ms: performance.now() - start });
    }
    else if (m.type === 'error') { message(m.message); awaiting = null; redraw(); }
    else if (m.type === 'saved') message(`saved ${m.file}`, true);
    else if (m.type === 'exported') message(`wrote ${m.file}`, true);
    else if (m.type === 'meshed') {
        record(studio.meshed, {
            revision: m.revision, level: m.level, ms: m.ms, waited: m.waited_ms,
            incremental: m.incremental, because: m.full_because, phases: m.phases_ms,
        });
        $('status').textContent = `revision ${m.revision} ${m.level ? 'full' : 'coarse'}: ` +
            `${m.vertices} vertices, ${m.triangles} triangles, meshed in ${m.ms.toFixed(0)} ms` +
            (m.incremental ? ' (incremental)' : m.full_because ? ` (from scratch: ${m.full_because})` : '');
    }
}

// --- the surface ------------------------------------------------------------------------
const palette = [0xd9b38c, 0x6fa8dc, 0x93c47d, 0xe06666, 0xffd966, 0x8e7cc3, 0x76a5af, 0xf6b26b];

function onFrame(buffer) {
    const dv = new DataView(buffer);
    const magic = String.fromCharCode(...new Uint8Array(buffer, 0, 4));
    if (magic !== 'SKFM') return;
    const revision = Number(dv.getBigUint64(8, true));
    const level = dv.getUint32(16, true), nv = dv.getUint32(20, true), nt = dv.getUint32(24, true);
    const flags = dv.getUint32(28, true);
    // A stale surface never replaces a newer one.
    if (revision < studio.frameRevision || (revision === studio.frameRevision && level < studio.level)) return;
    let at = 32;
    // The arrays are views of the message, which is this page's alone: nothing is copied.
    const positions = new Float32Array(buffer, at, nv * 3); at += nv * 12;
    let normals = null;
    if (flags & 1) { normals = new Float32Array(buffer, at, nv * 3); at += nv * 12; }
    const indices = new Uint32Array(buffer, at, nt * 3); at += nt * 12;
    let labels = null;
    if (flags & 2) { labels = new Uint32Array(buffer, at, nt * 2); }
    let geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(positions, 3));
    if (normals) geometry.setAttribute('normal', new THREE.BufferAttribute(normals, 3));
    geometry.setIndex(new THREE.BufferAttribute(indices, 1));
    let material = surfaceMaterial;
    if (labels) {
        // One colour a region pair: triangles are split apart so each keeps its own.
        geometry = geometry.toNonIndexed();
        const colours = new Float32Array(nt * 9);
        const c = new THREE.Color();
        for (let t = 0; t < nt; t++) {
            c.setHex(palette[(labels[2 * t] * 3 + labels[2 * t + 1]) % palette.length]);
            for (let k = 0; k < 3; k++) colours.set([c.r, c.g, c.b], t * 9 + k * 3);
        }
        geometry.setAttribute('color', new THREE.BufferAttribute(colours, 3));
        material = labelMaterial;
    }
    if (!normals) geometry.computeVertexNormals();
    if (surface) { scene.remove(surface); surface.geometry.dispose(); }
    surface = new THREE.Mesh(geometry, material);
    scene.add(surface);
    Object.assign(studio, { frameRevision: revision, level, vertices: nv, triangles: nt });
    if (awaiting && revision >= awaiting.revision) awaiting = null;
    redraw();
    const s = revisionSeq.get(revision);
    if (s !== undefined && sentAt.has(s)) {
        const ms = performance.now() - sentAt.get(s);
        record(studio.timings, { seq: s, revision, level, ms });
    }
    studio.ready = true;
}

// --- the slice plane: the field as a colour map with the iso contour (ch. 3) -------------
let slicePlane = null;
function dropSlice() {
    if (!slicePlane) return;
    scene.remove(slicePlane);
    slicePlane.geometry.dispose();
    slicePlane.material.map.dispose();
    slicePlane.material.dispose();
    slicePlane = null;
}
function onSlice(buffer) {
    if (!$('slice').checked) return;
    const dv = new DataView(buffer);
    const axis = dv.getUint32(16, true), w = dv.getUint32(20, true), h = dv.getUint32(24, true);
    const f = (k) => dv.getFloat32(32 + 4 * k, true);
    const [at, u0, u1, v0, v1] = [f(0), f(1), f(2), f(3), f(4)];
    const values = new Float32Array(buffer, 56, w * h);
    let scale = 0;
    for (const v of values) if (Number.isFinite(v)) scale = Math.max(scale, Math.abs(v));
    scale = scale || 1;
    const rgba = new Uint8Array(w * h * 4);
    for (let j = 0; j < h; j++) {
        for (let i = 0; i < w; i++) {
            const k = j * w + i, v = values[k];
            const t = Math.sqrt(Math.min(1, Math.abs(v) / scale));
            let c = v < 0 ? [255 * (1 - t) + 40 * t, 255 * (1 - t) + 90 * t, 255] : [255, 255 * (1 - t) + 70 * t, 255 * (1 - t) + 40 * t];
            const right = i + 1 < w ? values[k + 1] : v, up = j + 1 < h ? values[k + w] : v;
            if ((v < 0) !== (right < 0) || (v < 0) !== (up < 0)) c = [0, 0, 0];
            if (!Number.isFinite(v)) c = [128, 128, 128];
            rgba.set([c[0], c[1], c[2], 255], k * 4);
        }
    }
    const texture = new THREE.DataTexture(rgba, w, h, THREE.RGBAFormat);
    texture.needsUpdate = true;
    const [ua, va] = axis === 0 ? [1, 2] : axis === 1 ? [0, 2] : [0, 1];
    const corner = (u, v) => { const p = [0, 0, 0]; p[axis] = at; p[ua] = u; p[va] = v; return p; };
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.Float32BufferAttribute([...corner(u0, v0), ...corner(u1, v0), ...corner(u1, v1), ...corner(u0, v1)], 3));
    geometry.setAttribute('uv', new THREE.Float32BufferAttribute([0, 0, 1, 0, 1, 1, 0, 1], 2));
    geometry.setIndex([0, 1, 2, 0, 2, 3]);
    dropSlice();
    slicePlane = new THREE.Mesh(geometry, new THREE.MeshBasicMaterial({ map: texture, side: THREE.DoubleSide, transparent: true, opacity: 0.85 }));
    scene.add(slicePlane);
    studio.slice = { axis, w, h, at };
}
function sendSlice() {
    if (!$('slice').checked) { dropSlice(); send({ op: 'slice', value: null }); studio.slice = null; return; }
    send({ op: 'slice', value: { axis: Number($('slice-axis').value), at: Number($('slice-at').value) } });
}
$('slice').onchange = sendSlice;
$('slice-axis').onchange = sendSlice;
$('slice-at').oninput = sendSlice;

// --- the skeleton -----------------------------------------------------------------------
let selected = null; // {kind, index}
let dragging = null; // the handle the gizmo holds

function onState(m) {
    studio.state = m;
    studio.revision = m.revision;
    revisionSeq.set(m.revision, m.seq);
    if (revisionSeq.size > KEPT) revisionSeq.delete(revisionSeq.keys().next().value);
    $('file').textContent = m.file;
    $('dirty').textContent = m.dirty ? ' ●' : '';
    $('undo').disabled = !m.can_undo;
    $('redo').disabled = !m.can_redo;
    if (m.error) message(m.error);
    fillSelect($('method'), m.methods, m.method);
    fillSelect($('pose'), m.poses.length ? m.poses : ['rest'], m.pose);
    fillSelect($('toward'), m.poses.length ? m.poses : ['rest'], m.toward ? m.toward.pose : null);
    if (!playing && document.activeElement !== $('t')) $('t').value = m.toward ? m.toward.t : 0;
    if (document.activeElement !== $('cell') && m.cell != null) $('cell').value = +m.cell.toPrecision(4);
    if (document.activeElement !== $('samples') && m.samples != null) $('samples').value = m.samples;
    if (document.activeElement !== $('iso') && m.iso != null) $('iso').value = m.iso;
    if (m.domain && !framed) { frameDomain(m.domain); framed = true; }
    if (!gizmo.dragging) drawSkeleton(m.skeleton);
    drawPanel(m.skeleton);
    drawJoints(m.skeleton.joints);
    for (const k of ['blend', 'kernel', 'radius']) {
        const input = $(`skeleton-${k}`);
        const v = m.skeleton.settings?.[k];
        if (document.activeElement !== input) input.value = v == null ? '' : v.replace(/^"|"$/g, '');
    }
}

function fillSelect(select, names, current) {
    if (select.dataset.names !== names.join()) {
        select.replaceChildren(...names.map((n) => new Option(n, n)));
        select.dataset.names = names.join();
    }
    if (current != null) select.value = current;
}

// What the drawn skeleton is made of (elements, their points, joints, the selection): while
// an edit only moves points, the handles and lines are moved where they are, not made anew.
let skeletonShape = null;
let skeletonLines = [];
let jointHandles = [];
const closedKind = (kind) => kind === 'triangle' || kind === 'polygon';

function drawSkeleton(sk) {
    redraw();
    const shape = JSON.stringify([
        sk.elements.map((el) => [el.kind, el.index, el.points.map((p) => p.path)]),
        sk.joints.map((j) => [j.name, !!j.at]), selected,
    ]);
    if (shape === skeletonShape) { moveSkeleton(sk); return; }
    skeletonShape = shape;
    gizmo.detach();
    for (const c of skeletonGroup.children) if (c.isLine) c.geometry.dispose();
    skeletonGroup.clear();
    studio.handles = [];
    skeletonLines = [];
    jointHandles = [];
    for (const el of sk.elements) {
        const pts = el.points.map((p) => new THREE.Vector3(...p.at));
        const isSel = selected && selected.kind === el.kind && selected.index === el.index;
        if (pts.length > 1) {
            const geo = new THREE.BufferGeometry().setFromPoints(closedKind(el.kind) ? [...pts, pts[0]] : pts);
            const line = new THREE.Line(geo, lineMaterial);
            line.renderOrder = 1;
            skeletonGroup.add(line);
            skeletonLines.push(line);
        }
        el.points.forEach((p, k) => {
            const h = new THREE.Mesh(handleGeometry, isSel ? selectedMaterial : handleMaterial);
            h.position.copy(pts[k]);
            h.scale.setScalar(handleScale);
            h.renderOrder = 2;
            h.userData = { kind: el.kind, index: el.index, path: p.path };
            skeletonGroup.add(h);
            studio.handles.push(h);
            if (isSel && dragging && JSON.stringify(dragging.userData.path) === JSON.stringify(p.path)) {
                dragging = h;
                gizmo.attach(h);
            }
        });
    }
    for (const j of sk.joints) {
        if (!j.at) continue;
        const h = new THREE.Mesh(handleGeometry, jointMaterial);
        h.position.set(...j.at);
        h.scale.setScalar(handleScale * 1.3);
        h.renderOrder = 2;
        h.userData = { joint: j.name };
        skeletonGroup.add(h);
        jointHandles.push(h);
    }
}

/** The skeleton drawn moved to the positions of `sk`, whose shape is the one drawn. */
function moveSkeleton(sk) {
    let h = 0, l = 0, jh = 0;
    for (const el of sk.elements) {
        if (el.points.length > 1) {
            const geo = skeletonLines[l++].geometry;
            const attr = geo.getAttribute('position');
            el.points.forEach((p, k) => attr.setXYZ(k, ...p.at));
            if (closedKind(el.kind)) attr.setXYZ(el.points.length, ...el.points[0].at);
            attr.needsUpdate = true;
            geo.computeBoundingSphere();
        }
        for (const p of el.points) studio.handles[h++].position.set(...p.at);
    }
    for (const j of sk.joints) if (j.at) jointHandles[jh++].position.set(...j.at);
}

// Where a handle is on the screen, in CSS pixels of the page (for tests).
studio.handleScreen = (i) => {
    const h = studio.handles[i];
    const p = h.position.clone().project(camera);
    const r = renderer.domElement.getBoundingClientRect();
    return { x: r.left + (p.x + 1) / 2 * r.width, y: r.top + (1 - p.y) / 2 * r.height, path: h.userData.path };
};

// A small grey picture of the view, for tests that check the picture changed.
studio.snapshot = () => {
    const c = Object.assign(document.createElement('canvas'), { width: 96, height: 72 });
    const g = c.getContext('2d');
    g.drawImage(renderer.domElement, 0, 0, 96, 72);
    const d = g.getImageData(0, 0, 96, 72).data;
    const out = [];
    for (let i = 0; i < d.length; i += 4) out.push((d[i] + d[i + 1] + d[i + 2]) / 3 | 0);
    return out;
};

let lastMove = 0;
function sendMove(final) {
    if (!dragging) return;
    const now = performance.now();
    // While dragging, at most one edit per 60 ms: each cancels the meshing of the last.
    if (!final && now - lastMove < 60) return;
    lastMove = now;
    const p = dragging.position;
    send({ op: 'move', path: dragging.userData.path, to: [p.x, p.y, p.z] });
}

const raycaster = new THREE.Raycaster();
let downAt = null;
renderer.domElement.addEventListener('pointerdown', (e) => { downAt = [e.clientX, e.clientY]; });
renderer.domElement.addEventListener('pointerup', (e) => {
    if (!downAt || Math.hypot(e.clientX - downAt[0], e.clientY - downAt[1]) > 4 || gizmo.dragging) return;
    const r = renderer.domElement.getBoundingClientRect();
    const ndc = new THREE.Vector2((e.clientX - r.left) / r.width * 2 - 1, -((e.clientY - r.top) / r.height) * 2 + 1);
    raycaster.setFromCamera(ndc, camera);
    const hit = raycaster.intersectObjects(skeletonGroup.children.filter((c) => c.isMesh))[0];
    if (!hit) return;
    const u = hit.object.userData;
    if (u.joint) { focusJoint(u.joint); return; }
    selected = { kind: u.kind, index: u.index };
    dragging = hit.object;
    drawSkeleton(studio.state.skeleton);
    drawPanel(studio.state.skeleton);
});

// --- the side panel ---------------------------------------------------------------------
let panelShown = null; // what the panel shows, to be rebuilt only when it changes
function drawPanel(sk) {
    const box = $('selection');
    const el = selected && sk.elements.find((e) => e.kind === selected.kind && e.index === selected.index);
    const shown = JSON.stringify(el ? [el.kind, el.index, el.joint, el.radius, el.strength, el.group] : null);
    if (shown === panelShown) return;
    panelShown = shown;
    const parts = [Object.assign(document.createElement('h2'), { textContent: 'Selection' })];
    if (!el) {
        parts.push(Object.assign(document.createElement('p'), { className: 'hint', textContent: 'Click a handle to select its element; drag the gizmo to move it.' }));
        box.replaceChildren(...parts);
        return;
    }
    parts.push(Object.assign(document.createElement('p'), { textContent: `${el.kind} ${el.index}` + (el.joint ? ` (joint ${el.joint})` : '') }));
    const field = (name, value, parse) => {
        const label = document.createElement('label');
        label.textContent = name;
        const input = Object.assign(document.createElement('input'), { type: 'text', value: value ?? '' });
        input.id = `param-${name}`;
        input.addEventListener('change', () => {
            const v = parse(input.value);
            if (v === undefined) { message(`${name}: not a value`); return; }
            send({ op: 'set', path: ['skeleton', el.kind, el.index, name], value: v });
        });
        label.appendChild(input);
        parts.push(label);
    };
    const nums = (s) => {
        const xs = s.split(/[ ,]+/).filter(Boolean).map(Number);
        if (!xs.length) return undefined;
        if (xs.some((x) => !Number.isFinite(x))) return null; // refused by the server, with its message
        return xs.length === 1 ? xs[0] : xs;
    };
    field('radius', el.radius.join(', '), nums);
    field('strength', el.strength.join(', '), nums);
    field('group', el.group, (s) => s.trim() || undefined);
    const del = Object.assign(document.createElement('button'), { textContent: `Delete ${el.kind}` });
    del.addEventListener('click', () => { send({ op: 'delete', kind: el.kind, index: el.index }); selected = null; dragging = null; });
    parts.push(del);
    box.replaceChildren(...parts);
}

let jointsShown = null; // what the sliders show, to be rebuilt only when it changes
function drawJoints(joints) {
    const box = $('joints');
    if (box.contains(document.activeElement) && document.activeElement.type === 'range') return;
    const shown = JSON.stringify([studio.state.pose, joints.map((j) => [j.name, j.axes, j.angles])]);
    if (shown === jointsShown) return;
    jointsShown = shown;
    const parts = [Object.assign(document.createElement('h2'), { textContent: joints.length ? `Joints (pose ${studio.state.pose})` : 'Joints: none' })];
    for (const j of joints) {
        const div = Object.assign(document.createElement('div'), { className: 'joint', id: `joint-${j.name}` });
        div.appendChild(Object.assign(document.createElement('div'), { textContent: j.name }));
        const angles = j.axes.map((_, k) => j.angles[k] ?? 0);
        j.axes.forEach((axis, k) => {
            const label = document.createElement('label');
            label.textContent = `${axis} ${angles[k]}°`;
            const input = Object.assign(document.createElement('input'), { type: 'range', min: -180, max: 180, step: 1, value: angles[k] });
            input.dataset.joint = j.name;
            input.dataset.axis = k;
            let last = 0;
            const push = (final) => {
                const now = performance.now();
                if (!final && now - last < 60) return;
                last = now;
                angles[k] = Number(input.value);
                label.firstChild.textContent = `${axis} ${angles[k]}°`;
                send({ op: 'angles', joint: j.name, value: angles.length === 1 ? angles[0] : angles.slice() });
            };
            input.addEventListener('input', () => push(false));
            input.addEventListener('change', () => push(true));
            label.appendChild(input);
            div.appendChild(label);
        });
        parts.push(div);
    }
    box.replaceChildren(...parts);
}

function focusJoint(name) {
    const div = $(`joint-${name}`);
    if (div) { div.scrollIntoView({ block: 'nearest' }); div.style.background = '#e4f4e4'; setTimeout(() => { div.style.background = ''; }, 800); }
}

// The skeleton's own settings: a name (blend, kernel) or a number (radius).
for (const k of ['blend', 'kernel', 'radius']) {
    $(`skeleton-${k}`).addEventListener('change', (e) => {
        const text = e.target.value.trim();
        if (!text) return;
        const value = k === 'radius' ? Number(text) : text;
        send({ op: 'set', path: ['skeleton', k], value: Number.isFinite(value) || k !== 'radius' ? value : null });
    });
}

// --- the bar ----------------------------------------------------------------------------
$('undo').onclick = () => send({ op: 'undo' });
$('redo').onclick = () => send({ op: 'redo' });
$('save').onclick = () => send({ op: 'save' });
$('method').onchange = (e) => send({ op: 'method', value: e.target.value });
$('pose').onchange = (e) => send({ op: 'pose', value: e.target.value });
// Playback (DIS §2.8): the skeleton turned step by step from the pose toward another, each
// step shown as soon as its coarse surface arrives (a step cancels the last one's full run).
let playing = false;
$('t').oninput = (e) => send({ op: 'between', kind: $('toward').value, value: Number(e.target.value) });
$('play').onclick = async () => {
    if (playing) { playing = false; return; }
    playing = true;
    $('play').textContent = 'Stop';
    const steps = 16;
    for (let i = 0; i <= steps && playing; i++) {
        const t = i / steps;
        $('t').value = t;
        const revision = studio.revision;
        send({ op: 'between', kind: $('toward').value, value: t });
        const start = performance.now();
        while (playing && studio.frameRevision <= revision && performance.now() - start < 3000) {
            await new Promise((r) => setTimeout(r, 20));
        }
    }
    playing = false;
    $('play').textContent = 'Play';
};
$('cell').onchange = (e) => send({ op: 'cell', value: Number(e.target.value) });
$('samples').onchange = (e) => send({ op: 'resolution', value: Math.round(Number(e.target.value)) });
$('iso').onchange = (e) => send({ op: 'iso', value: Number(e.target.value) });
$('add').onchange = (e) => {
    const kind = e.target.value;
    e.target.value = '';
    const d = studio.state.domain;
    if (!kind || !d) return;
    const c = d.min.map((lo, k) => +((lo + d.max[k]) / 2).toFixed(4));
    const r = +(Math.min(...d.max.map((hi, k) => hi - d.min[k])) / 10).toFixed(4);
    // A small element at the domain's centre, in the xy plane: drag its handles from there.
    const at = (dx, dy) => [+(c[0] + dx * r).toFixed(4), +(c[1] + dy * r).toFixed(4), c[2]];
    const shapes = {
        point: { at: c },
        segment: { a: c, b: at(3, 0) },
        polyline: { points: [c, at(2, 1), at(4, 0)] },
        curve: { bezier: [c, at(1, 2), at(3, 2), at(4, 0)] },
        triangle: { vertices: [c, at(3, 0), at(1.5, 2)] },
        polygon: { vertices: [c, at(3, 0), at(3, 2), at(1.5, 3), at(0, 2)] },
    };
    if (!shapes[kind]) return;
    send({ op: 'add', kind, value: { ...shapes[kind], radius: r } });
};
window.addEventListener('keydown', (e) => {
    if (!(e.ctrlKey || e.metaKey) || e.target.tagName === 'INPUT') return;
    const k = e.key.toLowerCase();
    if (k === 'z' && !e.shiftKey) { send({ op: 'undo' }); e.preventDefault(); }
    else if (k === 'y' || (k === 'z' && e.shiftKey)) { send({ op: 'redo' }); e.preventDefault(); }
});

function download(name, href) {
    const a = Object.assign(document.createElement('a'), { href, download: name });
    document.body.appendChild(a);
    a.click();
    a.remove();
}
const stem = () => (studio.state?.file ?? 'scene').replace(/\.toml$/, '');
$('glb').onclick = () => download(`${stem()}.glb`, `/api/mesh/scene.glb?token=${encodeURIComponent(token)}`);
$('ply').onclick = () => download(`${stem()}.ply`, `/api/mesh/scene.ply?token=${encodeURIComponent(token)}`);
$('png').onclick = () => download(`${stem()}.png`, renderer.domElement.toDataURL('image/png'));

connect();
