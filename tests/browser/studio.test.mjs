// The design studio in real headless Chromium: `skelform studio` on a copy of the hand,
// the page opened with the printed URL, a handle dragged with the mouse, a joint slider
// moved, undo, save; the surface must change (vertex count and pixels) and the saved file
// must keep its comments. Prints edit → first surface and edit → full surface times.

import assert from 'node:assert/strict';
import { spawn } from 'node:child_process';
import { copyFileSync, mkdtempSync, readFileSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { after, before, test } from 'node:test';
import { launch, open, outDir, root, skelformBin } from './harness.mjs';

let browser;
let studio;
let dir;

/** Starts `skelform studio` and resolves to the URL it prints. */
function startStudio(scene) {
    studio = spawn(skelformBin, ['studio', scene, '--port', '0', '--no-open'], { cwd: root });
    let out = '';
    let err = '';
    studio.stderr.on('data', (d) => { err += d; });
    return new Promise((ok, fail) => {
        const timer = setTimeout(() => fail(new Error(`no URL from skelform studio in 60 s:\n${err}`)), 60000);
        studio.stdout.on('data', (d) => {
            out += d;
            const m = out.match(/skelform studio: (http:\/\/\S+)/);
            if (m) { clearTimeout(timer); ok(m[1]); }
        });
        studio.on('exit', (code) => fail(new Error(`skelform studio exited ${code}:\n${err}`)));
    });
}

before(async () => {
    browser = await launch();
    dir = mkdtempSync(join(tmpdir(), 'skelform-studio-'));
});

after(async () => {
    await browser?.close();
    studio?.kill();
    if (dir) rmSync(dir, { recursive: true, force: true });
});

/** Waits for a full surface newer than `revision`; returns what the page shows. */
async function fullAfter(page, revision) {
    await page.waitForFunction((r) => window.studio.level === 1 && window.studio.frameRevision > r, revision, { timeout: 120000 });
    return page.evaluate(() => ({ revision: window.studio.frameRevision, vertices: window.studio.vertices, errors: window.studio.errors }));
}

function differing(a, b) {
    let n = 0;
    for (let i = 0; i < a.length; i++) if (Math.abs(a[i] - b[i]) > 8) n++;
    return n;
}

test('the hand in the studio: drag a handle, bend a joint, undo, save', async () => {
    const scene = join(dir, 'hand.toml');
    copyFileSync(join(root, 'examples', 'skeleton', 'hand.toml'), scene);
    const original = readFileSync(scene, 'utf8');
    const url = await startStudio(scene);
    assert.match(url, /^http:\/\/127\.0\.0\.1:\d+\/\?token=[0-9a-f]{32}$/);

    const { page, errors } = await open(browser, url);
    await page.setViewportSize({ width: 1100, height: 720 });
    const first = await fullAfter(page, 0);
    assert.ok(first.vertices > 1000, `the hand has ${first.vertices} vertices`);
    await page.waitForTimeout(300);
    writeFileSync(join(outDir, 'studio-hand.png'), await page.screenshot());
    const before = await page.evaluate(() => window.studio.snapshot());

    // Drag the palm's vertex at the middle of the wrist with the mouse: a click selects it
    // and attaches the gizmo, a drag from its centre moves it in the view plane.
    const target = JSON.stringify(['skeleton', 'triangle', 0, 'vertices', 1]);
    const at = await page.evaluate((t) => {
        const i = window.studio.handles.findIndex((h) => JSON.stringify(h.userData.path) === t);
        return window.studio.handleScreen(i);
    }, target);
    await page.mouse.click(at.x, at.y);
    await page.waitForTimeout(200);
    await page.mouse.move(at.x, at.y);
    await page.mouse.down();
    await page.mouse.move(at.x + 60, at.y - 50, { steps: 10 });
    await page.mouse.up();
    const dragged = await fullAfter(page, first.revision);
    assert.notEqual(dragged.vertices, first.vertices, 'dragging the palm changed the surface');
    await page.waitForTimeout(300);
    const afterDrag = await page.evaluate(() => window.studio.snapshot());
    const changed = differing(before, afterDrag);
    assert.ok(changed > 5, `${changed} of ${before.length} pixels changed`);
    writeFileSync(join(outDir, 'studio-dragged.png'), await page.screenshot());

    // Bend the index finger's second knuckle with its slider.
    await page.evaluate(() => {
        const s = document.querySelector('input[type=range][data-joint="index2"]');
        s.value = 90;
        s.dispatchEvent(new Event('input', { bubbles: true }));
        s.dispatchEvent(new Event('change', { bubbles: true }));
    });
    const bent = await fullAfter(page, dragged.revision);
    assert.notEqual(bent.vertices, dragged.vertices, 'bending the finger changed the surface');
    writeFileSync(join(outDir, 'studio-bent.png'), await page.screenshot());

    // Undo with the keyboard: the same surface as before the bend.
    await page.evaluate(() => document.activeElement?.blur());
    await page.keyboard.press('Control+z');
    const undone = await fullAfter(page, bent.revision);
    assert.equal(undone.vertices, dragged.vertices, 'undo gives back the surface before the bend');

    // Save: the file has the drag, not the bend, and keeps its comments.
    await page.click('#save');
    await page.waitForFunction(() => /saved/.test(document.getElementById('message').textContent));
    const saved = readFileSync(scene, 'utf8');
    assert.notEqual(saved, original);
    assert.ok(saved.includes('# The hand of DIS chapter 6'), 'the header comment is kept');
    assert.ok(saved.includes('[[skeleton.joint]]              # index: first knuckle, theta = 10, phi = 15'));
    assert.ok(!saved.includes('vertices = [[-0.5, 0.05, 0], [0, 0, 0], [-0.25, 0.95, 0]]'), 'the dragged vertex moved');
    assert.ok(saved.includes('angles = 30\n'), 'the bend was undone');

    // The slice plane through the palm (z = 0, 0.8 of the way up the domain's z): the field
    // as a colour map with the iso contour.
    await page.check('#slice');
    await page.evaluate(() => {
        const s = document.getElementById('slice-at');
        s.value = 0.8;
        s.dispatchEvent(new Event('input', { bubbles: true }));
    });
    await page.waitForFunction(() => window.studio.slice && Math.abs(window.studio.slice.at) < 0.01);
    const slice = await page.evaluate(() => window.studio.slice);
    assert.equal(slice.axis, 2);
    assert.ok(slice.w > 100 && slice.h > 100, `slice ${slice.w}×${slice.h}`);
    await page.waitForTimeout(200);
    writeFileSync(join(outDir, 'studio-slice.png'), await page.screenshot());

    const timings = await page.evaluate(() => window.studio.timings);
    const firsts = timings.filter((t) => t.level === 0).map((t) => t.ms);
    const fulls = timings.filter((t) => t.level === 1).map((t) => t.ms);
    const median = (xs) => [...xs].sort((a, b) => a - b)[Math.floor(xs.length / 2)];
    console.log(`studio, hand: edit → first surface median ${median(firsts)?.toFixed(0)} ms (${firsts.length} edits), ` +
        `edit → full surface median ${median(fulls)?.toFixed(0)} ms (${fulls.length} edits)`);
    const meshed = await page.evaluate(() => window.studio.meshed);
    const server = (level) => median(meshed.filter((m) => m.level === level).map((m) => m.ms))?.toFixed(0);
    console.log(`studio, hand: the server's meshing alone, median coarse ${server(0)} ms, full ${server(1)} ms`);
    const seen = [...errors];
    const shown = await page.evaluate(() => window.studio.errors);
    await page.close();
    assert.deepEqual(seen, [], 'the page reported errors');
    assert.deepEqual(shown, [], 'the studio showed errors');
});
