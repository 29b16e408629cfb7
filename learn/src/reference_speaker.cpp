// The synthetic reference speaker (reference_speaker.h): overlapping phone
// gestures on lip and jaw tract variables (task dynamics, Saltzman & Munhall
// 1989), solved to the parameters through the built-in head's geometry, over
// espeak-ng-timed English sentences.
#include "avsi/learn/reference_speaker.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <optional>

#include <Eigen/Dense>
#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/labels.h"
#include "avsi/core/log.h"
#include "avsi/core/tts.h"

namespace avsi::learn {

namespace fs = std::filesystem;

namespace {

constexpr std::size_t LA = static_cast<std::size_t>(TractVariable::LipAperture);
constexpr std::size_t LW = static_cast<std::size_t>(TractVariable::LipWidth);
constexpr std::size_t UP = static_cast<std::size_t>(TractVariable::UpperProtrusion);
constexpr std::size_t LP = static_cast<std::size_t>(TractVariable::LowerProtrusion);
constexpr std::size_t JO = static_cast<std::size_t>(TractVariable::JawOpening);

// The source speaker's rest values in task_targets.tsv (its header):
// lips touching, 54 mm wide, protrusion 0, jaw 2.2 mm below teeth together.
constexpr double source_rest_width_mm = 54.0;
constexpr double source_rest_jaw_mm = 2.2;

// Blending strengths (Saltzman & Munhall's α) and the rest attractor's.
constexpr double consonant_strength = 100.0;
constexpr double vowel_strength = 1.0;
constexpr double rest_strength = 0.01;
constexpr double ramp_s = 0.010;  // raised-cosine activation ramps

using TaskVector = std::array<double, tract_variable_count>;

// A gesture: an activation interval, its targets on the face (mm), its
// blending strength, and its duration-limited stiffness.
struct Gesture {
    double on_s, off_s;
    std::array<std::optional<double>, tract_variable_count> target;
    double strength;
    bool consonant;
};

// Activation at t: 0 before on − ramp/2, 1 from on + ramp/2 to off − ramp/2.
double activation(const Gesture& g, double t) {
    auto rise = [](double x) { return x <= -0.5 ? 0.0 : x >= 0.5 ? 1.0 : 0.5 - 0.5 * std::cos(M_PI * (x + 0.5)); };
    return std::min(rise((t - g.on_s) / ramp_s), rise((g.off_s - t) / ramp_s));
}

// A source-speaker target (task_targets.tsv) as a tract-variable value on the face.
double on_face(std::size_t tv, double source_mm, const TaskGeometry& geometry) {
    switch (static_cast<TractVariable>(tv)) {
        case TractVariable::LipWidth: return geometry.at_rest_mm[LW] * source_mm / source_rest_width_mm;
        case TractVariable::JawOpening: return geometry.at_rest_mm[JO] + (source_mm - source_rest_jaw_mm);
        default: return source_mm;  // aperture (0 = contact) and protrusion from rest carry over
    }
}

bool is_vowel_symbol(const std::string& s) { return PhoneInventory::builtin().is_vowel(s); }

// The gestures of an utterance, with the variation's articulation scale and stress.
std::vector<Gesture> gestures(const PhoneSequence& phones, const std::map<std::string, PhoneGestures, std::less<>>& table,
                              const UtteranceVariation& v, const TaskGeometry& geometry) {
    std::vector<Gesture> out;
    for (std::size_t i = 0; i < phones.size(); ++i) {
        const Phone& ph = phones[i];
        const auto it = table.find(ph.symbol);
        if (it == table.end())
            throw InputError("", 0, 0, "phone",
                             fmt::format("the reference speaker has no gesture targets for phone \"{}\" "
                                         "(protocols/reference/task_targets.tsv)",
                                         ph.symbol));
        const bool vowel = is_vowel_symbol(ph.symbol);
        const bool consonant = !vowel && ph.symbol != "sil";
        const double stress = vowel ? (ph.stressed ? 1.10 : 0.85) : 1.0;
        double on = ph.start_s;
        // Onset consonant and nucleus in phase: the vowel starts with the consonant before it.
        if (vowel && i > 0 && phones[i - 1].symbol != "sil" && !is_vowel_symbol(phones[i - 1].symbol))
            on = phones[i - 1].start_s;
        auto make = [&](const GestureTargets& t, double from, double to) {
            Gesture g{from, to, {}, consonant ? consonant_strength : vowel_strength, consonant};
            for (std::size_t tv = 0; tv < tract_variable_count; ++tv) {
                if (!t.target_mm[tv]) continue;
                const double rest = geometry.at_rest_mm[tv];
                // Vowels are hypo- or hyperarticulated (scale, stress);
                // consonants make their constrictions as they are.
                const double scale = consonant ? 1.0 : stress * v.articulation_scale;
                g.target[tv] = rest + (on_face(tv, *t.target_mm[tv], geometry) - rest) * scale;
            }
            return g;
        };
        const PhoneGestures& pg = it->second;
        if (pg.second) {
            out.push_back(make(pg.first, on, ph.centre_s()));
            out.push_back(make(*pg.second, ph.centre_s(), ph.end_s));
        } else {
            out.push_back(make(pg.first, on, ph.end_s));
        }
    }
    return out;
}

}  // namespace

std::string_view tract_variable_name(TractVariable tv) {
    switch (tv) {
        case TractVariable::LipAperture: return "lip_aperture";
        case TractVariable::LipWidth: return "lip_width";
        case TractVariable::UpperProtrusion: return "upper_protrusion";
        case TractVariable::LowerProtrusion: return "lower_protrusion";
        case TractVariable::JawOpening: return "jaw_opening";
        case TractVariable::Count: break;
    }
    return "?";
}

const std::array<double, tract_variable_count>& reference_time_constants() {
    // Lips and jaw: aperture fastest, protrusion slowest (rounding builds up
    // over a syllable), width and jaw between.
    static const std::array<double, tract_variable_count> tau{0.020, 0.035, 0.040, 0.040, 0.025};
    return tau;
}

std::map<std::string, PhoneGestures, std::less<>> read_task_targets(const fs::path& path_in) {
    const fs::path path =
        path_in.empty() ? fs::path(AVSI_PROTOCOLS_DIR) / "reference" / "task_targets.tsv" : path_in;
    const std::string text = read_text_file(path);
    static const std::array<const char*, tract_variable_count> columns{
        "lip_aperture_mm", "lip_width_mm", "upper_protrusion_mm", "lower_protrusion_mm", "jaw_opening_mm"};
    std::map<std::string, PhoneGestures, std::less<>> out;
    std::vector<std::string> header;
    std::size_t pos = 0;
    int line_no = 0;
    while (pos < text.size()) {
        std::size_t eol = text.find('\n', pos);
        if (eol == std::string::npos) eol = text.size();
        const std::string line = text.substr(pos, eol - pos);
        pos = eol + 1;
        ++line_no;
        if (line.empty() || line[0] == '#') continue;
        std::vector<std::string> fields;
        for (std::size_t a = 0;;) {
            const std::size_t b = line.find('\t', a);
            fields.push_back(line.substr(a, b == std::string::npos ? std::string::npos : b - a));
            if (b == std::string::npos) break;
            a = b + 1;
        }
        if (header.empty()) {
            header = fields;
            for (const char* c : columns)
                if (std::find(header.begin(), header.end(), c) == header.end())
                    throw InputError(path, line_no, 1, c, "missing column");
            continue;
        }
        if (fields.size() != header.size())
            throw InputError(path, line_no, 1, "",
                             fmt::format("expected {} tab-separated fields, got {}", header.size(), fields.size()));
        GestureTargets g;
        for (std::size_t tv = 0; tv < tract_variable_count; ++tv) {
            const auto c = static_cast<std::size_t>(std::find(header.begin(), header.end(), columns[tv]) - header.begin());
            const std::string& f = fields[c];
            if (f == "-") continue;
            char* end = nullptr;
            const double v = std::strtod(f.c_str(), &end);
            if (f.empty() || end != f.c_str() + f.size() || !std::isfinite(v) || std::fabs(v) > 100.0)
                throw InputError(path, line_no, 1, columns[tv],
                                 fmt::format("expected millimetres in [-100, 100] or \"-\", got \"{}\"", f));
            g.target_mm[tv] = v;
        }
        std::string phone = fields[0];
        const auto dot = phone.find('.');
        if (dot != std::string::npos) {
            const std::string part = phone.substr(dot + 1);
            phone = phone.substr(0, dot);
            if (part == "1") out[phone].first = g;
            else if (part == "2") out[phone].second = g;
            else throw InputError(path, line_no, 1, "phone", fmt::format("expected PHONE, PHONE.1 or PHONE.2, got \"{}\"", fields[0]));
        } else {
            out[phone].first = g;
        }
    }
    if (out.empty()) throw InputError(path, "no phones in the gesture target table");
    return out;
}

const TaskGeometry& builtin_head_task_geometry() {
    static const TaskGeometry g = [] {
        TaskGeometry t;
        // Measured on the built-in head with `avsi measure` (central
        // differences of ±0.1 per parameter; tests/stimuli checks them
        // against the head). Lip aperture and protrusion with the jaw at
        // 0.5, clear of the lips' contact (at rest the lips touch and the
        // contact halves the aperture's slope); width, protrusion and jaw
        // opening at rest, the lower lip's and the jaw's slopes averaged over
        // both poses. Columns in study order: jaw_rotation, lip_rounding,
        // upper_lip_retraction, upper_lip_raise, lower_lip_retraction,
        // lower_lip_depression, corner_left, corner_right, jaw_thrust, jaw_shift.
        t.mm_per_unit = {{
            {19.52, 1.87, -0.37, 5.22, -4.25, 12.27, 0.22, 0.00, 0.11, 0.01},    // lip aperture
            {-8.17, -11.42, -1.00, 2.35, -0.84, -0.23, 3.92, 3.92, 0.00, -0.11}, // lip width
            {0.07, 2.68, -6.82, 0.72, -0.20, 0.00, -0.03, -0.03, 0.00, 0.00},    // upper lip protrusion
            {-13.48, 5.62, -1.40, 0.00, -3.62, -2.49, 0.08, -0.24, 6.39, 0.00},  // lower lip protrusion
            {21.41, 0.00, 0.00, 0.00, 0.00, 0.00, 0.00, 0.00, -3.93, 0.00},      // jaw opening
        }};
        t.at_rest_mm = {0.14, 46.58, 0.0, 0.0, 0.0};
        // Moving the jaw costs more than moving the lips; jaw_thrust and
        // jaw_shift are left to posture and drift.
        t.cost = {4.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1e6, 1e6};
        return t;
    }();
    return g;
}

Frame parameters_of_tract_variables(const TaskVector& z, const TaskGeometry& geometry) {
    using Eigen::Index;
    Eigen::Matrix<double, tract_variable_count, param_count> J;
    Eigen::Matrix<double, param_count, 1> w_inv;
    Eigen::Matrix<double, tract_variable_count, 1> dz;
    for (std::size_t r = 0; r < tract_variable_count; ++r) {
        for (std::size_t c = 0; c < param_count; ++c) J(Index(r), Index(c)) = geometry.mm_per_unit[r][c];
        dz(Index(r)) = z[r] - geometry.at_rest_mm[r];
    }
    for (std::size_t c = 0; c < param_count; ++c) w_inv(Index(c)) = 1.0 / geometry.cost[c];
    const Eigen::Matrix<double, param_count, tract_variable_count> WJt = w_inv.asDiagonal() * J.transpose();
    const Eigen::Matrix<double, tract_variable_count, tract_variable_count> A = J * WJt;
    const Eigen::Matrix<double, param_count, 1> dp = WJt * A.ldlt().solve(dz);
    Frame f{};
    for (std::size_t c = 0; c < param_count; ++c) f[c] = params()[c].neutral + dp(Index(c));
    return f;
}

std::vector<TaskVector> simulate_tract_variables(const PhoneSequence& phones, const UtteranceVariation& variation,
                                                 const ReferenceSpeakerSettings& settings) {
    AVSI_ASSERT(!phones.empty() && settings.fps > 0 && settings.simulation_step_s > 0);
    const TaskGeometry& geometry = builtin_head_task_geometry();
    auto table = read_task_targets(settings.targets_path);
    if (!settings.language_targets_path.empty())
        for (auto& [phone, g] : read_task_targets(settings.language_targets_path)) {
            if (table.count(phone))
                throw InputError(settings.language_targets_path, 0, 0, "phone",
                                 fmt::format("\"{}\" has a row in {} already", phone,
                                             settings.targets_path.empty() ? "the shipped task_targets.tsv"
                                                                           : settings.targets_path.string()));
            table[phone] = g;
        }
    const std::vector<Gesture> gs = gestures(phones, table, variation, geometry);
    const std::size_t frames = frame_count(phones.back().end_s, settings.fps);
    std::vector<TaskVector> out(frames);
    const double dt = settings.simulation_step_s;
    TaskVector z = geometry.at_rest_mm, v{};
    std::array<double, tract_variable_count> tau{};
    for (std::size_t tv = 0; tv < tract_variable_count; ++tv)
        tau[tv] = reference_time_constants()[tv] *
                  (variation.time_constant_scale[tv] > 0 ? variation.time_constant_scale[tv] : 1.0);
    std::size_t first = 0, k = 0;
    for (double time = 0.0; k < frames; time += dt) {
        while (k < frames && static_cast<double>(k) / settings.fps <= time + 1e-12) out[k++] = z;
        while (first < gs.size() && gs[first].off_s + ramp_s < time) ++first;
        for (std::size_t tv = 0; tv < tract_variable_count; ++tv) {
            double num = rest_strength * geometry.at_rest_mm[tv], den = rest_strength, stiff_tau = tau[tv];
            for (std::size_t g = first; g < gs.size() && gs[g].on_s - ramp_s <= time; ++g) {
                if (!gs[g].target[tv]) continue;
                const double a = activation(gs[g], time) * gs[g].strength;
                if (a <= 0.0) continue;
                num += a * *gs[g].target[tv];
                den += a;
                if (gs[g].consonant) stiff_tau = std::min(stiff_tau, (gs[g].off_s - gs[g].on_s) / 6.0);
            }
            const double target = num / den;
            const double t = std::max(stiff_tau, 4.0 * dt);  // stable for the step
            // Semi-implicit Euler on z'' = (z* − z)/τ² − 2z'/τ.
            v[tv] += dt * ((target - z[tv]) / (t * t) - 2.0 * v[tv] / t);
            z[tv] += dt * v[tv];
        }
    }
    return out;
}

ParamTrack simulate_reference_speaker(const PhoneSequence& phones, const UtteranceVariation& variation,
                                      const ReferenceSpeakerSettings& settings, Rng& rng) {
    const auto z = simulate_tract_variables(phones, variation, settings);
    ParamTrack track;
    track.fps = settings.fps;
    track.start_s = 0.0;
    track.present.fill(true);
    track.frames.resize(z.size());
    for (std::size_t k = 0; k < z.size(); ++k) {
        Frame f = parameters_of_tract_variables(z[k]);
        for (std::size_t p = 0; p < param_count; ++p) f[p] = std::clamp(f[p] + variation.offset[p], params()[p].min, params()[p].max);
        track.frames[k] = f;
    }
    if (variation.add_noise) {
        // Slow jaw_shift drift: an AR(1) process with a 0.5 s correlation time.
        const double a = std::exp(-1.0 / (0.5 * settings.fps));
        const double drift_sd = settings.jaw_shift_drift_sd * param_info(Param::JawShift).range();
        double drift = rng.normal(0.0, drift_sd);
        for (auto& f : track.frames) {
            drift = a * drift + std::sqrt(1.0 - a * a) * rng.normal(0.0, drift_sd);
            f[index(Param::JawShift)] += drift;
        }
        for (auto& f : track.frames)
            for (std::size_t p = 0; p < param_count; ++p)
                f[p] += rng.normal(0.0, settings.sensor_noise_sd * params()[p].range());
    }
    return track;
}

std::vector<std::string> read_sentence_list(const fs::path& path) {
    const std::string text = read_text_file(path);
    std::vector<std::string> out;
    std::size_t pos = 0;
    while (pos < text.size()) {
        std::size_t eol = text.find('\n', pos);
        if (eol == std::string::npos) eol = text.size();
        std::string line = text.substr(pos, eol - pos);
        pos = eol + 1;
        while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t')) line.pop_back();
        const auto first = line.find_first_not_of(" \t");
        if (first == std::string::npos || line[first] == '#') continue;
        out.push_back(line.substr(first));
    }
    if (out.empty()) throw InputError(path, "no sentences in the list");
    return out;
}

void resolve_reference_language(ReferenceSpeakerSettings& s, bool voice_given) {
    if (s.language == "en") return;
    const fs::path dir = fs::path(AVSI_PROTOCOLS_DIR) / "languages" / s.language;
    if (!PhoneInventory::builtin().has_language(s.language) || !fs::is_regular_file(dir / "task_targets.tsv") ||
        !fs::is_regular_file(dir / "reference_sentences.txt")) {
        std::string list;
        for (const auto& l : PhoneInventory::builtin().languages())
            if (l == "en" || fs::is_regular_file(fs::path(AVSI_PROTOCOLS_DIR) / "languages" / l / "task_targets.tsv"))
                list += (list.empty() ? "" : ", ") + l;
        throw InputError("", 0, 0, "language",
                         fmt::format("no reference speaker for language \"{}\" (needs protocols/languages/{}/"
                                     "task_targets.tsv and reference_sentences.txt); languages with one: {}",
                                     s.language, s.language, list));
    }
    if (!voice_given) s.voice = s.language;
    if (s.sentences_path.empty()) s.sentences_path = dir / "reference_sentences.txt";
    s.language_targets_path = dir / "task_targets.tsv";
}

std::size_t write_reference_corpus(const fs::path& out_dir, const ReferenceSpeakerSettings& s) {
    if (s.rate_min_wpm < 80 || s.rate_max_wpm > 450 || s.rate_min_wpm > s.rate_max_wpm)
        throw InputError("", 0, 0, "rate_wpm",
                         fmt::format("expected 80 ≤ min ≤ max ≤ 450 words per minute, got [{}, {}]", s.rate_min_wpm,
                                     s.rate_max_wpm));
    if (!(s.fps > 0.0)) throw InputError("", 0, 0, "fps", fmt::format("expected > 0, got {}", s.fps));
    const fs::path sentences_path =
        s.sentences_path.empty() ? fs::path(AVSI_PROTOCOLS_DIR) / "reference" / "sentences.txt" : s.sentences_path;
    std::vector<std::string> sentences = read_sentence_list(sentences_path);
    if (s.max_utterances > 0 && s.max_utterances < sentences.size()) sentences.resize(s.max_utterances);

    fs::create_directories(out_dir / "tracks");
    fs::create_directories(out_dir / "labels");
    const Rng base(s.seed);
    std::vector<CorpusEntry> entries;
    std::string table = "id\trate_wpm\ttext\n";
    Progress progress("reference corpus", sentences.size());
    for (std::size_t i = 0; i < sentences.size(); ++i) {
        const std::string id = fmt::format("ref{:03}", i + 1);
        Rng rng = base.derive("utterance/" + id);
        TtsSettings tts;
        tts.voice = s.voice;
        tts.rate_wpm = s.rate_min_wpm + static_cast<int>(rng.uniform_int(static_cast<std::uint64_t>(s.rate_max_wpm - s.rate_min_wpm + 1)));
        const TtsResult speech = synthesize_speech(sentences[i], tts);

        UtteranceVariation v;
        v.articulation_scale = std::max(0.5, rng.normal(1.0, s.articulation_scale_sd));
        for (std::size_t p = 0; p < param_count; ++p) v.offset[p] = rng.normal(0.0, s.offset_sd * params()[p].range());
        for (std::size_t tv = 0; tv < tract_variable_count; ++tv)
            v.time_constant_scale[tv] = 1.0 + rng.uniform(-s.time_constant_jitter, s.time_constant_jitter);
        v.add_noise = true;
        const ParamTrack track = simulate_reference_speaker(speech.phones, v, s, rng);

        CorpusEntry e;
        e.id = id;
        e.track = out_dir / "tracks" / (id + ".csv");
        e.labels = out_dir / "labels" / (id + ".tsv");
        e.kind = TrackKind::Parameters;
        write_param_track_csv(e.track, track);
        write_phones_tsv(e.labels, speech.phones);
        entries.push_back(e);
        table += fmt::format("{}\t{}\t{}\n", id, tts.rate_wpm, sentences[i]);
        progress.advance();
    }
    progress.finish();
    write_text_file(out_dir / "sentences.tsv", table);
    write_corpus_manifest(out_dir, "avsi-reference-speaker", entries, s.split_seed, s.test_fraction, true);
    write_text_file(
        out_dir / "README.md",
        fmt::format("# avsi synthetic reference speaker\n\n"
                    "Generated by `avsi corpus reference` (seed {}, {} utterances, {} fps) from\n"
                    "{}.\n\n"
                    "Trajectories come from a task-dynamic gesture model (Saltzman & Munhall 1989):\n"
                    "overlapping phone gestures on five lip and jaw tract variables, critically damped\n"
                    "dynamics, the parameters solved through the built-in head's geometry; targets from\n"
                    "protocols/reference/task_targets.tsv{}; per-utterance speaking rate, articulation\n"
                    "scale and posture, and sensor noise; timing from espeak-ng{}. The tracks are\n"
                    "synthetic: Table 2 on them checks the training pipeline.\n"
                    "See learn/include/avsi/learn/reference_speaker.h for the full description.\n\n"
                    "- `corpus.json`: the manifest (split seed {}, test fraction {})\n"
                    "- `tracks/<id>.csv`: the 10 parameters per frame\n"
                    "- `labels/<id>.tsv`: espeak-ng phone timing\n"
                    "- `sentences.tsv`: id, speaking rate, text\n",
                    s.seed, entries.size(), s.fps, sentences_path.filename().string(),
                    s.language_targets_path.empty()
                        ? std::string()
                        : fmt::format(" and protocols/languages/{}/task_targets.tsv", s.language),
                    s.language == "en" ? std::string() : fmt::format(" (voice {})", s.voice), s.split_seed, s.test_fraction));
    return entries.size();
}

}  // namespace avsi::learn
