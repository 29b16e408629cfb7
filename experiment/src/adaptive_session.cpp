// A subject's adaptive SRT tracks during a session (see adaptive_session.h).
#include "avsi/experiment/adaptive_session.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "avsi/analysis/scoring.h"
#include "avsi/core/error.h"
#include "avsi/core/rng.h"
#include "avsi/core/audio.h"
#include "avsi/stimuli/builder.h"
#include "avsi/vocoder/masking.h"

namespace avsi::experiment {

AdaptiveSession::AdaptiveSession(const Protocol& protocol, const Corpus& corpus,
                                 std::vector<Store::AdaptiveRow> stored, const std::string& database)
    : m_protocol(protocol), m_corpus(corpus), m_settings(analysis::adaptive_protocol(protocol)) {
    if (!m_settings.enabled)
        throw InputError(protocol.path, 0, 0, "adaptive", "expected an [adaptive] section for an adaptive session");
    if (m_settings.confirm_scores && protocol.session.response_mode != ResponseMode::Experimenter)
        throw InputError(protocol.path, protocol.adaptive.line(), 0, "adaptive.confirm_scores",
                         "expected session.response_mode = \"experimenter\" with confirm_scores = true: the score "
                         "check screen lists the sentence's keywords, which the subject must not see");
    analysis::ScoringSettings scoring = analysis::scoring_settings(protocol);
    scoring.vocabulary = analysis::corpus_vocabulary(corpus);
    m_scorer = std::make_unique<analysis::KeywordScorer>(scoring);
    for (const auto& c : protocol.conditions) m_tracks.emplace(c.name, analysis::AdaptiveTrack(m_settings.track));
    // Replay: each stored presentation of a track, in order, must be at the level the rules give.
    for (const auto& row : stored) {
        const AdaptiveRecord& r = row.record;
        m_attempts[row.position] = std::max(m_attempts[row.position], r.attempt);
        if (r.track.empty()) continue;
        const auto it = m_tracks.find(r.track);
        if (it == m_tracks.end())
            throw InputError(database, 0, 0, "adaptive_trials.track",
                             fmt::format("subject {} trial {}: the track \"{}\" is not a condition of the protocol",
                                         row.subject, row.position, r.track));
        const double expected = m_settings.value_of(it->second.level_db());
        if (std::fabs(expected - r.level_db) > 1e-9)
            throw InputError(database, 0, 0, "adaptive_trials.level_db",
                             fmt::format("subject {} trial {}: stored at {} {}, the protocol's [adaptive] rules give {} "
                                         "{}: the rules changed since the session started; resume with the protocol "
                                         "it started with",
                                         row.subject, row.position, r.level_db, m_settings.unit(), expected,
                                         m_settings.unit()));
        it->second.record(r.keywords, r.correct);
    }
}

AdaptiveSession::~AdaptiveSession() = default;

const Sentence& AdaptiveSession::sentence(const PlannedTrial& trial) const { return m_corpus.sentence(trial.sentence); }

const analysis::AdaptiveTrack& AdaptiveSession::track(const std::string& condition) const {
    const auto it = m_tracks.find(condition);
    if (it == m_tracks.end())
        throw InputError(m_protocol.path, 0, 0, "condition", fmt::format("no track for condition \"{}\"", condition));
    return it->second;
}

double AdaptiveSession::level_db(const PlannedTrial& trial) const {
    if (trial.phase != Phase::Test)
        return m_settings.list_variable() ? m_settings.practice_level : m_settings.practice_snr_db;
    return m_settings.value_of(track(trial.condition).level_db());
}

std::filesystem::path AdaptiveSession::variant_path(const PlannedTrial& trial) const {
    return m_stimuli_dir /
           stimuli::variant_audio_path(trial.stimulus, analysis::to_string(m_settings.variable), level_db(trial));
}

void AdaptiveSession::check_variants(const std::vector<PlannedTrial>& plan) const {
    if (!m_settings.list_variable()) return;
    const std::string variable = analysis::to_string(m_settings.variable);
    for (const auto& t : plan) {
        std::vector<double> levels = t.phase == Phase::Test ? m_settings.levels : std::vector{m_settings.practice_level};
        for (const double level : levels) {
            const auto path = m_stimuli_dir / stimuli::variant_audio_path(t.stimulus, variable, level);
            if (!std::filesystem::is_regular_file(path))
                throw InputError(path, fmt::format("the {} = {} audio variant of {} is missing: build the stimuli with "
                                                   "this protocol (avsi build-stimuli)",
                                                   variable, level, t.stimulus));
        }
    }
}

int AdaptiveSession::next_attempt(const PlannedTrial& trial) const {
    const auto it = m_attempts.find(trial.position);
    return it == m_attempts.end() ? 1 : it->second + 1;
}

MixedPresentation AdaptiveSession::mix(const PlannedTrial& trial, const std::vector<float>& speech, int sample_rate) {
    MixedPresentation out;
    out.sample_rate = sample_rate;
    out.attempt = next_attempt(trial);
    out.level_db = level_db(trial);
    if (m_settings.list_variable()) {
        // The builder's pre-rendered variant at this level, played as written.
        const auto path = variant_path(trial);
        if (!std::filesystem::is_regular_file(path))
            throw InputError(path, fmt::format("the stimulus's {} = {} variant is missing: run avsi build-stimuli with "
                                               "this protocol",
                                               analysis::to_string(m_settings.variable), out.level_db));
        const Audio variant = read_audio(path);
        if (variant.sample_rate_hz != sample_rate)
            throw InputError(path, 0, 0, "sample_rate",
                             fmt::format("expected the stimulus video's audio rate {} Hz, got {} Hz", sample_rate,
                                         variant.sample_rate_hz));
        out.samples = variant.mono();
        out.noise_gain_db = kNoNoiseDbfs;
        return out;
    }
    const std::uint64_t seed = derive_seed(
        m_protocol.seed, fmt::format("adaptive-noise/{}/{}/{}", trial.subject, trial.position, out.attempt));
    Audio s;
    s.sample_rate_hz = sample_rate;
    s.samples = speech;
    if (s.samples.empty()) throw InputError(trial.stimulus, "the stimulus has no audio to mix noise with");
    const auto reference = vocoder::parse_snr_reference(m_settings.snr_reference, "adaptive.snr_reference");
    // The noise: a recording (loaded once per rate) or noise shaped like this sentence.
    std::vector<double> noise;
    if (m_settings.noise == "speech-shaped") {
        const auto spectrum = vocoder::long_term_spectrum({s});
        noise = vocoder::speech_shaped_noise(spectrum, s.frames(), sample_rate, seed);
    } else {
        auto it = m_noise_by_rate.find(sample_rate);
        if (it == m_noise_by_rate.end())
            it = m_noise_by_rate.emplace(sample_rate, vocoder::load_noise(m_settings.noise, sample_rate)).first;
        noise = it->second;
    }
    double speech_gain = 1.0;
    if (m_settings.level_rule == analysis::LevelRule::SpeechVaries) {
        // The noise stays at fixed_level_dbfs: scale the speech so the mixed
        // noise (speech_rms · 10^(−snr/20)) lands there.
        std::vector<double> d(speech.begin(), speech.end());
        const double speech_rms = vocoder::speech_level_rms(d, sample_rate, reference);
        if (!(speech_rms > 0)) throw InputError(trial.stimulus, "the stimulus audio is silent: no SNR can be set");
        speech_gain = std::pow(10.0, m_settings.fixed_level_dbfs / 20.0) / (speech_rms * std::pow(10.0, -out.level_db / 20.0));
        for (float& v : s.samples) v = static_cast<float>(v * speech_gain);
    }
    vocoder::MixSettings mix;
    mix.snr_db = out.level_db;
    mix.reference = reference;
    mix.seed = seed;
    vocoder::MixResult r = vocoder::mix_at_snr(s, noise, mix);
    out.samples = std::move(r.audio.samples);
    out.limit_gain_db = r.limit_gain_db;
    out.speech_gain_db = 20.0 * std::log10(speech_gain) + r.limit_gain_db;
    out.noise_gain_db = 20.0 * std::log10(r.noise_rms) + r.limit_gain_db;
    return out;
}

std::vector<bool> AdaptiveSession::score(const PlannedTrial& trial, const std::string& response) const {
    std::vector<bool> marks;
    for (const auto& m : m_scorer->score(sentence(trial), response)) marks.push_back(m.correct);
    return marks;
}

namespace {
int count_true(const std::vector<bool>& v) { return static_cast<int>(std::count(v.begin(), v.end(), true)); }
}  // namespace

bool AdaptiveSession::repeats(const PlannedTrial& trial, const std::vector<bool>& marks) const {
    if (trial.phase != Phase::Test || marks.empty()) return false;
    analysis::AdaptiveTrack copy = track(trial.condition);
    return copy.record(static_cast<int>(marks.size()), count_true(marks)).repeat;
}

AdaptiveRecord AdaptiveSession::record(const PlannedTrial& trial, const MixedPresentation& mixed,
                                       const std::string& response, const std::vector<bool>& auto_marks,
                                       const std::vector<bool>& marks) {
    AVSI_ASSERT(auto_marks.size() == marks.size());
    AdaptiveRecord a;
    a.attempt = mixed.attempt;
    a.level_db = mixed.level_db;
    a.keywords = static_cast<int>(marks.size());
    a.correct = count_true(marks);
    a.auto_correct = count_true(auto_marks);
    for (bool m : marks) a.marks += m ? '1' : '0';
    a.corrected = marks != auto_marks;
    a.speech_gain_db = mixed.speech_gain_db;
    a.noise_gain_db = mixed.noise_gain_db;
    a.limit_gain_db = mixed.limit_gain_db;
    a.response = response;
    a.next_level_db = mixed.level_db;
    if (trial.phase == Phase::Test && !marks.empty()) {
        auto& t = m_tracks.at(trial.condition);
        if (std::fabs(m_settings.value_of(t.level_db()) - mixed.level_db) > 1e-12)
            throw std::logic_error("adaptive: the presentation was mixed at another level than its track's");
        const analysis::TrackStep& step = t.record(a.keywords, a.correct);
        a.track = trial.condition;
        a.presentation = step.presentation;
        a.sentence_index = step.sentence;
        a.next_level_db = m_settings.value_of(step.next_level_db);
        a.step_db = a.next_level_db - a.level_db;
        a.reversal = step.reversal;
        a.reversals = step.reversals;
        a.repeat = step.repeat;
        a.at_bound = step.at_bound;
    }
    m_attempts[trial.position] = mixed.attempt;
    return a;
}

}  // namespace avsi::experiment
