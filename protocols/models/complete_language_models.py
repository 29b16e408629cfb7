#!/usr/bin/env python3
"""Completes a language's trained per-phone models (models/<lang>/
cohen-massaro.json and ohman.json) for the phones of its table that the
reference corpus never had, so every phone espeak-ng's voice can produce
has an entry:

  * a vowel seen in training only stressed (or only unstressed), e.g. German
    YH1 without YH0: the trained entry is copied to the phone's base symbol
    (YH), which synthesis uses for a stress variant the table lacks
    (find_phone_entry in synth/include/avsi/synth/control_model.h);
  * a phone not seen at all (Swedish RT, retroflex /ʈ/): a copy of the
    nearest phone by the 17 features of protocols/languages/<lang>/phones.tsv
    (L1 distance; ties by symbol) that has a trained entry, under the base
    symbol (RD for RT: they differ in voicing only, which the face does not
    show).

Each copy is listed in the model's provenance notes. Entries the training
gave are never changed. Run from anywhere: python3 complete_language_models.py sv
"""
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
PROTO = os.path.dirname(HERE)
FEATURES = ["vowel", "bilabial", "labiodental", "dental", "retroflex", "alveolar", "velar", "nasal", "fricative",
            "stop", "release", "voiced", "open", "front", "rounded", "protruded", "stress"]


def language_phones(lang):
    """(symbol, is vowel, features) of each phone of the language's table."""
    path = os.path.join(PROTO, "languages", lang, "phones.tsv")
    with open(path, encoding="utf-8") as f:
        lines = [line.rstrip("\n") for line in f if line.strip() and not line.startswith("#")]
    header = lines[0].split("\t")
    missing = [c for c in ["symbol", "class"] + FEATURES if c not in header]
    if missing:
        sys.exit(f"{path}:1: error: header: missing columns {', '.join(missing)}")
    out = []
    for line in lines[1:]:
        row = dict(zip(header, line.split("\t")))
        if row["class"] == "silence":
            continue
        out.append((row["symbol"], row["class"] == "vowel", [float(row[c]) for c in FEATURES]))
    return out


def entry_of(table, symbol, stress):
    """The entry synthesis finds for symbol with stress ("0", "1" or "" for consonants), or None."""
    return table.get(symbol + stress, table.get(symbol))


def trained_symbol(table, symbol):
    """A key of the table for symbol: itself, or a stress variant (1 first)."""
    for key in (symbol, symbol + "1", symbol + "0"):
        if key in table:
            return key
    return None


def complete(table, phones, vowels_only=None):
    """Adds base entries to table (a dict symbol -> entry); returns the notes."""
    notes = []
    features = {symbol: f for symbol, _, f in phones}
    for symbol, is_vowel, f in phones:
        if vowels_only is not None and is_vowel != vowels_only:
            continue
        stresses = ("0", "1") if is_vowel else ("",)
        if all(entry_of(table, symbol, s) is not None for s in stresses):
            continue
        own = trained_symbol(table, symbol)
        if own is not None:
            table[symbol] = table[own]
            notes.append(f"{symbol} = {own}")
            continue
        candidates = [(sum(abs(a - b) for a, b in zip(f, features[other])), other)
                      for other, other_vowel, _ in phones
                      if other != symbol and other_vowel == is_vowel and trained_symbol(table, other) is not None]
        if not candidates:
            sys.exit(f"error: no trained phone to copy for {symbol}")
        _, nearest = min(candidates)
        table[symbol] = table[trained_symbol(table, nearest)]
        notes.append(f"{symbol} = {trained_symbol(table, nearest)} (nearest by features)")
    return notes


def update(path, tables):
    with open(path, encoding="utf-8") as f:
        model = json.load(f)
    notes = []
    for key, vowels_only, phones in tables:
        notes += complete(model[key], phones, vowels_only)
    if notes:
        model["provenance"]["notes"] += (" Completed by complete_language_models.py for phones of the language "
                                         "table the training data lacked (base entries, copied): " +
                                         ", ".join(notes) + ".")
        with open(path, "w", encoding="utf-8") as f:
            json.dump(model, f, indent=2, sort_keys=True, ensure_ascii=False)
            f.write("\n")
    print(f"{path}: {', '.join(notes) if notes else 'complete'}")


def main(lang):
    phones = language_phones(lang)
    update(os.path.join(HERE, lang, "cohen-massaro.json"), [("phones", None, phones)])
    update(os.path.join(HERE, lang, "ohman.json"), [("vowels", True, phones), ("consonants", False, phones)])


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: complete_language_models.py LANG (sv, de)")
    main(sys.argv[1])
