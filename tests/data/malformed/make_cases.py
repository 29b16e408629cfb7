#!/usr/bin/env python3
"""Writes the malformed-input corpus (issue 19): one folder per format, each
case one bad file derived from a good one by a single change, plus the
format's `command` (how tests/e2e/malformed_test.cpp runs it through avsi).
The golden .err files are written by the test (AVSI_UPDATE_GOLDEN=1) and
reviewed by hand. Run from anywhere: python3 tests/data/malformed/make_cases.py
"""
import json, os, struct, sqlite3, pathlib

HERE = pathlib.Path(__file__).resolve().parent
DATA = HERE.parent
PROTOCOLS = DATA.parent.parent / "protocols"


def write(fmt, name, content, command=None):
    d = HERE / fmt
    d.mkdir(exist_ok=True)
    mode = "wb" if isinstance(content, bytes) else "w"
    with open(d / name, mode) as f:
        f.write(content)


def command(fmt, text):
    d = HERE / fmt
    d.mkdir(exist_ok=True)
    (d / "command").write_text(text.strip() + "\n")


# ------------------------------------------------------------------ support files written here
# (good.fap and good_traj.csv come from avsi synth, session.sqlite is a copy
# of ../web/schema1-lab.sqlite; see README.md)
def write_support():
    import math
    sup = HERE / "_support"
    (sup / "sensors").mkdir(parents=True, exist_ok=True)
    # EMA track: 30 frames at 100 fps, 4 head-corrected sensors (x, y), the
    # lower incisor and lower lip opening 3 times a second by up to 5 mm.
    ch = ["ui_x", "ui_y", "li_x", "li_y", "ul_x", "ul_y", "ll_x", "ll_y"]
    lines = ["EST_File Track", "DataType ascii", "NumFrames 30", "NumChannels 8", "NumAuxChannels 0",
             "EqualSpace 1", "BreaksPresent true", "CommentChar ;", ""]
    lines += [f"Channel_{i} {c}" for i, c in enumerate(ch)]
    rows = []
    for k in range(30):
        t = k / 100
        o = 5 * math.sin(2 * math.pi * 3 * t)
        v = [0, 0, 0, -10 - o, 5, 5, 5, -8 - o]
        rows.append(f"{t:.6f} 1 " + " ".join(f"{x:.4f}" for x in v))
    (sup / "sensors" / "utt.est").write_text("\n".join(lines) + "\nEST_Header_End\n" + "\n".join(rows) + "\n")
    (sup / "sensors" / "utt.tsv").write_text("start_s\tend_s\tphone\n0\t0.1\tsil\n0.1\t0.2\tAA1\n0.2\t0.29\tM\n")
    (sup / "sensors" / "long.tsv").write_text("start_s\tend_s\tphone\n0\t0.1\tsil\n0.1\t0.2\tAA1\n0.2\t1000\tM\n")
    with open(sup / "sensors" / "corpus.json", "w") as f:
        json.dump({"format": "avsi-articulatory-corpus", "version": 1, "name": "malformed-support",
                   "split": {"seed": 1, "test_fraction": 0.5},
                   "sensor_mapping": {"reference_sensors": [], "fps": 100},
                   "utterances": [{"id": "utt", "kind": "sensors", "track": "utt.est", "labels": "utt.tsv"}]},
                  f, indent=1)
    rows = [("1", "1", "1", "warmup", "audio-only", "warmup", "w01", "the sun is warm today"),
            ("1", "1", "2", "warmup", "audio-only", "warmup", "w02", "a bird sang"),
            ("1", "1", "3", "practice", "clean", "practice", "p01", "she opened the red door"),
            ("1", "1", "4", "practice", "clean", "practice", "p02", "they walked"),
            ("1", "1", "5", "test", "clean", "1", "t01", "the dog barked at night"),
            ("1", "1", "6", "test", "none", "1", "t02", "he bought bread")]
    (sup / "responses.csv").write_text("subject,session,trial,phase,condition,list,sentence,response\n" +
                                       "".join(",".join(r) + "\n" for r in rows))


write_support()

DEEP = "[" * 100000 + "]" * 100000  # the two cases of the issue (rig, model)
NESTED = "[" * 20000 + "]" * 20000

# ------------------------------------------------------------------ TextGrid
tg = (DATA / "core" / "long.TextGrid").read_text()
command("textgrid", "args phones --textgrid {input} --out {out}/phones.tsv")
tg_cases = {
    "empty": "",
    "bom_only": "\ufeff",
    "not_textgrid": "hello world\n",
    "wrong_class": tg.replace('Object class = "TextGrid"', 'Object class = "Pitch"'),
    "xmax_nan": tg.replace("xmax = 1.2 \ntiers", "xmax = nan \ntiers", 1),
    "xmax_minus_nan": tg.replace("xmax = 1.2 \ntiers", "xmax = -nan \ntiers", 1),
    "xmax_inf": tg.replace("xmax = 1.2 \ntiers", "xmax = +inf \ntiers", 1),
    "reversed_grid": tg.replace("xmin = 0 \nxmax = 1.2", "xmin = 2 \nxmax = 1.2", 1),
    "reversed_interval": tg.replace("            xmin = 0.1 \n            xmax = 0.2 \n            text = \"K\"",
                                    "            xmin = 0.2 \n            xmax = 0.1 \n            text = \"K\""),
    "phone_at_1e9": tg.replace("xmax = 1.2", "xmax = 1e9"),
    "phone_at_1e300": tg.replace("xmax = 1.2", "xmax = 1e300"),
    "huge_tier_count": tg.replace("size = 3", "size = 1000000000", 1),
    "huge_interval_count": tg.replace("intervals: size = 6", "intervals: size = 1000000000", 1),
    "negative_count": tg.replace("size = 3", "size = -1", 1),
    "truncated": tg[: len(tg) // 2],
    "unclosed_string": tg.replace('text = "here"', 'text = "here'),
    "no_phones_tier": tg.replace('name = "phones"', 'name = "segments"'),
    "unknown_phone": tg.replace('text = "K"', 'text = "Q9"'),
    "long_label": tg.replace('text = "K"', 'text = "' + "K" * 200000 + '"'),
    "binary_garbage": bytes(range(256)) * 40,
    "number_overflow": tg.replace("xmax = 1.2", "xmax = 1e999"),
    "index_garbage": tg.replace("item [2]:", "item [two]:"),
}
for name, text in tg_cases.items():
    write("textgrid", name + ".TextGrid", text)

# ------------------------------------------------------------------ HTK .lab
lab = (DATA / "core" / "come.lab").read_text()
command("lab", "args phones --lab {input} --out {out}/phones.tsv")
lab_cases = {
    "empty": "",
    "blank_lines": "\n\n   \n",
    "two_fields": "0 1500000\n",
    "negative_start": "-5 1500000 sil\n",
    "reversed": "1500000 0 sil\n",
    "phone_at_1e9_s": "0 10000000000000000 AA1\n",
    "overflow": "0 99999999999999999999999 AA1\n",
    "float_times": "0.0 1.5e6 sil\n",
    "bad_score": lab.replace("-12.5", "loud"),
    "unknown_phone": lab.replace(" M", " QQ"),
    "long_label": "0 1500000 " + "A" * 1000000 + "\n",
    "overlap": "0 2000000 sil\n1000000 3000000 K\n",
    "nul_bytes": "0 1500000 s\0il\n",
    "zero_length_only": "0 0 sil\n",
}
for name, text in lab_cases.items():
    write("lab", name + ".lab", text)

# ------------------------------------------------------------------ TSV labels
tsv = (DATA / "core" / "come.tsv").read_text()
command("tsv", "args phones --tsv {input} --out {out}/phones.tsv")
tsv_cases = {
    "empty": "",
    "header_only": "start_s\tend_s\tphone\n",
    "two_fields": "start_s\tend_s\tphone\n0\t0.1\n",
    "four_fields": "start_s\tend_s\tphone\n0\t0.1\tsil\textra\n",
    "nan_time": "start_s\tend_s\tphone\n0\tnan\tsil\n",
    "inf_time": "start_s\tend_s\tphone\n0\tinf\tsil\n",
    "phone_at_1e9": "start_s\tend_s\tphone\n0\t1e9\tAA1\n",
    "phone_at_1e300": "start_s\tend_s\tphone\n0\t1e300\tAA1\n",
    "reversed": "start_s\tend_s\tphone\n0.5\t0.1\tAA1\n",
    "negative": "start_s\tend_s\tphone\n-1\t0.1\tAA1\n",
    "overlap": "start_s\tend_s\tphone\n0\t0.2\tsil\n0.1\t0.3\tK\n",
    "unknown_phone": tsv.replace("\tK\n", "\tKK9\n"),
    "long_label": "start_s\tend_s\tphone\n0\t0.1\t" + "B" * 200000 + "\n",
    "comma_separated": "start_s,end_s,phone\n0,0.1,sil\n",
    "hex_time": "start_s\tend_s\tphone\n0\t0x10\tsil\n",
}
for name, text in tsv_cases.items():
    write("tsv", name + ".tsv", text)

# ------------------------------------------------------------------ model JSON
rule = json.loads((PROTOCOLS / "models" / "rule.json").read_text())
cm = json.loads((PROTOCOLS / "models" / "cohen-massaro.json").read_text())
command("model", "args synth --model {input} --phones {data}/core/come.tsv --out {out}/traj.csv")
model_cases = {
    "empty": "",
    "not_json": "kind: rule\n",
    "array": "[1, 2, 3]\n",
    "deep_nesting": '{"kind": "rule", "version": 1, "provenance": ' + DEEP + "}\n",
    "deep_objects": '{"kind": "rule", "a": ' + '{"a": ' * 20000 + "1" + "}" * 20000 + "}\n",
    "number_overflow": '{"kind": "rule", "version": 1e999}\n',
    "truncated": json.dumps(rule, indent=2)[:200],
    "unknown_kind": json.dumps({**rule, "kind": "rulez"}),
    "version_string": json.dumps({**rule, "version": "one"}),
    "kind_number": json.dumps({**rule, "kind": 5}),
    "trailing_garbage": json.dumps(rule) + "\n}}}",
    "invalid_utf8": b'{"kind": "rule", "version": 1, "name": "\xff\xfe"}',
    "nul_in_string": '{"kind": "rule", "version": 1, "name": "a\\u0000b"}',
}
# a Cohen-Massaro target of 1e308 and a NaN-like string
cm_big = json.loads(json.dumps(cm))
def first_number_path(obj):
    if isinstance(obj, dict):
        for k, v in obj.items():
            if isinstance(v, (int, float)) and not isinstance(v, bool) and k not in ("version",):
                return [k]
            r = first_number_path(v)
            if r is not None:
                return [k] + r
    if isinstance(obj, list):
        for i, v in enumerate(obj):
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                return [i]
            r = first_number_path(v)
            if r is not None:
                return [i] + r
    return None
def set_path(obj, path, value):
    for p in path[:-1]:
        obj = obj[p]
    obj[path[-1]] = value
p = first_number_path(cm_big.get("phones", cm_big))
if p is not None:
    set_path(cm_big.get("phones", cm_big), p, 1e308)
    model_cases["cm_value_1e308"] = json.dumps(cm_big)
    cm_str = json.loads(json.dumps(cm))
    set_path(cm_str.get("phones", cm_str), p, "NaN")
    model_cases["cm_value_string"] = json.dumps(cm_str)
for name, text in model_cases.items():
    write("model", name + ".json", text)

# ------------------------------------------------------------------ FAP
fap = (HERE / "_support" / "good.fap").read_text()
fap_lines = fap.splitlines(keepends=True)
command("fap", "args fap2traj {input} --out {out}/traj.csv")
hdr = fap_lines[0].split()
def fap_with_header(new):
    return new + "\n" + "".join(fap_lines[1:])
value_line = fap_lines[2].split()
def fap_with_value(v):
    vl = list(value_line)
    vl[3] = v
    return "".join(fap_lines[:2]) + " ".join(vl) + "\n" + "".join(fap_lines[3:])
fap_cases = {
    "empty": "",
    "comment_only": "# nothing\n",
    "bad_version": fap_with_header("3.0 " + " ".join(hdr[1:])),
    "fps_zero": fap_with_header(" ".join([hdr[0], hdr[1], "0", hdr[3]])),
    "fps_nan": fap_with_header(" ".join([hdr[0], hdr[1], "nan", hdr[3]])),
    "fps_1e300": fap_with_header(" ".join([hdr[0], hdr[1], "1e300", hdr[3]])),
    "huge_frames": fap_with_header(" ".join([hdr[0], hdr[1], hdr[2], "1000000000"])),
    "negative_frames": fap_with_header(" ".join([hdr[0], hdr[1], hdr[2], "-3"])),
    "value_1e308": fap_with_value("1e308"),
    "value_word": fap_with_value("lots"),
    "short_mask": fap_lines[0] + "0 1 1\n" + "".join(fap_lines[2:]),
    "mask_two": "".join(fap_lines[:1]) + fap_lines[1].replace("1", "2", 1) + "".join(fap_lines[2:]),
    "missing_values": "".join(fap_lines[:2]) + value_line[0] + "\n" + "".join(fap_lines[3:]),
    "frame_number_jump": "".join(fap_lines[:4]) + "99 " + " ".join(fap_lines[4].split()[1:]) + "\n" + "".join(fap_lines[5:]),
    "truncated": "".join(fap_lines[:-1]),
    "extra_lines": fap + fap_lines[1] + fap_lines[2],
}
for name, text in fap_cases.items():
    write("fap", name + ".fap", text)

# ------------------------------------------------------------------ trajectory CSV
traj = (HERE / "_support" / "good_traj.csv").read_text()
tl = traj.splitlines(keepends=True)
command("trajectory", "args measure --traj {input} --out {out}/measures.csv")
def traj_cell(row, col, value):
    lines = list(tl)
    cells = lines[row].rstrip("\n").split(",")
    cells[col] = value
    lines[row] = ",".join(cells) + "\n"
    return "".join(lines)
traj_cases = {
    "empty": "",
    "header_only": tl[0],
    "one_frame": tl[0] + tl[1],
    "value_1e300": traj_cell(3, 1, "1e300"),
    "value_nan": traj_cell(3, 2, "nan"),
    "value_word": traj_cell(3, 2, "open"),
    "time_1e300": traj_cell(2, 0, "1e300"),
    "time_negative_start": traj_cell(1, 0, "-0.04"),
    "time_reversed": traj_cell(2, 0, "-1"),
    "uneven_step": traj_cell(4, 0, "0.13"),
    "missing_column": "".join(",".join(l.rstrip("\n").split(",")[:-1]) + "\n" for l in tl),
    "unknown_column": tl[0].replace("jaw_shift", "jaw_shfit") + "".join(tl[1:]),
    "short_row": "".join(tl[:3]) + ",".join(tl[3].split(",")[:4]) + "\n" + "".join(tl[4:]),
    "unclosed_quote": "".join(tl[:3]) + '"' + tl[3] + "".join(tl[4:]),
    "value_far_outside_range": traj_cell(3, 1, "250"),
}
for name, text in traj_cases.items():
    write("trajectory", name + ".csv", text)

# ------------------------------------------------------------------ head mesh (OBJ) and rig (JSON)
command("obj", "args measure --traj {data}/malformed/_support/good_traj.csv --mesh {input} --out {out}/measures.csv")
tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\ng mouth\nf 1 2 3\n"
obj_cases = {
    "empty": "",
    "no_faces": "v 0 0 0\nv 1 0 0\nv 0 1 0\n",
    "nan_vertex": tri.replace("v 1 0 0", "v nan 0 0"),
    "huge_vertex": tri.replace("v 1 0 0", "v 1e308 0 0"),
    "inf_vertex": tri.replace("v 1 0 0", "v inf 0 0"),
    "index_out_of_range": tri.replace("f 1 2 3", "f 1 2 99"),
    "index_zero": tri.replace("f 1 2 3", "f 0 1 2"),
    "garbage": "this is not a mesh\n\x01\x02\x03\n",
    "quad_index_huge": tri.replace("f 1 2 3", "f 1 2 3 4000000000"),
    "no_vertices": "g mouth\nf 1 2 3\n",
}
for name, text in obj_cases.items():
    write("obj", name + ".obj", text)

rig = json.loads((PROTOCOLS / "head" / "head.rig.json").read_text())
# The texture is found beside the rig file and the cases live elsewhere:
# without it the rig is still complete (the head is drawn untextured).
rig.pop("texture", None)
command("rig", "args measure --traj {data}/malformed/_support/good_traj.csv --rig {input} --out {out}/measures.csv")
def rig_with(mut):
    r = json.loads(json.dumps(rig))
    mut(r)
    return json.dumps(r)
def set_landmark(r, key, value):
    r["landmarks"][key] = value
rig_cases = {
    "empty": "",
    "deep_nesting": '{"format": "avsi-rig", "x": ' + DEEP + "}\n",
    "not_object": "[]\n",
    "nul_after_document": '{"format": "avsi-rig"}\x00 garbage',
    "wrong_format": rig_with(lambda r: r.__setitem__("format", "blender")),
    "landmark_1e308": rig_with(lambda r: set_landmark(r, "left_eye", [1e308, 0, 0])),
    "landmark_string": rig_with(lambda r: set_landmark(r, "left_eye", ["a", 0, 0])),
    "landmark_two_numbers": rig_with(lambda r: set_landmark(r, "left_eye", [0, 0])),
    "landmarks_array": rig_with(lambda r: r.__setitem__("landmarks", [1, 2])),
    "number_overflow": json.dumps(rig).replace('"format"', '"big": 1e999, "format"', 1),
    "truncated": json.dumps(rig)[:5000],
    "unknown_channel": rig_with(lambda r: r["transforms"][0].__setitem__("channel", "jaw_rotaton")),
    "transforms_object": rig_with(lambda r: r.__setitem__("transforms", {"a": 1})),
}
for name, text in rig_cases.items():
    write("rig", name + ".json", text)

# ------------------------------------------------------------------ glTF head
# A one-quad glTF (its buffer embedded as a data URI) with the avsi extras;
# every case fails before the ARKit mapping's targets are looked for.
command("gltf", "args measure --traj {data}/malformed/_support/good_traj.csv --head {input} --out {out}/measures.csv")
def gltf_doc():
    pos = [(-0.02, -0.06, 0.01), (0.02, -0.06, 0.01), (-0.02, -0.07, 0.01), (0.02, -0.07, 0.01)]
    data = b"".join(struct.pack("<3f", *p) for p in pos) + struct.pack("<6H", 0, 2, 1, 1, 2, 3)
    import base64
    return {
        "asset": {"version": "2.0"}, "extras": {"avsi": {"landmarks": {"left_eye": [0.03, 0, 0]}}},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"name": "face", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                       "min": [-0.02, -0.07, 0.01], "max": [0.02, -0.06, 0.01]},
                      {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"}],
        "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48}, {"buffer": 0, "byteOffset": 48, "byteLength": 12}],
        "buffers": [{"byteLength": len(data), "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}],
    }
def gltf_with(mut):
    d = gltf_doc()
    mut(d)
    return json.dumps(d, indent=1)
def glb(json_bytes, declared=None):
    j = json_bytes + b" " * ((4 - len(json_bytes) % 4) % 4)
    n = len(j) if declared is None else declared
    return struct.pack("<4sII", b"glTF", 2, 20 + len(j)) + struct.pack("<I4s", n, b"JSON") + j
gltf_good = json.dumps(gltf_doc(), indent=1)
gltf_cases = {
    "empty.gltf": "",
    "truncated.gltf": gltf_good[:700],
    "syntax_error.gltf": gltf_good.replace('"scene": 0,', '"scene": 0,,', 1),
    "deep_nesting.gltf": gltf_good.replace('"extras": {', '"extras": {"deep": ' + DEEP + ", ", 1),
    "number_overflow.gltf": gltf_good.replace('"scene": 0', '"scene": 1e999', 1),
    "not_object.gltf": "[]\n",
    "node_cycle.gltf": gltf_with(lambda d: d["nodes"][0].__setitem__("children", [0])),
    "node_index.gltf": gltf_with(lambda d: d["scenes"][0].__setitem__("nodes", [7])),
    "buffer_missing.gltf": gltf_with(lambda d: d["buffers"][0].__setitem__("uri", "missing.bin")),
    "buffer_device.gltf": gltf_with(lambda d: d["buffers"][0].__setitem__("uri", "../" * 16 + "dev/zero")),
    "extras_avsi_array.gltf": gltf_with(lambda d: d["extras"].__setitem__("avsi", [1, 2])),
    "accessor_count_huge.gltf": gltf_with(lambda d: d["accessors"][0].__setitem__("count", 4000000000)),
    "bad_magic.glb": b"glTF\x02\x00\x00\x00",
    "glb_json_length.glb": glb(json.dumps(gltf_doc()).encode(), declared=1 << 30),
    "glb_deep_nesting.glb": glb(('{"asset": {"version": "2.0"}, "x": ' + DEEP + "}").encode()),
}
for name, content in gltf_cases.items():
    write("gltf", name, content)

# ------------------------------------------------------------------ EST tracks (through a corpus)
est = (HERE / "_support" / "sensors" / "utt.est").read_text()
eh, ed = est.split("EST_Header_End\n")
command("est", """
copy {data}/malformed/_support/sensors/corpus.json
copy {data}/malformed/_support/sensors/utt.tsv
name utt.est
args evaluate --corpus {dir}/corpus.json --models {data}/../../protocols/models/rule.json --subset all --no-phonetic --out {out}/eval
""")
def est_header(old, new):
    return eh.replace(old, new) + "EST_Header_End\n" + ed
est_rows = ed.splitlines(keepends=True)
def est_value(row, col, v):
    rows = list(est_rows)
    cells = rows[row].split()
    cells[col] = v
    rows[row] = " ".join(cells) + "\n"
    return eh + "EST_Header_End\n" + "".join(rows)
est_cases = {
    "empty": "",
    "not_est": "hello\n",
    "huge_channels": est_header("NumChannels 8", "NumChannels 1000000000"),
    "huge_frames": est_header("NumFrames 30", "NumFrames 1000000000"),
    "huge_frames_binary": est_header("DataType ascii", "DataType binary\nByteOrder 01").replace("NumFrames 30", "NumFrames 1000000000"),
    "frames_overflow": est_header("NumFrames 30", "NumFrames 99999999999999999999"),
    "negative_frames": est_header("NumFrames 30", "NumFrames -1"),
    "no_header_end": eh,
    "bad_datatype": est_header("DataType ascii", "DataType float"),
    "coordinate_1e38": est_value(5, 3, "1e38"),
    "coordinate_1e300": est_value(5, 3, "1e300"),
    "time_1e9": est_value(29, 0, "1e9"),
    "value_word": est_value(5, 3, "x"),
    "short_row": eh + "EST_Header_End\n" + "".join(est_rows[:5]) + "0.05 1 2\n" + "".join(est_rows[6:]),
    "fewer_frames": eh + "EST_Header_End\n" + "".join(est_rows[:10]),
    "times_not_increasing": est_value(6, 0, "0.01"),
    "channel_index_huge": est_header("Channel_0", "Channel_999999999"),
    "binary_wrong_size": est_header("DataType ascii", "DataType binary\nByteOrder 01").split("EST_Header_End\n")[0] + "EST_Header_End\n" + "\0" * 17,
}
for name, text in est_cases.items():
    write("est", name + ".est", text)

# ------------------------------------------------------------------ articulatory corpus manifest
command("corpus_manifest", """
copy {data}/malformed/_support/sensors/utt.est
copy {data}/malformed/_support/sensors/utt.tsv
copy {data}/malformed/_support/sensors/long.tsv
name corpus.json
args evaluate --corpus {dir}/corpus.json --models {data}/../../protocols/models/rule.json --subset all --no-phonetic --out {out}/eval
""")
cj = json.loads((HERE / "_support" / "sensors" / "corpus.json").read_text())
def cj_with(mut):
    c = json.loads(json.dumps(cj))
    mut(c)
    return json.dumps(c, indent=1)
cm_cases = {
    "not_object": "1\n",
    "nul_after_number": '1\x00,\n"x"',
    "empty": "",
    "deep_nesting": '{"format": "avsi-articulatory-corpus", "utterances": ' + NESTED + "}",
    "wrong_format": cj_with(lambda c: c.__setitem__("format", "mocha")),
    "utterances_object": cj_with(lambda c: c.__setitem__("utterances", {"a": 1})),
    "missing_track": cj_with(lambda c: c["utterances"][0].__setitem__("track", "nope.est")),
    "mm_per_unit_1e308": cj_with(lambda c: c["sensor_mapping"].__setitem__("mm_per_unit", 1e308)),
    "fps_string": cj_with(lambda c: c["sensor_mapping"].__setitem__("fps", "sixty")),
    "labels_past_track": cj_with(lambda c: c["utterances"][0].__setitem__("labels", "long.tsv")),
    "duplicate_id": cj_with(lambda c: c["utterances"].append(dict(c["utterances"][0]))),
    "unknown_key": cj_with(lambda c: c.__setitem__("utterance", [])),
    "number_overflow": json.dumps(cj).replace('"format"', '"x": -1e999, "format"', 1),
}
for name, text in cm_cases.items():
    write("corpus_manifest", name + ".json", text)

# ------------------------------------------------------------------ protocol TOML and sentence corpus CSV
proto = (DATA / "experiment" / "protocol.toml").read_text()
command("protocol", """
copy {data}/experiment/corpus.csv
name protocol.toml
args design {input} --subjects 2 --out {out}/lists.csv
""")
protocol_cases = {
    "empty": "",
    "not_toml": "[experiment\nname = \n",
    "practice_string": proto.replace("practice = 2", 'practice = "two"'),
    "lists_huge": proto.replace("lists = 3", "lists = 1000000000"),
    "lists_negative": proto.replace("lists = 3", "lists = -3"),
    "lists_float": proto.replace("lists = 3", "lists = 1e300"),
    "seed_overflow": proto.replace("seed = 7", "seed = 99999999999999999999999"),
    "unknown_key": proto.replace("warmup = 2", "warmpu = 2"),
    "deep_arrays": proto + "\n[extra]\nx = " + "[" * 10000 + "]" * 10000 + "\n",
    "no_conditions": "\n".join(l for l in proto.splitlines() if "condition" not in l and not l.startswith("name = \"") and not l.startswith("face") and not l.startswith("audio")) + "\n",
    "missing_corpus": proto.replace('sentences = "corpus.csv"', 'sentences = "nope.csv"'),
    "nul_byte": proto.replace("exp-test", "exp\0test"),
    "split_compounds_unknown": proto + '\n[scoring]\nsplit_compounds = "sometimes"\n',
}
for name, text in protocol_cases.items():
    write("protocol", name + ".toml", text)

# The [vocoder] table of a protocol: an unknown carrier and impossible
# cochlear-implant settings, refused at the key (build-stimuli reads the table
# before anything is built or checked).
command("vocoder", """
copy {data}/experiment/corpus.csv
name protocol.toml
args build-stimuli {input} --out {out}/stimuli --verify
""")
vocoder_cases = {
    "unknown_carrier": '[vocoder]\nbands = 8\ncarrier = "pulses"\n',
    "n_of_m_over_bands": '[vocoder]\nbands = 8\nn_of_m = 12\n',
    "spread_negative": '[vocoder]\ncurrent_spread = "db-per-octave"\nspread_slope_db = -4\n',
    "pshc": '[vocoder]\ncarrier = "pshc"\n',
    "pulses_overlap": '[vocoder]\nbands = 16\ncarrier = "pulse-train"\npulse_rate_hz = 1000\n',
}
for name, text in vocoder_cases.items():
    write("vocoder", name + ".toml", proto.replace("[design]", text + "\n[design]"))

corpus = (DATA / "experiment" / "corpus.csv").read_text()
cl = corpus.splitlines(keepends=True)
command("sentences", """
copy {data}/experiment/protocol.toml
name corpus.csv
args design {dir}/protocol.toml --subjects 2 --out {out}/lists.csv
""")
sentence_cases = {
    "empty": "",
    "header_only": cl[0],
    "missing_column": cl[0].replace(",keywords", "") + "".join(",".join(l.split(",")[:2] + l.split(",")[3:]) for l in cl[1:]),
    "duplicate_id": corpus + cl[1],
    "unclosed_quote": cl[0] + '"w01,The sun\n',
    "no_keywords": cl[0] + "".join(l.replace(l.split(",")[2], "") if i == 0 else l for i, l in enumerate(cl[1:])),
    "extra_field": cl[0] + cl[1].rstrip("\n") + ",x\n" + "".join(cl[2:]),
    "keyword_not_in_text": cl[0] + cl[1].replace("sun;", "moon;") + "".join(cl[2:]),
    "binary": bytes(range(256)) * 10,
}
for name, text in sentence_cases.items():
    write("sentences", name + ".csv", text)

# ------------------------------------------------------------------ responses and scores CSV
resp = (HERE / "_support" / "responses.csv").read_text()
rl = resp.splitlines(keepends=True)
command("responses", "args score --protocol {data}/experiment/protocol.toml --responses {input} --out {out}/scores")
response_cases = {
    "empty": "",
    "header_only": rl[0],
    "duplicate_trial": "".join(rl) + rl[-1],
    "duplicate_trial_other_session": "".join(rl) + rl[-1].replace(",1,", ",2,", 1),
    "bad_phase": "".join(rl[:5]) + rl[5].replace("test", "tset", 1) + "".join(rl[6:]),
    "missing_column": "".join(",".join(l.split(",")[:-1]) + "\n" for l in rl),
    "empty_subject": "".join(rl[:2]) + "," + rl[2].split(",", 1)[1] + "".join(rl[3:]),
    "unknown_sentence": "".join(rl[:5]) + rl[5].replace(",t01,", ",zz99,", 1) + "".join(rl[6:]),
    "unclosed_quote": "".join(rl) + '1,1,99,test,clean,L1,w01,"never closed\n',
    "short_row": "".join(rl) + "1,1\n",
}
for name, text in response_cases.items():
    write("responses", name + ".csv", text)

scores = (DATA / "analysis" / "balanced.csv").read_text()
sl = scores.splitlines(keepends=True)
command("scores", "args analyze {input} --out {out}/report")
def sc_cell(row, col, v):
    lines = list(sl)
    cells = lines[row].rstrip("\n").split(",")
    cells[col] = v
    lines[row] = ",".join(cells) + "\n"
    return "".join(lines)
score_cases = {
    "empty": "",
    "header_only": sl[0],
    "percent_nan": sc_cell(1, len(sl[1].split(",")) - 1, "nan"),
    "percent_1e300": sc_cell(1, len(sl[1].split(",")) - 1, "1e300"),
    "percent_negative": sc_cell(1, len(sl[1].split(",")) - 1, "-5"),
    "percent_word": sc_cell(1, len(sl[1].split(",")) - 1, "high"),
    "duplicate_cell": "".join(sl) + sl[1],
    "missing_column": "".join(",".join(l.rstrip("\n").split(",")[:-1]) + "\n" for l in sl),
}
for name, text in score_cases.items():
    write("scores", name + ".csv", text)

# ------------------------------------------------------------------ session database
command("database", "name db.sqlite\nargs export {input} --out {out}/export")
good_db = (HERE / "_support" / "session.sqlite").read_bytes()
def db_with(sql, name):
    path = HERE / "database" / name
    path.parent.mkdir(exist_ok=True)
    if path.exists():
        path.unlink()
    path.write_bytes(good_db)
    c = sqlite3.connect(path)
    c.executescript(sql)
    c.commit()
    c.execute("PRAGMA journal_mode=DELETE")
    c.close()
db_cases = {
    "text_file.sqlite": b"subject,trial\n1,2\n",
    "truncated.sqlite": good_db[: len(good_db) // 3],
    "header_only.sqlite": good_db[:100],
    "zeroed_pages.sqlite": good_db[:4096] + b"\0" * (len(good_db) - 4096),
    "garbage_after_header.sqlite": good_db[:100] + bytes((i * 37) % 256 for i in range(len(good_db) - 100)),
}
for name, content in db_cases.items():
    write("database", name, content)
db_with("PRAGMA user_version=99;", "schema_too_new.sqlite")
db_with("DROP TABLE responses;", "missing_table.sqlite")
db_with("CREATE TABLE extra(x);PRAGMA user_version=0;", "no_version.sqlite")
db_with("DROP TABLE responses; CREATE TABLE responses(x);", "wrong_columns.sqlite")

# ------------------------------------------------------------------ stimulus manifest (through avsi run)
manifest = {"format": "avsi-stimuli-manifest", "experiment": "exp-test", "stimuli": [
    {"path": "w01/audio-only.mp4", "frames": 30, "fps": 30.0, "sha256": "0" * 64}]}
command("manifest", """
copy {data}/experiment/protocol.toml
copy {data}/experiment/corpus.csv
name stimuli/manifest.json
args run {dir}/protocol.toml --subject 1 --db {out}/db.sqlite --stimuli {dir}/stimuli --audio null --windowed
""")
def man_with(mut):
    m = json.loads(json.dumps(manifest))
    mut(m)
    return json.dumps(m)
manifest_cases = {
    "empty": "",
    "deep_nesting": '{"format": "avsi-stimuli-manifest", "stimuli": ' + NESTED + "}",
    "wrong_format": man_with(lambda m: m.__setitem__("format", "x")),
    "frames_1e300": man_with(lambda m: m["stimuli"][0].__setitem__("frames", 1e300)),
    "frames_float": man_with(lambda m: m["stimuli"][0].__setitem__("frames", 30.5)),
    "frames_negative": man_with(lambda m: m["stimuli"][0].__setitem__("frames", -30)),
    "fps_zero": man_with(lambda m: m["stimuli"][0].__setitem__("fps", 0)),
    "path_number": man_with(lambda m: m["stimuli"][0].__setitem__("path", 5)),
    "number_overflow": json.dumps(manifest).replace('"fps": 30.0', '"fps": 1e999'),
    "truncated": json.dumps(manifest)[:60],
}
for name, text in manifest_cases.items():
    write("manifest", name + ".json", text)

# ------------------------------------------------------------------ WAV audio
command("wav", "args vocode {input} {out}/vocoded.wav")
def wav(channels=1, rate=16000, bits=16, frames=1600, data_size=None, riff_size=None):
    data = b"\0" * (frames * channels * bits // 8)
    ds = len(data) if data_size is None else data_size
    fmt_chunk = struct.pack("<4sIHHIIHH", b"fmt ", 16, 1, channels, rate, (rate * channels * bits // 8) & 0xFFFFFFFF, (channels * bits // 8) & 0xFFFF, bits)
    body = b"WAVE" + fmt_chunk + struct.pack("<4sI", b"data", ds) + data
    rs = len(body) if riff_size is None else riff_size
    return struct.pack("<4sI", b"RIFF", rs) + body
wav_cases = {
    "empty.wav": b"",
    "text.wav": b"not audio at all\n",
    "header_only.wav": wav()[:44 - 8],
    "zero_rate.wav": wav(rate=0),
    "huge_channels.wav": wav(channels=65535, frames=0),
    "no_samples.wav": wav(frames=0),
}
for name, content in wav_cases.items():
    write("wav", name, content)

# ------------------------------------------------------------------ simulation shard (through avsi power --merge)
# A one-shard split of `avsi power --means 60,70 --subjects 4 --sims 3 --seed 1`
# as `--shard 0/1` writes it (the rows made up: the merge checks their form
# and ranges, not the simulation), each case one change.
import re
AVSI_VERSION = re.search(r"project\(avsi VERSION (\S+)", (DATA.parent.parent / "CMakeLists.txt").read_text()).group(1)
power_settings = {"alpha": 0.05, "condition_sd": 0.95, "contrast": [2, 1], "keywords_per_sentence": 3,
                  "means_percent": [60.0, 70.0], "seed": 1, "sentence_sd": 0.5, "sentences_per_cell": 15,
                  "simulations": 3, "subject_counts": [4], "subject_sd": 0.5}
command("power_shard", """
name power.shard-0-of-1.csv
args power --means 60,70 --subjects 4 --sims 3 --seed 1 --merge --out {dir}
""")
def power_shard(first="# avsi-power-shard 0/1", version=AVSI_VERSION, settings=None, columns=None, rows=None):
    lines = [first, "# avsi " + version,
             "# settings " + json.dumps(power_settings if settings is None else settings, separators=(",", ":"), sort_keys=True),
             columns or "subjects,simulation,anova,anova_gg,contrast,mean_percent"]
    lines += rows if rows is not None else ["4,0,1,0,1,62.5", "4,1,0,0,0,58.333333333333336", "4,2,1,1,1,66.66666666666667"]
    return "\n".join(lines) + "\n"
power_shard_cases = {
    "empty": "",
    "not_a_shard": "subjects,simulation,anova,anova_gg,contrast,mean_percent\n4,0,1,0,1,62.5\n",
    "claims_other_shard": power_shard(first="# avsi-power-shard 1/2"),
    "other_version": power_shard(version="0.0.1"),
    "settings_truncated": power_shard().replace('"subject_sd":0.5}', '"subject_sd":'),
    "other_seed": power_shard(settings=dict(power_settings, seed=2)),
    "other_columns": power_shard(columns="subjects,simulation,anova,contrast,mean_percent"),
    "cut_short": power_shard(rows=["4,0,1,0,1,62.5", "4,1,0,0,0,58.333333333333336"]),
    "extra_row": power_shard(rows=["4,0,1,0,1,62.5", "4,1,0,0,0,58.3", "4,2,1,1,1,66.7", "4,3,1,1,1,66.7"]),
    "wrong_replicate": power_shard(rows=["4,0,1,0,1,62.5", "4,2,0,0,0,58.3", "4,1,1,1,1,66.7"]),
    "extra_field": power_shard(rows=["4,0,1,0,1,62.5,9", "4,1,0,0,0,58.3", "4,2,1,1,1,66.7"]),
    "flag_2": power_shard(rows=["4,0,2,0,1,62.5", "4,1,0,0,0,58.3", "4,2,1,1,1,66.7"]),
    "mean_nan": power_shard(rows=["4,0,1,0,1,nan", "4,1,0,0,0,58.3", "4,2,1,1,1,66.7"]),
    "mean_1e999": power_shard(rows=["4,0,1,0,1,1e999", "4,1,0,0,0,58.3", "4,2,1,1,1,66.7"]),
    "mean_150": power_shard(rows=["4,0,1,0,1,150", "4,1,0,0,0,58.3", "4,2,1,1,1,66.7"]),
    "long_line": power_shard(rows=["4,0,1,0,1," + "6" * (100 << 10)]),
}
for name, text in power_shard_cases.items():
    write("power_shard", name + ".csv", text)

# ------------------------------------------------------------------ stimulus shard manifest (through build-stimuli --merge)
# A one-shard split of ../experiment/protocol.toml; the header as
# `build-stimuli --shard 0/1` writes it, each case one change (the
# inputs hash cannot be made here, so a well-formed shard stops at it).
import hashlib
BUILDER_VERSION = re.search(r'builder_version = "([^"]+)"', (DATA.parent.parent / "stimuli" / "src" / "builder.cpp").read_text()).group(1)
protocol_sha = hashlib.sha256((DATA / "experiment" / "protocol.toml").read_bytes()).hexdigest()
shard_manifest = {"format": "avsi-stimuli-shard", "version": 1, "shard": 0, "shards": 1, "protocol": "protocol.toml",
                  "protocol_sha256": protocol_sha, "inputs_sha256": "0" * 64, "builder": BUILDER_VERSION,
                  "avsi": AVSI_VERSION, "stimuli": []}
command("stimuli_shard", """
copy {data}/experiment/protocol.toml
copy {data}/experiment/corpus.csv
name shards/shard-0-of-1.json
args build-stimuli {dir}/protocol.toml --out {dir} --merge
""")
def shard_with(**changes):
    m = dict(shard_manifest)
    m.update(changes)
    return json.dumps(m, indent=2)
stimuli_shard_cases = {
    "empty": "",
    "truncated": shard_with()[:80],
    "deep_nesting": '{"format": "avsi-stimuli-shard", "stimuli": ' + NESTED + "}",
    "number_overflow": shard_with().replace('"version": 1', '"version": 1e999'),
    "wrong_format": shard_with(format="avsi-stimuli-manifest"),
    "version_2": shard_with(version=2),
    "claims_other_shard": shard_with(shard=1, shards=2),
    "foreign_protocol": shard_with(protocol_sha256="f" * 64),
    "other_avsi": shard_with(avsi="0.0.1"),
    "inputs_changed": shard_with(),
}
for name, text in stimuli_shard_cases.items():
    write("stimuli_shard", name + ".json", text)

# ------------------------------------------------------------------ optical markers (through avsi markers)
def c3d(points=3, frames=10, scale=0.1, rate=60.0, frames_param=None, data_start=None, cut=0, param_blocks=1,
        next_offset=None, processor=84, units="mm"):
    """A small Intel C3D file: header block, a POINT group, int16 data (or
    float when scale < 0); one broken field per case."""
    def param(name, ptype, dims, data):
        body = struct.pack("<bB", ptype, len(dims)) + bytes(dims) + data + b"\0"
        return struct.pack("<bb", len(name), 1) + name.encode() + struct.pack("<h", 2 + len(body)) + body
    start = data_start if data_start is not None else 2 + param_blocks
    labels = [f"M{i + 1:02d}" for i in range(points)]
    fr = struct.pack("<f", frames_param) if frames_param is not None else struct.pack("<h", frames)
    ps = b"".join([
        param("USED", 2, [], struct.pack("<h", points)),
        param("SCALE", 4, [], struct.pack("<f", scale)),
        param("RATE", 4, [], struct.pack("<f", rate)),
        param("DATA_START", 2, [], struct.pack("<h", start)),
        param("FRAMES", 4 if frames_param is not None else 2, [], fr),
        param("UNITS", -1, [len(units)], units.encode()),
        param("LABELS", -1, [4, points], b"".join(l.ljust(4).encode() for l in labels)),
    ])
    group = struct.pack("<bb", 5, -1) + b"POINT" + struct.pack("<h", next_offset if next_offset is not None else 3) + b"\0"
    section = struct.pack("<BBBB", 1, 0x50, param_blocks, processor) + group + ps + b"\0\0"
    section = section.ljust(512 * param_blocks, b"\0")
    header = struct.pack("<BBhhhhhfhhf", 2, 0x50, points, 0, 1, frames, 10, scale, start, 0, rate).ljust(512, b"\0")
    data = b""
    for f in range(frames):
        for m in range(points):
            if scale > 0:
                data += struct.pack("<hhhh", 100 * m + f, -50 + f, 200 + m, 0x0302 if (f + m) % 4 else -1)
            else:
                data += struct.pack("<ffff", 10.0 * m + f, -5.0 + f, 20.0 + m, 770.0 if (f + m) % 4 else -1.0)
    data = data.ljust((len(data) + 511) // 512 * 512, b"\0")
    out = header + section + data
    return out[:len(out) - cut] if cut else out
command("c3d", "args markers {input} --out {out}/markers.csv")
c3d_cases = {
    "empty.c3d": b"",
    "text.c3d": b"POINT labels, not a C3D file\n" * 30,
    "truncated_data.c3d": c3d(frames=200, cut=512),
    "huge_frames.c3d": c3d(frames_param=1e9),
    "frames_nan.c3d": c3d(frames_param=float("nan")),
    "scale_nan.c3d": c3d(scale=float("nan")),
    "rate_zero.c3d": c3d(rate=0.0),
    "parameter_past_end.c3d": c3d(next_offset=4000),
    "parameter_blocks_past_end.c3d": c3d(param_blocks=200, frames=1)[:2048],
    "data_start_in_parameters.c3d": c3d(data_start=2),
    "processor_unknown.c3d": c3d(processor=90),
    "units_inches.c3d": c3d(units="in"),
    "float_coordinate_nan.c3d": c3d(scale=-0.1).replace(struct.pack("<f", 11.0), struct.pack("<f", float("nan")), 1),
}
for name, content in c3d_cases.items():
    write("c3d", name, content)
command("qualisys", "args markers {input} --out {out}/markers.csv")
QTM = ("NO_OF_FRAMES\t2\nNO_OF_CAMERAS\t4\nNO_OF_MARKERS\t2\nFREQUENCY\t60\nNO_OF_ANALOG\t0\n"
       "DATA_INCLUDED\t3D\nMARKER_NAMES\tA\tB\nFrame\tTime\tA X\tA Y\tA Z\tB X\tB Y\tB Z\n"
       "1\t0.000\t1.0\t2.0\t3.0\t4.0\t5.0\t6.0\n2\t0.017\t1.1\t2.1\t3.1\t4.1\t5.1\t6.1\n")
qualisys_cases = {
    "empty.tsv": "",
    "no_frequency.tsv": QTM.replace("FREQUENCY\t60\n", ""),
    "frequency_nan.tsv": QTM.replace("FREQUENCY\t60", "FREQUENCY\tnan"),
    "marker_count_wrong.tsv": QTM.replace("NO_OF_MARKERS\t2", "NO_OF_MARKERS\t3"),
    "frame_count_huge.tsv": QTM.replace("NO_OF_FRAMES\t2", "NO_OF_FRAMES\t1000000000"),
    "short_row.tsv": QTM.replace("\t6.1\n", "\n"),
    "coordinate_word.tsv": QTM.replace("\t5.1\t", "\tfive\t"),
    "coordinate_1e300.tsv": QTM.replace("\t5.1\t", "\t1e300\t"),
}
for name, content in qualisys_cases.items():
    write("qualisys", name, content)
command("motive", "args markers {input} --out {out}/markers.csv")
MOTIVE = ("Format Version,1.23,Take Name,t,Export Frame Rate,120.000000,Length Units,Meters\n\n"
          "Type,,Marker,Marker,Marker\nName,,A,A,A\nID,,1,1,1\n,,Position,Position,Position\n"
          "Frame,Time (Seconds),X,Y,Z\n0,0.000000,0.1,0.2,0.3\n1,0.008333,0.1,0.2,0.3\n")
motive_cases = {
    "empty.csv": "",
    "not_motive.csv": "time_s,a_x\n0,1\n",
    "no_units.csv": MOTIVE.replace(",Length Units,Meters", ""),
    "units_feet.csv": MOTIVE.replace("Meters", "Feet"),
    "rate_negative.csv": MOTIVE.replace("120.000000", "-120"),
    "no_frame_row.csv": MOTIVE.replace("Frame,Time", "Frames,Time"),
    "long_row.csv": MOTIVE.replace("0.1,0.2,0.3\n1,", "0.1,0.2,0.3,0.4\n1,"),
    "coordinate_word.csv": MOTIVE.replace("1,0.008333,0.1", "1,0.008333,x"),
    "half_dropout.csv": MOTIVE.replace("1,0.008333,0.1,0.2,0.3", "1,0.008333,0.1,,"),
}
for name, content in motive_cases.items():
    write("motive", name, content)

# ------------------------------------------------------------------ pronunciation table and phonemes.csv
ph = DATA / "analysis" / "phonemes"
pron = (ph / "pronunciations.tsv").read_text()
pl = pron.splitlines(keepends=True)
command("pronunciations", "args score --corpus {data}/analysis/phonemes/corpus.csv --responses "
        "{data}/analysis/phonemes/responses.csv --phonemes --pronunciations {input} --out {out}/scores")
pronunciation_cases = {
    "unknown_phone": "".join(pl[:3]) + pl[3].replace("G", "QQ", 1) + "".join(pl[4:]),
    "repeated_word": "".join(pl) + pl[2],
    "no_tab": "".join(pl) + "garden G AA1 R D AH0 N\n",
    "two_words": "".join(pl) + "big dog\tB IH1 G D AO1 G\n",
    "no_phones": "".join(pl) + "garden\t \n",
}
for name, text in pronunciation_cases.items():
    write("pronunciations", name + ".tsv", text)

phonemes = ("subject,condition,sentence,position,target,response,outcome\n"
            "a,audio,s1,1,DH,DH,correct\na,audio,s1,2,AH,AH,correct\na,audio,s1,3,B,P,substituted\n"
            "b,face,s1,1,DH,,deleted\nb,face,s1,1,,AH,inserted\n")
ql = phonemes.splitlines(keepends=True)
command("phonemes", "args analyze {data}/analysis/balanced.csv --out {out}/report --phonemes {input}")
phoneme_cases = {
    "empty": "",
    "missing_column": "".join(",".join(l.split(",")[:-1]) + "\n" for l in ql),
    "unknown_phone": "".join(ql[:3]) + ql[3].replace(",P,", ",QQ,", 1) + "".join(ql[4:]),
    "bad_outcome": "".join(ql[:2]) + ql[2].replace("correct", "right", 1) + "".join(ql[3:]),
    "outcome_does_not_fit": "".join(ql[:3]) + ql[3].replace("substituted", "correct", 1) + "".join(ql[4:]),
    "bad_position": "".join(ql[:1]) + ql[1].replace(",1,", ",-1,", 1) + "".join(ql[2:]),
    "short_row": "".join(ql) + "a,audio\n",
}
for name, text in phoneme_cases.items():
    write("phonemes", name + ".csv", text)

print("written")
