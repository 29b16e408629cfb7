#!/usr/bin/env python3
"""Independent numpy reference for phoneme scoring (analysis/phoneme_scoring.h).

Reads the hand-built case (tests/data/analysis/phonemes: corpus.csv,
responses.csv, pronunciations.tsv) and the phone features of
protocols/languages/en/phones.tsv, aligns every test answer as the header states
(words: deletion/insertion 0.5, substitution d(a, b) / (|a| + |b|); phones:
deletion/insertion 1, substitution min(2, 0.5 + 0.25 * L1 distance of the 16
features without stress); the backtrace from the end prefers substitution,
then deletion, then insertion) and compares every row with
expected_phonemes.csv, the outcomes worked out by hand; then computes the
information transmitted per condition and feature grouping (Miller & Nicely
T, Miller-Madow corrected, RTI; analysis/include/avsi/analysis/
phoneme_information.h) and compares it with expected_information.csv. Exit status 0 when
all rows agree, 1 otherwise (each difference printed).

    tests/analysis/phoneme_reference.py --case tests/data/analysis/phonemes \
        --phones protocols/languages/en/phones.tsv [--write out.csv]
"""
import argparse
import csv
import re
import sys

import numpy as np


def read_features(path):
    """symbol -> numpy vector of the 16 features before `stress`."""
    rows = [line.rstrip("\n").split("\t") for line in open(path, encoding="utf-8")
            if line.strip() and not line.startswith("#")]
    header = rows[0]
    first, last = header.index("vowel"), header.index("stress")
    return {r[0]: np.array([float(x) for x in r[first:last]]) for r in rows[1:] if r and r[0]}


def read_pronunciations(path):
    out = {}
    for line in open(path, encoding="utf-8"):
        if line.startswith("#") or not line.strip():
            continue
        word, phones = line.rstrip("\n").split("\t")
        out[word] = [re.sub(r"[0-9]$", "", p) for p in phones.split()]
    return out


def words_of(text):
    return [w.strip("'") for w in re.split(r"[^a-z0-9']+", text.lower()) if w.strip("'")]


def edit_alignment(n, m, sub, deletion, insertion):
    """Weighted edit distance: (cost, pairs), pairs as (i or None, j or None)."""
    d = np.zeros((n + 1, m + 1))
    d[1:, 0] = np.arange(1, n + 1) * deletion
    d[0, 1:] = np.arange(1, m + 1) * insertion
    for i in range(1, n + 1):
        for j in range(1, m + 1):
            d[i, j] = min(d[i - 1, j - 1] + sub[i - 1, j - 1], d[i - 1, j] + deletion, d[i, j - 1] + insertion)
    pairs, i, j = [], n, m
    while i > 0 or j > 0:
        if i > 0 and j > 0 and d[i, j] == d[i - 1, j - 1] + sub[i - 1, j - 1]:
            i, j = i - 1, j - 1
            pairs.append((i, j))
        elif i > 0 and d[i, j] == d[i - 1, j] + deletion:
            i -= 1
            pairs.append((i, None))
        else:
            j -= 1
            pairs.append((None, j))
    return d[n, m], pairs[::-1]


def phone_cost(features, a, b):
    if a == b:
        return 0.0
    return min(2.0, 0.5 + 0.25 * float(np.abs(features[a] - features[b]).sum()))


def align_phones(features, t, r):
    sub = np.array([[phone_cost(features, a, b) for b in r] for a in t]).reshape(len(t), len(r))
    return edit_alignment(len(t), len(r), sub, 1.0, 1.0)


def align_words(features, pron, tw, rw):
    sub = np.zeros((len(tw), len(rw)))
    for i, a in enumerate(tw):
        for j, b in enumerate(rw):
            if a != b:
                sub[i, j] = align_phones(features, pron[a], pron[b])[0] / (len(pron[a]) + len(pron[b]))
    return edit_alignment(len(tw), len(rw), sub, 0.5, 0.5)


def score_answer(features, pron, subject, condition, sentence, target_text, answer):
    tw, rw = words_of(target_text), words_of(answer)
    rows, position = [], 0

    def emit(t, r):
        nonlocal position
        if t is not None:
            position += 1
        outcome = "inserted" if t is None else "deleted" if r is None else "correct" if t == r else "substituted"
        rows.append([subject, condition, sentence, str(position), t or "", r or "", outcome])

    for i, j in align_words(features, pron, tw, rw)[1]:
        t = pron[tw[i]] if i is not None else []
        r = pron[rw[j]] if j is not None else []
        for a, b in align_phones(features, t, r)[1]:
            emit(t[a] if a is not None else None, r[b] if b is not None else None)
    return rows


# Feature groupings of analysis/include/avsi/analysis/phoneme_information.h,
# written from the feature columns of phones.tsv.
NAMES = ["vowel", "bilabial", "labiodental", "dental", "retroflex", "alveolar", "velar", "nasal", "fricative", "stop",
         "release", "voiced", "open", "front", "rounded", "protruded"]


def category(features, grouping, phone, as_response):
    if phone is None:
        return "-"
    f = dict(zip(NAMES, features[phone]))
    is_rounded = f["rounded"] >= 0.5 or f["protruded"] >= 0.5
    if grouping in ("voicing", "manner", "place") and f["vowel"] == 1:
        return "other" if as_response else None
    if grouping == "voicing":
        return "voiced" if f["voiced"] else "voiceless"
    if grouping == "manner":
        if f["nasal"]:
            return "nasal"
        if f["stop"] and f["fricative"]:
            return "affricate"
        return "stop" if f["stop"] else "fricative" if f["fricative"] else "approximant"
    if grouping == "place":
        if f["bilabial"] and f["velar"]:
            return "labial-velar"
        for name in ("bilabial", "labiodental", "dental", "alveolar", "retroflex", "velar"):
            if f[name]:
                return name
        return "other place"
    if grouping == "rounding":
        return "rounded" if is_rounded else "spread"
    # viseme: core's VisemeClass (core/include/avsi/core/sentence_profile.h)
    consonant = f["vowel"] == 0
    if consonant and f["labiodental"]:
        return "labiodental"
    if consonant and f["dental"]:
        return "dental"
    if consonant and f["bilabial"] and not is_rounded:
        return "bilabial"
    if is_rounded:
        return "rounded"
    if not consonant:
        return "open vowel" if f["open"] >= 1 else "spread vowel"
    return "lingual"


def transmission(counts):
    """Miller & Nicely T and H(x) in bits, plug-in and Miller-Madow corrected, and RTI."""
    n = counts.sum()
    p = counts / n
    px, py = p.sum(axis=1), p.sum(axis=0)

    def h(q):
        q = q[q > 0]
        return float(-(q * np.log2(q)).sum())

    t = h(px) + h(py) - h(p.ravel())
    per_bin = 1.0 / (2.0 * n * np.log(2.0))
    mx, my, mxy = (px > 0).sum(), (py > 0).sum(), (p > 0).sum()
    hx_mm = h(px) + (mx - 1) * per_bin
    t_mm = t - (mxy - mx - my + 1) * per_bin
    return {"phones": int(n), "h_x": h(px), "t_plugin": t, "h_x_corrected": hx_mm, "t_corrected": t_mm,
            "rti": t_mm / hx_mm}


def information(features, rows):
    """condition -> grouping -> transmission, over the pooled rows."""
    out = {}
    for grouping in ("voicing", "manner", "place", "rounding", "viseme"):
        pairs = []
        for r in rows:
            if r[6] == "inserted":
                continue
            x = category(features, grouping, r[4], False)
            if x is not None:
                pairs.append((r[1], x, category(features, grouping, r[5] or None, True)))
        xs = sorted({x for _, x, _ in pairs})
        ys = sorted({y for _, _, y in pairs})
        for condition in dict.fromkeys(c for c, _, _ in pairs):
            counts = np.zeros((len(xs), len(ys)))
            for c, x, y in pairs:
                if c == condition:
                    counts[xs.index(x), ys.index(y)] += 1
            out.setdefault(condition, {})[grouping] = transmission(counts)
    return out


def compare_information(computed, path):
    """Differences between the computed values and expected_information.csv (within 1e-9)."""
    bad = 0
    expected = list(csv.DictReader(open(path, encoding="utf-8")))
    for e in expected:
        got = computed[e["condition"]][e["feature"]]
        for key in ("phones", "h_x", "t_plugin", "h_x_corrected", "t_corrected", "rti"):
            if abs(float(e[key]) - float(got[key])) > 1e-9:
                print(f"{path}: {e['condition']} {e['feature']} {key}: expected {e[key]}, reference computes {got[key]}")
                bad += 1
    if len(expected) != sum(len(v) for v in computed.values()):
        print(f"{path}: {len(expected)} rows, reference computes {sum(len(v) for v in computed.values())}")
        bad += 1
    return bad


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--case", required=True)
    ap.add_argument("--phones", required=True)
    ap.add_argument("--write")
    ap.add_argument("--write-information")
    args = ap.parse_args()
    features = read_features(args.phones)
    pron = read_pronunciations(f"{args.case}/pronunciations.tsv")
    corpus = {r["id"]: r["text"] for r in csv.DictReader(open(f"{args.case}/corpus.csv", encoding="utf-8"))}
    rows = []
    for r in csv.DictReader(open(f"{args.case}/responses.csv", encoding="utf-8")):
        if r["phase"] == "test":
            rows += score_answer(features, pron, r["subject"], r["condition"], r["sentence"], corpus[r["sentence"]],
                                 r["response"])
    header = ["subject", "condition", "sentence", "position", "target", "response", "outcome"]
    if args.write:
        with open(args.write, "w", newline="", encoding="utf-8") as f:
            csv.writer(f, lineterminator="\n").writerows([header] + rows)
    expected = list(csv.reader(open(f"{args.case}/expected_phonemes.csv", encoding="utf-8")))
    bad = 0
    if expected[0] != header or len(expected) - 1 != len(rows):
        print(f"expected {len(expected) - 1} rows with header {expected[0]}, computed {len(rows)}")
        bad += 1
    for k, (e, g) in enumerate(zip(expected[1:], rows), start=2):
        if e != g:
            print(f"expected_phonemes.csv:{k}: expected {e}, reference computes {g}")
            bad += 1
    info = information(features, rows)
    if args.write_information:
        keys = ["phones", "h_x", "t_plugin", "h_x_corrected", "t_corrected", "rti"]
        with open(args.write_information, "w", newline="", encoding="utf-8") as f:
            w = csv.writer(f, lineterminator="\n")
            w.writerow(["condition", "feature"] + keys)
            for condition, groupings in info.items():
                for grouping, t in groupings.items():
                    w.writerow([condition, grouping] + [t[k] if k == "phones" else repr(float(t[k])) for k in keys])
    bad += compare_information(info, f"{args.case}/expected_information.csv")
    print(f"{len(rows)} phone rows, information of {sum(len(v) for v in info.values())} condition x feature cells, "
          f"{bad} differences")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
