#!/usr/bin/env bash
# Rebuild src/appell/io/viewer/three.min.js: the parts of three.js the viewer uses
# (scripts/vendor/three-entry.js), bundled into one minified script that defines the
# global THREE. Pinned versions; the result is committed so that appell needs no
# network and no Node.js at run time. Needs node and npm.
set -euo pipefail
THREE_VERSION=0.187.0
ESBUILD_VERSION=0.28.2
here="$(cd "$(dirname "$0")" && pwd)"
out="$here/../../src/appell/io/viewer"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"
npm init -y >/dev/null
npm install --no-audit --no-fund "three@$THREE_VERSION" "esbuild@$ESBUILD_VERSION" >/dev/null
cp "$here/three-entry.js" entry.js
./node_modules/.bin/esbuild entry.js --bundle --minify --format=iife --global-name=THREE \
    --legal-comments=none --outfile=three.min.js
{ echo "three.js $THREE_VERSION (bundled by scripts/vendor/three.sh with esbuild $ESBUILD_VERSION)"; echo;
  cat node_modules/three/LICENSE; } > "$out/THREE-LICENSE.txt"
{ echo "/* three.js $THREE_VERSION, MIT licence (THREE-LICENSE.txt); the parts in scripts/vendor/three-entry.js */";
  cat three.min.js; } > "$out/three.min.js"
sha256sum "$out/three.min.js"
