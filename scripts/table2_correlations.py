#!/usr/bin/env python3
"""How independent the reference speaker is of the models it trains
(docs/table2.md): per phone and parameter, the mean value at the centres of
the phone's segments over a corpus, for the corpus tracks and for
each model's trajectory on the same phones, and the rule model's table
(protocols/rule_targets.tsv, where it specifies the value). Prints the
Pearson r of the corpus's phone-centre means with each, over the phone ×
parameter pairs both have, and the mean absolute difference.

Usage (from the repository root, after `avsi corpus reference --out out/refcorpus`):
  python3 scripts/table2_correlations.py out/refcorpus protocols/models/{rule,cohen-massaro,mpeg4-cohen-massaro,ohman,ann1,ann2}.json
"""
import csv
import json
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
AVSI = os.environ.get("AVSI", os.path.join(ROOT, "build", "cli", "avsi"))
PARAMS = ["jaw_rotation", "lip_rounding", "upper_lip_retraction", "upper_lip_raise", "lower_lip_retraction",
          "lower_lip_depression", "mouth_corner_stretch_left", "mouth_corner_stretch_right", "jaw_thrust", "jaw_shift"]


def read_track(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["time_s"]) for r in rows])
    v = np.array([[float(r[p]) for p in PARAMS] for r in rows])
    return t, v


def read_phones(path):
    out = []
    with open(path) as f:
        for line in f:
            parts = line.split()
            if len(parts) != 3 or parts[0] == "start_s":
                continue
            out.append((float(parts[0]), float(parts[1]), re.sub(r"[012]$", "", parts[2])))
    return out


def centre_means(pairs):
    """pairs: list of (phones, times, values) → {phone: mean parameter vector at segment centres}."""
    sums, counts = {}, {}
    for phones, t, v in pairs:
        for start, end, ph in phones:
            if ph == "sil":
                continue
            k = int(np.argmin(np.abs(t - 0.5 * (start + end))))
            sums[ph] = sums.get(ph, 0) + v[k]
            counts[ph] = counts.get(ph, 0) + 1
    return {ph: sums[ph] / counts[ph] for ph in sums}


def rule_table():
    path = os.path.join(ROOT, "protocols", "rule_targets.tsv")
    with open(path) as f:
        lines = [l for l in f if l.strip() and not l.startswith("#")]
    table = {}
    for r in csv.DictReader(lines, delimiter="\t"):
        table[r["phone"]] = np.array([np.nan if r[p] == "-" else float(r[p]) for p in PARAMS])
    return table


def compare(reference, other):
    xs, ys = [], []
    for ph, ref in reference.items():
        if ph not in other:
            continue
        for q in range(len(PARAMS)):
            if PARAMS[q] == "jaw_shift":  # drift only
                continue
            if np.isfinite(other[ph][q]) and np.isfinite(ref[q]):
                xs.append(ref[q])
                ys.append(other[ph][q])
    xs, ys = np.array(xs), np.array(ys)
    return float(np.corrcoef(xs, ys)[0, 1]), float(np.mean(np.abs(xs - ys))), len(xs)


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    corpus = sys.argv[1]
    models = sys.argv[2:]
    with open(os.path.join(corpus, "corpus.json")) as f:
        manifest = json.load(f)
    # Every utterance: the speaker's phone targets do not depend on the split.
    data = []
    for u in manifest["utterances"]:
        t, v = read_track(os.path.join(corpus, u["track"]))
        data.append((u, read_phones(os.path.join(corpus, u["labels"])), t, v))
    reference = centre_means([(ph, t, v) for _, ph, t, v in data])
    rows = [("rule_targets.tsv (the rule model's table)",) + compare(reference, rule_table())]
    with tempfile.TemporaryDirectory() as tmp:
        for m in models:
            pairs = []
            for u, ph, t, _ in data:
                out = os.path.join(tmp, "traj.csv")
                subprocess.run([AVSI, "synth", "--model", m, "--phones", os.path.join(corpus, u["labels"]),
                                "--fps", "60", "--out", out], check=True, capture_output=True)
                mt, mv = read_track(out)
                pairs.append((ph, mt, mv))
            rows.append((os.path.basename(m) + " on the same phones",) + compare(reference, centre_means(pairs)))
    print(f"Corpus {manifest.get('name')} ({corpus}): {len(data)} utterances; phone-centre means, "
          f"{len(reference)} phones x 9 parameters (jaw_shift left out).\n")
    print("| compared with | Pearson r | mean abs difference (units) | pairs |\n| --- | ---: | ---: | ---: |")
    for name, r, mad, n in rows:
        print(f"| {name} | {r:.3f} | {mad:.3f} | {n} |")


if __name__ == "__main__":
    main()
