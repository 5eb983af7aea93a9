// cpgait dashboard: trial list with live progress, upload form, trial review.
import './style.css';
import { Viewer } from './viewer.js';
import { linePlot, heatMap, cyclePlot, parseNormativeCsv, COLORS } from './plots.js';

const app = document.getElementById('app');
const state = { cleanups: [] };
// Test and debugging hooks: the browser tests read these.
window.__cpgait = { frame: 0, frames: 0, plots: {}, ready: false };

// ---------------------------------------------------------------- API
function token() { return localStorage.getItem('cpgait.token') || ''; }
async function api(path, opts = {}) {
  const headers = Object.assign({}, opts.headers || {});
  if (token()) headers.Authorization = 'Bearer ' + token();
  const res = await fetch('/api/v1' + path, Object.assign({}, opts, { headers }));
  const text = await res.text();
  let body = null;
  try { body = text ? JSON.parse(text) : null; } catch { body = { error: { message: text } }; }
  if (!res.ok) {
    if (res.status === 401) askToken();
    const err = new Error((body && body.error && body.error.message) || res.statusText);
    err.status = res.status;
    err.detail = (body && body.error) || {};
    throw err;
  }
  return body;
}
function askToken() {
  const t = prompt('This server needs an access token:');
  if (t) { localStorage.setItem('cpgait.token', t); route(); }
}

// ---------------------------------------------------------------- helpers
const h = (tag, attrs = {}, ...children) => {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) {
    if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
    else if (v !== undefined && v !== null && v !== false) e.setAttribute(k, v === true ? '' : v);
  }
  for (const c of children.flat()) if (c !== null && c !== undefined) e.append(c.nodeType ? c : document.createTextNode(String(c)));
  return e;
};
const fmt = (v, d = 1) => (v == null || Number.isNaN(v) ? '–' : Number(v).toFixed(d));
function cleanup() { state.cleanups.forEach((f) => f()); state.cleanups = []; }

// ---------------------------------------------------------------- router
window.addEventListener('hashchange', route);
function route() {
  cleanup();
  window.__cpgait.ready = false;
  const hash = location.hash || '#/';
  const m = hash.match(/^#\/trial\/([0-9a-f]{16})/);
  if (m) return trialView(m[1]);
  const c = hash.match(/^#\/compare\/([0-9a-f]{16})\/([0-9a-f]{16})/);
  if (c) return compareView(c[1], c[2]);
  if (hash.startsWith('#/upload')) return uploadView();
  return listView();
}

// ---------------------------------------------------------------- trial list
function stageCell(s) {
  const pct = Math.round(100 * (s.state === 'done' ? 1 : s.progress || 0));
  return h('span', { title: `${s.name}: ${s.state}` }, h('span', { class: `bar ${s.state}` }, h('span', { style: `width:${pct}%` })), s.name, ' ');
}
function metrics(t) {
  const ik = (t.stages.find((s) => s.name === 'ik') || {}).summary || {};
  const so = (t.stages.find((s) => s.name === 'so') || {}).summary || {};
  const parts = [];
  if (ik.frames) parts.push(`${ik.frames} frames`, `marker RMS ${fmt(1000 * ik.marker_rms_mean_m, 1)} mm`);
  if (so.frames) parts.push(`SO max violation ${Number(so.max_equality_violation).toExponential(1)} N·m`);
  return parts.join(' · ');
}
async function listView() {
  app.replaceChildren(h('h1', {}, 'Trials'), h('p', { class: 'muted' }, 'Loading…'));
  // Two finished trials picked here open side by side in the gait-cycle comparison.
  const picked = new Set();
  const compareBtn = h('button', { id: 'compare', type: 'button', disabled: true }, 'Compare gait cycles');
  compareBtn.addEventListener('click', () => { location.hash = `#/compare/${[...picked].join('/')}`; });
  const render = async () => {
    let data;
    try { data = await api('/trials?limit=100'); } catch (e) { app.replaceChildren(h('h1', {}, 'Trials'), h('p', { class: 'form-error' }, e.message)); return []; }
    const pick = (t) => {
      const box = h('input', { type: 'checkbox', class: 'compare-pick', 'data-id': t.id, checked: picked.has(t.id), disabled: t.status !== 'done',
        title: 'select two finished trials to compare their gait cycles' });
      box.addEventListener('change', () => { if (box.checked) picked.add(t.id); else picked.delete(t.id); compareBtn.disabled = picked.size !== 2; });
      return box;
    };
    const rows = data.trials.map((t) => h('tr', { 'data-id': t.id },
      h('td', {}, pick(t), ' ', h('a', { href: `#/trial/${t.id}` }, t.name)),
      h('td', {}, h('span', { class: `status ${t.status}` }, t.status)),
      h('td', {}, t.stages.map(stageCell)),
      h('td', { class: 'muted' }, metrics(t)),
      h('td', { class: 'muted' }, new Date(t.created_at).toLocaleString())));
    compareBtn.disabled = picked.size !== 2;
    app.replaceChildren(
      h('h1', {}, 'Trials ', h('a', { href: '#/upload' }, h('button', {}, 'Upload a trial')), ' ', compareBtn),
      h('div', { class: 'card' }, data.trials.length
        ? h('table', { id: 'trials' }, h('tr', {}, ['Trial', 'Status', 'Stages', 'Key metrics', 'Created'].map((x) => h('th', {}, x))), rows)
        : h('p', { class: 'muted' }, 'No trials yet. Upload one to start.')));
    return data.trials;
  };
  const trials = await render();
  // Live progress: Server-Sent Events for unfinished trials (polling when a token is needed,
  // since EventSource cannot send one).
  const open = trials.filter((t) => t.status === 'queued' || t.status === 'running');
  if (!token()) {
    for (const t of open) {
      const es = new EventSource(`/api/v1/trials/${t.id}/events`);
      es.addEventListener('progress', () => scheduleRender());
      es.addEventListener('end', () => { es.close(); scheduleRender(); });
      state.cleanups.push(() => es.close());
    }
  }
  let pending = null;
  function scheduleRender() { if (!pending) pending = setTimeout(async () => { pending = null; await render(); }, 150); }
  const timer = setInterval(() => { if (token() || open.length === 0) render(); }, 3000);
  state.cleanups.push(() => clearInterval(timer), () => pending && clearTimeout(pending));
}

// ---------------------------------------------------------------- comparison
// Two trials' gait cycles on one plot: each trial's strides thin and its mean ± SD, right and left.
async function compareView(a, b) {
  app.replaceChildren(h('p', { class: 'muted' }, 'Loading…'));
  let trials, cycles;
  try {
    trials = await Promise.all([api(`/trials/${a}`), api(`/trials/${b}`)]);
    cycles = await Promise.all([api(`/trials/${a}/cycles`), api(`/trials/${b}/cycles`)]);
  } catch (e) { app.replaceChildren(h('p', { class: 'form-error' }, e.message)); return; }
  const tag = ['A', 'B'];
  const colours = [{ r: '#2563eb', l: '#60a5fa' }, { r: '#ea580c', l: '#f59e0b' }];
  const base = (name) => name.replace(/_(r|l)(_moment|_force)?$/, '$2');
  const panelNames = cycles[0].panels.filter((p) => cycles[1].panels.some((q) => q.name === p.name && q.series.length) && p.series.length).map((p) => p.name);
  const panelSel = h('select', { id: 'compare-panel' }, panelNames.map((n) => h('option', { value: n }, n)));
  const quantitySel = h('select', { id: 'compare-quantity' });
  const box = h('div', { id: 'plot-compare' });
  app.replaceChildren(h('h1', {}, 'Gait cycles compared'),
    h('div', { class: 'card' }, trials.map((t, i) => h('div', {}, h('b', {}, `${tag[i]}: `), h('a', { href: `#/trial/${t.id}` }, t.name), ` (${t.id}, ${new Date(t.created_at).toLocaleString()})`)),
      h('div', { class: 'controls' }, panelSel, quantitySel), box));
  const fill = () => {
    const names = new Set(cycles[0].panels.find((p) => p.name === panelSel.value).series.map((s) => base(s.name)));
    const both = [...new Set(cycles[1].panels.find((p) => p.name === panelSel.value).series.map((s) => base(s.name)))].filter((n) => names.has(n));
    const preferred = ['knee_angle', 'knee_angle_moment', 'soleus'].find((n) => both.includes(n)) || both[0];
    quantitySel.replaceChildren(...both.map((n) => h('option', { value: n, selected: n === preferred }, n)));
  };
  const draw = () => {
    const groups = [];
    cycles.forEach((cy, i) => {
      for (const s of cy.panels.find((p) => p.name === panelSel.value).series.filter((x) => base(x.name) === quantitySel.value))
        groups.push({ label: `${tag[i]} ${/_l(_moment|_force)?$/.test(s.name) ? 'left' : /_r(_moment|_force)?$/.test(s.name) ? 'right' : s.name}`,
          color: colours[i][s.side], strides: s.strides, mean: s.mean, sd: s.sd, unit: s.unit });
    });
    box.replaceChildren();
    const unit = groups[0] && groups[0].unit;
    window.__cpgait.plots.compare = cyclePlot(box, cycles[0].percent, groups, `${quantitySel.value}${unit ? ` (${unit})` : ''}`, null);
    window.__cpgait.plots.compare.groups = groups.map((g) => ({ label: g.label, strides: g.strides.length }));
  };
  panelSel.addEventListener('change', () => { fill(); draw(); });
  quantitySel.addEventListener('change', draw);
  if (panelNames.length) { fill(); draw(); }
  window.__cpgait.ready = true;
}

// ---------------------------------------------------------------- upload
// One input per option of the published schema (GET /api/v1/options/schema), showing its default.
function optionInput(stage, key, field) {
  const id = `opt-${stage}-${key}`;
  const common = { id, 'data-stage': stage, 'data-key': key, 'data-type': field.type, title: field.description };
  if (field.enum) return h('select', common, field.enum.map((v) => h('option', { value: v, selected: v === field.default }, v)));
  if (field.type === 'boolean') return h('input', Object.assign({ type: 'checkbox', checked: field.default === true }, common));
  if (field.type === 'number' || field.type === 'integer') {
    return h('input', Object.assign({ type: 'number', step: field.type === 'integer' ? 1 : 'any', placeholder: field.default ?? '',
      min: field.minimum, max: field.maximum }, common));
  }
  if (field.type === 'string') return h('input', Object.assign({ type: 'text', placeholder: field.default ?? '' }, common));
  if (field.type === 'array' && field.items && field.items.type === 'number') {
    // Empty keeps the default; "none" sends an empty list (a default that is not empty can be turned off).
    return h('input', Object.assign({ type: 'text', placeholder: (field.default || []).join(' ') || 'none' }, common,
      { title: `${field.description} (empty: the default; "none": an empty list)` }));
  }
  return null;  // objects (IK task weights) come from files, not the form
}
// The muscle-activity estimate the CPG is fitted to (the options' "activation"), when the server offers a choice.
function activationRow(schema, row) {
  const field = schema && schema.properties && schema.properties.activation;
  if (!field || !field.enum) return null;
  return row('Activation', h('select', { id: 'activation', title: field.description, 'data-default': field.default },
    field.enum.map((v) => h('option', { value: v, selected: v === field.default }, v === 'so' ? 'static optimization (so)' : v === 'cmc' ? 'computed muscle control (cmc)' : v))), 'activation');
}

function optionsSection(schema, stages, row) {
  if (!schema) return h('p', { class: 'muted' }, 'The options schema could not be loaded: every stage runs with its defaults.');
  // In run order when the stage list is known.
  const order = stages.length ? stages.map((s) => s.name) : Object.keys(schema.properties);
  const stageNames = order.filter((k) => schema.properties[k] && schema.properties[k].properties);
  return h('details', { id: 'stage-options' }, h('summary', {}, 'Stage options'),
    stageNames.map((stage) => {
      const fields = Object.entries(schema.properties[stage].properties)
        .map(([key, f]) => [key, f, optionInput(stage, key, f)]).filter(([, , input]) => input);
      return h('fieldset', { 'data-stage': stage }, h('legend', { title: schema.properties[stage].description }, stage),
        fields.map(([key, f, input]) => {
          const r = row(`${key}${f['x-unit'] ? ` (${f['x-unit']})` : ''}`, input, `${stage}.${key}`);
          r.querySelector('label').htmlFor = input.id;
          return r;
        }));
    }));
}
// The options a person changed from their defaults, as {stage: {key: value}}.
function changedOptions(form) {
  const out = {};
  for (const input of form.querySelectorAll('[data-stage][data-key]')) {
    const { stage, key, type } = input.dataset;
    const asType = (v) => (v !== undefined && type === 'integer' ? Number(v) : v);  // a select's values are text
    let value;
    if (type === 'boolean') value = input.checked;
    else if (input.tagName === 'SELECT') value = asType(input.value);
    else if (input.value === '') continue;
    else if (type === 'array') value = input.value.trim() === 'none' ? [] : input.value.split(/[\s,]+/).filter((x) => x).map(Number);
    else value = type === 'number' || type === 'integer' ? Number(input.value) : input.value;
    const dflt = input.tagName === 'SELECT' ? asType(input.querySelector('option[selected]')?.value) : type === 'boolean' ? input.defaultChecked : undefined;
    if (dflt !== undefined && value === dflt) continue;
    (out[stage] ??= {})[key] = value;
  }
  return out;
}

async function uploadView() {
  let models = [], stages = [], schema = null;
  try { models = (await api('/models')).models; } catch (e) { /* shown below */ }
  try { stages = (await api('/stages')).stages; } catch (e) { /* no stage choice: every stage runs */ }
  try { schema = await api('/options/schema'); } catch (e) { /* said in the form */ }
  const fieldError = (name) => h('div', { class: 'field-error', 'data-error-for': name });
  const row = (label, input, name) => h('div', { class: 'row' }, h('label', { for: name }, label), input, fieldError(name));
  const form = h('form', { id: 'upload' },
    row('Markers (.trc, .c3d)', h('input', { type: 'file', id: 'markers', name: 'markers', accept: '.trc,.c3d' }), 'markers'),
    h('p', { class: 'muted' }, 'or AprilTag footage: one video per camera, named after its camera in the calibration'),
    row('Videos', h('input', { type: 'file', id: 'videos', name: 'videos', accept: 'video/*,.avi,.mp4,.mkv', multiple: true }), 'videos'),
    row('Calibration (.json, .yml)', h('input', { type: 'file', id: 'calibration', name: 'calibration', accept: '.json,.yml,.yaml,.xml' }), 'calibration'),
    row('Tag set (.json)', h('input', { type: 'file', id: 'tags', name: 'tags', accept: '.json' }), 'tags'),
    row('GRF (.mot)', h('input', { type: 'file', id: 'grf', name: 'grf', accept: '.mot,.sto' }), 'grf'),
    row('Loads (.xml)', h('input', { type: 'file', id: 'loads', name: 'loads', accept: '.xml' }), 'loads'),
    row('Static trial (.trc, .c3d)', h('input', { type: 'file', id: 'static', name: 'static', accept: '.trc,.c3d', title: 'the subject standing: the model (the generic one) is scaled to it first' }), 'static'),
    row('Scale setup (.xml)', h('input', { type: 'file', id: 'scale_setup', name: 'scale_setup', accept: '.xml', title: "OpenSim's ScaleTool setup; without one, with a static trial, scaling is automatic" }), 'scale_setup'),
    row('Model', h('select', { id: 'model', name: 'model' }, models.map((m) => h('option', { value: m.id }, `${m.name} (${m.summary.coordinates} coordinates, ${m.summary.muscles} muscles)`))), 'model'),
    row('Muscle lengths scaled from', h('select', { id: 'scale_muscles_from', name: 'scale_muscles_from' },
      h('option', { value: '' }, 'as in the model'),
      models.map((m) => h('option', { value: m.id }, `${m.name} (the generic model it was scaled from)`))), 'scale_muscles_from'),
    row('Time range (s)', h('span', {}, h('input', { type: 'number', step: 'any', id: 't0', placeholder: 'start' }), ' – ', h('input', { type: 'number', step: 'any', id: 't1', placeholder: 'end' })), 'time_range'),
    row('Stages', h('span', {}, stages.filter((s) => s.selectable).map((s) => h('label', { title: s.description }, h('input', { type: 'checkbox', name: 'stage', value: s.name, checked: true }), ` ${s.name.toUpperCase()} `))), 'stages'),
    activationRow(schema, row),
    optionsSection(schema, stages, row),
    h('div', { class: 'form-error', id: 'form-error' }),
    h('button', { type: 'submit' }, 'Upload and run'));
  const modelUpload = h('form', { id: 'model-upload' },
    row('Model (.osim, or a .zip of it and its Geometry folder)', h('input', { type: 'file', id: 'osim', accept: '.osim,.zip', required: true }), 'model-file'),
    row('Marker set (.xml)', h('input', { type: 'file', id: 'markerset', accept: '.xml' }), 'markerset'),
    row('Bone meshes (.vtp, .stl, .obj)', h('input', { type: 'file', id: 'geometry', accept: '.vtp,.stl,.obj', multiple: true }), 'geometry'),
    h('button', { type: 'submit', class: 'secondary' }, 'Add model'));
  app.replaceChildren(h('h1', {}, 'Upload a trial'), h('div', { class: 'card' }, form), h('h2', {}, 'Add a model'), h('div', { class: 'card' }, modelUpload));

  const clearErrors = (f) => f.querySelectorAll('[data-error-for], .form-error').forEach((e) => (e.textContent = ''));
  const showError = (f, err, partToField) => {
    const d = err.detail || {};
    const where = partToField(d);
    const target = where && f.querySelector(`[data-error-for="${where}"]`);
    const text = d.line ? `${err.message}` : err.message;
    (target || f.querySelector('.form-error') || f).textContent = text;
  };
  form.addEventListener('submit', async (ev) => {
    ev.preventDefault();
    clearErrors(form);
    const fd = new FormData();
    for (const p of ['markers', 'grf', 'loads', 'calibration', 'tags', 'static', 'scale_setup']) { const f = form.querySelector('#' + p).files[0]; if (f) fd.append(p, f, f.name); }
    for (const v of form.querySelector('#videos').files) fd.append('videos', v, v.name);
    const options = { model: form.querySelector('#model').value };
    const generic = form.querySelector('#scale_muscles_from').value;
    if (generic) options.scale_muscles_from = generic;
    const t0 = form.querySelector('#t0').value, t1 = form.querySelector('#t1').value;
    if (t0 !== '' && t1 !== '') options.time_range = [Number(t0), Number(t1)];
    if (stages.length) options.stages = [...form.querySelectorAll('input[name=stage]:checked')].map((c) => c.value);
    const activation = form.querySelector('#activation');
    if (activation && activation.value !== activation.dataset.default) options.activation = activation.value;
    Object.assign(options, changedOptions(form));
    fd.append('options', new Blob([JSON.stringify(options)], { type: 'application/json' }), 'options.json');
    try {
      const r = await api('/trials', { method: 'POST', body: fd });
      location.hash = `#/trial/${r.id}`;
    } catch (err) {
      showError(form, err, (d) => (['markers', 'grf', 'loads', 'videos', 'calibration', 'tags', 'static', 'scale_setup'].includes(d.part) ? d.part
        : d.field && form.querySelector(`[data-error-for="${CSS.escape(d.field)}"]`) ? d.field
        : d.part === 'options' ? 'stages' : d.field === 'markers' ? 'markers' : null));
    }
  });
  modelUpload.addEventListener('submit', async (ev) => {
    ev.preventDefault();
    clearErrors(modelUpload);
    const fd = new FormData();
    const f = modelUpload.querySelector('#osim').files[0], m = modelUpload.querySelector('#markerset').files[0];
    if (f) fd.append('model', f, f.name);
    if (m) fd.append('markerset', m, m.name);
    for (const g of modelUpload.querySelector('#geometry').files) fd.append('geometry', g, g.name);
    try { await api('/models', { method: 'POST', body: fd }); route(); } catch (err) { showError(modelUpload, err, (d) => (d.part === 'markerset' || d.part === 'geometry' ? d.part : 'model-file')); }
  });
}

// ---------------------------------------------------------------- trial review
function parseMot(text) {
  const lines = text.split(/\r?\n/);
  const end = lines.findIndex((l) => l.trim() === 'endheader');
  const labels = lines[end + 1].trim().split(/\t|\s+/);
  const rows = lines.slice(end + 2).filter((l) => l.trim()).map((l) => l.trim().split(/\s+/).map(Number));
  const cols = labels.map((_, c) => rows.map((r) => r[c]));
  return { labels, columns: cols, inDegrees: !/inDegrees=no/.test(text) };
}
const column = (table, label) => table.columns[table.labels.indexOf(label)];
// Linear interpolation of (xs, ys) at x, held at the ends.
const interp = (xs, ys, x) => {
  if (x <= xs[0]) return ys[0];
  for (let i = 1; i < xs.length; ++i) if (x <= xs[i]) return ys[i - 1] + ((ys[i] - ys[i - 1]) * (x - xs[i - 1])) / (xs[i] - xs[i - 1]);
  return ys[ys.length - 1];
};

async function trialView(id) {
  app.replaceChildren(h('p', { class: 'muted' }, 'Loading…'));
  let trial;
  try { trial = await api(`/trials/${id}`); } catch (e) { app.replaceChildren(h('p', { class: 'form-error' }, e.message)); return; }
  const head = h('div', {},
    h('h1', {}, trial.name, ' ', h('span', { class: `status ${trial.status}` }, trial.status)),
    h('div', { class: 'card' }, trial.stages.map(stageCell), h('span', { class: 'muted' }, ' ', metrics(trial)),
      trial.error ? h('p', { class: 'form-error' }, trial.error.message) : null));
  app.replaceChildren(head);
  if (trial.status === 'queued' || trial.status === 'running') {
    const es = new EventSource(`/api/v1/trials/${id}/events`);
    es.addEventListener('end', () => { es.close(); route(); });
    es.addEventListener('progress', async () => { try { const t = await api(`/trials/${id}`); head.querySelector('.card').replaceChildren(...t.stages.map(stageCell)); } catch {} });
    state.cleanups.push(() => es.close());
    return;
  }
  if (trial.status !== 'done') return;
  // The self-contained report (summary, stages, warnings, gait-cycle plots), saved as a file.
  const reportBtn = h('button', { id: 'report' }, 'Download report');
  reportBtn.addEventListener('click', async () => {
    const res = await fetch(`/api/v1/trials/${id}/report`, { headers: token() ? { Authorization: `Bearer ${token()}` } : {} });
    if (!res.ok) return;
    const a = h('a', { href: URL.createObjectURL(await res.blob()), download: `${trial.name}_report.html` });
    document.body.append(a);
    a.click();
    a.remove();
  });
  head.querySelector('h1').append(' ', reportBtn);
  const done = (s) => (trial.stages.find((x) => x.name === s) || {}).state === 'done';
  const cpgSummary = (trial.stages.find((x) => x.name === 'cpg') || {}).summary || {};
  const cpgFitted = done('cpg') && cpgSummary.mean_r_squared_active !== undefined;
  const gaitSummary = (trial.stages.find((x) => x.name === 'gait') || {}).summary || {};
  const gaitRan = done('gait') && gaitSummary.reference_begin_s !== undefined;
  const [kin, ik, id_, so, cpg, gait, scale, cycles] = await Promise.all([
    api(`/trials/${id}/kinematics`), api(`/trials/${id}/results/ik`),
    done('id') ? api(`/trials/${id}/results/id`) : null, done('so') ? api(`/trials/${id}/results/so`) : null,
    cpgFitted ? api(`/trials/${id}/results/cpg`) : null, gaitRan ? api(`/trials/${id}/results/gait`) : null,
    done('scale') ? api(`/trials/${id}/results/scale`) : null, api(`/trials/${id}/cycles`).catch(() => null)]);
  const coords = ik.tables[0], errors = ik.tables[1];
  const time = coords.columns[0];
  const n = kin.frames.length;
  let frame = 0, playing = false, speed = 1, last = null, reference = null;
  window.__cpgait.frames = n;

  // Viewer and playback controls.
  const viewerBox = h('div', { class: 'viewer', id: 'viewer' });
  const slider = h('input', { type: 'range', min: 0, max: n - 1, value: 0, id: 'scrub', 'aria-label': 'frame' });
  const play = h('button', { id: 'play' }, 'Play');
  const speedSel = h('select', { id: 'speed' }, [0.25, 0.5, 1, 2].map((s) => h('option', { value: s, selected: s === 1 }, `${s}×`)));
  const clock = h('span', { class: 'muted', id: 'clock' });
  // While playing: the frame rate the browser reaches and the page's own work per frame.
  const rate = h('span', { class: 'muted', id: 'frame-rate', title: 'frames drawn per second while playing, and the time the page spends posing and drawing each' });
  const legend = h('div', { class: 'legend muted' }, h('span', {}, h('i', { style: 'background:#60a5fa' }), 'model markers'), h('span', {}, h('i', { style: 'background:#fb923c' }), 'measured markers'),
    h('span', {}, h('i', { style: 'background:#facc15' }), 'centres of mass'), kin.frames[0].grf.length ? h('span', {}, h('i', { style: 'background:#22c55e' }), 'ground reaction force (1 mm/N)') : null,
    kin.treadmill ? h('span', { id: 'belt-legend' }, h('i', { style: 'background:#94a3b8' }), `treadmill belt, ${fmt(Math.hypot(...kin.treadmill.belt_velocity_m_s), 2)} m/s (from the stance feet)`) : null);
  app.append(h('div', { class: 'card' }, viewerBox, h('div', { class: 'controls' }, play, slider, speedSel, clock, rate), legend,
    h('div', { class: 'muted' }, 'Keys: space plays/pauses, ←/→ step one frame.')));
  const viewer = new Viewer(viewerBox, kin);
  window.__cpgait.viewer = viewer;
  // The model's bones, where its mesh files were uploaded with it or sit in a --geometry folder.
  const modelId = trial.options.model;
  if (modelId && kin.bodies.some((b) => (b.meshes || []).length))
    await viewer.loadMeshes((file) => api(`/models/${modelId}/meshes/${encodeURIComponent(file)}`).catch(() => null));
  const viewButtons = ['side', 'front', 'top'].map((v) => {
    const b = h('button', { id: `view-${v}`, type: 'button' }, v[0].toUpperCase() + v.slice(1));
    b.addEventListener('click', () => viewer.setView(v));
    return b;
  });
  const linesBox = h('input', { type: 'checkbox', id: 'bones-lines', checked: viewer.boneMode === 'lines', disabled: !viewer.meshCount });
  linesBox.addEventListener('change', () => viewer.setBoneMode(linesBox.checked ? 'lines' : 'meshes'));
  const musclesBox = h('input', { type: 'checkbox', id: 'show-muscles', checked: true });
  musclesBox.addEventListener('change', () => viewer.setMusclesVisible(musclesBox.checked));
  viewerBox.parentElement.querySelector('.controls').append(...viewButtons, h('label', {}, linesBox, ' bones as lines'),
    h('label', {}, musclesBox, ' muscles'));
  // The reproduced gait over the measured trial: a second, translucent figure on the same timeline.
  if (gaitRan) {
    const kin2 = await api(`/trials/${id}/kinematics?source=gait`).catch(() => null);
    if (kin2 && kin2.frames.length) {
      viewer.addOverlay(kin2, 'reproduced gait');
      const overlayBox = h('input', { type: 'checkbox', id: 'show-overlay', checked: true });
      overlayBox.addEventListener('change', () => viewer.setOverlayVisible(overlayBox.checked));
      legend.append(h('span', {}, h('i', { style: 'background:#38bdf8' }), h('label', {}, overlayBox, ` reproduced gait (translucent; ${kin2.frames.length} of ${n} frames)`)));
    }
  }
  // Muscles coloured by static optimization's activations (the SO row nearest the frame's time).
  if (so && kin.muscle_names) {
    const act = so.tables[0], actTime = act.columns[0];
    const columns = kin.muscle_names.map((m) => column(act, m) || null);
    // Both in time order: one pass, each frame's nearest row from the last one's.
    let row = 0;
    const rowOf = kin.frames.map((f) => {
      while (row + 1 < actTime.length && Math.abs(actTime[row + 1] - f.time) < Math.abs(actTime[row] - f.time)) row++;
      return row;
    });
    viewer.setActivation((frameIndex, i) => (columns[i] ? columns[i][rowOf[frameIndex]] : 0));
  }

  // Plots.
  const plotsBox = h('div', { class: 'grid2' });
  app.append(plotsBox);
  const card = (title, ...content) => { const c = h('div', { class: 'card' }, h('h2', {}, title), ...content); plotsBox.append(c); return c; };
  const playhead = () => time[frame];
  const redrawAll = () => Object.values(window.__cpgait.plots).forEach((p) => p.redraw && p.redraw(false, false));

  if (scale) {
    // The scale stage: each body's factors, and each marker's distance from its measured place at the
    // static pose before the markers were placed.
    const sum = (trial.stages.find((x) => x.name === 'scale') || {}).summary || {};
    const errors = scale.tables[1];
    const markerErr = errors.labels.slice(1).map((l) => [l, 1000 * column(errors, l)[0]]).sort((a, b) => b[1] - a[1]);
    const worst = markerErr.length ? markerErr[0][1] : 1;
    card('Scaling',
      h('div', { class: 'muted' }, `${sum.method}; ${fmt(sum.total_mass_kg, 2)} kg; static marker RMS ${fmt(1000 * sum.static_marker_rms_m, 1)} mm before ${sum.markers_moved} markers were placed`),
      h('table', { id: 'scale-factors' }, h('tr', {}, ['Body', 'x', 'y', 'z'].map((x) => h('th', {}, x))),
        Object.entries(sum.factors || {}).map(([b, f]) => h('tr', {}, h('td', {}, b), f.map((v) => h('td', {}, fmt(v, 4)))))),
      h('div', { id: 'static-marker-errors' }, markerErr.map(([m, e]) => h('div', { class: 'row' }, h('span', { style: 'display:inline-block;width:9em' }, m),
        h('span', { class: 'bar done', title: `${fmt(e, 1)} mm` }, h('span', { style: `width:${Math.round((100 * e) / worst)}%` })), ` ${fmt(e, 1)} mm`))));
  }

  // Joint angles, with an optional OpenSim reference .mot from the user.
  const angleNames = coords.labels.slice(1);
  const defaults = angleNames.filter((c) => /^(hip_flexion_r|knee_angle_r|ankle_angle_r)$/.test(c));
  const angleSel = h('select', { multiple: true, id: 'angle-select' }, angleNames.map((c) => h('option', { value: c, selected: defaults.includes(c) || (defaults.length === 0 && angleNames.indexOf(c) < 3) }, c)));
  const refInput = h('input', { type: 'file', accept: '.mot,.sto', id: 'reference' });
  const angleBox = h('div', { id: 'plot-angles' });
  card('Joint angles', h('div', { class: 'controls' }, angleSel, h('label', {}, 'OpenSim reference (.mot): ', refInput)), angleBox);
  const drawAngles = () => {
    angleBox.replaceChildren();
    const chosen = [...angleSel.selectedOptions].map((o) => o.value);
    const series = chosen.map((c) => ({ label: c, values: column(coords, c) }));
    if (reference) for (const c of chosen) {
      const rc = column(reference, c);
      if (!rc) continue;
      const rt = reference.columns[0];
      const values = time.map((t) => { let i = rt.findIndex((x) => x >= t - 1e-9); if (i < 0) return null; const v = rc[i]; return reference.inDegrees ? v : (v * 180) / Math.PI; });
      series.push({ label: `reference ${c}`, values, dash: [4, 3] });
    }
    window.__cpgait.plots.angles = linePlot(angleBox, time, series, 'angle (deg) / translation (m)', playhead);
  };
  angleSel.addEventListener('change', drawAngles);
  refInput.addEventListener('change', async () => { const f = refInput.files[0]; if (f) { reference = parseMot(await f.text()); drawAngles(); } });
  drawAngles();

  // Gait cycles: each stride from heel strike to heel strike at 0-100 %, right and left, thin; their
  // mean bold with a ± SD band; an optional normative band from a CSV (coordinate, percent, mean, sd).
  if (cycles && cycles.panels.some((p) => p.series.length)) {
    window.__cpgait.cycles = cycles;
    const panels = cycles.panels.filter((p) => p.series.length);
    const base = (name) => name.replace(/_(r|l)(_moment|_force)?$/, '$2');
    const panelSel = h('select', { id: 'cycle-panel' }, panels.map((p) => h('option', { value: p.name }, p.name)));
    const quantitySel = h('select', { id: 'cycle-quantity' });
    const normInput = h('input', { type: 'file', accept: '.csv', id: 'normative' });
    const cycleBox = h('div', { id: 'plot-cycle' });
    const info = h('div', { class: 'muted', id: 'cycle-info' });
    let normative = null;
    card('Gait cycle', h('div', { class: 'controls' }, panelSel, quantitySel, h('label', {}, 'normative band (.csv): ', normInput)), cycleBox, info);
    const fillQuantities = () => {
      const panel = panels.find((p) => p.name === panelSel.value);
      const names = [...new Set(panel.series.map((s) => base(s.name)))];
      const preferred = ['knee_angle', 'knee_angle_moment', 'soleus', 'knee'].find((n) => names.includes(n)) || names[0];
      quantitySel.replaceChildren(...names.map((n) => h('option', { value: n, selected: n === preferred }, n)));
    };
    const drawCycle = () => {
      const panel = panels.find((p) => p.name === panelSel.value);
      const chosen = panel.series.filter((s) => base(s.name) === quantitySel.value);
      const groups = chosen.map((s) => ({ label: s.side === 'l' && /_l(_moment|_force)?$/.test(s.name) ? 'left' : /_r(_moment|_force)?$/.test(s.name) ? 'right' : s.name,
        color: s.side === 'l' ? '#dc2626' : '#2563eb', strides: s.strides, mean: s.mean, sd: s.sd }));
      const unit = chosen[0] ? chosen[0].unit : '';
      const n = normative && (normative[quantitySel.value] || normative[chosen[0] && chosen[0].name]);
      const norm = n ? { mean: cycles.percent.map((x) => interp(n.percent, n.mean, x)), sd: cycles.percent.map((x) => interp(n.percent, n.sd, x)) } : null;
      cycleBox.replaceChildren();
      window.__cpgait.plots.cycle = cyclePlot(cycleBox, cycles.percent, groups, `${quantitySel.value}${unit ? ` (${unit})` : ''}`, norm);
      window.__cpgait.plots.cycle.groups = groups.map((g) => ({ label: g.label, strides: g.strides.length }));
      info.textContent = `heel strikes: right ${cycles.heel_strike_source.r || '–'}, left ${cycles.heel_strike_source.l || '–'}; ` +
        groups.map((g) => `${g.label}: ${g.strides.length} stride${g.strides.length === 1 ? '' : 's'}`).join(', ');
    };
    panelSel.addEventListener('change', () => { fillQuantities(); drawCycle(); });
    quantitySel.addEventListener('change', drawCycle);
    normInput.addEventListener('change', async () => {
      const f = normInput.files[0];
      if (!f) return;
      try { normative = parseNormativeCsv(await f.text()); info.classList.remove('form-error'); drawCycle(); } catch (e) { info.textContent = e.message; info.classList.add('form-error'); }
    });
    fillQuantities();
    drawCycle();
  }

  // Marker error per frame.
  const errBox = h('div', { id: 'plot-marker-error' });
  card('Marker error', errBox);
  window.__cpgait.plots.markerError = linePlot(errBox, errors.columns[0],
    [{ label: 'RMS', values: column(errors, 'marker_error_RMS').map((v) => v * 1000) }, { label: 'max', values: column(errors, 'marker_error_max').map((v) => v * 1000) }],
    'marker error (mm)', () => errors.columns[0][frame]);

  if (id_) {
    const idTable = id_.tables[0];
    const idBox = h('div', { id: 'plot-moments' });
    card('Joint moments (inverse dynamics)', idBox);
    const moments = idTable.labels.filter((l) => /^(hip_flexion_r|knee_angle_r|ankle_angle_r)_moment$/.test(l));
    window.__cpgait.plots.moments = linePlot(idBox, idTable.columns[0], moments.map((l) => ({ label: l, values: column(idTable, l) })), 'moment (N·m)', () => idTable.columns[0][frame]);
  }

  if (so) {
    const act = so.tables[0];
    const muscles = act.labels.slice(1).filter((l) => !/_(reserve|residual)$/.test(l));
    const cols = muscles.map((m) => column(act, m));
    const canvas = h('canvas', { class: 'heatmap', id: 'heatmap' });
    const tip = h('div', { class: 'muted' }, `${muscles.length} muscles (rows, model order) × ${act.rows} frames; white 0 → dark red 1`);
    const peak = muscles.map((m, i) => [Math.max(...cols[i]), m]).sort((a, b) => b[0] - a[0]);
    const muscleSel = h('select', { multiple: true, id: 'muscle-select' }, muscles.map((m) => h('option', { value: m, selected: peak.slice(0, 4).some((p) => p[1] === m) }, m)));
    const curveBox = h('div', { id: 'plot-activations' });
    card('Muscle activations (static optimization)', canvas, tip, h('div', { class: 'controls' }, muscleSel), curveBox);
    const heat = heatMap(canvas, muscles, cols, () => {
      const t = time[frame]; const at = act.columns[0]; let i = 0; while (i + 1 < at.length && at[i + 1] <= t + 1e-9) ++i; return i;
    });
    canvas.addEventListener('mousemove', (e) => {
      const r = canvas.getBoundingClientRect();
      const row = Math.floor(((e.clientY - r.top) / r.height) * muscles.length);
      if (muscles[row]) tip.textContent = `${muscles[row]}`;
    });
    window.__cpgait.plots.heatmap = heat;
    const drawCurves = () => {
      curveBox.replaceChildren();
      const chosen = [...muscleSel.selectedOptions].map((o) => o.value);
      window.__cpgait.plots.activations = linePlot(curveBox, act.columns[0], chosen.map((m) => ({ label: m, values: column(act, m) })), 'activation (0–1)', () => act.columns[0][Math.min(frame, act.rows - 1)]);
    };
    muscleSel.addEventListener('change', drawCurves);
    drawCurves();
  }
  if (cpg) {
    // Over one gait cycle: each chosen muscle's cycle-averaged activation (dashed) and the CPG's
    // excitation; below, the rhythm neurons. The playhead shows where the trial is in its cycle.
    const [target, fitted, neurons] = cpg.tables;
    const cycleT = target.columns[0];
    const cycleS = cpgSummary.cycle_s, hs0 = (cpgSummary.heel_strikes_s || [0])[0];
    const inCycle = () => { const t = time[frame] - hs0; return ((t % cycleS) + cycleS) % cycleS; };
    const muscles = target.labels.slice(1);
    const peak = muscles.map((m) => [Math.max(...column(target, m)), m]).sort((a, b) => b[0] - a[0]);
    const sel = h('select', { multiple: true, id: 'cpg-muscle-select' }, muscles.map((m) => h('option', { value: m, selected: peak.slice(0, 4).some((p) => p[1] === m) }, m)));
    const box = h('div', { id: 'plot-cpg' }), nbox = h('div', { id: 'plot-cpg-neurons' });
    const r2 = cpgSummary.r_squared || {};
    card('CPG outputs vs fitted excitations',
      h('div', { class: 'muted' }, `${cpgSummary.neurons} Matsuoka neurons; mean R² ${cpgSummary.mean_r_squared_active.toFixed(3)} over ${cpgSummary.active_muscles} active muscles; cycle ${cycleS.toFixed(3)} s from ${cpgSummary.heel_strike_source}`),
      h('div', { class: 'controls' }, sel), box, nbox);
    const draw = () => {
      box.replaceChildren();
      const chosen = [...sel.selectedOptions].map((o) => o.value);
      const series = [];
      chosen.forEach((m, i) => {
        series.push({ label: `${m} (SO, cycle mean)`, values: column(target, m), dash: [4, 3], color: COLORS[i % COLORS.length] });
        series.push({ label: `${m} CPG (R² ${(r2[m] ?? 0).toFixed(2)})`, values: column(fitted, m), color: COLORS[i % COLORS.length] });
      });
      window.__cpgait.plots.cpg = linePlot(box, cycleT, series, 'activation / excitation (0–1), time in cycle (s)', inCycle);
    };
    sel.addEventListener('change', draw);
    draw();
    const rhythm = neurons.labels.slice(1).filter((l) => l.startsWith('rhythm'));
    window.__cpgait.plots.cpgNeurons = linePlot(nbox, neurons.columns[0], rhythm.map((l) => ({ label: l, values: column(neurons, l) })), 'rhythm neuron output y', inCycle);
  } else {
    card('CPG outputs vs fitted excitations', h('p', { class: 'muted' }, cpgSummary.not_fitted ? `Not fitted: ${cpgSummary.not_fitted}.` : 'Not computed for this trial (the CPG stage was not run).'));
  }
  if (gait) {
    // The simulated motion (solid) against the trial's (dashed) from the simulation's start, a heel
    // strike; the playhead is the trial's time since then.
    const sim = gait.tables[0], residuals = gait.tables[1];
    const simT = sim.columns[0], t0 = gaitSummary.reference_begin_s;
    const names = sim.labels.slice(1).filter((c) => !/^pelvis_t[xyz]$/.test(c));
    const sel = h('select', { multiple: true, id: 'gait-select' }, names.map((c) => h('option', { value: c, selected: /^(hip_flexion_r|knee_angle_r|ankle_angle_r)$/.test(c) }, c)));
    const box = h('div', { id: 'plot-gait' }), rbox = h('div', { id: 'plot-gait-residuals' });
    const rms = gaitSummary.tracking_rms_deg_or_m || {};
    const fell = gaitSummary.fell_at_s !== null && gaitSummary.fell_at_s !== undefined ? `fell at ${gaitSummary.fell_at_s.toFixed(2)} s` : 'did not fall';
    card('Reproduced gait vs measured',
      h('div', { class: 'muted' }, `${simT[simT.length - 1].toFixed(2)} s simulated on contact spheres from ${t0.toFixed(3)} s; stride ${gaitSummary.stride_time_s.toFixed(3)} s, ${gaitSummary.stride_length_m.toFixed(2)} m, ${gaitSummary.speed_m_s.toFixed(2)} m/s; pelvis residual force ${gaitSummary.pelvis_residual_force_percent_bw.toFixed(1)} % body weight; ${fell}`),
      h('div', { class: 'controls' }, sel), box, rbox);
    const since = () => time[frame] - t0;
    const draw = () => {
      box.replaceChildren();
      const series = [];
      [...sel.selectedOptions].map((o) => o.value).forEach((c, i) => {
        const measured = column(coords, c);
        const values = simT.map((t) => { const tt = t0 + t; let k = time.findIndex((x) => x >= tt - 1e-9); return k < 0 || !measured ? null : measured[k]; });
        series.push({ label: `${c} measured`, values, dash: [4, 3], color: COLORS[i % COLORS.length] });
        series.push({ label: `${c} simulated (RMS ${(rms[c] ?? 0).toFixed(1)}°)`, values: column(sim, c), color: COLORS[i % COLORS.length] });
      });
      window.__cpgait.plots.gait = linePlot(box, simT, series, 'angle (deg), time since the start (s)', since);
    };
    sel.addEventListener('change', draw);
    draw();
    window.__cpgait.plots.gaitResiduals = linePlot(rbox, residuals.columns[0], residuals.labels.slice(1).map((l) => ({ label: l, values: column(residuals, l) })),
      'pelvis residual (N·m, N), time since the start (s)', since);
    gaitCycleCard(card, gaitSummary, cycles);
  } else {
    card('Reproduced gait vs measured', h('p', { class: 'muted' }, gaitSummary.not_run ? `Not run: ${gaitSummary.not_run}.` : 'Not computed for this trial (the gait stage was not run).'));
  }
  app.append(h('div', { class: 'card files' }, h('h2', {}, 'Result files'), (trial.files || []).map((f) => h('a', { href: `/api/v1/trials/${id}/files/${f}`, download: f }, f))));

  // Playback.
  const show = (i) => {
    frame = Math.max(0, Math.min(n - 1, i));
    slider.value = frame;
    clock.textContent = `t = ${fmt(time[frame], 3)} s  (frame ${frame + 1}/${n})`;
    viewer.show(frame);
    redrawAll();
    window.__cpgait.frame = frame;
  };
  slider.addEventListener('input', () => show(Number(slider.value)));
  speedSel.addEventListener('change', () => (speed = Number(speedSel.value)));
  const toggle = () => { playing = !playing; play.textContent = playing ? 'Pause' : 'Play'; last = null; };
  play.addEventListener('click', toggle);
  let tPlay = time[0];
  const perf = { frames: 0, work: 0, since: null };
  const tick = (now) => {
    if (playing) {
      if (last != null) {
        tPlay += (speed * (now - last)) / 1000;
        if (tPlay > time[n - 1]) tPlay = time[0];
        let i = frame; while (i + 1 < n && time[i + 1] <= tPlay) ++i; if (time[i] > tPlay) i = 0; while (i + 1 < n && time[i + 1] <= tPlay) ++i;
        const t0 = performance.now();
        if (i !== frame) show(i);
        perf.work += performance.now() - t0;
        perf.frames++;
        if (perf.since == null) perf.since = now;
        if (now - perf.since >= 1000) {
          const fps = (1000 * perf.frames) / (now - perf.since);
          rate.textContent = `${fps.toFixed(0)} frames/s, ${(perf.work / perf.frames).toFixed(1)} ms of page work each`;
          window.__cpgait.frameRate = { fps, workMs: perf.work / perf.frames };
          perf.frames = 0; perf.work = 0; perf.since = now;
        }
      }
      last = now;
    } else { tPlay = time[frame]; perf.frames = 0; perf.work = 0; perf.since = null; }
    raf = requestAnimationFrame(tick);
  };
  let raf = requestAnimationFrame(tick);
  const onKey = (e) => {
    if (e.target.tagName === 'INPUT' || e.target.tagName === 'SELECT') return;
    if (e.code === 'Space') { e.preventDefault(); toggle(); }
    if (e.code === 'ArrowRight') { e.preventDefault(); show(frame + 1); }
    if (e.code === 'ArrowLeft') { e.preventDefault(); show(frame - 1); }
  };
  window.addEventListener('keydown', onKey);
  state.cleanups.push(() => cancelAnimationFrame(raf), () => window.removeEventListener('keydown', onKey));
  window.__cpgait.setFrame = show;
  show(0);
  window.__cpgait.ready = true;
}

// The reproduced gait over the gait cycle against the trial's, and its walks at other speed knobs
// side by side: per coordinate, the trial's mean ± SD (right strides), the simulation's strides and
// mean ± SD, each knob's mean ± SD; and a table of each walk's strides, speed and fall.
function gaitCycleCard(card, summary, cycles) {
  const panel = (name) => cycles && cycles.panels.find((p) => p.name === name);
  const gaitPanel = panel('gait');
  const sim = gaitPanel && gaitPanel.series.length ? gaitPanel : null;  // null: no simulated stride
  const runs = [Object.assign({ speed_knob: 1, panel: gaitPanel }, summary)].concat((summary.speed_knobs || []).map((r) => Object.assign({}, r, { panel: cycles && cycles.panels.find((p) => p.name.startsWith('gait_speed_') && p.speed_knob === r.speed_knob) })));
  const strides = (r, side) => Math.max(0, ((r.heel_strikes_s || {})[side] || []).length - 1);
  const phases = (r) => {
    const p = r.contact_phases;
    return p && strides(r, 'right') > 0
      ? `${fmt(p.stance_percent.right, 0)} / ${fmt(p.stance_percent.left, 0)}, ${fmt(p.double_support_percent, 0)}, ${fmt(p.flight_percent, 0)}` : '';
  };
  const walked = (r) => (r.fell_at_s == null ? `${fmt(r.simulated_s, 1)} s, did not fall` : `fell at ${fmt(r.fell_at_s, 2)} s`);
  const table = h('table', { id: 'gait-runs' },
    h('tr', {}, ['Speed knob', 'Walked', 'Strides R / L', 'Stride (s)', 'Cycle / knob (s)', 'Stride length (m)', 'Speed (m/s)', 'Stance R / L, double support, flight (%)'].map((x) => h('th', {}, x))),
    runs.map((r) => h('tr', { 'data-knob': r.speed_knob, class: r.fell_at_s == null ? '' : 'fell' },
      h('td', {}, `${r.speed_knob}×`), h('td', {}, walked(r)),
      h('td', {}, `${strides(r, 'right')} / ${strides(r, 'left')}`), h('td', {}, fmt(r.stride_time_s, 3)),
      h('td', {}, `${fmt(r.cycle_over_speed_s, 3)}${r.stride_time_s > 0 && r.cycle_over_speed_s ? ` (${fmt(100 * (r.stride_time_s / r.cycle_over_speed_s - 1), 1)} %)` : ''}`),
      h('td', {}, fmt(r.stride_length_m, 2)), h('td', {}, fmt(r.speed_m_s, 2)), h('td', {}, phases(r)))));
  // The same walk at other integrator tolerances (the stage's check without residuals; ROS34PW2 for a
  // linearly implicit Euler walk): a walk that stands in its own integration alone stands by its error.
  const checks = summary.tolerance_check || [];
  const checkTable = checks.length ? h('table', { id: 'gait-tolerance-check' },
    h('tr', {}, ['Integrator, tolerance', 'Walked'].map((x) => h('th', {}, x))),
    checks.map((c) => h('tr', { 'data-tolerance': c.tolerance, class: c.fell_at_s == null ? '' : 'fell' },
      h('td', {}, `${c.integrator ? `${c.integrator}, ` : ''}${c.tolerance}`), h('td', {}, walked(c))))) : null;
  const box = h('div', { id: 'plot-gait-cycle' });
  const trialPanel = panel('kinematics');
  const names = sim ? sim.series.map((s) => s.name).filter((n) => !/^pelvis_t[xyz]$/.test(n)) : [];
  const sel = h('select', { id: 'gait-cycle-quantity' }, names.map((n) => h('option', { value: n, selected: n === 'knee_angle_r' }, n)));
  const residuals = summary.pelvis_residuals ? 'with pelvis residual actuators' : 'on its own (no residual actuators)';
  card('Reproduced gait over the gait cycle, and its speed knobs', h('div', { class: 'muted' },
    `The CPG-driven model ${residuals}: every simulated stride from its own heel strikes against the trial's strides, and the same controller at the other speed knobs.`),
  table, checkTable, sim ? h('div', { class: 'controls' }, sel) : h('p', { class: 'muted' }, 'No simulated stride to plot.'), box);
  if (!sim) return;
  const draw = () => {
    const q = sel.value;
    const groups = [];
    const measured = trialPanel && trialPanel.series.find((s) => s.name === q);
    if (measured) groups.push({ label: 'trial', color: '#6b7280', strides: measured.strides, mean: measured.mean, sd: measured.sd });
    runs.forEach((r, i) => {
      const s = r.panel && r.panel.series.find((x) => x.name === q);
      if (s) groups.push({ label: `simulated ${r.speed_knob}×`, color: COLORS[i % COLORS.length], strides: i === 0 ? s.strides : [], mean: s.mean, sd: s.sd, all: s.strides });
    });
    box.replaceChildren();
    const unit = (measured || {}).unit || 'deg';
    window.__cpgait.plots.gaitCycle = cyclePlot(box, cycles.percent, groups, `${q} (${unit})`, null);
    window.__cpgait.plots.gaitCycle.groups = groups.map((g) => ({ label: g.label, strides: (g.all || g.strides).length, mean50: g.mean[50],
      strides50: (g.all || g.strides).map((x) => x[50]) }));
  };
  sel.addEventListener('change', draw);
  draw();
}

route();
