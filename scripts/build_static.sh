#!/usr/bin/env bash
# Bundle the browser libraries from node_modules into static/vendor/ (git-ignored), so
# pages load them as static files: nothing comes from a CDN. roslib 2.x is ESM-only with
# npm dependencies; esbuild (its binary ships inside an npm package) resolves them into
# one ES module; Leaflet's ES module is minified the same way and its stylesheet and
# images copied beside it; uPlot (the robot page's plots), cytoscape.js (the topology
# editor) and nipplejs (the touch joystick) are minified ES modules beside them, with
# uPlot's stylesheet; three.js (the mapping card's 3D view) is one module of the parts
# the page uses and its OrbitControls (mouse and touch), so unused parts are left out.
# Quick when nothing changed.
set -euo pipefail
cd "$(dirname "$0")/.."

OUT=static/vendor
STAMP=$OUT/.build.sha256
want=$(cat package-lock.json "$0" | sha256sum | cut -d' ' -f1)
if [ "$(cat "$STAMP" 2>/dev/null)" = "$want" ] && [ -f "$OUT/roslib.js" ] && [ -f "$OUT/leaflet.js" ] \
  && [ -f "$OUT/uplot.js" ] && [ -f "$OUT/cytoscape.js" ] && [ -f "$OUT/nipplejs.js" ] && [ -f "$OUT/three.js" ]; then
  exit 0
fi
echo "setup: bundling browser libraries into $OUT/"
mkdir -p "$OUT"
node_modules/.bin/esbuild node_modules/roslib/dist/RosLib.js --bundle --format=esm \
  --platform=browser --target=es2022 --minify --legal-comments=none --log-level=warning \
  --outfile="$OUT/roslib.js"
node_modules/.bin/esbuild node_modules/leaflet/dist/leaflet-src.esm.js --format=esm \
  --target=es2022 --minify --legal-comments=none --log-level=warning --outfile="$OUT/leaflet.js"
# One self-contained ES module per library, each imported by its pages as a static file.
esm() {
  node_modules/.bin/esbuild "$1" --bundle --format=esm --platform=browser --target=es2022 --minify \
    --legal-comments=none --log-level=warning --outfile="$OUT/$2"
}
esm node_modules/uplot/dist/uPlot.esm.js uplot.js
esm node_modules/cytoscape/dist/cytoscape.esm.mjs cytoscape.js
esm node_modules/nipplejs/dist/index.mjs nipplejs.js
echo 'export { BufferAttribute, BufferGeometry, Color, GridHelper, Group, LineBasicMaterial, Line,
  LineSegments, PerspectiveCamera, Points, PointsMaterial, Scene, WebGLRenderer } from "three";
export { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";' |
  node_modules/.bin/esbuild --bundle --format=esm --platform=browser --target=es2022 --minify \
    --legal-comments=none --log-level=warning --outfile="$OUT/three.js"
cp node_modules/uplot/dist/uPlot.min.css "$OUT/uplot.css"
cp node_modules/leaflet/dist/leaflet.css "$OUT/leaflet.css"
mkdir -p "$OUT/images"
cp node_modules/leaflet/dist/images/*.png "$OUT/images/"
echo "$want" > "$STAMP"
