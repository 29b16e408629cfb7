#!/usr/bin/env python3
"""Measure `avsi stream` emission latency end to end, through the pipes.

Plays a timed phone file (TSV start_s, end_s, phone) into `avsi stream` in
real time, as a phoneme recogniser would: each phone is cut into pieces of
--piece-ms and each piece is written at the wall time its end is reached.
`avsi stream --latency-log` times each frame's emission against that clock
(latency = emission time - frame time). The issue's bound for a frame at time
t is t + look-ahead + one frame; a piece of length g adds up to g on top,
because the phone at t + look-ahead is only known once its piece has ended.

    python3 bench/stream_latency.py --avsi build/cli/avsi \
        --model protocols/models/ann2.json --phones out/refcorpus/labels/ref001.tsv

Prints median / 95th percentile / max latency over the frames emitted while
input was still arriving (the last look-ahead frames can only come at end of
input) and whether every one met the bound.
"""
import argparse
import csv
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def read_phones(path):
    rows = []
    with open(path, newline="") as f:
        for line_no, row in enumerate(csv.reader(f, delimiter="\t"), start=1):
            if not row or row[0].startswith("#") or row[0] == "start_s":
                continue
            try:
                rows.append((float(row[0]), float(row[1]), row[2]))
            except (ValueError, IndexError):
                sys.exit(f"{path}:{line_no}: error: expected 'start_s<TAB>end_s<TAB>phone', got {row!r}")
    if not rows:
        sys.exit(f"{path}: error: no phones")
    return rows


def pieces(phones, piece_s):
    for start, end, label in phones:
        t = start
        while t < end - 1e-9:
            stop = min(end, t + piece_s)
            yield t, stop, label
            t = stop


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--avsi", default="build/cli/avsi", help="the avsi executable (default %(default)s)")
    ap.add_argument("--model", default="protocols/models/ann2.json", help="ANN model file (default %(default)s)")
    ap.add_argument("--phones", required=True, help="timed phones, TSV start_s end_s phone")
    ap.add_argument("--piece-ms", type=float, default=2.0,
                    help="length of each piece sent to the stream (default %(default)s ms)")
    ap.add_argument("--startup-s", type=float, default=3.0,
                    help="wait this long for avsi to load the model before streaming (default %(default)s s);"
                         " the stream's clock starts at the first line it reads")
    ap.add_argument("--log", help="keep the per-frame latency CSV here")
    args = ap.parse_args()

    config = json.loads(Path(args.model).read_text())["config"]
    fps = float(config["fps"])
    look_ahead = int(config["look_ahead"])
    bound_s = (look_ahead + 1) / fps + args.piece_ms / 1000.0

    with tempfile.TemporaryDirectory() as tmp:
        log = Path(args.log) if args.log else Path(tmp) / "latency.csv"
        proc = subprocess.Popen([args.avsi, "stream", "--model", args.model, "--latency-log", str(log)],
                                stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True)
        time.sleep(args.startup_s)
        origin = None
        for start, end, label in pieces(read_phones(args.phones), args.piece_ms / 1000.0):
            if origin is None:
                origin = time.monotonic() - end
            delay = origin + end - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            proc.stdin.write(f"{start:.6f} {end:.6f} {label}\n")
            proc.stdin.flush()
        input_end = time.monotonic() - origin
        proc.stdin.close()
        if proc.wait() != 0:
            sys.exit(f"avsi stream failed with exit code {proc.returncode}")
        with open(log, newline="") as f:
            frames = [(float(r["time_s"]), float(r["latency_s"])) for r in csv.DictReader(f)]

    live = [lat for t, lat in frames if t + lat < input_end - 1e-3]
    if not live:
        sys.exit("no frames were emitted while input was arriving")
    live_sorted = sorted(live)
    p95 = live_sorted[min(len(live_sorted) - 1, int(0.95 * len(live_sorted)))]
    over = sum(1 for lat in live if lat > bound_s)
    print(f"model {args.model}: {fps:g} fps, look-ahead {look_ahead} frames; pieces of {args.piece_ms:g} ms")
    print(f"frames emitted during input: {len(live)} of {len(frames)}")
    print(f"latency: median {1000 * statistics.median(live):.1f} ms, 95th percentile {1000 * p95:.1f} ms, "
          f"max {1000 * max(live):.1f} ms")
    print(f"bound (look-ahead + 1 frame + piece): {1000 * bound_s:.1f} ms; frames over it: {over}")
    return 1 if over else 0


if __name__ == "__main__":
    sys.exit(main())
