// The protocol's [adaptive] section read and validated (adaptive_protocol.h).
#include "avsi/core/adaptive_protocol.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <stdexcept>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "avsi/core/error.h"
#include "avsi/core/protocol.h"

namespace avsi {

std::string to_string(AdaptiveProcedure procedure) {
    return procedure == AdaptiveProcedure::Sentence ? "sentence" : "word";
}
std::string to_string(SrtEstimator estimator) {
    return estimator == SrtEstimator::MeanOfLevels ? "mean" : "ml";
}
std::string to_string(TrackOrder order) { return order == TrackOrder::Interleaved ? "interleaved" : "blocked"; }
std::string to_string(LevelRule rule) { return rule == LevelRule::NoiseVaries ? "noise" : "speech"; }
std::string to_string(MaskerStage stage) { return stage == MaskerStage::AfterVocoding ? "after" : "before"; }
std::string to_string(AdaptiveVariable v) {
    return v == AdaptiveVariable::Bands ? "bands" : v == AdaptiveVariable::CutoffHz ? "cutoff" : "snr";
}

std::string AdaptiveProtocol::unit() const {
    return variable == AdaptiveVariable::Bands ? "bands" : variable == AdaptiveVariable::CutoffHz ? "Hz" : "dB";
}

double AdaptiveProtocol::value_of(double track_level) const {
    if (!list_variable()) return track_level;
    const long position = std::lround(track_level);
    if (levels.empty() || position < 0 || position >= static_cast<long>(levels.size()) ||
        std::fabs(track_level - static_cast<double>(position)) > 1e-9)
        throw std::logic_error(fmt::format("adaptive: track level {} is not a position on the list of {} levels",
                                           track_level, levels.size()));
    return levels[static_cast<std::size_t>(position)];
}

namespace {

// The [adaptive] keys of a list variable (bands, cutoff): the levels, the
// start and practice levels on them, the steps in positions. The SNR keys and
// word scoring are refused; every condition must present vocoded audio.
void list_levels(AdaptiveProtocol& a, const Protocol& protocol, DiagnosticList& problems) {
    const ConfigSection& c = protocol.adaptive;
    TrackSettings& t = a.track;
    const std::string variable = to_string(a.variable);
    for (const char* key : {"start_snr_db", "min_snr_db", "max_snr_db", "large_step_db", "small_step_db",
                            "practice_snr_db", "noise", "level_rule", "fixed_level_dbfs", "snr_reference",
                            "noise_stage", "noise_lead_ms", "noise_tail_ms"})
        if (c.find(key))  // find() also marks the key known: one error, not a second "unknown key"
            c.report(key, fmt::format("expected only with variable = \"snr\", not \"{}\" (a list variable steps on "
                                      "`levels`: start_level, large_step_levels, small_step_levels)",
                                      variable),
                     problems);
    if (t.procedure == AdaptiveProcedure::Word)
        c.report("procedure",
                 fmt::format("expected \"sentence\" with variable = \"{}\": word scoring's step "
                             "-f(i)·(p − target)/slope is a real number of dB, which has no meaning on a list of levels",
                             variable),
                 problems);
    const bool bands = a.variable == AdaptiveVariable::Bands;
    const double lo = bands ? 1.0 : 1e-9, hi = bands ? 64.0 : 10000.0;
    const ConfigValue* v = c.find("levels");
    if (!v) {
        c.report("levels", fmt::format("expected a list of levels for variable = \"{}\", e.g. {}", variable,
                                       bands ? "[1, 2, 3, 4, 6, 8, 12, 16]" : "[4, 8, 16, 32, 64, 128, 256]"),
                 problems);
    } else if (v->type != ConfigValue::Type::Array) {
        c.report("levels", "expected an array of numbers, got " + v->describe(), problems);
    } else {
        for (std::size_t i = 0; i < v->items.size(); ++i) {
            const ConfigValue& item = v->items[i];
            const std::string field = fmt::format("{}[{}]", c.field("levels"), i + 1);
            const bool number = item.type == ConfigValue::Type::Integer ||
                                (!bands && item.type == ConfigValue::Type::Float);
            const double x = item.type == ConfigValue::Type::Integer ? static_cast<double>(item.integer) : item.number;
            if (!number || !(x >= lo && x <= hi)) {
                problems.add(c.path(), item.line, item.column, field,
                             fmt::format("expected {} in [{}, {}], got {}", bands ? "a band count" : "a cutoff in Hz",
                                         bands ? 1 : 0, hi, item.describe()));
            } else if (!a.levels.empty() && x <= a.levels.back()) {
                problems.add(c.path(), item.line, item.column, field,
                             fmt::format("expected levels in strictly ascending order (easier upwards), got {} after {}",
                                         item.describe(), a.levels.back()));
            } else {
                a.levels.push_back(x);
            }
        }
        if (v->items.size() < 2) c.report("levels", "expected at least two levels, got " + v->describe(), problems);
    }
    // A value of the list by key, as its position.
    const auto position_of = [&](const char* key, std::size_t fallback) -> std::size_t {
        if (a.levels.empty()) return 0;
        const double value = c.get_number(key, a.levels[fallback], -1e9, 1e9, problems);
        const auto it = std::find(a.levels.begin(), a.levels.end(), value);
        if (it == a.levels.end()) {
            c.report(key, fmt::format("expected one of the levels ({}), got {}", fmt::join(a.levels, ", "), value),
                     problems);
            return fallback;
        }
        return static_cast<std::size_t>(it - a.levels.begin());
    };
    const std::size_t n = a.levels.size();
    t.start_db = static_cast<double>(position_of("start_level", n / 2));
    a.practice_level = n ? a.levels[position_of("practice_level", n - 1)] : 0.0;
    t.min_db = 0.0;
    t.max_db = n >= 2 ? static_cast<double>(n - 1) : 1.0;
    t.large_step_db = static_cast<double>(c.get_int("large_step_levels", 2, 1, 64, problems));
    t.small_step_db = static_cast<double>(c.get_int("small_step_levels", 1, 1, 64, problems));
    for (const auto& cond : protocol.conditions)
        if (cond.audio != ConditionAudio::Vocoded)
            c.report("variable",
                     fmt::format("expected every condition to present vocoded audio with variable = \"{}\", but "
                                 "condition \"{}\" has audio = \"{}\"",
                                 variable, cond.name, to_string(cond.audio)),
                     problems);
}

// The masker's stage and timing of an SNR track (noise_stage, noise_lead_ms,
// noise_tail_ms).
void masker_timing(AdaptiveProtocol& a, const ConfigSection& c, DiagnosticList& problems) {
    a.noise_stage = c.get_choice("noise_stage", {"before", "after"}, "before", problems) == "after"
                        ? MaskerStage::AfterVocoding
                        : MaskerStage::BeforeVocoding;
    a.noise_lead_s = c.get_number("noise_lead_ms", 1000.0 * a.noise_lead_s, 0.0, 5000.0, problems) / 1000.0;
    a.noise_tail_s = c.get_number("noise_tail_ms", 1000.0 * a.noise_tail_s, 0.0, 5000.0, problems) / 1000.0;
}

}  // namespace

AdaptiveProtocol adaptive_protocol(const Protocol& protocol) {
    AdaptiveProtocol a;
    const ConfigSection& c = protocol.adaptive;
    if (!c.present()) return a;
    a.enabled = true;
    DiagnosticList problems;
    TrackSettings& t = a.track;
    const std::string procedure = c.get_choice("procedure", {"sentence", "word"}, "sentence", problems);
    t.procedure = procedure == "word" ? AdaptiveProcedure::Word : AdaptiveProcedure::Sentence;
    const std::string variable = c.get_choice("variable", {"snr", "bands", "cutoff"}, "snr", problems);
    a.variable = variable == "bands"    ? AdaptiveVariable::Bands
                 : variable == "cutoff" ? AdaptiveVariable::CutoffHz
                                        : AdaptiveVariable::Snr;
    a.order = c.get_choice("tracks", {"interleaved", "blocked"}, "interleaved", problems) == "blocked"
                  ? TrackOrder::Blocked
                  : TrackOrder::Interleaved;
    a.level_rule = c.get_choice("level_rule", {"noise", "speech"}, "noise", problems) == "speech"
                       ? LevelRule::SpeechVaries
                       : LevelRule::NoiseVaries;
    a.noise = c.get_string("noise", "speech-shaped", problems);
    if (a.noise != "speech-shaped") {
        const auto resolved = protocol.path.parent_path() / a.noise;
        if (!std::filesystem::is_regular_file(resolved))
            c.report("noise",
                     fmt::format("expected \"speech-shaped\" or an existing noise recording, got \"{}\" (resolved to {})",
                                 a.noise, resolved.string()),
                     problems);
        a.noise = resolved.string();
    }
    a.fixed_level_dbfs = c.get_number("fixed_level_dbfs", protocol.corpus.level_dbfs, -80.0, -3.0, problems);
    a.snr_reference = c.get_choice("snr_reference", {"active", "whole"}, "active", problems);
    if (!a.list_variable()) masker_timing(a, c, problems);
    if (a.list_variable()) {
        list_levels(a, protocol, problems);
    } else {
        for (const char* key : {"levels", "start_level", "practice_level", "large_step_levels", "small_step_levels"})
            if (c.find(key)) c.report(key, "expected only with variable = \"bands\" or \"cutoff\"", problems);
        t.start_db = c.get_number("start_snr_db", t.start_db, -60.0, 60.0, problems);
        t.min_db = c.get_number("min_snr_db", t.min_db, -60.0, 60.0, problems);
        t.max_db = c.get_number("max_snr_db", t.max_db, -60.0, 60.0, problems);
        t.large_step_db = c.get_number("large_step_db", t.large_step_db, 0.1, 20.0, problems);
        t.small_step_db = c.get_number("small_step_db", t.small_step_db, 0.1, 20.0, problems);
    }
    t.large_steps = static_cast<int>(c.get_int("large_steps", t.large_steps, 0, 1000, problems));
    t.repeat_first = c.get_bool("repeat_first", t.repeat_first, problems);
    t.max_first_repeats = static_cast<int>(c.get_int("max_first_repeats", t.max_first_repeats, 0, 100, problems));
    t.target = c.get_number("target", t.target, 0.01, 0.99, problems);
    t.slope_per_db = c.get_number("slope_per_db", t.slope_per_db, 0.01, 1.0, problems);
    t.f_start = c.get_number("f_start", t.f_start, 0.01, 10.0, problems);
    t.f_ratio = c.get_number("f_ratio", t.f_ratio, 1.0, 10.0, problems);
    t.f_min = c.get_number("f_min", t.f_min, 0.001, 10.0, problems);
    t.srt_from = static_cast<int>(c.get_int("srt_from", t.srt_from, 1, 1000, problems));
    t.srt_include_next = c.get_bool("srt_include_next", t.srt_include_next, problems);
    t.min_reversals = static_cast<int>(c.get_int("min_reversals", t.min_reversals, 0, 1000, problems));
    // Ceilings per condition (a pilot's proportion of keywords right in quiet).
    if (const ConfigSection* ceilings = c.get_table("ceilings", problems)) {
        for (const auto& name : ceilings->keys()) {
            const double v = ceilings->get_number(name, 1.0, 0.01, 1.0, problems);
            if (protocol.condition_index(name) < 0)
                ceilings->report(name,
                                 fmt::format("expected one of the conditions ({}), got \"{}\"",
                                             fmt::join(protocol.condition_names(), ", "), name),
                                 problems);
            else
                a.ceilings[name] = v;
        }
    }
    t.estimator = c.get_choice("estimate", {"mean", "ml"}, "mean", problems) == "ml" ? SrtEstimator::MaximumLikelihood
                                                                                    : SrtEstimator::MeanOfLevels;
    if (t.procedure == AdaptiveProcedure::Sentence && t.estimator == SrtEstimator::MaximumLikelihood)
        c.report("estimate", "expected \"mean\" for sentence scoring (the ML fit is reported beside it)", problems);
    if (!a.list_variable())
        a.practice_snr_db = c.get_number("practice_snr_db", a.practice_snr_db, -60.0, 60.0, problems);
    a.confirm_scores = c.get_bool("confirm_scores", a.confirm_scores, problems);
    a.reference = c.get_string("reference", "", problems);
    if (!a.reference.empty() && protocol.condition_index(a.reference) < 0)
        c.report("reference",
                 fmt::format("expected one of the conditions ({}), got \"{}\"",
                             fmt::join(protocol.condition_names(), ", "), a.reference),
                 problems);
    if (t.min_db >= t.max_db)
        c.report("min_snr_db", fmt::format("expected min_snr_db < max_snr_db ({}), got {}", t.max_db, t.min_db), problems);
    else if (t.start_db < t.min_db || t.start_db > t.max_db)
        c.report("start_snr_db", fmt::format("expected a level in [{}, {}], got {}", t.min_db, t.max_db, t.start_db),
                 problems);
    if (t.f_min > t.f_start)
        c.report("f_min", fmt::format("expected f_min ≤ f_start ({}), got {}", t.f_start, t.f_min), problems);
    if (t.srt_from > protocol.design.sentences_per_list)
        c.report("srt_from",
                 fmt::format("expected a sentence of the track (design.sentences_per_list = {}), got {}",
                             protocol.design.sentences_per_list, t.srt_from),
                 problems);
    c.check_unknown_keys(problems);
    problems.throw_if_any();
    return a;
}

std::string masker_description(const AdaptiveProtocol& a) {
    if (!a.enabled || a.list_variable()) return "";
    const std::string noise = a.noise == "speech-shaped"
                                  ? std::string("speech-shaped noise (the long-term spectrum of each sentence)")
                                  : fmt::format("the noise recording {}", std::filesystem::path(a.noise).filename().string());
    const std::string rule =
        a.level_rule == LevelRule::NoiseVaries
            ? std::string("the speech stayed at the stimulus level and the noise level varied")
            : fmt::format("the noise stayed at {:g} dBFS and the speech level varied", a.fixed_level_dbfs);
    const std::string stage =
        a.noise_stage == MaskerStage::BeforeVocoding
            ? std::string("added to the speech before vocoding (the mixture was vocoded at run time with the stimuli's "
                          "vocoder settings and carrier seed; conditions with clean audio were not vocoded)")
            : std::string("added to the presented audio after vocoding");
    const std::string timing =
        a.noise_lead_s > 0 || a.noise_tail_s > 0
            ? fmt::format("it started {:g} ms before the stimulus (the face shown at rest) and ended {:g} ms after it, "
                          "with {:g} ms raised-cosine ramps",
                          1000.0 * a.noise_lead_s, 1000.0 * a.noise_tail_s, 1000.0 * a.noise_ramp_s)
            : std::string("it ran exactly as long as the stimulus");
    return fmt::format("Masker: {}, {}; {}; the SNR's speech level is the RMS of {}; {}; a new noise excerpt was drawn "
                       "for every presentation.",
                       noise, stage, rule,
                       a.snr_reference == "active" ? "the active speech (20 ms frames within 40 dB of the loudest)"
                                                   : "the whole sentence",
                       timing);
}

}  // namespace avsi
