#!/usr/bin/env python3
"""Writes the starting point of a language's MPEG-4 Cohen-Massaro model:
models/<lang>/mpeg4-cohen-massaro.visemes.json (English's trained viseme set,
its phones replaced by the language's: each phone of
protocols/languages/<lang>/phones.tsv in the viseme its `mpeg4_viseme`
column names) and models/<lang>/mpeg4-cohen-massaro.json (English's trained
dominance parameters with that set). `avsi train --model mpeg4-cohen-massaro
--init` on it then trains the targets on the language's reference corpus
(docs/table2.md). Run from anywhere: python3 make_language_starts.py sv."""
import csv
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
PROTO = os.path.dirname(HERE)


def language_visemes(lang):
    path = os.path.join(PROTO, "languages", lang, "phones.tsv")
    with open(path, encoding="utf-8") as f:
        lines = [l for l in f if l.strip() and not l.startswith("#")]
    return [(r["symbol"], r["mpeg4_viseme"]) for r in csv.DictReader(lines, delimiter="\t")]


def main(lang):
    with open(os.path.join(HERE, "mpeg4-cohen-massaro.visemes.json"), encoding="utf-8") as f:
        vis = json.load(f)
    with open(os.path.join(HERE, "mpeg4-cohen-massaro.json"), encoding="utf-8") as f:
        model = json.load(f)
    by_name = {v["name"]: v for v in vis["visemes"]}
    for v in vis["visemes"]:
        v["phones"] = []
    for symbol, name in language_visemes(lang):
        by_name[name]["phones"].append(symbol)
    out = {"name": "mpeg4-14-" + lang, "source": "English's trained set (../mpeg4-cohen-massaro.visemes.json) with the "
           "phones of protocols/languages/%s/phones.tsv by their mpeg4_viseme column; make_language_starts.py" % lang,
           "language": lang, "visemes": vis["visemes"]}
    os.makedirs(os.path.join(HERE, lang), exist_ok=True)
    with open(os.path.join(HERE, lang, "mpeg4-cohen-massaro.visemes.json"), "w", encoding="utf-8") as f:
        json.dump(out, f, indent=2, ensure_ascii=False)
        f.write("\n")
    model["viseme_set"] = "mpeg4-cohen-massaro.visemes.json"
    model["provenance"] = {"method": "hand-set", "data": "", "split": "", "errors": {},
                           "notes": "Starting point for training on the %s reference corpus: English's trained "
                                    "dominance parameters and viseme targets, the %s phones by viseme class "
                                    "(make_language_starts.py)." % (lang, lang)}
    with open(os.path.join(HERE, lang, "mpeg4-cohen-massaro.json"), "w", encoding="utf-8") as f:
        json.dump(model, f, indent=2, sort_keys=True)
        f.write("\n")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "sv")
