// Articulatory corpus: manifest, parameter track CSV, seeded split, corpus
// hash (see articulatory_corpus.h; Beskow §4.1 for the 200/87 split).
#include "avsi/learn/articulatory_corpus.h"

#include <algorithm>
#include <cmath>
#include <future>
#include <limits>
#include <map>
#include <set>
#include <system_error>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "avsi/core/checks.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "avsi/core/labels.h"
#include "avsi/core/rng.h"
#include "avsi/core/text.h"
#include "avsi/learn/haskins_mat.h"

namespace avsi::learn {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// How far labels may run past the end of their track.
constexpr double k_label_overrun_s = 1.0;

std::vector<std::string> param_names() {
    std::vector<std::string> names;
    for (const auto& info : params()) names.emplace_back(info.name);
    return names;
}

TrackKind default_kind(const fs::path& track) {
    const std::string ext = ascii_lower(track.extension().string());
    return (ext == ".ema" || ext == ".est" || ext == ".track" || ext == ".mat") ? TrackKind::Sensors
                                                                                : TrackKind::Parameters;
}

}  // namespace

ParamTrack read_param_track_csv(const fs::path& path) {
    const CsvTable table = read_csv(path);
    std::optional<std::size_t> time_col = table.column("time_s");
    if (!time_col) time_col = table.column("time");
    if (!time_col) time_col = table.require_column("time_s");
    ParamTrack track;
    std::vector<std::pair<std::size_t, std::size_t>> cols;  // csv column → parameter index
    DiagnosticList problems;
    for (std::size_t c = 0; c < table.header.size(); ++c) {
        if (c == *time_col) continue;
        const auto p = param_from_name(table.header[c]);
        if (!p) {
            const std::string hint = closest_match(table.header[c], param_names());
            problems.add(table.path, 1, static_cast<int>(c + 1), table.header[c],
                         fmt::format("unknown parameter column{}; expected time_s and any of the 10 "
                                     "parameters (jaw_rotation, lip_rounding, …)",
                                     hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
            continue;
        }
        if (track.present[index(*p)])
            problems.add(table.path, 1, static_cast<int>(c + 1), table.header[c], "duplicate parameter column");
        track.present[index(*p)] = true;
        cols.emplace_back(c, index(*p));
    }
    problems.throw_if_any();
    if (table.rows.size() < 2)
        throw InputError(table.path, 0, 0, "rows", fmt::format("expected at least 2 frames, got {}", table.rows.size()));
    std::vector<double> times;
    for (const auto& row : table.rows) {
        if (row.fields.size() != table.header.size()) {
            problems.add(table.path, row.line, 1, "row",
                         fmt::format("expected {} fields, got {}", table.header.size(), row.fields.size()));
            continue;
        }
        const auto t = parse_double(row.fields[*time_col]);
        if (!t) {
            problems.add(table.path, row.line, 0, table.header[*time_col],
                         fmt::format("expected a time in seconds, got \"{}\"", row.fields[*time_col]));
            continue;
        }
        require_time_s(*t, at(table.path, row.line, static_cast<int>(*time_col) + 1, table.header[*time_col]));
        times.push_back(*t);
        Frame f;
        f.fill(missing_value);
        for (const auto& [c, p] : cols) {
            const std::string& field = row.fields[c];
            if (field.empty() || ascii_lower(field) == "nan") continue;
            const auto v = parse_double(field);
            if (!v)
                problems.add(table.path, row.line, 0, table.header[c],
                             fmt::format("expected a number, empty or nan, got \"{}\"", field));
            else {
                // Within one range width beyond the parameter's documented range.
                const auto& info = params()[p];
                try {
                    f[p] = require_near_range(*v, info.min, info.max, 1.0,
                                              at(table.path, row.line, static_cast<int>(c) + 1, table.header[c]));
                } catch (const InputError& e) {
                    problems.add(e.first());
                }
            }
        }
        track.frames.push_back(f);
    }
    problems.throw_if_any();
    const double step = (times.back() - times.front()) / static_cast<double>(times.size() - 1);
    if (!(step > 0.0))
        throw InputError(table.path, table.rows.back().line, 0, table.header[*time_col], "expected increasing times");
    for (std::size_t k = 0; k < times.size(); ++k) {
        const double expected = times.front() + static_cast<double>(k) * step;
        if (std::abs(times[k] - expected) > 0.01 * step + 1e-6)
            throw InputError(table.path, table.rows[k].line, 0, table.header[*time_col],
                             fmt::format("expected a constant frame step of {:.6f} s (time {:.6f}), got {:.6f}",
                                         step, expected, times[k]));
    }
    track.fps = 1.0 / step;
    // Snap to a whole rate when the times are rounded (e.g. 0.016667 → 60).
    if (std::abs(track.fps - std::round(track.fps)) < 1e-3 * track.fps) track.fps = std::round(track.fps);
    track.start_s = times.front();
    return track;
}

void write_param_track_csv(const fs::path& path, const ParamTrack& track) {
    std::string out = "time_s";
    for (const auto& info : params())
        if (track.present[index(info.param)]) out += fmt::format(",{}", info.name);
    out += '\n';
    for (std::size_t k = 0; k < track.size(); ++k) {
        out += fmt::format("{:.6f}", track.time_s(k));
        for (std::size_t p = 0; p < param_count; ++p) {
            if (!track.present[p]) continue;
            const double v = track.frames[k][p];
            out += std::isfinite(v) ? fmt::format(",{:.6f}", v) : std::string(",");
        }
        out += '\n';
    }
    write_text_file(path, out);
}

namespace {

std::optional<SplitPart> parse_split(const std::string& text, DiagnosticList& problems, const std::string& path,
                                     int line, const std::string& field) {
    if (text.empty()) return std::nullopt;
    if (text == "train") return SplitPart::Train;
    if (text == "test") return SplitPart::Test;
    problems.add(path, line, 0, field, fmt::format("expected \"train\", \"test\" or nothing, got \"{}\"", text));
    return std::nullopt;
}

std::optional<TrackKind> parse_kind(const std::string& text, const fs::path& track, DiagnosticList& problems,
                                    const std::string& path, int line, const std::string& field) {
    if (text.empty()) return default_kind(track);
    if (text == "parameters") return TrackKind::Parameters;
    if (text == "sensors") return TrackKind::Sensors;
    problems.add(path, line, 0, field, fmt::format("expected \"parameters\" or \"sensors\", got \"{}\"", text));
    return std::nullopt;
}

void read_mapping(const json& j, SensorMappingSettings& s, DiagnosticList& problems, const std::string& path) {
    static const std::vector<std::string> keys = {
        "preset", "upper_incisor", "lower_incisor", "upper_lip", "lower_lip", "reference_sensors", "x_suffix",
        "y_suffix", "mm_per_unit", "rest_percentile", "jaw_opening_full_mm", "jaw_thrust_full_mm",
        "lip_vertical_full_mm", "lip_protrusion_full_mm", "fps", "lateral_suffix", "lateral_positive_left",
        "mouth_corner_left", "mouth_corner_right", "jaw_shift_full_mm", "corner_stretch_full_mm"};
    if (!j.is_object()) {
        problems.add(path, 0, 0, "sensor_mapping", "expected an object");
        return;
    }
    // A preset first; the other keys change it.
    if (j.contains("preset")) {
        const json& v = j["preset"];
        const auto preset = v.is_string() ? sensor_mapping_preset(v.get<std::string>()) : std::nullopt;
        if (!preset)
            problems.add(path, 0, 0, "sensor_mapping.preset",
                         fmt::format("expected \"mocha\" or \"haskins\", got {}", v.dump()));
        else
            s = *preset;
    }
    for (const auto& [key, value] : j.items()) {
        const std::string field = "sensor_mapping." + key;
        try {
            if (key == "preset") continue;
            else if (key == "upper_incisor") s.upper_incisor = value.get<std::string>();
            else if (key == "lower_incisor") s.lower_incisor = value.get<std::string>();
            else if (key == "upper_lip") s.upper_lip = value.get<std::string>();
            else if (key == "lower_lip") s.lower_lip = value.get<std::string>();
            else if (key == "reference_sensors") s.reference_sensors = value.get<std::vector<std::string>>();
            else if (key == "x_suffix") s.x_suffix = value.get<std::string>();
            else if (key == "y_suffix") s.y_suffix = value.get<std::string>();
            else if (key == "mm_per_unit") s.mm_per_unit = value.get<double>();
            else if (key == "rest_percentile") s.rest_percentile = value.get<double>();
            else if (key == "jaw_opening_full_mm") s.jaw_opening_full_mm = value.get<double>();
            else if (key == "jaw_thrust_full_mm") s.jaw_thrust_full_mm = value.get<double>();
            else if (key == "lip_vertical_full_mm") s.lip_vertical_full_mm = value.get<double>();
            else if (key == "lip_protrusion_full_mm") s.lip_protrusion_full_mm = value.get<double>();
            else if (key == "fps") s.fps = value.get<double>();
            else if (key == "lateral_suffix") s.lateral_suffix = value.get<std::string>();
            else if (key == "lateral_positive_left") s.lateral_positive_left = value.get<bool>();
            else if (key == "mouth_corner_left") s.mouth_corner_left = value.get<std::string>();
            else if (key == "mouth_corner_right") s.mouth_corner_right = value.get<std::string>();
            else if (key == "jaw_shift_full_mm") s.jaw_shift_full_mm = value.get<double>();
            else if (key == "corner_stretch_full_mm") s.corner_stretch_full_mm = value.get<double>();
            else {
                const std::string hint = closest_match(key, keys);
                problems.add(path, 0, 0, field,
                             fmt::format("unknown key{}", hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
            }
        } catch (const json::exception&) {
            problems.add(path, 0, 0, field, fmt::format("wrong type, got {}", value.dump()));
        }
    }
    for (double v : {s.mm_per_unit, s.jaw_opening_full_mm, s.jaw_thrust_full_mm, s.lip_vertical_full_mm,
                     s.lip_protrusion_full_mm, s.fps, s.jaw_shift_full_mm, s.corner_stretch_full_mm})
        if (!(v > 0.0 && v <= 1e6)) {
            problems.add(path, 0, 0, "sensor_mapping",
                         fmt::format("expected every scale, unit and fps in (0, 1e6], got {}", v));
            break;
        }
    if (!(s.rest_percentile >= 0.0 && s.rest_percentile <= 100.0))
        problems.add(path, 0, 0, "sensor_mapping.rest_percentile",
                     fmt::format("expected a number in [0, 100], got {}", s.rest_percentile));
}

// The manifest's "split" section: the seed and the test fraction.
void read_split_section(const json& s, ArticulatoryCorpus& corpus, DiagnosticList& problems, const std::string& mpath) {
    if (s.contains("seed") && s["seed"].is_number_unsigned()) corpus.split_seed = s["seed"].get<std::uint64_t>();
    else if (s.contains("seed")) problems.add(mpath, 0, 0, "split.seed", fmt::format("expected an integer ≥ 0, got {}", s["seed"].dump()));
    if (s.contains("test_fraction") && s["test_fraction"].is_number()) corpus.test_fraction = s["test_fraction"].get<double>();
    else if (s.contains("test_fraction")) problems.add(mpath, 0, 0, "split.test_fraction", fmt::format("expected a number, got {}", s["test_fraction"].dump()));
    if (!(corpus.test_fraction > 0.0 && corpus.test_fraction < 1.0))
        problems.add(mpath, 0, 0, "split.test_fraction", fmt::format("expected a number in (0, 1), got {}", corpus.test_fraction));
}

// The corpus hash: the manifest, then each utterance's id and files.
std::string corpus_hash(const std::string& manifest_text, const std::vector<CorpusEntry>& entries) {
    std::string digest_input = sha256_hex(manifest_text);
    for (const auto& e : entries) {
        digest_input += "\n" + e.id + " " + sha256_file(e.track) + " " + sha256_file(e.labels);
        if (!e.audio.empty()) digest_input += " " + sha256_file(e.audio);
    }
    return sha256_hex(digest_input);
}

}  // namespace

ArticulatoryCorpus load_articulatory_corpus(const fs::path& dir_or_manifest) {
    ArticulatoryCorpus corpus;
    if (fs::is_directory(dir_or_manifest)) {
        corpus.dir = dir_or_manifest;
        if (fs::exists(dir_or_manifest / "corpus.json"))
            corpus.manifest = dir_or_manifest / "corpus.json";
        else if (fs::exists(dir_or_manifest / "corpus.csv"))
            corpus.manifest = dir_or_manifest / "corpus.csv";
        else
            throw InputError(dir_or_manifest, "not an articulatory corpus: expected corpus.json or corpus.csv in it");
    } else {
        corpus.manifest = dir_or_manifest;
        corpus.dir = dir_or_manifest.parent_path();
    }
    corpus.name = corpus.dir.filename().string();
    const std::string mpath = corpus.manifest.string();
    const std::string text = read_text_file(corpus.manifest);
    DiagnosticList problems;
    std::set<std::string> ids;

    auto add_entry = [&](const std::string& id, const std::string& track, const std::string& labels,
                         const std::string& audio, const std::string& kind, const std::string& split, int line,
                         const std::string& where) {
        if (id.empty()) problems.add(mpath, line, 0, where + ".id", "expected a non-empty id");
        if (!ids.insert(id).second) problems.add(mpath, line, 0, where + ".id", fmt::format("duplicate id \"{}\"", id));
        CorpusEntry e;
        e.id = id;
        e.track = corpus.dir / track;
        // A Haskins .mat holds its own phones: its labels default to the file itself.
        const bool mat = ascii_lower(fs::path(track).extension().string()) == ".mat";
        e.labels = labels.empty() && mat ? e.track : corpus.dir / labels;
        if (!audio.empty()) e.audio = corpus.dir / audio;
        for (const auto& [field, p, required] :
             {std::tuple{"track", e.track, true}, std::tuple{"labels", e.labels, true},
              std::tuple{"audio", e.audio, false}}) {
            if (p.empty() || (!required && p == corpus.dir)) continue;
            // The non-throwing form: a name the system refuses (too long, …) is "not found" too.
            std::error_code ec;
            if (!fs::is_regular_file(p, ec))
                problems.add(mpath, line, 0, where + "." + field,
                             fmt::format("file not found: {}{}", p.string().substr(0, 200),
                                         p.string().size() > 200 ? "…" : ""));
        }
        if (track.empty()) problems.add(mpath, line, 0, where + ".track", "expected a file name");
        if (labels.empty() && !mat) problems.add(mpath, line, 0, where + ".labels", "expected a file name");
        if (auto k = parse_kind(kind, e.track, problems, mpath, line, where + ".kind")) e.kind = *k;
        e.fixed_split = parse_split(split, problems, mpath, line, where + ".split");
        corpus.entries.push_back(std::move(e));
    };

    if (ascii_lower(corpus.manifest.extension().string()) == ".csv") {
        const CsvTable table = parse_csv(text, mpath);
        const std::size_t id = table.require_column("id");
        const std::size_t track = table.require_column("track");
        const std::size_t labels = table.require_column("labels");
        const auto audio = table.column("audio"), kind = table.column("kind"), split = table.column("split");
        for (const auto& row : table.rows) {
            auto get = [&](std::optional<std::size_t> c) {
                return c && *c < row.fields.size() ? row.fields[*c] : std::string();
            };
            add_entry(get(id), get(track), get(labels), get(audio), get(kind), get(split), row.line,
                      fmt::format("row {}", row.line));
        }
    } else {
        const json j = parse_json(text, mpath);
        if (!j.is_object())
            throw InputError(mpath, fmt::format("expected a JSON object (an avsi articulatory corpus manifest), got {}",
                                                j.dump().substr(0, 40)));
        static const std::vector<std::string> top = {"format", "version", "name", "split", "sensor_mapping",
                                                     "utterances", "description", "generator", "synthetic"};
        for (const auto& [key, value] : j.items())
            if (std::find(top.begin(), top.end(), key) == top.end()) {
                const std::string hint = closest_match(key, top);
                problems.add(mpath, 0, 0, key,
                             fmt::format("unknown key{}", hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
            }
        const json* format = j.contains("format") ? &j["format"] : nullptr;
        if (!format || !format->is_string() || format->get<std::string>() != "avsi-articulatory-corpus")
            problems.add(mpath, 0, 0, "format",
                         fmt::format("expected \"avsi-articulatory-corpus\", got {}",
                                     j.contains("format") ? j["format"].dump() : "nothing"));
        if (j.contains("name") && j["name"].is_string()) corpus.name = j["name"].get<std::string>();
        if (j.contains("synthetic")) {
            if (j["synthetic"].is_boolean()) corpus.synthetic = j["synthetic"].get<bool>();
            else problems.add(mpath, 0, 0, "synthetic", fmt::format("expected true or false, got {}", j["synthetic"].dump()));
        }
        if (j.contains("split")) read_split_section(j["split"], corpus, problems, mpath);
        if (j.contains("sensor_mapping")) {
            read_mapping(j["sensor_mapping"], corpus.sensor_mapping, problems, mpath);
            corpus.sensor_mapping_given = true;
        }
        if (!j.contains("utterances") || !j["utterances"].is_array()) {
            problems.add(mpath, 0, 0, "utterances", "expected an array of utterances");
        } else {
            std::size_t i = 0;
            for (const auto& u : j["utterances"]) {
                const std::string where = fmt::format("utterances[{}]", i++);
                auto str = [&](const char* key) {
                    if (!u.contains(key)) return std::string();
                    if (!u[key].is_string()) {
                        problems.add(mpath, 0, 0, where + "." + key, fmt::format("expected a string, got {}", u[key].dump()));
                        return std::string();
                    }
                    return u[key].get<std::string>();
                };
                add_entry(str("id"), str("track"), str("labels"), str("audio"), str("kind"), str("split"), 0, where);
            }
        }
    }
    if (corpus.entries.empty()) problems.add(mpath, 0, 0, "utterances", "the corpus lists no utterances");
    problems.throw_if_any();

    corpus.hash = corpus_hash(text, corpus.entries);
    return corpus;
}

CorpusSplit split_corpus(const ArticulatoryCorpus& corpus, const SplitSettings& settings) {
    CorpusSplit split;
    split.seed = settings.seed.value_or(corpus.split_seed);
    split.test_fraction = settings.test_fraction.value_or(corpus.test_fraction);
    if (!(split.test_fraction > 0.0 && split.test_fraction < 1.0))
        throw InputError("", 0, 0, "test_fraction", fmt::format("expected a number in (0, 1), got {}", split.test_fraction));
    std::vector<std::size_t> free;
    std::vector<bool> is_test(corpus.entries.size(), false);
    for (std::size_t i = 0; i < corpus.entries.size(); ++i) {
        if (corpus.entries[i].fixed_split)
            is_test[i] = *corpus.entries[i].fixed_split == SplitPart::Test;
        else
            free.push_back(i);
    }
    // Fisher-Yates with the project's platform-independent RNG.
    Rng rng(split.seed);
    for (std::size_t i = free.size(); i > 1; --i) std::swap(free[i - 1], free[rng.uniform_int(i)]);
    const auto n_test = static_cast<std::size_t>(std::llround(static_cast<double>(free.size()) * split.test_fraction));
    for (std::size_t i = 0; i < n_test; ++i) is_test[free[i]] = true;
    for (std::size_t i = 0; i < corpus.entries.size(); ++i)
        (is_test[i] ? split.test_ids : split.train_ids).push_back(corpus.entries[i].id);
    return split;
}

CorpusUtterance load_corpus_utterance(const ArticulatoryCorpus& corpus, const CorpusEntry& entry) {
    CorpusUtterance u;
    u.id = entry.id;
    const bool mat = ascii_lower(entry.track.extension().string()) == ".mat";
    if (mat && entry.kind == TrackKind::Sensors) {
        // A Haskins recording: sensors, and (when it is its own label file) phones.
        const HaskinsRecording rec = read_haskins_mat(entry.track);
        if (entry.labels == entry.track) {
            check_label_times(rec.phones, entry.track.string(), "seconds", 1.0);
            u.phones = phones_from_intervals(rec.phones, entry.track.string(), LabelPhoneSet::Arpabet);
        } else {
            u.phones = read_phones(entry.labels);
        }
        const SensorMappingSettings mapping =
            corpus.sensor_mapping_given ? corpus.sensor_mapping : *sensor_mapping_preset("haskins");
        u.track = map_sensors_to_params(rec.track, mapping, entry.track.string());
    } else {
        u.phones = read_phones(entry.labels);
        if (entry.kind == TrackKind::Parameters)
            u.track = read_param_track_csv(entry.track);
        else
            u.track = map_sensors_to_params(read_sensor_file(entry.track), corpus.sensor_mapping, entry.track.string());
    }
    if (u.phones.empty()) throw InputError(entry.labels, "no phones in the label file");
    // The labels must describe this track: ending at most k_label_overrun_s
    // after its last frame (aligners round the final silence).
    const double track_end_s =
        u.track.start_s + static_cast<double>(u.track.frames.size() > 0 ? u.track.frames.size() - 1 : 0) / u.track.fps;
    if (u.phones.back().end_s > track_end_s + k_label_overrun_s)
        throw InputError(entry.labels, 0, 0, "end",
                         fmt::format("expected the labels to end by {:.3f} s (the track {} ends at {:.3f} s, plus "
                                     "{} s), got {:.3f} s",
                                     track_end_s + k_label_overrun_s, entry.track.string(), track_end_s,
                                     k_label_overrun_s, u.phones.back().end_s));
    return u;
}

std::vector<CorpusUtterance> load_corpus_utterances(const ArticulatoryCorpus& corpus,
                                                    const std::vector<std::string>& ids) {
    std::map<std::string, const CorpusEntry*> by_id;
    for (const auto& e : corpus.entries) by_id[e.id] = &e;
    std::vector<const CorpusEntry*> wanted;
    for (const auto& id : ids) {
        const auto it = by_id.find(id);
        if (it == by_id.end()) throw InputError(corpus.manifest, fmt::format("no utterance \"{}\" in the corpus", id));
        wanted.push_back(it->second);
    }
    std::vector<CorpusUtterance> out(wanted.size());
    const std::size_t workers = std::max<std::size_t>(1, std::min<std::size_t>(std::thread::hardware_concurrency(), 8));
    std::vector<std::future<void>> jobs;
    for (std::size_t w = 0; w < workers; ++w)
        jobs.push_back(std::async(std::launch::async, [&, w] {
            for (std::size_t i = w; i < wanted.size(); i += workers) out[i] = load_corpus_utterance(corpus, *wanted[i]);
        }));
    for (auto& j : jobs) j.get();
    return out;
}

void write_corpus_manifest(const fs::path& dir, const std::string& name, const std::vector<CorpusEntry>& entries,
                           std::uint64_t split_seed, double test_fraction, bool synthetic) {
    json j;
    j["format"] = "avsi-articulatory-corpus";
    j["version"] = 1;
    j["name"] = name;
    if (synthetic) j["synthetic"] = true;
    j["split"] = {{"seed", split_seed}, {"test_fraction", test_fraction}};
    j["utterances"] = json::array();
    for (const auto& e : entries) {
        json u;
        u["id"] = e.id;
        u["track"] = fs::relative(e.track, dir).generic_string();
        u["labels"] = fs::relative(e.labels, dir).generic_string();
        if (!e.audio.empty()) u["audio"] = fs::relative(e.audio, dir).generic_string();
        u["kind"] = e.kind == TrackKind::Parameters ? "parameters" : "sensors";
        if (e.fixed_split) u["split"] = *e.fixed_split == SplitPart::Train ? "train" : "test";
        j["utterances"].push_back(u);
    }
    write_text_file(dir / "corpus.json", j.dump(2) + "\n");
}

std::optional<std::size_t> phone_at(const PhoneSequence& phones, double time_s) {
    if (phones.empty() || time_s < phones.front().start_s || time_s > phones.back().end_s) return std::nullopt;
    const auto it = std::upper_bound(phones.begin(), phones.end(), time_s,
                                     [](double t, const Phone& p) { return t < p.start_s; });
    if (it == phones.begin()) return std::nullopt;
    const std::size_t i = static_cast<std::size_t>(it - phones.begin()) - 1;
    if (time_s < phones[i].end_s || i + 1 == phones.size()) return i;
    return std::nullopt;
}

}  // namespace avsi::learn
