#!/usr/bin/env bash
# Builds the playground (and the character app with the Fox, as character.html) for the web
# into web/dist/, ready to serve as static files:
#   bash web/build.sh && python3 -m http.server -d web/dist
# then open http://localhost:8000 (the playground) or http://localhost:8000/character.html.
# Installs what it needs: the wasm32 target, wasm-bindgen-cli at the version Cargo.lock pins (the
# CLI must match the library exactly) and binaryen's wasm-opt (the npm package web/package.json
# pins: Debian's binaryen is too old for the wasm features Rust emits today).
#
# The `web` profile (Cargo.toml) builds for size; wasm-opt -Oz shrinks the result further; each
# .wasm gets a gzip copy beside it (`.wasm.gz`, what any static server or CDN can send with
# `Content-Encoding: gzip`). `python3 -m http.server` sends the plain file.
set -euo pipefail
cd "$(dirname "$0")/.."
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-$HOME/.cache/bevy_wii_deform/target}"

if ! rustup target list --installed | grep -qx wasm32-unknown-unknown; then
  rustup target add wasm32-unknown-unknown
fi
version=$(awk '$0 == "name = \"wasm-bindgen\"" { getline; gsub(/"/, "", $3); print $3; exit }' Cargo.lock)
if ! command -v wasm-bindgen >/dev/null 2>&1 || ! wasm-bindgen --version | grep -qF " $version"; then
  cargo install wasm-bindgen-cli --version "$version"
fi

if [ ! -x web/node_modules/.bin/wasm-opt ] || [ ! -d web/node_modules/playwright-core ]; then
  (cd web && npm ci --no-audit --no-fund)
fi

# No hidapi in a browser: the default features but that one.
cargo build --profile web --target wasm32-unknown-unknown --no-default-features --features bevy \
  --example playground --example character

dist=web/dist
rm -rf "$dist"
mkdir -p "$dist/assets/models"
for app in playground character; do
  wasm-bindgen --target web --no-typescript --remove-name-section --out-dir "$dist" --out-name "$app" \
    "$CARGO_TARGET_DIR/wasm32-unknown-unknown/web/examples/$app.wasm"
done
# wasm-opt -Oz on both modules at once (minutes each on a 40 MB module). The features the
# modules use (bulk memory, sign extension, non-trapping float-to-int, SIMD, multi-value,
# reference types) must be allowed to wasm-opt too.
for app in playground character; do
  web/node_modules/.bin/wasm-opt -Oz --strip-debug --strip-producers \
    --enable-bulk-memory --enable-sign-ext --enable-nontrapping-float-to-int --enable-simd \
    --enable-multivalue --enable-reference-types --enable-mutable-globals \
    -o "$dist/${app}_bg.opt.wasm" "$dist/${app}_bg.wasm" &
done
wait
for app in playground character; do
  [ -s "$dist/${app}_bg.opt.wasm" ] || { echo "wasm-opt failed on $app"; exit 1; }
  mv "$dist/${app}_bg.opt.wasm" "$dist/${app}_bg.wasm"
  gzip -9 -k -f "$dist/${app}_bg.wasm"
  echo "$app: $(stat -c %s "$dist/${app}_bg.wasm") bytes, gzip $(stat -c %s "$dist/${app}_bg.wasm.gz")"
done
cp web/index.html web/character.html "$dist/"
# What the pages load over HTTP (the playground's cactus is compiled in).
cp assets/models/alien.glb assets/models/Fox.glb "$dist/assets/models/"
echo "built $dist ($(du -sh "$dist" | cut -f1)); serve it with: python3 -m http.server -d $dist"
