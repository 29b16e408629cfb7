// A subject's adaptive SRT tracks during a session (protocol [adaptive];
// the rules are analysis/adaptive.h): the SNR of each presentation, the
// masking noise mixed into the stimulus audio at that SNR, the live keyword
// score of each answer, and the track's step. No window or device here: the
// runner calls it per trial, the tests call it directly.
//
// Mixing happens at run time, sample-exact, on the samples sent to the audio
// device (not from pre-mixed files): word-scoring tracks move by any real
// step (Brand & Kollmeier's ΔL), which a grid of pre-mixed levels would
// round; mixing a 2–3 s sentence takes milliseconds. The level rule says
// which signal moves: the noise (the speech stays at the stimulus level) or
// the speech (the noise stays at fixed_level_dbfs). The SNR's speech level is
// vocoder::speech_level_rms with the protocol's reference (active frames by
// default), the noise's its RMS over the stimulus's span. A mixture that
// would clip is scaled down as a whole (the SNR is unchanged) and the gain
// logged. The noise of each presentation is seeded by (experiment seed,
// subject, position, attempt), so a repeated run mixes the same noise.
//
// The masker runs over the whole presentation, not only the sentence: it
// starts noise_lead_ms before the stimulus (the runner shows the face at
// rest until the video starts) and ends noise_tail_ms after it, with
// raised-cosine ramps at its ends. noise_stage = "before" (the default, as
// `avsi vocode`) adds it to the speech before vocoding and vocodes the
// mixture at run time with the stimuli's vocoder and the sentence's carrier
// seed, from the unvocoded speech the builder writes beside each vocoded
// stimulus; "after" adds it to the stimulus's vocoded audio. Vocoding a
// sentence at run time takes milliseconds as well.
//
// Score check (confirm_scores = true, with session.response_mode =
// "experimenter"): the runner shows the live score of each answer keyword by
// keyword; the experimenter toggles a keyword (keys 1-9) and accepts (Enter)
// before the score counts. The record keeps both (auto_correct, correct,
// marks, corrected) and the runner logs a "score-corrected" event.
//
// List variables (variable = "bands" | "cutoff"): no noise is mixed; the
// presentation's audio is the builder's pre-rendered variant of the stimulus
// at the track's level (stimuli::variant_audio_path, a WAV beside the MP4),
// played sample for sample while the MP4's video is shown. Levels (the
// track's, the stored ones) are then band counts or cutoffs in Hz, and the
// record's noise level is kNoNoiseDbfs.
//
// Resume: the constructor replays the stored records of the subject through
// fresh tracks; the next level is then what it was before the interruption.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include "avsi/analysis/adaptive.h"
#include "avsi/core/corpus.h"
#include "avsi/core/protocol.h"
#include "avsi/experiment/design.h"
#include "avsi/experiment/store.h"
#include "avsi/vocoder/vocoder.h"

namespace avsi::analysis {
class KeywordScorer;
}

namespace avsi::experiment {

// The noise level recorded when no noise is mixed (list-variable tracks).
constexpr double kNoNoiseDbfs = -200.0;

// The audio of one presentation, mixed.
struct MixedPresentation {
    std::vector<float> samples;
    int sample_rate = 0;
    int attempt = 1;
    double level_db = 0.0;       // the SNR (dB), or the band count / cutoff (Hz) of a list variable
    double speech_gain_db = 0.0; // applied to the stimulus audio, limiter included
    double noise_gain_db = 0.0;  // the noise RMS in dBFS after the limiter
    double limit_gain_db = 0.0;
    // The masker's lead: the stimulus's video starts this long after the
    // audio (the face is shown at rest meanwhile).
    double lead_s = 0.0;
    // Noise before vocoding: the mixture at the vocoder's input (the SNR and
    // the gains above are measured there); empty otherwise.
    std::vector<float> vocoder_input;
};

class AdaptiveSession {
public:
    // Replays `stored` (the subject's records, in position and attempt order)
    // through the tracks. Throws InputError naming the database when a stored
    // level differs from the replayed one (the protocol's rules changed).
    AdaptiveSession(const Protocol& protocol, const Corpus& corpus, std::vector<Store::AdaptiveRow> stored,
                    const std::string& database);
    ~AdaptiveSession();
    AdaptiveSession(const AdaptiveSession&) = delete;
    AdaptiveSession& operator=(const AdaptiveSession&) = delete;

    const analysis::AdaptiveProtocol& settings() const { return m_settings; }

    // The stimulus folder the variants and the unvocoded speech are read
    // from (the planned stimulus paths are relative to it).
    void set_stimuli_dir(std::filesystem::path dir) { m_stimuli_dir = std::move(dir); }
    // Every file the session will read is there (InputError naming the first
    // missing one), so a session does not stop mid-track on a missing file:
    // for a list variable every level's variant of every test trial of
    // `plan`; for noise before vocoding the unvocoded speech of each vocoded
    // trial. Needs the stimulus folder (nothing to check for a test pattern).
    void check_variants(const std::vector<PlannedTrial>& plan) const;

    // The level the trial's next presentation gets, in the variable's units:
    // its track's level (test trials) or the fixed practice level.
    double level_db(const PlannedTrial& trial) const;
    // The pre-rendered audio variant the trial's next presentation plays (list variables).
    std::filesystem::path variant_path(const PlannedTrial& trial) const;
    // Presentations of the trial already stored (repeats), + 1.
    int next_attempt(const PlannedTrial& trial) const;

    // Mixes the masking noise at level_db(trial) into the trial's speech:
    // `speech` (the stimulus's audio, mono) when the noise goes after
    // vocoding or the condition is clean; the stimulus's unvocoded speech
    // (stimuli::unvocoded_audio_path; `speech` itself for a test pattern,
    // with no stimuli folder) when it goes before, the mixture then vocoded.
    // The masker spans lead + stimulus + tail, scaled so that its RMS over
    // the stimulus's span gives the SNR, ramped at its ends. For a list
    // variable, returns the variant's samples instead (InputError when a file
    // is missing or at another sample rate than `sample_rate`).
    MixedPresentation mix(const PlannedTrial& trial, const std::vector<float>& speech, int sample_rate);

    // The live score of an answer: one mark per keyword of the trial's sentence.
    std::vector<bool> score(const PlannedTrial& trial, const std::string& response) const;

    // Would this answer make the track present the trial again (first-sentence rule)?
    bool repeats(const PlannedTrial& trial, const std::vector<bool>& marks) const;

    // Steps the trial's track with `marks` (the live score, or the
    // experimenter's correction of it) and returns the record to commit.
    AdaptiveRecord record(const PlannedTrial& trial, const MixedPresentation& mixed, const std::string& response,
                          const std::vector<bool>& auto_marks, const std::vector<bool>& marks);

    // The track of a condition (for tests and the end-of-session log).
    const analysis::AdaptiveTrack& track(const std::string& condition) const;

private:
    const Sentence& sentence(const PlannedTrial& trial) const;
    const ProtocolCondition& condition(const PlannedTrial& trial) const;
    // Whether the trial's masker goes in before its condition's vocoder.
    bool vocodes_mixture(const PlannedTrial& trial) const;
    std::vector<float> unvocoded_speech(const PlannedTrial& trial, const std::vector<float>& presented,
                                        int sample_rate) const;

    const Protocol& m_protocol;
    const Corpus& m_corpus;
    analysis::AdaptiveProtocol m_settings;
    std::unique_ptr<analysis::KeywordScorer> m_scorer;
    std::map<std::string, analysis::AdaptiveTrack> m_tracks;
    std::map<int, int> m_attempts;  // position → presentations stored
    std::map<int, std::vector<double>> m_noise_by_rate;  // a noise recording, per sample rate
    std::filesystem::path m_stimuli_dir;
    // Noise before vocoding: the stimuli's vocoder of each vocoded condition.
    std::map<std::string, vocoder::VocoderSettings> m_vocoder;
};

}  // namespace avsi::experiment
