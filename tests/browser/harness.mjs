// What every browser test of skelform shares: the system's Chromium started headless by
// playwright-core (no browser is downloaded), a static server on loopback that serves the
// test pages and three.js from its npm package (nothing comes from the internet), the
// skelform binary, and the folder where outputs and screenshots go for people to look at.

import { spawnSync } from 'node:child_process';
import { createReadStream, existsSync, mkdirSync, statSync } from 'node:fs';
import { createServer } from 'node:http';
import { dirname, extname, join, normalize, resolve, sep } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

const here = dirname(fileURLToPath(import.meta.url));

/** The repository's root. */
export const root = resolve(here, '..', '..');

/** Where tests write meshes and screenshots (git-ignored). */
export const outDir = join(root, 'target', 'browser');
mkdirSync(outDir, { recursive: true });

/** The skelform binary: `SKELFORM`, else the test profile's build. */
export const skelformBin = process.env.SKELFORM
    ? resolve(root, process.env.SKELFORM)
    : join(root, 'target', 'debug', 'skelform');

/** Runs skelform with `args` and returns its standard output; throws with its stderr. */
export function skelform(...args) {
    const run = spawnSync(skelformBin, args, { cwd: root, encoding: 'utf8' });
    if (run.error) throw new Error(`cannot run ${skelformBin}: ${run.error.message}`);
    if (run.status !== 0) {
        throw new Error(`skelform ${args.join(' ')} exited ${run.status}:\n${run.stderr}`);
    }
    return run.stdout;
}

const types = {
    '.html': 'text/html; charset=utf-8',
    '.js': 'text/javascript; charset=utf-8',
    '.mjs': 'text/javascript; charset=utf-8',
    '.json': 'application/json',
    '.glb': 'model/gltf-binary',
    '.png': 'image/png',
};

/**
 * Serves files on 127.0.0.1 at a free port. `mounts` maps a URL prefix ("/three/") to a
 * folder; a path that leaves its folder is refused. Resolves to `{ url, close }`.
 */
export function serve(mounts) {
    const server = createServer((req, res) => {
        const path = decodeURIComponent(new URL(req.url, 'http://localhost').pathname);
        if (path === '/favicon.ico') {
            // Browsers ask for it unbidden; a 404 would show as a console error.
            res.writeHead(204);
            res.end();
            return;
        }
        for (const [prefix, folder] of Object.entries(mounts)) {
            if (!path.startsWith(prefix)) continue;
            const base = resolve(folder);
            const file = normalize(join(base, path.slice(prefix.length)));
            if (file !== base && !file.startsWith(base + sep)) break;
            if (!existsSync(file) || !statSync(file).isFile()) break;
            res.writeHead(200, {
                'content-type': types[extname(file)] ?? 'application/octet-stream',
                'content-length': statSync(file).size,
                'cache-control': 'no-store',
            });
            createReadStream(file).pipe(res);
            return;
        }
        res.writeHead(404, { 'content-type': 'text/plain' });
        res.end(`not found: ${path}`);
    });
    return new Promise((ok, fail) => {
        server.once('error', fail);
        server.listen(0, '127.0.0.1', () => {
            const { port } = server.address();
            ok({
                url: `http://127.0.0.1:${port}`,
                close: () => new Promise((done) => server.close(done)),
            });
        });
    });
}

/** The folder of the three.js npm package. */
export const threeDir = join(here, 'node_modules', 'three');

/** The system's Chromium: `SKELFORM_CHROMIUM`, else Debian's /usr/bin/chromium. */
export function chromiumPath() {
    const path = process.env.SKELFORM_CHROMIUM ?? '/usr/bin/chromium';
    if (!existsSync(path)) {
        throw new Error(
            `no Chromium at ${path}: install Debian's chromium package ` +
                '(tests/browser/run.sh does) or set SKELFORM_CHROMIUM',
        );
    }
    return path;
}

/**
 * Starts headless Chromium. The flags keep it off the network (this machine's network is
 * closed, and a test must not depend on it) and give WebGL through SwiftShader, the
 * software renderer, since test machines have no GPU.
 */
export async function launch() {
    return chromium.launch({
        executablePath: chromiumPath(),
        headless: true,
        args: [
            '--no-sandbox',
            '--disable-gpu-sandbox',
            '--use-angle=swiftshader',
            '--enable-unsafe-swiftshader',
            '--disable-quic',
            '--no-first-run',
            '--disable-background-networking',
            '--disable-component-update',
            '--disable-sync',
        ],
    });
}

/**
 * Opens `url` in a new page whose console errors and uncaught exceptions are collected
 * into the returned `errors` array (a test asserts it stays empty).
 */
export async function open(browser, url) {
    const page = await browser.newPage({ viewport: { width: 640, height: 480 } });
    const errors = [];
    page.on('pageerror', (e) => errors.push(`page error: ${e.message}`));
    page.on('console', (m) => {
        if (m.type() === 'error') errors.push(`console error: ${m.text()}`);
    });
    // Chromium reports fetches whose body was read through a stream (three.js's FileLoader
    // does, for progress) as ERR_ABORTED even when they completed; a load that really
    // fails rejects in the page, so only other failures count here.
    page.on('requestfailed', (r) => {
        const why = r.failure()?.errorText ?? 'unknown';
        if (why !== 'net::ERR_ABORTED') errors.push(`request failed: ${r.url()} (${why})`);
    });
    await page.goto(url);
    return { page, errors };
}
