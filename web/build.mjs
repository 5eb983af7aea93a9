// Bundles the dashboard into dist/ (served by `cpgait serve` at /). No CDN: everything is local.
import { build } from 'esbuild';
import { cpSync, mkdirSync } from 'node:fs';

mkdirSync('dist', { recursive: true });
await build({
  entryPoints: ['src/main.js'],
  bundle: true,
  minify: true,
  sourcemap: true,
  format: 'esm',
  target: ['es2020'],
  outfile: 'dist/app.js',
  loader: { '.css': 'css' },
  logLevel: 'warning',
});
cpSync('src/index.html', 'dist/index.html');
console.log('dashboard built into web/dist');
