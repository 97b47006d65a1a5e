// Browser test of the dashboard: starts `avsep serve --demo` on a free port, drives the
// system's Chromium with playwright-core, and checks the demo room's tracks appear and move,
// a label's player receives separated audio, a session created by uploading a calibration
// file reads back over REST, and a screenshot of the live view is not blank.
//
// AVSEP_BIN: the binary (default ../../target/debug/avsep); CHROMIUM: the browser
// (default /usr/bin/chromium). Screenshots go to tests/dashboard/out/.

import { test, before, after } from 'node:test';
import assert from 'node:assert/strict';
import { spawn } from 'node:child_process';
import { createServer } from 'node:net';
import { mkdirSync, readFileSync } from 'node:fs';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import { chromium } from 'playwright-core';

const here = dirname(fileURLToPath(import.meta.url));
const bin = process.env.AVSEP_BIN || resolve(here, '../../target/debug/avsep');
const browserPath = process.env.CHROMIUM || '/usr/bin/chromium';
const outDir = join(here, 'out');
const fixture = join(here, 'fixtures/room.json');

let server;
let base;
let browser;
let page;
const pageErrors = [];

function freePort() {
  return new Promise((ok, fail) => {
    const s = createServer();
    s.listen(0, '127.0.0.1', () => {
      const { port } = s.address();
      s.close(() => ok(port));
    });
    s.on('error', fail);
  });
}

/** Starts the server and resolves once stdout shows `pattern`. */
function startServer(port) {
  // --no-zenoh: Zenoh's default listener is a fixed port that concurrent test runs contend for.
  const child = spawn(bin, ['serve', '--demo', '--no-zenoh', '--bind', `127.0.0.1:${port}`], {
    env: { ...process.env, AVSEP_LOG: process.env.AVSEP_LOG || 'warn' },
    stdio: ['ignore', 'pipe', 'inherit'],
  });
  let seen = '';
  const ready = new Promise((ok, fail) => {
    const timer = setTimeout(() => fail(new Error(`no demo within 120 s; stdout: ${seen}`)), 120_000);
    child.stdout.on('data', (d) => {
      seen += d;
      if (/demo room ready/.test(seen)) {
        clearTimeout(timer);
        ok();
      }
    });
    child.on('exit', (code) => fail(new Error(`avsep exited with ${code}; stdout: ${seen}`)));
  });
  return { child, ready, stdout: () => seen };
}

async function rest(path, token) {
  const res = await fetch(base + path, { headers: token ? { Authorization: `Bearer ${token}` } : {} });
  assert.equal(res.status, 200, `${path}: ${res.status}`);
  return res.json();
}

before(async () => {
  mkdirSync(outDir, { recursive: true });
  const port = await freePort();
  base = `http://127.0.0.1:${port}`;
  server = startServer(port);
  await server.ready;
  assert.match(server.stdout(), new RegExp(`listening on ${base}`));
  assert.match(server.stdout(), new RegExp(`open ${base}/ in a browser`));
  browser = await chromium.launch({
    executablePath: browserPath,
    args: ['--no-sandbox', '--autoplay-policy=no-user-gesture-required', '--use-fake-ui-for-media-stream'],
  });
  page = await browser.newPage({ viewport: { width: 1400, height: 1000 } });
  page.on('pageerror', (e) => pageErrors.push(e.message));
  page.on('console', (m) => m.type() === 'error' && pageErrors.push(m.text()));
  page.on('response', (r) => r.status() >= 400 && pageErrors.push(`${r.status()} ${r.url()}`));
});

after(async () => {
  await browser?.close();
  if (server) {
    server.child.kill('SIGTERM');
    await new Promise((ok) => server.child.once('exit', ok));
  }
});

test('the demo room is listed, its tracks appear and move, and its voices arrive', async () => {
  await page.goto(base + '/');
  const row = page.locator('tr.demo');
  await row.waitFor({ timeout: 10_000 });
  const demoId = await row.getAttribute('data-session');
  assert.equal(await page.evaluate(() => window.avsep.demo), demoId);
  await row.locator('a').click();
  await page.waitForFunction(() => window.avsep.live && window.avsep.live.steps > 0, null, { timeout: 15_000 });

  // Tracks appear...
  await page.waitForFunction(() => window.avsep.live.visibleTracks().some((t) => t.live), null, {
    timeout: 30_000,
  });
  const snapshot = () =>
    page.evaluate(() =>
      Object.fromEntries(
        window.avsep.live.visibleTracks().filter((t) => t.live).map((t) => [t.label, t.position]),
      ),
    );
  // ...and move: some label seen twice 3 s apart has moved, or labels changed.
  const first = await snapshot();
  const step0 = await page.evaluate(() => window.avsep.live.step);
  await page.waitForTimeout(3000);
  const second = await snapshot();
  const step1 = await page.evaluate(() => window.avsep.live.step);
  assert.ok(step1 - step0 >= 15, `steps advance in real time (${step0} -> ${step1})`);
  const moved = Object.keys(first).filter(
    (l) => second[l] && Math.hypot(second[l][0] - first[l][0], second[l][1] - first[l][1]) > 0.02,
  );
  assert.ok(moved.length > 0, `a track moved: ${JSON.stringify({ first, second })}`);

  // A label's player receives separated audio, counted on the element and on window.
  await page.waitForFunction(() => Object.values(window.avsep.audioSamples).some((n) => n >= 16000), null, {
    timeout: 30_000,
  });
  const players = await page.$$eval('#players .player', (els) =>
    els.map((e) => ({ label: e.dataset.label, samples: Number(e.dataset.samples) })),
  );
  assert.ok(players.some((p) => p.samples >= 16000), JSON.stringify(players));

  // The camera panel and the metrics panel are filled.
  assert.ok((await page.locator('#cameras canvas').count()) >= 1);
  await page.waitForSelector('dd[data-metric="real-time factor"]', { timeout: 5000 });
  const rtf = Number(await page.textContent('dd[data-metric="real-time factor"]'));
  assert.ok(rtf > 0 && rtf < 1, `the demo keeps up (real-time factor ${rtf})`);
  // The demo room's camera is among the sensors whose clutter rate the tracker estimates.
  const clutter = await page.textContent('dd[data-metric="false detections per scan (configured)"]');
  assert.match(clutter, /\(1\)/, `the camera's rate is shown: ${clutter}`);

  // Screenshot of the live view; it is not blank (pixel variance measured in the page).
  const shot = await page.screenshot({ path: join(outDir, 'dashboard-live.png'), fullPage: true });
  const stats = await page.evaluate(async (b64) => {
    const img = new Image();
    img.src = `data:image/png;base64,${b64}`;
    await img.decode();
    const c = document.createElement('canvas');
    c.width = img.width;
    c.height = img.height;
    const g = c.getContext('2d');
    g.drawImage(img, 0, 0);
    const d = g.getImageData(0, 0, c.width, c.height).data;
    let n = 0;
    let sum = 0;
    let sum2 = 0;
    const colours = new Set();
    for (let i = 0; i < d.length; i += 4) {
      const v = 0.299 * d[i] + 0.587 * d[i + 1] + 0.114 * d[i + 2];
      sum += v;
      sum2 += v * v;
      n++;
      if (i % 64 === 0) colours.add((d[i] << 16) | (d[i + 1] << 8) | d[i + 2]);
    }
    const mean = sum / n;
    return { variance: sum2 / n - mean * mean, colours: colours.size };
  }, shot.toString('base64'));
  assert.ok(stats.variance > 50 && stats.colours > 20, `screenshot not blank: ${JSON.stringify(stats)}`);
  const room = await page.locator('#room').screenshot({ path: join(outDir, 'room-map.png') });
  assert.ok(room.length > 5000);
});

test('a session created from an uploaded calibration reads back over REST', async () => {
  await page.goto(base + '/#/');
  await page.setInputFiles('#create-file', fixture);
  await page.waitForFunction(() => document.getElementById('create-body').value.includes('"arrays"'));
  await page.click('#create-form button[type=submit]');
  await page.waitForFunction(() => window.avsep.created, null, { timeout: 30_000 });
  const id = await page.evaluate(() => window.avsep.created);
  const token = await page.evaluate((sid) => JSON.parse(sessionStorage.getItem('avsep.tokens'))[sid], id);
  assert.ok(token && token.length === 64, 'the tab keeps the new token');
  await page.locator(`tr[data-session="${id}"]`).waitFor({ timeout: 5000 });

  const sent = JSON.parse(readFileSync(fixture, 'utf8'));
  const info = await rest(`/v1/sessions/${id}`, token);
  assert.equal(info.name, sent.name);
  assert.equal(info.sample_rate, sent.sample_rate);
  assert.deepEqual(info.arrays.map((a) => [a.id, a.channels]), sent.arrays.map((a) => [a.id, a.channels]));
  info.arrays[0].mics.flat().forEach((v, i) => assert.ok(Math.abs(v - sent.arrays[0].mics.flat()[i]) < 1e-9));
  assert.equal(info.cameras[0].id, sent.cameras[0].id);
  assert.equal(info.cameras[0].width, 1280);
  info.cameras[0].projection.flat().forEach((v, i) => {
    // The server may rescale P (a projection is defined up to scale): compare normalised.
    const s = info.cameras[0].projection[2][1] / sent.cameras[0].projection[2][1];
    assert.ok(Math.abs(v - s * sent.cameras[0].projection.flat()[i]) < 1e-6, `P[${i}] ${v}`);
  });
  assert.deepEqual(info.region, sent.region);

  // Its live view opens with the token the tab holds, and draws the uploaded camera.
  await page.goto(`${base}/#/session/${id}`);
  await page.waitForFunction(() => document.getElementById('live-state').textContent.startsWith('streaming'), null, {
    timeout: 10_000,
  });
  assert.equal(await page.locator('#cameras canvas[data-camera="wall"]').count(), 1);
  await page.screenshot({ path: join(outDir, 'dashboard-uploaded.png') });
  assert.deepEqual(pageErrors, [], 'no errors in the page');
});

test('the live view keeps drawing with 10 tracks updated 30 times a second', async () => {
  // Runs on the live view the previous test left open (the uploaded room, no input): feeds
  // synthetic estimates straight into the live state and counts animation frames.
  await page.waitForFunction(() => window.avsep.live && window.avsep.live.info.cameras.length === 1);
  const r = await page.evaluate(async () => {
    const live = window.avsep.live;
    let step = 0;
    const feed = setInterval(() => {
      const t = step * (1 / 30);
      const tracks = Array.from({ length: 10 }, (_, i) => ({
        label: `1.${i}`,
        position: [3 + 2 * Math.cos(t + i), 2.5 + 2 * Math.sin(t + i), 1.6],
        velocity: [0, 0, 0],
        existence: 1,
        speaking: i % 2,
      }));
      live.applyTracks({ type: 'tracks', step: step++, t, tracks });
    }, 1000 / 30);
    const gaps = [];
    let last = performance.now();
    await new Promise((done) => {
      const end = last + 3000;
      const tick = (now) => {
        gaps.push(now - last);
        last = now;
        if (now < end) requestAnimationFrame(tick);
        else done();
      };
      requestAnimationFrame(tick);
    });
    clearInterval(feed);
    gaps.sort((a, b) => a - b);
    return { frames: gaps.length, updates: step, p50: gaps[gaps.length >> 1], p95: gaps[Math.floor(gaps.length * 0.95)] };
  });
  console.log(`10 tracks at 30 updates/s: ${JSON.stringify(r)}`);
  assert.ok(r.updates >= 60, JSON.stringify(r));
  assert.ok(r.frames >= 45 && r.p50 < 40, `at least 15 frames/s: ${JSON.stringify(r)}`);
  assert.deepEqual(pageErrors, []);
});
