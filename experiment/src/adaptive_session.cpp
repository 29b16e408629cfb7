// A subject's adaptive SRT tracks during a session (see adaptive_session.h).
#include "avsi/experiment/adaptive_session.h"

#include <algorithm>
#include <cmath>
#include <span>

#include <fmt/format.h>

#include "avsi/analysis/scoring.h"
#include "avsi/core/error.h"
#include "avsi/core/rng.h"
#include "avsi/core/audio.h"
#include "avsi/core/log.h"
#include "avsi/stimuli/builder.h"
#include "avsi/vocoder/masking.h"
#include "avsi/vocoder/vocoder.h"

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
    scoring.vocabulary = analysis::corpus_vocabulary(corpus, scoring.language);
    m_scorer = std::make_unique<analysis::KeywordScorer>(scoring);
    for (const auto& c : protocol.conditions) m_tracks.emplace(c.name, analysis::AdaptiveTrack(m_settings.track));
    // Noise before vocoding: the stimuli's vocoder, for the mixture.
    if (!m_settings.list_variable() && m_settings.noise_stage == analysis::MaskerStage::BeforeVocoding)
        for (const auto& c : protocol.conditions)
            if (c.audio == ConditionAudio::Vocoded) {
                m_vocoder = stimuli::protocol_vocoder_settings(protocol);
                break;
            }
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
    if (m_stimuli_dir.empty()) return;
    if (!m_settings.list_variable()) {
        for (const auto& t : plan) {
            if (!vocodes_mixture(t)) continue;
            const auto path = m_stimuli_dir / stimuli::unvocoded_audio_path(t.stimulus);
            if (!std::filesystem::is_regular_file(path))
                throw InputError(path, fmt::format("the unvocoded speech of {} is missing (noise_stage = \"before\" "
                                                   "vocodes speech + noise at run time): build the stimuli with this "
                                                   "protocol (avsi build-stimuli)",
                                                   t.stimulus));
        }
        return;
    }
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

namespace {

// `frames` samples of a noise recording: a seeded excerpt when it is longer,
// else the recording looped from a seeded start.
std::vector<double> noise_excerpt(const std::vector<double>& noise, std::size_t frames, std::uint64_t seed) {
    Rng rng(seed);
    std::vector<double> out(frames);
    if (noise.size() >= frames) {
        const std::size_t offset = rng.uniform_int(noise.size() - frames + 1);
        std::copy_n(noise.begin() + static_cast<std::ptrdiff_t>(offset), frames, out.begin());
    } else {
        const std::size_t offset = rng.uniform_int(noise.size());
        for (std::size_t i = 0; i < frames; ++i) out[i] = noise[(offset + i) % noise.size()];
    }
    return out;
}

// Raised-cosine ramps over the first `in` and the last `out` samples.
void ramp_ends(std::vector<double>& x, std::size_t in, std::size_t out) {
    const double pi = std::acos(-1.0);
    for (std::size_t i = 0; i < in && i < x.size(); ++i) x[i] *= 0.5 * (1.0 - std::cos(pi * double(i) / double(in)));
    for (std::size_t i = 0; i < out && i < x.size(); ++i)
        x[x.size() - 1 - i] *= 0.5 * (1.0 - std::cos(pi * double(i) / double(out)));
}

double rms_of(std::span<const double> x) {
    double sum = 0.0;
    for (double v : x) sum += v * v;
    return x.empty() ? 0.0 : std::sqrt(sum / double(x.size()));
}

}  // namespace

const ProtocolCondition& AdaptiveSession::condition(const PlannedTrial& trial) const {
    const int i = m_protocol.condition_index(trial.condition);
    if (i < 0)
        throw InputError(m_protocol.path, 0, 0, "condition", fmt::format("no condition \"{}\"", trial.condition));
    return m_protocol.conditions[static_cast<std::size_t>(i)];
}

bool AdaptiveSession::vocodes_mixture(const PlannedTrial& trial) const {
    return !m_settings.list_variable() && m_settings.noise_stage == analysis::MaskerStage::BeforeVocoding &&
           condition(trial).audio == ConditionAudio::Vocoded;
}

std::vector<float> AdaptiveSession::unvocoded_speech(const PlannedTrial& trial, const std::vector<float>& presented,
                                                     int sample_rate) const {
    if (m_stimuli_dir.empty()) return presented;  // a test pattern: its audio is not vocoded
    const auto path = m_stimuli_dir / stimuli::unvocoded_audio_path(trial.stimulus);
    if (!std::filesystem::is_regular_file(path))
        throw InputError(path, "the stimulus's unvocoded speech is missing (noise_stage = \"before\" vocodes speech + "
                               "noise at run time): run avsi build-stimuli with this protocol");
    const Audio clean = read_audio(path);
    if (clean.sample_rate_hz != sample_rate)
        throw InputError(path, 0, 0, "sample_rate",
                         fmt::format("expected the stimulus video's audio rate {} Hz, got {} Hz", sample_rate,
                                     clean.sample_rate_hz));
    return clean.mono();
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
    const bool vocode_mixture = vocodes_mixture(trial);
    const std::vector<float> clean = vocode_mixture ? unvocoded_speech(trial, speech, sample_rate) : speech;
    if (clean.empty()) throw InputError(trial.stimulus, "the stimulus has no audio to mix noise with");
    const std::uint64_t seed = derive_seed(
        m_protocol.seed, fmt::format("adaptive-noise/{}/{}/{}", trial.subject, trial.position, out.attempt));
    const auto reference = vocoder::parse_snr_reference(m_settings.snr_reference, "adaptive.snr_reference");

    // The speech at its level: the stimulus level, or scaled so the noise
    // lands at fixed_level_dbfs (level_rule = "speech").
    const std::vector<double> s(clean.begin(), clean.end());
    const double speech_rms = vocoder::speech_level_rms(s, sample_rate, reference);
    if (!(speech_rms > 0)) throw InputError(trial.stimulus, "the stimulus audio is silent: no SNR can be set");
    const double speech_gain = m_settings.level_rule == analysis::LevelRule::SpeechVaries
                                   ? std::pow(10.0, m_settings.fixed_level_dbfs / 20.0) /
                                         (speech_rms * std::pow(10.0, -out.level_db / 20.0))
                                   : 1.0;
    const double noise_rms = speech_gain * speech_rms * std::pow(10.0, -out.level_db / 20.0);

    // The masker over the whole presentation: lead, the stimulus, tail. Its
    // level is set on the stimulus's span, where the SNR is defined.
    const auto lead = static_cast<std::size_t>(std::lround(m_settings.noise_lead_s * sample_rate));
    const auto tail = static_cast<std::size_t>(std::lround(m_settings.noise_tail_s * sample_rate));
    const std::size_t frames = lead + s.size() + tail;
    std::vector<double> noise;
    if (m_settings.noise == "speech-shaped") {
        Audio a;
        a.sample_rate_hz = sample_rate;
        a.samples = clean;
        noise = vocoder::speech_shaped_noise(vocoder::long_term_spectrum({a}), frames, sample_rate, seed);
    } else {
        auto it = m_noise_by_rate.find(sample_rate);
        if (it == m_noise_by_rate.end())
            it = m_noise_by_rate.emplace(sample_rate, vocoder::load_noise(m_settings.noise, sample_rate)).first;
        noise = noise_excerpt(it->second, frames, seed);
    }
    const double span_rms = rms_of(std::span<const double>(noise).subspan(lead, s.size()));
    if (!(span_rms > 0)) throw InputError(m_settings.noise, "the noise is silent over the stimulus: no SNR can be set");
    const auto ramp = static_cast<std::size_t>(std::lround(m_settings.noise_ramp_s * sample_rate));
    for (double& v : noise) v *= noise_rms / span_rms;
    ramp_ends(noise, std::min(ramp, lead), std::min(ramp, tail));
    std::vector<double> mixture = std::move(noise);
    for (std::size_t i = 0; i < s.size(); ++i) mixture[lead + i] += speech_gain * s[i];

    out.lead_s = double(lead) / sample_rate;
    double limit_gain = 1.0;
    if (vocode_mixture) {
        // Noise before vocoding: the mixture through the stimuli's vocoder,
        // with the sentence's carrier seed (vocode() limits its own output).
        vocoder::VocoderSettings v = m_vocoder;
        v.seed = stimuli::sentence_vocoder_seed(m_vocoder, sentence(trial).id);
        Audio in;
        in.sample_rate_hz = sample_rate;
        in.samples.assign(mixture.begin(), mixture.end());
        vocoder::VocoderResult r = vocoder::vocode(in, v);
        out.vocoder_input = std::move(in.samples);
        out.samples = std::move(r.audio.samples);
        limit_gain = std::pow(10.0, r.limit_gain_db / 20.0);
    } else {
        double peak = 0.0;
        for (double x : mixture) peak = std::max(peak, std::fabs(x));
        if (peak > 1.0) {
            limit_gain = 1.0 / peak;
            log_warning("trial {}: the mixture at {:.1f} dB SNR would clip (peak {:.2f}); scaled down by {:.2f} dB",
                        trial.position, out.level_db, peak, 20.0 * std::log10(limit_gain));
        }
        out.samples.resize(mixture.size());
        for (std::size_t i = 0; i < mixture.size(); ++i) out.samples[i] = static_cast<float>(mixture[i] * limit_gain);
    }
    out.limit_gain_db = 20.0 * std::log10(limit_gain);
    out.speech_gain_db = 20.0 * std::log10(speech_gain) + out.limit_gain_db;
    out.noise_gain_db = 20.0 * std::log10(noise_rms) + out.limit_gain_db;
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
