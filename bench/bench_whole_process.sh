#!/usr/bin/env bash
# Whole avsi processes as a user runs them (issue 21), side by side in one
# run with what a user would otherwise pick, on files this script makes:
#   start-up      avsi --version
#   synth         avsi synth of a short sentence (from its phones, and from text through espeak-ng)
#   vocode        avsi vocode of 9 minutes of 22.05 kHz speech  vs  the numpy/scipy vocoder
#                 (bench/reference_vocoder.py, same settings) and sox reading + writing the same file;
#                 and with each other carrier (sine, low-noise, pulse-train, Poisson) and a CI
#                 simulation (8 bands, 250 pulses/s, 8 dB/octave spread, 2 mm shift, 4-of-8)
#   stoi          avsi stoi of those 9 minutes against their vocoded version
#   render        avsi render of a sentence to MP4  vs  ffmpeg encoding the same frames (PNG, libx264)
#   score         avsi score of a 25-subject study (simulated answers to the default protocol's lists)
#   phonemes      avsi score --phonemes of the same 25 subjects with all 111 answers each (warm-up and
#                 practice counted as test): keywords, Festival transcription, alignment, information;
#                 and of the Swedish protocol's 25 subjects (espeak-ng's Swedish transcription)
# Each median of RUNS runs (default 7, at least 5), the mean user and system
# CPU, and the peak resident memory of one more run (/usr/bin/time). The tasks run in
# rounds, each round every task once in turn after a warm-up round
# (bench/interleave.py, which says why). Prints a Markdown table (also
# written to OUT/table.md, with each task's JSON beside it).
#
#   bench/bench_whole_process.sh [BUILD_DIR]       (default build)
#   RUNS=9 OUT=out/bench-whole AVSI_BEFORE=/path/to/older/avsi bench/bench_whole_process.sh build
#   ONLY='vocode|sox' bench/bench_whole_process.sh build   (only the tasks whose names match)
#
# AVSI_BEFORE: another avsi executable timed on the same tasks (e.g. one
# built from an older commit) for a before/after column.
#
# Needs (Debian, installed by scripts/install-deps): sox, ffmpeg, espeak-ng,
# time, python3-numpy, python3-scipy. The machine's load is printed
# before and after; on a shared machine compare CPU time rather than wall time.
set -euo pipefail

build_dir="${1:-build}"
runs="${RUNS:-7}"
out="${OUT:-out/bench-whole}"
before="${AVSI_BEFORE:-}"
only="${ONLY:-}"  # extended regular expression on the task names; empty: all
if [[ -n "$before" ]]; then
  [[ -x "$before" ]] || { echo "bench_whole_process: AVSI_BEFORE=$before is not an executable" >&2; exit 1; }
  before="$(cd "$(dirname "$before")" && pwd)/$(basename "$before")"  # before the cd below
fi
repo="$(cd "$(dirname "$0")/.." && pwd)"
avsi="$(cd "$build_dir" && pwd)/cli/avsi"
python=/usr/bin/python3  # Debian's, where python3-numpy and python3-scipy install
for tool in sox ffmpeg espeak-ng /usr/bin/time "$python"; do
  command -v "$tool" >/dev/null || { echo "bench_whole_process: $tool is missing (see the header)" >&2; exit 1; }
done
"$python" -c "import numpy, scipy" 2>/dev/null || {
  echo "bench_whole_process: $python lacks numpy/scipy (apt-get install python3-numpy python3-scipy)" >&2; exit 1; }
[[ -x "$avsi" ]] || { echo "bench_whole_process: $avsi not built" >&2; exit 1; }
((runs >= 5)) || { echo "bench_whole_process: RUNS must be at least 5" >&2; exit 1; }
mkdir -p "$out"
out="$(cd "$out" && pwd)"
work="$out/work"
mkdir -p "$work"
cd "$work"

load_before="$(uptime)"
echo "load before: $load_before"
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs)"

# --- Inputs -----------------------------------------------------------------
# wanted NAME...: whether any of these tasks is selected by ONLY.
wanted() {
  [[ -z "$only" ]] && return 0
  local name
  for name in "$@"; do grep -Eq -- "$only" <<<"$name" && return 0; done
  return 1
}
sentence="The boy fell from the window."
if [[ ! -f speech9.wav ]]; then
  # 9 minutes of espeak-ng speech (22.05 kHz mono): the corpus sentences read
  # one after another, repeated, cut at 540 s.
  cut -d, -f2 "$repo/protocols/corpus/sentences.csv" | tail -n +2 > sentences.txt
  espeak-ng -v en-us -w part.wav -f sentences.txt
  sox part.wav part.wav part.wav part.wav speech9.wav trim 0 540
  rm -f part.wav
fi
if wanted "synth, phones of a sentence" "render a sentence (MP4)" "encode its frames: ffmpeg"; then
  "$avsi" phones --text "$sentence" --wav sentence.wav --out sentence.tsv 2>/dev/null
  "$avsi" synth --phones sentence.tsv --out sentence.csv 2>/dev/null
fi
if wanted "score 25 subjects" "score --phonemes, 25 x 111 answers" && [[ ! -f lists.csv ]]; then
  "$avsi" design "$repo/protocols/beskow2004-en.toml" --subjects 25 --out lists.csv >/dev/null 2>&1
fi
if wanted "score 25 subjects" "score --phonemes, 25 x 111 answers" && [[ ! -f responses.csv ]]; then
  # Every test trial of the 25 subjects answered with each word of the
  # sentence kept with probability 0.7 (seeded), as scripts/dry-run-responses does.
  "$python" - "$repo/protocols/corpus/sentences.csv" lists.csv responses.csv <<'EOF'
import csv, random, re, sys
corpus = {r["id"]: r["text"] for r in csv.DictReader(open(sys.argv[1], newline=""))}
rng = random.Random(1)
with open(sys.argv[3], "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(["subject", "session", "trial", "phase", "condition", "list", "sentence", "response"])
    for row in csv.DictReader(open(sys.argv[2], newline="")):
        words = re.findall(r"[A-Za-z']+", corpus[row["sentence"]])
        answer = " ".join(x for x in words if rng.random() < 0.7)
        w.writerow([row["subject"], 1, row["position"], row["phase"], row["condition"], row["list"], row["sentence"], answer])
EOF
fi
if wanted "score --phonemes, 25 x 111 answers" && [[ ! -f responses111.csv ]]; then
  # The same answers with every trial (15 warm-up, 6 practice, 90 test) scored: 25 x 111.
  sed -e '1!s/^\([^,]*,[^,]*,[^,]*\),\(warmup\|practice\),/\1,test,/' responses.csv > responses111.csv
fi
if wanted "score --phonemes, Swedish, 25 x 111 answers" && [[ ! -f responses111-sv.csv ]]; then
  # The same for the Swedish protocol: its lists, its sentences' words (å ä ö kept), every trial scored.
  "$avsi" design "$repo/protocols/beskow2004-sv.toml" --subjects 25 --out lists-sv.csv >/dev/null 2>&1
  "$python" - "$repo/protocols/languages/sv/sentences/sentences.csv" lists-sv.csv responses111-sv.csv <<'EOF'
import csv, random, re, sys
corpus = {r["id"]: r["text"] for r in csv.DictReader(open(sys.argv[1], newline="", encoding="utf-8"))}
rng = random.Random(1)
with open(sys.argv[3], "w", newline="", encoding="utf-8") as f:
    w = csv.writer(f)
    w.writerow(["subject", "session", "trial", "phase", "condition", "list", "sentence", "response"])
    for row in csv.DictReader(open(sys.argv[2], newline="")):
        words = re.findall(r"[^\W\d_]+", corpus[row["sentence"]])
        answer = " ".join(x for x in words if rng.random() < 0.7)
        w.writerow([row["subject"], 1, row["position"], "test", row["condition"], row["list"], row["sentence"], answer])
EOF
fi
# The frames of the sentence as PNGs, for ffmpeg to encode.
fps=60
pattern="frames/frame_%05d.png"
if wanted "encode its frames: ffmpeg"; then
  rm -rf frames && "$avsi" render --traj sentence.csv --out frames/ 2>/dev/null
  fps=$(awk -F, 'NR==2{t0=$1} NR==3{printf "%.0f", 1/($1-t0)}' sentence.csv)
  [[ -f frames/frame_00000.png ]] || { echo "bench_whole_process: expected frames/frame_00000.png from avsi render" >&2; exit 1; }
fi
if wanted "stoi 9 min"; then
  "$avsi" vocode speech9.wav vocoded9.wav 2>/dev/null
fi

# --- Timing -----------------------------------------------------------------
# name|command (run without a shell; quotes group words)
tasks=(
  "startup: avsi --version|$avsi --version"
  "synth, phones of a sentence|$avsi synth --phones sentence.tsv --out s1.csv"
  "synth, text of a sentence (espeak-ng)|$avsi synth --text '$sentence' --out s2.csv"
  "vocode 9 min|$avsi vocode speech9.wav v.wav"
  "vocode 9 min: numpy/scipy|$python $repo/bench/reference_vocoder.py speech9.wav r.wav"
  "vocode 9 min, sine carrier|$avsi vocode --carrier sine speech9.wav vs.wav"
  "vocode 9 min, low-noise carrier|$avsi vocode --carrier low-noise speech9.wav vl.wav"
  "vocode 9 min, pulse-train carrier|$avsi vocode --carrier pulse-train speech9.wav vp.wav"
  "vocode 9 min, poisson carrier|$avsi vocode --carrier poisson speech9.wav vq.wav"
  "vocode 9 min, CI simulation|$avsi vocode --bands 8 --low-hz 250 --high-hz 8000 --carrier pulse-train --pulse-rate 250 --current-spread db-per-octave --spread-slope-db 8 --insertion-shift-mm 2 --n-of-m 4 speech9.wav vc.wav"
  "read + write 9 min: sox|sox speech9.wav x.wav"
  "stoi 9 min|$avsi stoi speech9.wav vocoded9.wav"
  "render a sentence (MP4)|$avsi render --traj sentence.csv --audio sentence.wav --out m.mp4"
  "encode its frames: ffmpeg|ffmpeg -loglevel error -y -framerate $fps -i $pattern -c:v libx264 -crf 18 -pix_fmt yuv420p f.mp4"
  "score 25 subjects|$avsi score --protocol $repo/protocols/beskow2004-en.toml --responses responses.csv --out scores"
  "score --phonemes, 25 x 111 answers|$avsi score --protocol $repo/protocols/beskow2004-en.toml --responses responses111.csv --out pscores --phonemes"
  "score --phonemes, Swedish, 25 x 111 answers|$avsi score --protocol $repo/protocols/beskow2004-sv.toml --responses responses111-sv.csv --out pscores-sv --phonemes"
)
if [[ -n "$before" ]]; then
  tasks+=(
    "before: startup|$before --version"
    "before: synth, phones|$before synth --phones sentence.tsv --out b1.csv"
    "before: synth, text|$before synth --text '$sentence' --out b2.csv"
    "before: vocode 9 min|$before vocode speech9.wav bv.wav"
    "before: stoi 9 min|$before stoi speech9.wav vocoded9.wav"
    "before: render a sentence|$before render --traj sentence.csv --audio sentence.wav --out bm.mp4"
    "before: score 25 subjects|$before score --protocol $repo/protocols/beskow2004-en.toml --responses responses.csv --out bscores"
  )
fi

# Every selected task once a round, in turn (bench/interleave.py: so that
# a machine whose speed drifts slows them all alike), after a warm-up round.
selected="$out/tasks.txt"
: > "$selected"
for task in "${tasks[@]}"; do
  [[ -z "$only" ]] || grep -Eq -- "$only" <<<"${task%%|*}" || continue
  printf '%s\n' "$task" >> "$selected"
done
[[ -s "$selected" ]] || { echo "bench_whole_process: ONLY='$only' selects no task" >&2; exit 1; }
"$python" "$repo/bench/interleave.py" "$selected" "$out" "$runs" 1

table="$out/table.md"
{
  echo "| task | median wall (ms) | CPU user + sys (ms) | peak RSS (MiB) |"
  echo "| --- | ---: | ---: | ---: |"
} > "$table"
declare -A median cpu
while IFS= read -r task; do
  name="${task%%|*}"
  command="${task#*|}"
  json="$out/$(printf '%s' "$name" | tr -c 'A-Za-z0-9' '_').json"
  if "$python" -c "import json,sys; sys.exit('failed' not in json.load(open(sys.argv[1]))['results'][0])" "$json"; then
    # An older executable may not read today's data files: its row says so.
    [[ "$name" == before:* ]] || { echo "bench_whole_process: failed: $command" >&2; exit 1; }
    echo "| $name | failed (\`$command\` exits non-zero) | | |" | tee -a "$table"
    continue
  fi
  read -r med cpu rss < <("$python" -c "import json,sys; r=json.load(open(sys.argv[1]))['results'][0]; print(r['median']*1e3, (r['user']+r['system'])*1e3, r['max_rss_kib'] / 1024)" "$json")
  median["$name"]=$med
  cpu["$name"]=$cpu
  printf '| %s | %.1f | %.1f | %.1f |\n' "$name" "$med" "$cpu" "$rss" | tee -a "$table"
done < "$selected"
ratio() { "$python" -c "print(f'{$1 / $2:.2f}')"; }
# "a / b: wall x (CPU y)", medians of wall time, means of CPU time.
ratios() {
  [[ -n "${median[$1]:-}" && -n "${median[$2]:-}" ]] || { echo "n/a"; return; }
  echo "$(ratio "${median[$1]}" "${median[$2]}")x wall ($(ratio "${cpu[$1]}" "${cpu[$2]}")x CPU)"
}
{
  echo
  if [[ -n "${median['vocode 9 min']:-}" ]]; then
    echo "vocode 9 min, numpy/scipy / avsi: $(ratios 'vocode 9 min: numpy/scipy' 'vocode 9 min');" \
         "avsi at $(ratio 540000 "${median['vocode 9 min']}")x real time wall, $(ratio 540000 "${cpu['vocode 9 min']}")x on CPU time"
  fi
  echo "sox read + write 9 min / avsi vocode: $(ratios 'read + write 9 min: sox' 'vocode 9 min')"
  echo "ffmpeg encoding the frames / avsi render (render + encode + mux): $(ratios 'encode its frames: ffmpeg' 'render a sentence (MP4)')"
  if [[ -n "$before" ]]; then
    for t in "startup:startup: avsi --version" "synth, phones:synth, phones of a sentence" "synth, text:synth, text of a sentence (espeak-ng)" \
             "vocode 9 min:vocode 9 min" "stoi 9 min:stoi 9 min" "render a sentence:render a sentence (MP4)" "score 25 subjects:score 25 subjects"; do
      echo "before / now, ${t%%:*}: $(ratios "before: ${t%%:*}" "${t#*:}")"
    done
  fi
} | tee -a "$table"
echo "load before: $load_before; after: $(uptime)" | tee -a "$table"
echo "table: $table"
