// Browser test of the dashboard: Debian's Chromium (headless) driven by playwright-core against a
// real `cpgait serve` on 127.0.0.1. Uploads a trial through the UI, waits for it to finish, and
// checks the 3-D view, the plots, scrubbing and the keyboard. Screenshots go to $ARTIFACTS.
// Exit 77 (ctest: skipped) when Chromium or the dashboard's packages are absent.
import assert from 'node:assert/strict';
import { spawn, execFileSync } from 'node:child_process';
import { createRequire } from 'node:module';
import { existsSync, mkdirSync, mkdtempSync, readFileSync, rmSync, statSync } from 'node:fs';
import { tmpdir } from 'node:os';
import path from 'node:path';

const { CPGAIT_BINARY, CPGAIT_SOURCE_DIR, CPGAIT_SHARED_DIR, ARTIFACTS } = process.env;
const CHROMIUM = process.env.CHROMIUM || '/usr/bin/chromium';
const skip = (why) => { console.log(`SKIPPED: ${why}`); process.exit(77); };
if (!existsSync(CHROMIUM)) skip(`no Chromium at ${CHROMIUM} (install the Debian package 'chromium')`);
const webDir = path.join(CPGAIT_SOURCE_DIR, 'web');
if (!existsSync(path.join(webDir, 'node_modules', 'playwright-core'))) skip('web/node_modules is missing (run ./install-deps.sh)');
if (!existsSync(path.join(webDir, 'dist', 'app.js'))) skip('the dashboard is not built (web/dist)');
const { chromium } = createRequire(path.join(webDir, 'package.json'))('playwright-core');

mkdirSync(ARTIFACTS, { recursive: true });
const work = mkdtempSync(path.join(tmpdir(), 'cpgait-browser-'));
const pipeline = path.join(CPGAIT_SHARED_DIR, 'reference/opensim/gait2392/pipeline');
const haveShared = existsSync(path.join(pipeline, 'subject01_walk1.trc'));
let passed = 0, failed = 0;

// The server.
// gait2392's bone meshes (../shared) for the 3-D view, as a lab's Geometry folder.
const geometry = path.join(CPGAIT_SHARED_DIR, 'reference/opensim/Geometry');
const server = spawn(CPGAIT_BINARY, ['serve', '--port', '0', '--data', path.join(work, 'data'), ...(existsSync(geometry) ? ['--geometry', geometry] : [])],
  { stdio: ['ignore', 'pipe', 'pipe'] });
const port = await new Promise((resolve, reject) => {
  let out = '';
  server.stdout.on('data', (d) => { out += d; const m = out.match(/listening on http:\/\/127\.0\.0\.1:(\d+)/); if (m) resolve(Number(m[1])); });
  server.on('exit', (c) => reject(new Error(`server exited ${c}: ${out}`)));
  setTimeout(() => reject(new Error('server did not start')), 20000);
});
const base = `http://127.0.0.1:${port}`;
const browser = await chromium.launch({
  executablePath: CHROMIUM,
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
const page = await browser.newPage({ viewport: { width: 1400, height: 1000 } });
const consoleErrors = [];
page.on('pageerror', (e) => consoleErrors.push(String(e)));

async function check(name, fn) {
  try { await fn(); passed++; console.log(`ok - ${name}`); } catch (e) { failed++; console.log(`not ok - ${name}\n  ${e.stack || e}`); }
}
// Pixels of the WebGL canvas that differ from the background.
const viewerPixels = () => page.evaluate(() => {
  const src = document.querySelector('#viewer canvas');
  const c = document.createElement('canvas');
  c.width = src.width; c.height = src.height;
  const g = c.getContext('2d');
  g.drawImage(src, 0, 0);
  const d = g.getImageData(0, 0, c.width, c.height).data;
  let n = 0; const sig = [];
  for (let i = 0; i < d.length; i += 4) {
    const lit = Math.abs(d[i] - 15) + Math.abs(d[i + 1] - 23) + Math.abs(d[i + 2] - 42) > 40;
    if (lit) n++;
    if (i % 4096 === 0) sig.push(lit ? 1 : 0);
  }
  return { lit: n, signature: sig.join('') };
});

try {
  // Inputs: subject01 from ../shared with its model, else a synthetic trial on the built-in model.
  let trc, grf, loads, model = null;
  if (haveShared) {
    trc = path.join(pipeline, 'subject01_walk1.trc');
    grf = path.join(pipeline, 'subject01_walk1_grf.mot');
    loads = path.join(pipeline, 'subject01_walk1_grf.xml');
    model = path.join(pipeline, 'OutputReference/subject01_simbody.osim');
  } else {
    console.log(`without ${pipeline}: a synthetic trial on the built-in model instead of subject01; dropped: the model upload, `
      + 'the time range, and the CPG and reproduced-gait panel checks (they need a full gait cycle with GRF)');
    trc = path.join(work, 'walk.trc');
    execFileSync(CPGAIT_BINARY, ['synth', '--model', path.join(CPGAIT_SOURCE_DIR, 'fixtures/models/walker.osim'), '--duration', '2', '-o', trc]);
  }

  await check('upload form shows the API\'s validation message next to the field', async () => {
    await page.goto(`${base}/#/upload`);
    const bad = path.join(work, 'bad.trc');
    execFileSync('sh', ['-c', `printf 'PathFileType\\t4\\nDataRate\\tNumFrames\\tNumMarkers\\tUnits\\n60\\t1\\t1\\tfurlongs\\n' > ${bad}`]);
    await page.setInputFiles('#markers', bad);
    await page.click('#upload button[type=submit]');
    const msg = page.locator('[data-error-for="markers"]');
    await msg.waitFor({ state: 'visible' });
    await page.waitForFunction(() => document.querySelector('[data-error-for="markers"]').textContent.length > 0);
    assert.match(await msg.textContent(), /bad\.trc:\d+: /);
    await page.screenshot({ path: path.join(ARTIFACTS, 'dashboard-upload-error.png') });
  });

  await check('the upload form\'s stages and options follow the API (stages, options schema)', async () => {
    await page.goto(`${base}/#/upload`);
    await page.locator('#stage-options').waitFor({ state: 'attached' });
    const stages = (await (await page.request.get(`${base}/api/v1/stages`)).json()).stages;
    const schema = await (await page.request.get(`${base}/api/v1/options/schema`)).json();
    const boxes = await page.locator('input[name=stage]').evaluateAll((b) => b.map((x) => x.value));
    assert.deepEqual(boxes, stages.filter((s) => s.selectable).map((s) => s.name));
    let fields = 0;
    for (const s of stages) {
      for (const [key, f] of Object.entries(schema.properties[s.name].properties)) {
        if (f.type === 'object') continue;  // IK task weights: not a form field
        const shown = await page.locator(`#opt-${s.name}-${key}`).evaluate((e) => (e.type === 'checkbox' ? e.checked
          : e.tagName === 'SELECT' ? e.value : e.placeholder));
        // A list's default is shown space-separated, "none" when empty.
        const expected = f.type === 'array' ? (f.default.length ? f.default.join(' ') : 'none') : String(f.default ?? '');
        assert.equal(String(shown), expected, `${s.name}.${key}`);
        fields++;
      }
    }
    assert.ok(fields >= 15, `only ${fields} option fields`);
    await page.click('#stage-options summary');
    await page.screenshot({ path: path.join(ARTIFACTS, 'dashboard-upload-options.png'), fullPage: true });
    await page.click('#stage-options summary');
  });

  let scaledId;
let trialId;
  await check('upload a trial and watch it complete', async () => {
    if (model) {
      // subject01's model zipped with gait2392's Geometry folder, as a lab keeps it.
      mkdirSync(path.join(work, 'lab/Geometry'), { recursive: true });
      execFileSync('cp', [model, path.join(work, 'lab')]);
      execFileSync('sh', ['-c', `cp ${geometry}/*.vtp ${path.join(work, 'lab/Geometry')} && cd ${path.join(work, 'lab')} && zip -q -r ../subject01.zip .`]);
      await page.setInputFiles('#osim', path.join(work, 'subject01.zip'));
      await page.click('#model-upload button[type=submit]');
      await page.waitForFunction(() => document.querySelectorAll('#model option').length >= 2);
      const models = (await (await page.request.get(`${base}/api/v1/models`)).json()).models;
      assert.equal(models.find((m) => m.name === path.basename(model)).summary.meshes, 20);  // gait2392's .vtp files, from the zip
      const values = await page.locator('#model option').evaluateAll((o) => o.map((x) => x.value));
      await page.selectOption('#model', values.find((v) => v !== 'walker'));
    }
    await page.setInputFiles('#markers', trc);
    if (grf) { await page.setInputFiles('#grf', grf); await page.setInputFiles('#loads', loads); }
    if (haveShared) { await page.fill('#t0', '0.5'); await page.fill('#t1', '2.5'); }
    await page.click('#stage-options summary');
    await page.fill('#opt-capture-decimate', '2');  // no effect on a TRC trial, but kept in job.json
    // The walk held by pelvis residuals, untuned (the stage's default tunes for minutes): what is checked is the page.
    await page.check('#opt-gait-residuals');
    await page.uncheck('#opt-gait-phase_reference');
    await page.selectOption('#opt-gait-foot_spheres', '2');
    await page.fill('#opt-gait-tune_evaluations', '0');
    await page.fill('#opt-gait-speed_knobs', 'none');  // an empty list, not the default
    await page.click('#upload button[type=submit]');
    await page.waitForURL(/#\/trial\/[0-9a-f]{16}/);
    trialId = page.url().match(/trial\/([0-9a-f]{16})/)[1];
    await page.waitForFunction(() => window.__cpgait.ready === true, null, { timeout: 120000 });
    assert.equal(await page.locator('h1 .status').textContent(), 'done');
  });

  await check('an option changed in the form reaches job.json, the others keep their defaults', async () => {
    const job = await (await page.request.get(`${base}/api/v1/trials/${trialId}/files/job.json`)).json();
    assert.equal(job.capture.decimate, 2);
    assert.equal(job.gait.residuals, true);
    assert.deepEqual(job.gait.speed_knobs, []);
    assert.deepEqual(job.gait.tune_stop_at, [0.45]);  // untouched: the default
    assert.equal(job.so.activation_exponent, 2);
    assert.deepEqual(job.stages, ['ik', 'id', 'so', 'cmc', 'cpg', 'gait']);
    assert.equal(job.activation, 'so');
  });

  await check('trial list shows the trial with its status and metrics', async () => {
    await page.goto(`${base}/#/`);
    const row = page.locator(`tr[data-id="${trialId}"]`);
    await row.waitFor();
    assert.match(await row.textContent(), /done/);
    assert.match(await row.textContent(), /marker RMS [\d.]+ mm/);
    await page.screenshot({ path: path.join(ARTIFACTS, 'dashboard-list.png') });
    await page.goto(`${base}/#/trial/${trialId}`);
    await page.waitForFunction(() => window.__cpgait.ready === true, null, { timeout: 60000 });
  });

  await check('3-D view draws the model (non-blank canvas)', async () => {
    await page.waitForTimeout(300);
    const { lit } = await viewerPixels();
    assert.ok(lit > 500, `only ${lit} lit pixels`);
    await page.screenshot({ path: path.join(ARTIFACTS, 'dashboard-trial.png'), fullPage: true });
  });

  await check('bones: the model\'s meshes in side view, whole body in frame, and far more figure than the stick figure', async () => {
    if (!haveShared) return;  // the walker has no meshes
    const state = await page.evaluate(() => ({ meshes: window.__cpgait.viewer.meshCount, view: window.__cpgait.viewer.view,
      mode: window.__cpgait.viewer.boneMode, bounds: window.__cpgait.viewer.figureScreenBounds() }));
    assert.equal(state.meshes, 19);  // every body's meshes of subject01 (the treadmill is on the ground)
    assert.equal(state.view, 'side');
    assert.equal(state.mode, 'meshes');
    // Head and feet inside the canvas.
    for (const v of [...state.bounds.min, ...state.bounds.max]) assert.ok(Math.abs(v) < 1, `figure leaves the canvas: ${JSON.stringify(state.bounds)}`);
    await page.screenshot({ path: path.join(ARTIFACTS, 'dashboard-bones.png') });
    // Silhouette areas with only the figure drawn: meshes against lines.
    // The figure: bones and muscles; the stick figure: lines and joints, as the dashboard drew it before.
    const figureOnly = (mode) => page.evaluate((m) => {
      const v = window.__cpgait.viewer;
      [v.modelMarkers, v.measuredMarkers, v.coms, ...v.arrows, ...(v.belt ? [v.belt.mesh] : []), ...v.scene.children.filter((o) => o.type === 'GridHelper')]
        .forEach((o) => { o.visible = false; });
      v.muscles.visible = m === 'meshes';
      v.setBoneMode(m);
    }, mode);
    await figureOnly('meshes');
    const meshes = (await viewerPixels()).lit;
    await figureOnly('lines');
    const lines = (await viewerPixels()).lit;
    await page.evaluate(() => {
      const v = window.__cpgait.viewer;
      [v.modelMarkers, v.coms, ...(v.belt ? [v.belt.mesh] : []), ...v.scene.children.filter((o) => o.type === 'GridHelper')].forEach((o) => { o.visible = true; });
      v.muscles.visible = true;
      v.setBoneMode('meshes');
      v.show(window.__cpgait.frame);
    });
    console.log(`# figure pixels in side view: bones and muscles ${meshes}, stick figure ${lines} (${(meshes / lines).toFixed(1)}x)`);
    // Muscles change colour with their activation between two frames.
    const colours = (f) => page.evaluate((frame) => {
      const v = window.__cpgait.viewer;
      v.show(frame);
      return { n: v.muscles.count, c: Array.from(v.muscles.instanceColor.array.slice(0, 3 * v.muscles.count)) };
    }, f);
    const a = await colours(10), b = await colours(60);
    assert.ok(a.n > 92, `${a.n} muscle segments`);
    let changed = 0;
    for (let i = 0; i < Math.min(a.c.length, b.c.length); i += 3) changed += Math.abs(a.c[i] - b.c[i]) > 0.05;
    assert.ok(changed > 20, `only ${changed} muscle segments changed colour between frames 10 and 60`);
    await page.evaluate(() => window.__cpgait.viewer.show(window.__cpgait.frame));
    assert.ok(meshes >= 5 * lines, `meshes ${meshes} vs lines ${lines}`);
  });

  await check('side by side: the reproduced gait as a second, translucent figure on the trial\'s timeline', async () => {
    if (!haveShared) return;  // the walker's trial is too short for the reproduced gait
    const r = await page.evaluate(() => {
      const v = window.__cpgait.viewer;
      let shown = 0;
      v.kin.frames.forEach((_, i) => { shown += v.overlayShownAt(i); });
      const first = v.overlay.frameAt.findIndex((k) => k >= 0);
      v.show(first + 10);
      const drawn = (groups) => groups.filter((g) => g.visible && g.children.length).length;
      return { frames: v.kin.frames.length, shown, first, trial: drawn(v.boneGroups), overlay: drawn(v.overlay.groups),
        withMeshes: v.kin.bodies.filter((b) => b.meshes.length).length,
        opacity: v.overlay.groups.find((g) => g.children.length).children[0].material.opacity };
    });
    assert.ok(r.shown >= 60, `the reproduced gait covers only ${r.shown} of ${r.frames} frames`);
    assert.equal(r.withMeshes, 12);  // gait2392's bodies, ground aside
    assert.equal(r.trial, r.withMeshes);
    assert.equal(r.overlay, r.withMeshes);  // two figures, every body's bones in each
    assert.ok(r.opacity < 1);
    const withOverlay = (await viewerPixels()).lit;
    await page.evaluate(() => window.__cpgait.viewer.setOverlayVisible(false));
    const without = (await viewerPixels()).lit;
    await page.evaluate(() => window.__cpgait.viewer.setOverlayVisible(true));
    assert.ok(withOverlay > without, `overlay adds no pixels (${withOverlay} vs ${without})`);
    await page.screenshot({ path: path.join(ARTIFACTS, 'dashboard-overlay.png') });
    await page.evaluate(() => window.__cpgait.viewer.show(window.__cpgait.frame));
  });

  await check('plots hold the right number of series', async () => {
    const counts = await page.evaluate(() => {
      const p = window.__cpgait.plots;
      return { angles: p.angles.series.length, markerError: p.markerError.series.length, activations: p.activations && p.activations.series.length,
        heatRows: p.heatmap && p.heatmap.rows, moments: p.moments && p.moments.series.length };
    });
    assert.equal(counts.angles, 1 + 3);        // time + three default coordinates
    assert.equal(counts.markerError, 1 + 2);   // time + RMS + max
    assert.equal(counts.activations, 1 + 4);   // time + the four most active muscles
    assert.equal(counts.moments, 1 + 3);
    assert.equal(counts.heatRows, haveShared ? 92 : 6);
    if (haveShared) {
      // subject01 has a full right gait cycle: the CPG panel plots four muscles, SO and CPG each.
      const cpg = await page.evaluate(() => ({ fit: window.__cpgait.plots.cpg && window.__cpgait.plots.cpg.series.length,
        neurons: window.__cpgait.plots.cpgNeurons && window.__cpgait.plots.cpgNeurons.series.length }));
      assert.equal(cpg.fit, 1 + 2 * 4);
      assert.equal(cpg.neurons, 1 + 4);  // two rhythm pairs
      // The reproduced gait: three coordinates, measured and simulated each; six pelvis residuals.
      const gait = await page.evaluate(() => ({ angles: window.__cpgait.plots.gait && window.__cpgait.plots.gait.series.length,
        residuals: window.__cpgait.plots.gaitResiduals && window.__cpgait.plots.gaitResiduals.series.length }));
      assert.equal(gait.angles, 1 + 2 * 3);
      assert.equal(gait.residuals, 1 + 6);
      // The gait-cycle card: one walk (no speed knobs); without a simulated stride it says so, no empty plot.
      assert.equal(await page.locator('#gait-runs tr[data-knob]').count(), 1);
      const cycles = await (await page.request.get(`${base}/api/v1/trials/${trialId}/cycles`)).json();
      const strides = cycles.panels.find((x) => x.name === 'gait').series.length;
      assert.equal(await page.locator('#gait-cycle-quantity').count(), strides ? 1 : 0);
      if (!strides) assert.match(await page.locator('.card:has(#gait-runs)').textContent(), /No simulated stride to plot/);
    }
  });

  await check('gait-cycle plot: every stride and the mean ± SD band, right and left, over 0-100 %', async () => {
    if (!haveShared) return;  // the synthetic walker trial is shorter than a stride
    const r = await page.evaluate(() => {
      const p = window.__cpgait.plots.cycle;
      return { x: p.data[0], labels: p.series.map((s) => s.label), at50: p.data.map((a) => a[50]), groups: p.groups,
        quantity: document.querySelector('#cycle-quantity').value };
    });
    assert.equal(r.quantity, 'knee_angle');
    assert.equal(r.x.length, 101);
    assert.equal(r.x[0], 0);
    assert.equal(r.x[100], 100);
    assert.deepEqual(r.groups.map((g) => g.label), ['right', 'left']);
    // subject01 between 0.5 and 2.5 s: one full stride of each foot between its force-plate strikes.
    assert.deepEqual(r.groups.map((g) => g.strides), [1, 1]);
    assert.equal(r.labels.length, 1 + r.groups.reduce((n, g) => n + g.strides + 3, 0));
    // The bold mean is the average of the strides drawn, at 50 % of the cycle.
    for (const g of r.groups) {
      const strides = r.labels.map((l, i) => [l, i]).filter(([l]) => l.startsWith(`${g.label} stride`)).map(([, i]) => r.at50[i]);
      const mean = r.at50[r.labels.indexOf(`${g.label} mean`)];
      assert.ok(Math.abs(mean - strides.reduce((a, b) => a + b, 0) / strides.length) < 1e-9, `${g.label}: mean ${mean} vs strides ${strides}`);
    }
    await page.locator('#plot-cycle').screenshot({ path: path.join(ARTIFACTS, 'dashboard-gait-cycle.png') });
  });

  await check('the report downloads, opens offline with its plots as images, and is under 2 MB', async () => {
    const [download] = await Promise.all([page.waitForEvent('download'), page.click('#report')]);
    const file = path.join(ARTIFACTS, 'report.html');
    await download.saveAs(file);
    const size = statSync(file).size;
    assert.ok(size < 2 * 1024 * 1024, `${size} bytes`);
    const offline = await browser.newContext({ offline: true });
    const rp = await offline.newPage({ viewport: { width: 1100, height: 900 } });
    const fetched = [];
    rp.on('request', (r) => { if (!/^(data|file):/.test(r.url())) fetched.push(r.url()); });
    await rp.goto(`file://${file}`);
    const images = await rp.evaluate(() => [...document.images].map((i) => i.complete && i.naturalWidth > 0));
    assert.deepEqual(fetched, []);
    assert.ok(images.every(Boolean), 'an image did not load');
    if (haveShared) assert.equal(images.length, 16);
    assert.match(await rp.locator('h1').textContent(), haveShared ? /subject01_walk1/ : /./);
    await rp.screenshot({ path: path.join(ARTIFACTS, 'report.png'), fullPage: true });
    await offline.close();
  });

  await check('scrubbing changes the pose and moves the playhead', async () => {
    const before = await viewerPixels();
    const n = await page.evaluate(() => window.__cpgait.frames);
    await page.locator('#scrub').fill(String(Math.floor(n / 2)));
    await page.waitForTimeout(200);
    const after = await viewerPixels();
    assert.equal(await page.evaluate(() => window.__cpgait.frame), Math.floor(n / 2));
    let diff = 0;
    for (let i = 0; i < before.signature.length; ++i) diff += before.signature[i] !== after.signature[i];
    assert.ok(diff > 5, `pose barely changed (${diff} sampled pixels differ)`);
    await page.screenshot({ path: path.join(ARTIFACTS, 'dashboard-scrubbed.png') });
  });

  await check('keyboard: arrows step frames, space plays and pauses', async () => {
    const f0 = await page.evaluate(() => window.__cpgait.frame);
    await page.locator('body').click({ position: { x: 5, y: 5 } });
    await page.keyboard.press('ArrowRight');
    assert.equal(await page.evaluate(() => window.__cpgait.frame), f0 + 1);
    await page.keyboard.press('ArrowLeft');
    assert.equal(await page.evaluate(() => window.__cpgait.frame), f0);
    await page.keyboard.press('Space');
    await page.waitForTimeout(500);
    assert.notEqual(await page.evaluate(() => window.__cpgait.frame), f0, 'playback did not advance');
    await page.keyboard.press('Space');
    assert.equal(await page.locator('#play').textContent(), 'Play');
  });

  await check('every result file is downloadable', async () => {
    const links = await page.locator('.files a').evaluateAll((a) => a.map((x) => x.getAttribute('href')));
    assert.ok(links.length >= 6, `only ${links.length} files listed`);
    for (const href of links) {
      const r = await page.request.get(base + href);
      assert.equal(r.status(), 200, href);
    }
  });

  if (haveShared) {
    await check('treadmill: subject01\'s belt is drawn under the feet and moves at the stance feet\'s speed', async () => {
      await page.goto(`${base}/#/trial/${trialId}`);
      await page.waitForFunction(() => window.__cpgait.ready === true, null, { timeout: 60000 });
      const kin = await (await page.request.get(`${base}/api/v1/trials/${trialId}/kinematics`)).json();
      assert.ok(kin.treadmill, 'subject01 (a treadmill trial) has no belt');
      const r = await page.evaluate(() => {
        const v = window.__cpgait.viewer;
        const at = (f) => { v.show(f); return { t: v.kin.frames[f].time, offset: v.belt.texture.offset.x }; };
        const a = at(10), b = at(60);
        // The feet: the lowest body origin over the trial.
        const lowest = Math.min(...v.kin.frames.map((f) => Math.min(...f.bodies.map((p) => p[1]))));
        return { a, b, speed: v.belt.speed, period: v.belt.period, visible: v.belt.mesh.visible, y: v.belt.mesh.position.y, lowest,
          legend: document.querySelector('#belt-legend').textContent };
      });
      assert.ok(Math.abs(r.speed - Math.hypot(...kin.treadmill.belt_velocity_m_s)) < 1e-9);
      assert.ok(r.speed > 0.8 && r.speed < 1.6, `belt ${r.speed} m/s`);
      // The stripes moved backwards by the belt's travel between the two frames (modulo one stripe).
      const moved = -(r.speed * (r.b.t - r.a.t)) / r.period;
      const wrapped = (x) => x - Math.floor(x);
      assert.ok(Math.abs(wrapped(r.b.offset - r.a.offset) - wrapped(moved)) < 1e-6, JSON.stringify(r));
      assert.ok(r.visible);
      assert.ok(Math.abs(r.y - r.lowest) < 0.06, `belt at ${r.y} m, feet down to ${r.lowest} m`);
      assert.match(r.legend, /treadmill belt, 1\.\d\d m\/s/);
      await page.evaluate(() => window.__cpgait.setFrame(40));
      await page.locator('#viewer').screenshot({ path: path.join(ARTIFACTS, 'dashboard-treadmill.png') });
    });

    await check('a 15 s trial with 92 muscles loads and plays in time (frame time reported)', async () => {
      const modelId = (await (await page.request.get(`${base}/api/v1/trials/${trialId}`)).json()).options.model;
      const long = path.join(work, 'walk15.trc');
      execFileSync(CPGAIT_BINARY, ['synth', '--model', model, '--duration', '15', '-o', long]);
      const up = await page.request.post(`${base}/api/v1/trials`, { multipart: {
        markers: { name: 'walk15.trc', mimeType: 'text/plain', buffer: readFileSync(long) },
        options: JSON.stringify({ model: modelId, stages: ['ik'] }) } });
      assert.equal(up.status(), 202, await up.text());
      const id = (await up.json()).id;
      for (let i = 0; i < 600; i++) {
        const st = (await (await page.request.get(`${base}/api/v1/trials/${id}`)).json()).status;
        if (st === 'done') break;
        assert.ok(st !== 'failed' && st !== 'cancelled', st);
        await page.waitForTimeout(100);
      }
      const t0 = Date.now();
      await page.goto(`${base}/#/trial/${id}`);
      await page.waitForFunction(() => window.__cpgait.ready === true && window.__cpgait.frames > 0, null, { timeout: 120000 });
      const loadMs = Date.now() - t0;
      const r = await page.evaluate(async () => {
        const v = window.__cpgait.viewer;
        const show = v.show.bind(v), work = [];
        v.show = (i) => { const a = performance.now(); show(i); work.push(performance.now() - a); };
        const clock = () => Number(document.querySelector('#clock').textContent.match(/t = ([\d.]+)/)[1]);
        const before = clock(), wall0 = performance.now();
        document.querySelector('#play').click();
        const intervals = [];
        let last = null;
        await new Promise((done) => {
          const tick = (now) => { if (last != null) intervals.push(now - last); last = now; if (now - wall0 < 3000) requestAnimationFrame(tick); else done(); };
          requestAnimationFrame(tick);
        });
        document.querySelector('#play').click();
        const wall = (performance.now() - wall0) / 1000, advanced = clock() - before;
        v.show = show;
        const q = (a, p) => { const x = [...a].sort((m, n) => m - n); return x[Math.floor(p * (x.length - 1))]; };
        return { frames: v.kin.frames.length, muscles: v.kin.muscle_names.length, segments: v.muscles.count, wall, advanced,
          intervalMedian: q(intervals, 0.5), intervalP95: q(intervals, 0.95), workMedian: q(work, 0.5), workP95: q(work, 0.95),
          software: v.software, triangles: v.renderer.info.render.triangles, calls: v.renderer.info.render.calls };
      });
      console.log(`# 15 s trial (${r.frames} frames, ${r.muscles} muscles, ${r.segments} muscle segments, ${r.triangles} triangles in ${r.calls} draw calls): `
        + `page ready in ${loadMs} ms; playing, frame interval median ${r.intervalMedian.toFixed(1)} ms (p95 ${r.intervalP95.toFixed(1)}), `
        + `the frame's own work (pose, muscles, markers, draw call) median ${r.workMedian.toFixed(2)} ms (p95 ${r.workP95.toFixed(2)})`
        + `${r.software ? '; WebGL is a software rasteriser here (no GPU), antialiasing off' : ''}`);
      assert.equal(r.frames, 1501);
      assert.equal(r.muscles, 92);
      assert.ok(r.segments > 92);
      // Playback keeps the trial's time whatever the frame rate: 3 s of wall clock play about 3 s.
      assert.ok(Math.abs(r.advanced - r.wall) < 0.5, `played ${r.advanced} s of the trial in ${r.wall} s`);
      // The page shows the rate it reached (for a look on the user's own machine): the same as measured here.
      const shown = await page.evaluate(() => ({ text: document.querySelector('#frame-rate').textContent, rate: window.__cpgait.frameRate }));
      assert.match(shown.text, /^\d+ frames\/s, [\d.]+ ms of page work each$/);
      const measured = 1000 / r.intervalMedian;
      assert.ok(shown.rate.fps > measured / 2 && shown.rate.fps < measured * 2, `shown ${shown.rate.fps} frames/s, measured ${measured}`);
    });
  }

  if (haveShared) {
    await check('a generic model with a static trial and a scale setup: the Scaling card shows the factors and marker errors', async () => {
      const generic = path.join(CPGAIT_SHARED_DIR, 'reference/opensim/gait2392/model/gait2392_simbody.osim');
      await page.goto(`${base}/#/upload`);
      await page.waitForSelector('#osim');
      const before = await page.locator('#model option').count();
      await page.setInputFiles('#osim', generic);
      await page.setInputFiles('#markerset', path.join(pipeline, 'gait2392_Scale_MarkerSet.xml'));
      await page.click('#model-upload button[type=submit]');
      await page.waitForFunction((n) => document.querySelectorAll('#model option').length > n, before);
      const values = await page.locator('#model option').evaluateAll((o) => o.map((x) => x.value));
      await page.selectOption('#model', values[values.length - 1]);
      await page.setInputFiles('#markers', path.join(pipeline, 'subject01_walk1.trc'));
      await page.setInputFiles('#static', path.join(pipeline, 'subject01_static.trc'));
      await page.setInputFiles('#scale_setup', path.join(pipeline, 'subject01_Setup_Scale.xml'));
      for (const s of ['id', 'so', 'cmc', 'cpg', 'gait']) await page.uncheck(`input[name=stage][value=${s}]`);
      await page.click('#upload button[type=submit]');
      await page.waitForURL(/#\/trial\/[0-9a-f]{16}/);
      await page.waitForFunction(() => window.__cpgait.ready === true, null, { timeout: 120000 });
      scaledId = page.url().match(/trial\/([0-9a-f]{16})/)[1];
      assert.equal(await page.locator('#scale-factors tr').count(), 1 + 12);  // header, then gait2392's 12 bodies
      assert.match(await page.locator('#scale-factors').textContent(), /pelvis1\.0246/);
      assert.ok(await page.locator('#static-marker-errors .row').count() >= 30);
      await page.locator('#scale-factors').scrollIntoViewIfNeeded();
      await page.screenshot({ path: path.join(ARTIFACTS, 'dashboard-scaling.png'), fullPage: true });
    });
  }

  if (haveShared) {
    await check('the autonomous gait: its strides against the trial\'s over the gait cycle, the speed knobs side by side, falls and strides', async () => {
      const models = (await (await page.request.get(`${base}/api/v1/models`)).json()).models;
      await page.goto(`${base}/#/upload`);
      await page.waitForSelector('#osim');
      await page.selectOption('#model', models.find((m) => m.name === path.basename(model)).id);
      // Its muscles scaled from the generic model (uploaded by the scaling check), as `cpgait run --scale-muscles-from`.
      await page.selectOption('#scale_muscles_from', models.find((m) => m.name === 'gait2392_simbody.osim').id);
      await page.setInputFiles('#markers', trc);
      await page.setInputFiles('#grf', grf);
      await page.setInputFiles('#loads', loads);
      await page.fill('#t0', '0.5');
      await page.fill('#t1', '2.5');
      await page.click('#stage-options summary');
      // Without residuals (the default), a few tuning simulations in one round, no schedule (short
      // walks: what is checked is the page).
      await page.fill('#opt-gait-tune_evaluations', '8');
      await page.fill('#opt-gait-tune_horizon_s', '3');
      await page.fill('#opt-gait-tune_rounds', '1');
      await page.fill('#opt-gait-tune_restarts', '0');
      await page.fill('#opt-gait-tune_rotation_limit_deg', '0');
      await page.fill('#opt-gait-tune_stop_at', 'none');
      await page.fill('#opt-gait-schedule_evaluations', '0');
      await page.fill('#opt-gait-duration_s', '4');
      await page.fill('#opt-gait-speed_knobs', '0.8 1.2');
      await page.selectOption('#opt-gait-foot_spheres', '5');  // an integer choice: sent as a number
      await page.click('#upload button[type=submit]');
      await page.waitForURL(/#\/trial\/[0-9a-f]{16}/);
      const id = page.url().match(/trial\/([0-9a-f]{16})/)[1];
      await page.waitForFunction(() => window.__cpgait.ready === true, null, { timeout: 120000 });
      const job = await (await page.request.get(`${base}/api/v1/trials/${id}/files/job.json`)).json();
      assert.deepEqual(job.gait.speed_knobs, [0.8, 1.2]);
      assert.strictEqual(job.gait.foot_spheres, 5);
      assert.equal(job.gait.residuals, false);
      // The table: one row per walk, each with the stage's own figures.
      const trial = await (await page.request.get(`${base}/api/v1/trials/${id}`)).json();
      const summary = trial.stages.find((s) => s.name === 'gait').summary;
      assert.equal(Object.keys(summary.foot_fit.radius_change_mm).length, 10);
      const runs = [summary, ...summary.speed_knobs];
      const rows = await page.locator('#gait-runs tr[data-knob]').evaluateAll((r) => r.map((x) => ({ knob: x.dataset.knob, cells: [...x.cells].map((c) => c.textContent) })));
      assert.deepEqual(rows.map((r) => r.knob), ['1', '0.8', '1.2']);
      rows.forEach((r, i) => {
        const run = runs[i];
        assert.equal(r.cells[1], run.fell_at_s == null ? `${run.simulated_s.toFixed(1)} s, did not fall` : `fell at ${run.fell_at_s.toFixed(2)} s`);
        const strides = (side) => Math.max(0, run.heel_strikes_s[side].length - 1);
        assert.equal(r.cells[2], `${strides('right')} / ${strides('left')}`);
        assert.equal(r.cells[3], run.stride_time_s.toFixed(3));
        assert.equal(r.cells[6], run.speed_m_s.toFixed(2));
        const ph = run.contact_phases;
        assert.equal(r.cells[7], strides('right') > 0
          ? `${ph.stance_percent.right.toFixed(0)} / ${ph.stance_percent.left.toFixed(0)}, ${ph.double_support_percent.toFixed(0)}, ${ph.flight_percent.toFixed(0)}` : '');
      });
      // The stage's check at other integrator tolerances (its default ones), each row its figures.
      const checks = await page.locator('#gait-tolerance-check tr[data-tolerance]').evaluateAll((r) => r.map((x) => ({ tol: Number(x.dataset.tolerance), walked: x.cells[1].textContent })));
      assert.deepEqual(checks.map((c) => c.tol), [5e-4, 2e-3]);
      checks.forEach((c, i) => {
        const run = summary.tolerance_check[i];
        assert.equal(c.walked, run.fell_at_s == null ? `${run.simulated_s.toFixed(1)} s, did not fall` : `fell at ${run.fell_at_s.toFixed(2)} s`);
      });
      // The plot: the trial's strides and mean, the simulation's strides and mean, the mean of each
      // knob that made a right stride (knee_angle_r's strides run between right heel strikes; a knob
      // of this short search may fall first); every mean at 50 % the average of its strides there,
      // the trial's the cycles endpoint's.
      await page.selectOption('#gait-cycle-quantity', 'knee_angle_r');
      const p = await page.evaluate(() => { const g = window.__cpgait.plots.gaitCycle; return { groups: g.groups, x: g.data[0] }; });
      const striding = summary.speed_knobs.filter((k) => k.heel_strikes_s.right.length > 1).map((k) => `simulated ${k.speed_knob}×`);
      assert.ok(striding.length >= 1, 'no knob made a right stride');
      assert.deepEqual(p.groups.map((g) => g.label), ['trial', 'simulated 1×', ...striding]);
      assert.equal(p.x[0], 0);
      assert.equal(p.x[100], 100);
      assert.ok(p.groups[1].strides >= 1, 'no simulated stride');
      for (const g of p.groups) {
        if (!g.strides) continue;
        const avg = g.strides50.reduce((a, b) => a + b, 0) / g.strides;
        assert.ok(Math.abs(g.mean50 - avg) < 1e-9, `${g.label}: mean ${g.mean50} at 50 %, strides' average ${avg}`);
      }
      const cycles = await (await page.request.get(`${base}/api/v1/trials/${id}/cycles`)).json();
      const knee = cycles.panels.find((x) => x.name === 'kinematics').series.find((x) => x.name === 'knee_angle_r');
      assert.ok(Math.abs(p.groups[0].mean50 - knee.mean[50]) < 1e-9);
      for (const run of summary.speed_knobs) {
        const knee_r = cycles.panels.find((x) => x.name === `gait_speed_${run.speed_knob}`).series.find((x) => x.name === 'knee_angle_r');
        const right = run.heel_strikes_s.right.length - 1;
        if (right > 0) assert.equal(knee_r.strides.length, right, `knob ${run.speed_knob}`);
        else assert.equal(knee_r, undefined, `knob ${run.speed_knob}: no right stride, no series`);
      }
      await page.locator('.card:has(#gait-runs)').screenshot({ path: path.join(ARTIFACTS, 'dashboard-autonomous-gait.png') });
    });
  }

  if (haveShared) {
    await check('comparing two trials: both trials\' gait cycles on one plot, picked in the list', async () => {
      await page.goto(`${base}/#/`);
      await page.locator(`input.compare-pick[data-id="${trialId}"]`).check();
      await page.locator(`input.compare-pick[data-id="${scaledId}"]`).check();
      await page.click('#compare');
      await page.waitForURL(/#\/compare\//);
      await page.waitForFunction(() => window.__cpgait.ready === true && window.__cpgait.plots.compare, null, { timeout: 60000 });
      const r = await page.evaluate(() => { const p = window.__cpgait.plots.compare; return { groups: p.groups, labels: p.series.map((s) => s.label), x: p.data[0], at50: p.data.map((d) => d[50]) }; });
      assert.deepEqual(r.groups.map((g) => g.label).sort(), ['A left', 'A right', 'B left', 'B right']);
      assert.equal(r.x[0], 0);
      assert.equal(r.x[100], 100);
      // A's right mean is trial A's own knee_angle_r mean from its cycles.
      const a = await (await page.request.get(`${base}/api/v1/trials/${trialId}/cycles`)).json();
      const knee = a.panels.find((p) => p.name === 'kinematics').series.find((s) => s.name === 'knee_angle_r');
      assert.ok(Math.abs(r.at50[r.labels.indexOf('A right mean')] - knee.mean[50]) < 1e-9);
      await page.screenshot({ path: path.join(ARTIFACTS, 'dashboard-compare.png'), fullPage: true });
    });
  }

  await check('no script errors', async () => assert.deepEqual(consoleErrors, []));
} finally {
  await browser.close();
  server.kill('SIGTERM');
  rmSync(work, { recursive: true, force: true });
}
console.log(`screenshots in ${ARTIFACTS}`);
console.log(`${passed} passed, ${failed} failed`);
process.exit(failed ? 1 : 0);
