#!/usr/bin/env bash
# The web build in a real browser: serves web/dist on 127.0.0.1, opens it in headless Chromium
# (WebGL2 through SwiftShader), waits for the first frame, drags the bar with real input events
# and checks that it bent and that the console holds no error. The last stdout line is JSON:
#   {"rendered": true, "bent": true, "console_errors": 0, "first_frame_s": …, "grab_to_first_pose_ms": …,
#    "wasm_bytes": …, "wasm_gzip_bytes": …}  (the playground's download, plain and gzipped)
# Builds web/dist first when it is missing; installs Chromium (Debian's package) and the test's
# two npm packages when they are missing.
set -euo pipefail
cd "$(dirname "$0")/.."

[ -f web/dist/playground_bg.wasm ] || bash web/build.sh >&2

if ! command -v chromium >/dev/null 2>&1; then
  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium) >&2 \
    || sudo -n sh -c 'apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium' >&2
fi
if [ ! -d web/node_modules/playwright-core ] || [ ! -d web/node_modules/pngjs ]; then
  (cd web && npm ci --no-audit --no-fund) >&2
fi

port=${WEB_TEST_PORT:-8123}
python3 -m http.server --bind 127.0.0.1 "$port" -d web/dist >/dev/null 2>&1 &
server=$!
trap 'kill $server 2>/dev/null || true' EXIT
for _ in $(seq 50); do
  curl -sf "http://127.0.0.1:$port/" >/dev/null && break
  sleep 0.1
done
timeout 300 node web/test.mjs "http://127.0.0.1:$port/" web/dist/screenshots
