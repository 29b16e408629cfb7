#!/usr/bin/env bash
# The marker fit as a whole process (issue 43's target: 10 minutes of 60 fps
# motion capture, 36,000 frames × 35 markers, fitted in under 30 s on 2
# cores): bench/marker_fit_data writes a synthetic C3D of the built-in head's
# markers, then `avsi corpus fit-markers` reads, fits and writes the corpus
# with its residual report, timed with /usr/bin/time. The load is printed
# before and after.
#
#   bench/bench_marker_fit.sh [BUILD_DIR] [FRAMES]     (default build 36000)
set -euo pipefail
build_dir="${1:-build}"
frames="${2:-36000}"
out="${OUT:-out/bench-marker-fit}"
threads="${THREADS:-2}"
mkdir -p "$out"
"$build_dir/bench/marker_fit_data" "$out/data" "$frames"
echo "load before: $(uptime)"
/usr/bin/time -f "wall %e s, user %U s, system %S s, peak %M KiB" \
  "$build_dir/cli/avsi" corpus fit-markers "$out/data/recordings.csv" --out "$out/corpus" --threads "$threads"
echo "load after: $(uptime)"
