#!/usr/bin/env bash
# The full stimulus set of the default protocol, timed: 90 sentences × 6
# conditions (audio-only and the rule, Cohen-Massaro, Öhman, ANN 1 and ANN 2
# control models), 3-band vocoder, 30 fps, 640×480, speech from the
# protocol's voice (Festival SLT) —
# `avsi build-stimuli protocols/beskow2004-en.toml --max-sentences 90`, from
# scratch (--force), one worker per core. Prints the wall time and the
# builder's own summary (stimuli, frames, seconds).
#
# Usage: bench/bench_stimuli_full_set.sh [BUILD_DIR] [OUT_DIR]
#   BUILD_DIR  holds the avsi executable in cli/ (default: build)
#   OUT_DIR    where the stimuli go (default: BUILD_DIR/bench-stimuli-full-set)
# Measure at a moment of low load (`uptime`): the machine has 2 cores.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
build="${1:-$root/build}"
out="${2:-$build/bench-stimuli-full-set}"
avsi="$build/cli/avsi"
[[ -x "$avsi" ]] || { echo "no avsi executable at $avsi (build the avsi target first)" >&2; exit 2; }

echo "load before: $(uptime)"
start=$(date +%s.%N)
"$avsi" build-stimuli "$root/protocols/beskow2004-en.toml" --out "$out" --max-sentences 90 --all-sentences --force
end=$(date +%s.%N)
echo "load after: $(uptime)"
stimuli=$(find "$out" -name '*.mp4' | wc -l)
printf 'full stimulus set: %d MP4s in %.1f s wall time\n' "$stimuli" "$(echo "$end - $start" | bc -l)"
