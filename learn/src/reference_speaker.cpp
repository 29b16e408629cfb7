// The synthetic reference speaker (reference_speaker.h): critically damped
// articulator dynamics toward phone targets with anticipatory onset, over
// espeak-ng-timed English sentences.
#include "avsi/learn/reference_speaker.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <optional>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/labels.h"
#include "avsi/core/log.h"
#include "avsi/core/tts.h"

namespace avsi::learn {

namespace fs = std::filesystem;

namespace {

constexpr double U = std::numeric_limits<double>::quiet_NaN();  // unspecified

// Targets in study order: jaw_rotation, lip_rounding, upper_lip_retraction,
// upper_lip_raise, lower_lip_retraction, lower_lip_depression,
// mouth_corner_stretch_left, mouth_corner_stretch_right, jaw_thrust,
// jaw_shift. The right corner is the left one × 0.9 (a slight asymmetry);
// jaw_shift is always 0 (it only drifts). U = unspecified (next vowel's).
using Target = std::array<double, param_count>;

Target t(double jaw, double round, double ulret, double ulraise, double llret, double lldep, double corner,
         double thrust) {
    return {jaw, round, ulret, ulraise, llret, lldep, corner, std::isnan(corner) ? U : 0.9 * corner, thrust, 0.0};
}

struct PhoneTargets {
    Target first;
    std::optional<Target> second;  // diphthongs: target of the second half
};

const std::map<std::string, PhoneTargets, std::less<>>& target_table() {
    static const std::map<std::string, PhoneTargets, std::less<>> table = [] {
        const Target AA = t(0.85, 0.00, 0.10, 0.25, 0.05, 0.35, 0.10, -0.10);
        const Target AE = t(0.75, -0.30, 0.30, 0.30, 0.20, 0.40, 0.45, 0.00);
        const Target AH = t(0.60, 0.00, 0.10, 0.20, 0.05, 0.25, 0.15, 0.00);
        const Target AO = t(0.70, 0.55, -0.40, 0.15, -0.35, 0.25, -0.20, -0.05);
        const Target EH = t(0.55, -0.25, 0.30, 0.25, 0.20, 0.30, 0.40, 0.00);
        const Target ER = t(0.35, 0.40, -0.30, 0.10, -0.25, 0.10, -0.10, 0.00);
        const Target IH = t(0.30, -0.35, 0.35, 0.15, 0.25, 0.15, 0.50, 0.03);
        const Target IY = t(0.20, -0.45, 0.45, 0.15, 0.35, 0.10, 0.70, 0.05);
        const Target UH = t(0.30, 0.60, -0.50, 0.05, -0.45, 0.05, -0.30, 0.00);
        const Target UW = t(0.20, 0.90, -0.80, 0.00, -0.70, 0.00, -0.45, 0.00);
        const Target OW1 = t(0.55, 0.60, -0.45, 0.10, -0.40, 0.15, -0.25, -0.03);
        std::map<std::string, PhoneTargets, std::less<>> m;
        m["AA"] = {AA, {}};
        m["AE"] = {AE, {}};
        m["AH"] = {AH, {}};
        m["AO"] = {AO, {}};
        m["EH"] = {EH, {}};
        m["ER"] = {ER, {}};
        m["IH"] = {IH, {}};
        m["IY"] = {IY, {}};
        m["UH"] = {UH, {}};
        m["UW"] = {UW, {}};
        m["AW"] = {AA, UH};
        m["AY"] = {AA, IH};
        m["EY"] = {EH, IY};
        m["OW"] = {OW1, UW};
        m["OY"] = {AO, IY};
        // Consonants: what the place of articulation constrains.
        // Bilabials aim beyond contact (a virtual target: the lips stop each
        // other, Löfqvist & Gracco 1997), ~3-4 mm of overlap on the built-in head.
        m["P"] = {t(0.04, U, U, -0.40, U, -0.50, U, U), {}};
        m["B"] = {t(0.05, U, U, -0.38, U, -0.48, U, U), {}};
        m["M"] = {t(0.06, U, U, -0.35, U, -0.46, U, U), {}};
        // Labiodentals: the lower lip under the upper incisors, the upper lip
        // raised off them, little rounding (protruded lips would leave the teeth).
        m["F"] = {t(0.12, 0.15, U, 0.45, 0.75, 0.00, U, -0.05), {}};
        m["V"] = {t(0.12, 0.15, U, 0.42, 0.72, 0.02, U, -0.05), {}};
        m["TH"] = {t(0.18, U, U, 0.10, U, 0.15, U, 0.05), {}};
        m["DH"] = {t(0.16, U, U, 0.08, U, 0.12, U, 0.05), {}};
        m["T"] = {t(0.15, U, U, U, U, U, U, 0.05), {}};
        m["D"] = {t(0.15, U, U, U, U, U, U, 0.05), {}};
        m["N"] = {t(0.15, U, U, U, U, U, U, 0.03), {}};
        m["L"] = {t(0.22, U, U, U, U, U, U, 0.00), {}};
        m["S"] = {t(0.07, U, U, 0.10, U, 0.05, 0.30, 0.15), {}};
        m["Z"] = {t(0.08, U, U, 0.10, U, 0.05, 0.28, 0.15), {}};
        m["SH"] = {t(0.10, 0.60, -0.60, 0.20, -0.50, 0.20, -0.30, 0.10), {}};
        m["ZH"] = {t(0.10, 0.55, -0.55, 0.20, -0.45, 0.20, -0.28, 0.10), {}};
        m["CH"] = {t(0.10, 0.60, -0.60, 0.20, -0.50, 0.20, -0.30, 0.10), {}};
        m["JH"] = {t(0.10, 0.55, -0.55, 0.20, -0.45, 0.20, -0.28, 0.10), {}};
        m["K"] = {t(0.28, U, U, U, U, U, U, U), {}};
        m["G"] = {t(0.28, U, U, U, U, U, U, U), {}};
        m["NG"] = {t(0.25, U, U, U, U, U, U, U), {}};
        m["HH"] = {t(U, U, U, U, U, U, U, U), {}};
        m["R"] = {t(0.20, 0.45, -0.35, 0.10, -0.30, 0.05, -0.15, 0.00), {}};
        m["W"] = {t(0.12, 0.95, -0.80, 0.00, -0.70, -0.05, -0.45, 0.00), {}};
        m["Y"] = {t(0.15, -0.30, 0.30, U, 0.25, U, 0.40, 0.03), {}};
        m["sil"] = {Target{}, {}};
        return m;
    }();
    return table;
}

const PhoneTargets& targets_of(const Phone& phone) {
    const auto it = target_table().find(phone.symbol);
    if (it == target_table().end())
        throw InputError("", 0, 0, "phone",
                         fmt::format("the reference speaker has no targets for phone \"{}\"", phone.symbol));
    return it->second;
}

bool is_vowel_symbol(const std::string& s) { return PhoneInventory::builtin().is_vowel(s); }

// The constriction task of a consonant: what the speaker makes sure it
// reaches however short the segment (see the planning in
// simulate_reference_speaker).
enum class Task { None, LipClosure, Labiodental };

// A command segment: from start_s, the target vector (fully specified). The
// parameters of its task take over `extra_lead_s` earlier than their
// anticipation says (a planned early gesture).
struct Command {
    double start_s;
    Target target;
    double extra_lead_s = 0.0;
    Task task = Task::None;
    double centre_s = 0.0;
};

// The speaker's task variables, linear in the parameters near rest as the
// built-in head's rig makes them (mm; the stimuli tests measure the corpus
// on the head itself). Lip aperture (Saltzman & Munhall's LA): jaw 20.9 mm
// per unit at the lips, lower lip depression 6, upper lip raise 5, upper lip
// retraction 0.8, lower lip retraction −3.5. Lower lip height (up positive),
// which brings the lower lip to the upper incisors: −20.9 jaw + 3.5 lower lip
// retraction − 6 lower lip depression.
double lip_aperture_mm(const Frame& f) {
    return 20.9 * f[index(Param::JawRotation)] + 0.8 * f[index(Param::UpperLipRetraction)] +
           5.0 * f[index(Param::UpperLipRaise)] - 3.5 * f[index(Param::LowerLipRetraction)] +
           6.0 * f[index(Param::LowerLipDepression)];
}
double lower_lip_height_mm(const Frame& f) {
    return -20.9 * f[index(Param::JawRotation)] + 3.5 * f[index(Param::LowerLipRetraction)] -
           6.0 * f[index(Param::LowerLipDepression)];
}

// How far `f` is from achieving the command's task (≤ 0: achieved).
double task_shortfall_mm(const Command& c, const Frame& f, double closure_margin_mm) {
    switch (c.task) {
        case Task::LipClosure: return lip_aperture_mm(f) + closure_margin_mm;
        case Task::Labiodental: return lower_lip_height_mm(c.target) - lower_lip_height_mm(f) - 1.0;
        case Task::None: return 0.0;
    }
    return 0.0;
}

// The parameters a task's gesture moves early.
bool task_parameter(Task task, std::size_t p) {
    switch (task) {
        case Task::LipClosure:
            return p == index(Param::JawRotation) || p == index(Param::UpperLipRaise) ||
                   p == index(Param::LowerLipDepression);
        case Task::Labiodental:
            return p == index(Param::JawRotation) || p == index(Param::LowerLipRetraction) ||
                   p == index(Param::LowerLipDepression);
        case Task::None: return false;
    }
    return false;
}

// The piecewise-constant command sequence for an utterance (before leads).
std::vector<Command> commands(const PhoneSequence& phones, const UtteranceVariation& v) {
    std::vector<Command> out;
    for (std::size_t i = 0; i < phones.size(); ++i) {
        const Phone& ph = phones[i];
        const PhoneTargets& pt = targets_of(ph);
        const bool vowel = is_vowel_symbol(ph.symbol);
        auto resolve = [&](Target tgt) {
            // Unspecified: the next vowel's (first) target, or neutral if a pause comes first.
            for (std::size_t p = 0; p < param_count; ++p) {
                if (!std::isnan(tgt[p])) continue;
                double fill = 0.0;
                for (std::size_t j = i + 1; j < phones.size(); ++j) {
                    if (phones[j].symbol == "sil") break;
                    if (is_vowel_symbol(phones[j].symbol)) {
                        fill = targets_of(phones[j]).first[p];
                        break;
                    }
                }
                tgt[p] = fill;
            }
            const double stress = vowel ? (ph.stressed ? 1.10 : 0.85) : 1.0;
            for (std::size_t p = 0; p < param_count; ++p) {
                const ParamInfo& info = params()[p];
                const double x = info.neutral + (tgt[p] - info.neutral) * stress * v.articulation_scale + v.offset[p];
                tgt[p] = std::clamp(x, info.min, info.max);
            }
            return tgt;
        };
        Command first{ph.start_s, resolve(pt.first)};
        if (ph.symbol == "P" || ph.symbol == "B" || ph.symbol == "M") first.task = Task::LipClosure;
        if (ph.symbol == "F" || ph.symbol == "V") first.task = Task::Labiodental;
        first.centre_s = ph.centre_s();
        out.push_back(first);
        if (pt.second) out.push_back({ph.centre_s(), resolve(*pt.second)});
    }
    return out;
}

}  // namespace

const std::array<ArticulatorDynamics, param_count>& reference_dynamics() {
    static const std::array<ArticulatorDynamics, param_count> d{{
        {0.028, 0.030},  // jaw_rotation
        {0.035, 0.070},  // lip_rounding: slow, long anticipatory rounding
        {0.032, 0.060},  // upper_lip_retraction
        {0.018, 0.020},  // upper_lip_raise: fast lip closure
        {0.030, 0.055},  // lower_lip_retraction
        {0.018, 0.020},  // lower_lip_depression
        {0.030, 0.040},  // mouth_corner_stretch_left
        {0.030, 0.040},  // mouth_corner_stretch_right
        {0.040, 0.030},  // jaw_thrust
        {0.045, 0.000},  // jaw_shift (drift only)
    }};
    return d;
}

namespace {

// The noise-free trajectories of the commands (frames k/fps up to `frames`).
std::vector<Frame> simulate_commands(const std::vector<Command>& cmds, const UtteranceVariation& variation,
                                     const ReferenceSpeakerSettings& settings, std::size_t frames) {
    std::vector<Frame> out(frames, Frame{});
    const double dt = settings.simulation_step_s;
    for (std::size_t p = 0; p < param_count; ++p) {
        const ArticulatorDynamics& dyn = reference_dynamics()[p];
        const double tau = dyn.time_constant_s * (variation.time_constant_scale[p] > 0 ? variation.time_constant_scale[p] : 1.0);
        // A command takes over at start_s minus its lead; an early gesture
        // may take over before the commands just ahead of it, which it then
        // skips (the jaw closes for /b/ without first going to /l/'s height).
        // The gesture after a constriction does not release it before
        // hold_s after the constriction's centre (a stop is released, not
        // anticipated away).
        const double hold_s = settings.closure_hold_s;
        auto takes_over = [&](std::size_t j) {
            const Command& c = cmds[j];
            double t = c.start_s - dyn.anticipation_s - (task_parameter(c.task, p) ? c.extra_lead_s : 0.0);
            if (j > 0 && task_parameter(cmds[j - 1].task, p)) t = std::max(t, cmds[j - 1].centre_s + hold_s);
            return t;
        };
        const double lookahead = settings.max_closure_lead_s;
        double x = cmds.front().target[p], v = 0.0;  // start at rest on the first (silence) target
        std::size_t c = 0, k = 0;
        for (double time = 0.0; k < frames; time += dt) {
            // Sample every frame whose time has been reached.
            while (k < frames && static_cast<double>(k) / settings.fps <= time + 1e-12) out[k++][p] = x;
            for (std::size_t j = c + 1; j < cmds.size() && cmds[j].start_s - dyn.anticipation_s - lookahead <= time; ++j)
                if (takes_over(j) <= time) c = j;
            const double u = cmds[c].target[p];
            // Semi-implicit Euler on x'' = (u − x)/τ² − 2x'/τ (stable for dt ≪ τ).
            v += dt * ((u - x) / (tau * tau) - 2.0 * v / tau);
            x += dt * v;
        }
    }
    return out;
}

}  // namespace

ParamTrack simulate_reference_speaker(const PhoneSequence& phones, const UtteranceVariation& variation,
                                      const ReferenceSpeakerSettings& settings, Rng& rng) {
    AVSI_ASSERT(!phones.empty() && settings.fps > 0 && settings.simulation_step_s > 0);
    std::vector<Command> cmds = commands(phones, variation);
    const double end_s = phones.back().end_s;
    const std::size_t frames = frame_count(end_s, settings.fps);
    ParamTrack track;
    track.fps = settings.fps;
    track.start_s = 0.0;
    track.present.fill(true);

    // Speakers close the lips for every bilabial and bring the lower lip to
    // the upper incisors for every /f v/, however short the segment: each
    // such gesture starts early enough that its task is achieved from
    // closure_hold_s before the segment's centre to closure_hold_s after it
    // (the lip aperture closure_margin_mm beyond contact; the lower lip
    // within 1 mm of its labiodental height), found by lengthening its lead
    // 5 ms at a time, up to max_closure_lead_s.
    track.frames = simulate_commands(cmds, variation, settings, frames);
    auto achieved = [&](const Command& c) {
        for (double t : {c.centre_s - settings.closure_hold_s, c.centre_s, c.centre_s + settings.closure_hold_s}) {
            const auto k = std::min(frames - 1, static_cast<std::size_t>(std::lround(std::max(t, 0.0) * settings.fps)));
            if (task_shortfall_mm(c, track.frames[k], settings.closure_margin_mm) > 0.0) return false;
        }
        return true;
    };
    for (int round = 0; round < 64; ++round) {
        bool changed = false;
        for (auto& c : cmds) {
            if (c.task == Task::None || achieved(c)) continue;
            if (c.extra_lead_s + 0.005 > settings.max_closure_lead_s) continue;
            c.extra_lead_s += 0.005;
            changed = true;
        }
        if (!changed) break;
        track.frames = simulate_commands(cmds, variation, settings, frames);
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
        for (std::size_t p = 0; p < param_count; ++p) {
            v.offset[p] = rng.normal(0.0, s.offset_sd * params()[p].range());
            v.time_constant_scale[p] = 1.0 + rng.uniform(-s.time_constant_jitter, s.time_constant_jitter);
        }
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
    write_corpus_manifest(out_dir, "avsi-reference-speaker", entries, s.split_seed, s.test_fraction);
    write_text_file(
        out_dir / "README.md",
        fmt::format("# avsi synthetic reference speaker\n\n"
                    "Generated by `avsi corpus reference` (seed {}, {} utterances, {} fps) from\n"
                    "{}.\n\n"
                    "Trajectories come from critically damped second-order articulator dynamics\n"
                    "driven toward per-phone targets with anticipatory onset, per-utterance speaking\n"
                    "rate, articulation scale and posture, and sensor noise; timing from espeak-ng.\n"
                    "See synth/include/avsi/synth/reference_speaker.h for the full description.\n\n"
                    "- `corpus.json`: the manifest (split seed {}, test fraction {})\n"
                    "- `tracks/<id>.csv`: the 10 parameters per frame\n"
                    "- `labels/<id>.tsv`: espeak-ng phone timing\n"
                    "- `sentences.tsv`: id, speaking rate, text\n",
                    s.seed, entries.size(), s.fps, sentences_path.filename().string(), s.split_seed, s.test_fraction));
    return entries.size();
}

}  // namespace avsi::learn
