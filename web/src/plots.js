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
