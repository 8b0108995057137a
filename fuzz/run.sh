#!/usr/bin/env bash
# Coverage-guided fuzzing of every reader that takes outside bytes (cargo-fuzz, libFuzzer).
#
#   bash fuzz/run.sh [TARGET|all] [SECONDS]     (default: all targets, 60 s each)
#
# Installs what it needs (a pinned nightly toolchain through rustup, cargo-fuzz from crates.io),
# writes the seed corpora from the repository's files (fuzz/src/bin/seeds.rs), and runs each
# target for SECONDS with a 1 s time limit and a 2 GB memory limit per input. The corpus that
# coverage grows is kept between runs under $FUZZ_WORK. Findings are saved as
# $FUZZ_WORK/artifacts/<target>/{crash,timeout,oom}-*; keep one as a regression test under
# tests/fuzz_regressions/<target>/ (the main crate's `cargo test` replays them).
# The last line printed is JSON: per target "execs", "crashes", "timeouts", "ooms", "corpus"
# (inputs in the corpus), "coverage" (edges) and "features" (libFuzzer's coverage features).
# Exits 1 when any target found something.
set -euo pipefail
cd "$(dirname "$0")"
FUZZ_DIR=$(pwd)
ROOT=$(cd .. && pwd)

TARGET=${1:-all}
SECONDS_EACH=${2:-60}
NIGHTLY=nightly-2026-10-30
CARGO_FUZZ_VERSION=0.13.2
FUZZ_WORK=${FUZZ_WORK:-$HOME/.cache/bevy_wii_deform/fuzz}
# The fuzz builds (sanitizer flags) keep a target folder of their own: sharing one with the
# ordinary builds would rebuild both every time.
export CARGO_TARGET_DIR=$FUZZ_WORK/target

rustup toolchain install "$NIGHTLY" --profile minimal >/dev/null 2>&1 \
  || rustup toolchain install "$NIGHTLY" --profile minimal
if ! cargo fuzz --version 2>/dev/null | grep -q "$CARGO_FUZZ_VERSION"; then
  cargo install cargo-fuzz --locked --version "$CARGO_FUZZ_VERSION"
fi

TARGETS=(wiimote_reports pad_reports mesh_files selection_files gltf_character gltf_clip vrm_springs ron_files bvh_files)
if [ "$TARGET" != all ]; then
  if [[ ! " ${TARGETS[*]} " =~ " $TARGET " ]]; then
    echo "unknown target $TARGET (targets: ${TARGETS[*]})" >&2
    exit 2
  fi
  TARGETS=("$TARGET")
fi

dict_of() {
  case "$1" in
    gltf_*|vrm_springs) echo "$FUZZ_DIR/dict/gltf.dict" ;;
    mesh_files|selection_files) echo "$FUZZ_DIR/dict/mesh.dict" ;;
    ron_files) echo "$FUZZ_DIR/dict/ron.dict" ;;
    bvh_files) echo "$FUZZ_DIR/dict/bvh.dict" ;;
    *) echo "" ;;
  esac
}

# Seeds, written fresh from the repository (with the stable toolchain: no sanitizers needed),
# then swapped in for the targets of this run only (runs of other targets may go on beside it).
fresh=$(mktemp -d "$FUZZ_WORK/seeds.XXXXXX" 2>/dev/null || { mkdir -p "$FUZZ_WORK"; mktemp -d "$FUZZ_WORK/seeds.XXXXXX"; })
cargo run --quiet --manifest-path "$FUZZ_DIR/Cargo.toml" --bin seeds -- "$fresh" "$ROOT"
mkdir -p "$FUZZ_WORK/seeds"
for t in "${TARGETS[@]}"; do
  rm -rf "$FUZZ_WORK/seeds/$t"
  mv "$fresh/$t" "$FUZZ_WORK/seeds/$t"
done
rm -rf "$fresh"

# Debug assertions on: an integer overflow is a finding too.
for t in "${TARGETS[@]}"; do
  cargo +"$NIGHTLY" fuzz build --fuzz-dir "$FUZZ_DIR" --features libfuzzer --debug-assertions "$t"
done

results=()
failed=0
for t in "${TARGETS[@]}"; do
  corpus="$FUZZ_WORK/corpus/$t"
  artifacts="$FUZZ_WORK/artifacts/$t"
  mkdir -p "$corpus" "$artifacts"
  log="$FUZZ_WORK/$t.log"
  ls "$artifacts" | sort >"$FUZZ_WORK/$t.before"
  dict=$(dict_of "$t")
  set +e
  cargo +"$NIGHTLY" fuzz run --fuzz-dir "$FUZZ_DIR" --features libfuzzer --debug-assertions "$t" \
    "$corpus" "$FUZZ_WORK/seeds/$t" -- \
    -max_total_time="$SECONDS_EACH" -timeout=1 -rss_limit_mb=2048 -malloc_limit_mb=2048 \
    -max_len=262144 -print_final_stats=1 -artifact_prefix="$artifacts/" \
    ${dict:+-dict="$dict"} >"$log" 2>&1
  status=$?
  set -e
  execs=$(grep -oE 'stat::number_of_executed_units: *[0-9]+' "$log" | grep -oE '[0-9]+$' | tail -n1)
  cov=$(grep -oE 'cov: [0-9]+' "$log" | tail -n1 | grep -oE '[0-9]+' || true)
  ft=$(grep -oE 'ft: [0-9]+' "$log" | tail -n1 | grep -oE '[0-9]+' || true)
  # Findings of this run: the artifacts that were not there before it.
  new=$(ls "$artifacts" | sort | comm -13 "$FUZZ_WORK/$t.before" - || true)
  crashes=$(grep -cE '^crash-' <<<"$new" || true)
  timeouts=$(grep -cE '^timeout-' <<<"$new" || true)
  ooms=$(grep -cE '^oom-' <<<"$new" || true)
  found=$(grep -c . <<<"$new" || true)
  if [ "$status" -ne 0 ] || [ "$found" -gt 0 ]; then
    failed=1
    echo "$t: a finding (exit $status); see $log and $artifacts" >&2
    grep -m1 -A12 -E 'panicked|ERROR: libFuzzer|ERROR: AddressSanitizer' "$log" >&2 || true
  fi
  results+=("\"$t\": {\"seconds\": $SECONDS_EACH, \"execs\": ${execs:-0}, \"crashes\": $crashes, \"timeouts\": $timeouts, \"ooms\": $ooms, \"corpus\": $(ls "$corpus" | wc -l), \"coverage\": ${cov:-0}, \"features\": ${ft:-0}}")
done

json=$(IFS=,; echo "{${results[*]}}")
echo "$json"
exit $failed
