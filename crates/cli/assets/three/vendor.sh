#!/usr/bin/env bash
# Re-creates three-bundle.min.js and LICENSE from the npm registry (run by hand when
# upgrading three.js; the bundle is committed and embedded in the armature binary).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
npm init -y >/dev/null
npm install --no-audit --no-fund three@0.187.0 esbuild@0.25.12 >/dev/null
cp "$here/entry.js" .
node_modules/.bin/esbuild entry.js --bundle --minify --format=iife --legal-comments=none \
    --outfile="$here/three-bundle.min.js"
cp node_modules/three/LICENSE "$here/LICENSE"
echo "three.js $(node -p "require('./node_modules/three/package.json').version") bundled: $(wc -c <"$here/three-bundle.min.js") bytes"
