// Time-series plots (uPlot) with a playhead, and an activation heat map.
import uPlot from 'uplot';
import 'uplot/dist/uPlot.min.css';

export const COLORS = ['#2563eb', '#dc2626', '#16a34a', '#9333ea', '#ea580c', '#0891b2', '#ca8a04', '#db2777'];

// series: [{label, values}] over `time`; yLabel names the quantity and unit.
export function linePlot(container, time, series, yLabel, playhead) {
  const opts = {
    width: container.clientWidth || 600,
    height: 240,
    scales: { x: { time: false } },
    axes: [{ label: 'time (s)' }, { label: yLabel }],
    series: [{ label: 'time (s)' }, ...series.map((s, i) => ({ label: s.label, stroke: s.color || COLORS[i % COLORS.length], width: s.dash ? 1 : 1.5, dash: s.dash }))],
    hooks: {
      draw: [(u) => {
        const t = playhead();
        if (t == null) return;
        const x = u.valToPos(t, 'x', true);
        const ctx = u.ctx;
        ctx.save();
        ctx.strokeStyle = '#111827';
        ctx.lineWidth = 1;
        ctx.beginPath();
        ctx.moveTo(x, u.bbox.top);
        ctx.lineTo(x, u.bbox.top + u.bbox.height);
        ctx.stroke();
        ctx.restore();
      }],
    },
  };
  const data = [time, ...series.map((s) => s.values)];
  const plot = new uPlot(opts, data, container);
  new ResizeObserver(() => plot.setSize({ width: container.clientWidth, height: 240 })).observe(container);
  return plot;
}

// Muscles x frames, activation 0..1 as colour (white -> dark red).
export function heatMap(canvas, names, columns, playheadIndex) {
  const rows = names.length, cols = columns[0] ? columns[0].length : 0;
  canvas.width = cols;
  canvas.height = rows;
  const ctx = canvas.getContext('2d');
  const img = ctx.createImageData(cols, rows);
  for (let r = 0; r < rows; ++r)
    for (let c = 0; c < cols; ++c) {
      const a = Math.max(0, Math.min(1, columns[r][c]));
      const k = 4 * (r * cols + c);
      img.data[k] = 255 - 100 * a;
      img.data[k + 1] = 255 - 240 * a;
      img.data[k + 2] = 255 - 230 * a;
      img.data[k + 3] = 255;
    }
  const draw = () => {
    ctx.putImageData(img, 0, 0);
    const i = playheadIndex();
    if (i != null) {
      ctx.fillStyle = 'rgba(17,24,39,0.8)';
      ctx.fillRect(i, 0, 1, rows);
    }
  };
  draw();
  return { redraw: draw, rows, cols };
}

// Gait-cycle plot over 0-100 % of the stride. groups: [{label, color, strides: [[...]], mean, sd}],
// one per side; each stride drawn thin, the mean bold with a mean ± SD band; norm: an optional
// normative {mean, sd} drawn as a grey band. Series order: per group, strides then mean, mean+SD, mean-SD.
export function cyclePlot(container, percent, groups, yLabel, norm) {
  const series = [{ label: '% of gait cycle' }];
  const data = [percent];
  const bands = [];
  const add = (label, values, style) => { series.push(Object.assign({ label, points: { show: false } }, style)); data.push(values); return data.length - 1; };
  const band = (mean, sd, label, color, fill) => {
    const hi = add(`${label} +SD`, mean.map((m, i) => m + sd[i]), { stroke: color, width: 0 });
    const lo = add(`${label} −SD`, mean.map((m, i) => m - sd[i]), { stroke: color, width: 0 });
    bands.push({ series: [hi, lo], fill });
  };
  if (norm) {
    add('normative mean', norm.mean, { stroke: '#6b7280', width: 1, dash: [4, 3] });
    band(norm.mean, norm.sd, 'normative', '#6b7280', 'rgba(107,114,128,0.18)');
  }
  for (const g of groups) {
    g.strides.forEach((s, i) => add(`${g.label} stride ${i + 1}`, s, { stroke: g.color + '80', width: 1 }));
    add(`${g.label} mean`, g.mean, { stroke: g.color, width: 2.5 });
    band(g.mean, g.sd, g.label, g.color, g.color + '30');
  }
  const opts = {
    width: container.clientWidth || 600,
    height: 240,
    scales: { x: { time: false, range: [0, 100] } },
    axes: [{ label: '% of gait cycle (heel strike to heel strike)' }, { label: yLabel }],
    legend: { live: false },
    series,
    bands,
  };
  const plot = new uPlot(opts, data, container);
  new ResizeObserver(() => plot.setSize({ width: container.clientWidth, height: 240 })).observe(container);
  return plot;
}

// A normative-data CSV: a header line, then rows of coordinate, percent, mean, sd (any order of
// rows; percent 0-100). Returns {coordinate: {percent: [], mean: [], sd: []}} sorted by percent.
export function parseNormativeCsv(text) {
  const out = {};
  const lines = text.split(/\r?\n/).filter((l) => l.trim());
  const head = lines.shift().split(',').map((s) => s.trim().toLowerCase());
  const col = (n) => head.indexOf(n);
  const [ci, pi, mi, si] = ['coordinate', 'percent', 'mean', 'sd'].map(col);
  if ([ci, pi, mi, si].some((i) => i < 0)) throw new Error('normative CSV needs the columns coordinate, percent, mean, sd');
  for (const l of lines) {
    const f = l.split(',').map((s) => s.trim());
    const c = (out[f[ci]] = out[f[ci]] || []);
    c.push([Number(f[pi]), Number(f[mi]), Number(f[si])]);
  }
  for (const k of Object.keys(out)) {
    const rows = out[k].sort((a, b) => a[0] - b[0]);
    out[k] = { percent: rows.map((r) => r[0]), mean: rows.map((r) => r[1]), sd: rows.map((r) => r[2]) };
  }
  return out;
}
