// skelform's .glb files as a web viewer sees them: three.js's GLTFLoader in headless
// Chromium loads what `skelform mesh` wrote, and what it builds must be what skelform says
// it wrote (`skelform check --json`): every triangle, the intersection curves as line
// segments in their own dark material (not three.js's white default), one colour per
// region pair, normals for shading, and a picture that shows the model.

import assert from 'node:assert/strict';
import { writeFileSync } from 'node:fs';
import { join } from 'node:path';
import { after, before, test } from 'node:test';
import { launch, open, outDir, root, serve, skelform, threeDir } from './harness.mjs';

let browser;
let server;

before(async () => {
    server = await serve({
        '/three/': threeDir,
        '/out/': outDir,
        '/': join(root, 'tests', 'browser', 'pages'),
    });
    browser = await launch();
});

after(async () => {
    await browser?.close();
    await server?.close();
});

/** Meshes `scene` to target/browser/`name`.glb and returns skelform's own account of it. */
function meshed(scene, name, ...flags) {
    const file = join(outDir, `${name}.glb`);
    skelform('mesh', scene, '-o', file, ...flags);
    return JSON.parse(skelform('check', '--json', file));
}

/** Loads target/browser/`name`.glb in three.js, saves the picture, returns the report. */
async function inThree(name) {
    const { page, errors } = await open(browser, `${server.url}/glb.html`);
    await page.waitForFunction(() => window.ready === true);
    const report = await page.evaluate((url) => window.loadGlb(url), `/out/${name}.glb`);
    writeFileSync(join(outDir, `${name}.png`), await page.locator('canvas').screenshot());
    const seen = [...errors];
    await page.close();
    assert.deepEqual(seen, [], `${name}: the page reported errors`);
    return report;
}

function curveSegments(check) {
    return check.curve_labels.reduce((sum, c) => sum + c.segments, 0);
}

test('a closed surface: every triangle, with normals, drawn', async () => {
    const check = meshed('examples/torus.toml', 'torus');
    const three = await inThree('torus');
    assert.equal(three.triangles, check.faces);
    assert.equal(three.lineSegments, 0);
    assert.ok(three.attributes.includes('normal'), `attributes ${three.attributes}`);
    assert.match(three.webgl, /WebGL/);
    assert.ok(three.coverage > 0.05, `the torus covers ${three.coverage} of the picture`);
    for (let axis = 0; axis < 3; axis += 1) {
        assert.ok(Math.abs(three.min[axis] - check.bounds.min[axis]) < 1e-4);
        assert.ok(Math.abs(three.max[axis] - check.bounds.max[axis]) < 1e-4);
    }
});

test('regions: one colour per region pair, curves as dark line segments', async () => {
    const check = meshed('examples/nonmanifold/saucer-and-square.toml', 'saucer-and-square');
    const three = await inThree('saucer-and-square');
    assert.equal(three.triangles, check.faces);
    assert.ok(check.labels.length >= 2, 'the scene has several region pairs');
    const colours = new Set(three.meshColors);
    const perVertex = three.vertexColors && three.attributes.includes('color');
    assert.ok(
        perVertex || colours.size >= check.labels.length,
        `region pairs ${check.labels.length}, colours ${[...colours]}`,
    );
    assert.ok(check.curves > 0);
    assert.equal(three.lineSegments, curveSegments(check));
    assert.ok(three.lineColors.length > 0);
    for (const colour of three.lineColors) assert.equal(colour, '#181818');
    assert.ok(three.coverage > 0.05, `coverage ${three.coverage}`);
});

test('--no-curves leaves the curves out and the surfaces in', async () => {
    const check = meshed(
        'examples/nonmanifold/saucer-and-square.toml',
        'saucer-no-curves',
        '--no-curves',
    );
    const three = await inThree('saucer-no-curves');
    assert.equal(three.triangles, check.faces);
    assert.ok(three.triangles > 0);
    assert.equal(three.lineSegments, 0);
    assert.equal(three.lines, 0);
});

test('a healed self-intersecting surface loads whole', async () => {
    const check = meshed('examples/healed/double-cone.toml', 'double-cone');
    const three = await inThree('double-cone');
    assert.equal(three.triangles, check.faces);
    assert.equal(three.lineSegments, curveSegments(check));
    for (const colour of three.lineColors) assert.equal(colour, '#181818');
    assert.ok(three.coverage > 0.05, `coverage ${three.coverage}`);
});
