// Build three-film.min.js: three.js's WebGL renderer, glTF loader and orbit controls, tree-shaken
// into one minified script that defines the global `PaintcellThree`, with three.js's MIT
// licence at its head (the file is copied into every report.html).
import { readFileSync } from 'node:fs';
import { build } from 'esbuild';

const version = JSON.parse(readFileSync('node_modules/three/package.json', 'utf8')).version;
const licence = readFileSync('node_modules/three/LICENSE', 'utf8').trim();
await build({
  entryPoints: ['bundle-entry.js'],
  bundle: true,
  minify: true,
  format: 'iife',
  globalName: 'PaintcellThree',
  legalComments: 'none',
  banner: { js: `/*! three.js ${version} (https://threejs.org), bundled for paintcell.\n${licence}\n*/` },
  outfile: 'three-film.min.js',
});
