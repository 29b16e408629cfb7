// The [adaptive] section of a protocol: the rules of the adaptive SRT tracks
// (procedure, bounds, steps, estimator), what they vary (SNR, vocoder bands or
// envelope cutoff) and how, read and validated from Protocol::adaptive. Beside
// the protocol in core because the stimulus builder (a list variable's levels
// are pre-rendered), the design, the session runner and the analysis all read
// it; the procedures, estimates and psychometric fit these settings drive are
// analysis/adaptive.h's.
#pragma once

#include <map>
#include <string>
#include <vector>

namespace avsi {

struct Protocol;

enum class AdaptiveProcedure { Sentence, Word };
// How a word track's SRT is estimated.
enum class SrtEstimator { MeanOfLevels, MaximumLikelihood };
// What the track varies: the SNR of the masking noise (dB, any real level),
// or, for vocoded speech, the number of vocoder bands or the envelope
// cutoff (Hz), stepped by position on the protocol's list of levels.
enum class AdaptiveVariable { Snr, Bands, CutoffHz };
// Interleaved: the conditions' tracks alternate sentence by sentence; blocked:
// one condition's track after the other (the design's blocks).
enum class TrackOrder { Interleaved, Blocked };
// Which signal the SNR moves: the noise (speech level fixed) or the speech (noise fixed).
enum class LevelRule { NoiseVaries, SpeechVaries };
// Where an SNR track's masker is added: to the speech before it is vocoded,
// or to the vocoded stimulus audio.
enum class MaskerStage { BeforeVocoding, AfterVocoding };

std::string to_string(AdaptiveProcedure procedure);
std::string to_string(SrtEstimator estimator);
std::string to_string(TrackOrder order);
std::string to_string(LevelRule rule);
std::string to_string(AdaptiveVariable variable);
std::string to_string(MaskerStage stage);  // "before" or "after" (vocoding)

// The rules of one track (every condition's track of a protocol uses the same).
struct TrackSettings {
    AdaptiveProcedure procedure = AdaptiveProcedure::Sentence;
    double start_db = 0.0;     // level of the first sentence
    double min_db = -30.0;     // bounds of the level
    double max_db = 30.0;
    // sentence scoring
    double large_step_db = 4.0;
    int large_steps = 4;       // steps after sentences 1..large_steps are large
    double small_step_db = 2.0;
    bool repeat_first = true;  // first sentence repeated upward until correct
    int max_first_repeats = 10;  // then the track goes on as if it was wrong
    // word scoring (Brand & Kollmeier 2002)
    double target = 0.5;
    double slope_per_db = 0.15;  // assumed slope at the target, proportion per dB
    double f_start = 1.5;
    double f_ratio = 1.41;
    double f_min = 0.1;
    // estimates
    int srt_from = 5;               // first sentence (1-based) averaged
    int min_reversals = 2;          // fewer reversals over the track: not converged (0: no criterion)
    bool srt_include_next = true;   // also the level the next sentence would get
    SrtEstimator estimator = SrtEstimator::MeanOfLevels;  // word tracks; sentence tracks use the mean
};

// The [adaptive] section of a protocol.
struct AdaptiveProtocol {
    bool enabled = false;  // the protocol has an [adaptive] section
    TrackSettings track;
    AdaptiveVariable variable = AdaptiveVariable::Snr;
    TrackOrder order = TrackOrder::Interleaved;
    LevelRule level_rule = LevelRule::NoiseVaries;
    std::string noise = "speech-shaped";  // or a noise recording (resolved path)
    double fixed_level_dbfs = -26.0;      // the level that stays: the noise's when the speech varies
    std::string snr_reference = "active"; // vocoder::parse_snr_reference: "whole" or "active"
    // Where the masker enters (noise_stage): before vocoding (the mixture is
    // vocoded at run time, as `avsi vocode --noise-stage before` and CI
    // simulations do) or after it (added to the stimulus's vocoded audio).
    // Conditions with clean audio are not vocoded either way.
    MaskerStage noise_stage = MaskerStage::BeforeVocoding;
    // The masker runs over the whole presentation: it starts noise_lead_s
    // before the stimulus (the face shown at rest) and ends noise_tail_s
    // after it, with raised-cosine ramps of noise_ramp_s at its ends.
    double noise_lead_s = 0.5;
    double noise_tail_s = 0.5;
    double noise_ramp_s = 0.02;
    double practice_snr_db = 10.0;        // warm-up and practice sentences (fixed)
    bool confirm_scores = false;          // the experimenter confirms or corrects each score
    std::string reference;                // the audio-only condition (visual benefit); "" = the first
    // List variables (bands, cutoff): the levels in the variable's units,
    // strictly ascending (easier upwards). The track then runs on positions
    // 0..n−1 of this list (track.start_db, min_db, max_db and the steps are
    // positions); every level stored or reported is the list's value.
    std::vector<double> levels;
    double practice_level = 0.0;          // list variables: the level of warm-up and practice sentences
    // Upper asymptotes by condition ([adaptive] ceilings = { "audio-only" = 0.627 }): the
    // proportion of keywords a pilot got right at the easiest level. Absent: 1.
    std::map<std::string, double> ceilings;

    // Whether the track steps on a list of levels (bands, cutoff).
    bool list_variable() const { return variable != AdaptiveVariable::Snr; }
    // The unit of levels and thresholds: "dB", "bands" or "Hz".
    std::string unit() const;
    // A track level in the variable's units: the SNR itself, or levels[position].
    double value_of(double track_level) const;
};

// Reads and validates protocol.adaptive (every problem at once, with file:line:col).
// variable = "bands" | "cutoff" needs `levels` (strictly ascending numbers;
// bands integers in [1, 64], cutoffs in (0, 10000] Hz), sentence scoring
// (word scoring's real-valued ΔL has no meaning on a list: refused), every
// condition vocoded, and takes start_level / practice_level (values on the
// list; defaults the middle and the top level), large_step_levels and
// small_step_levels (positions; defaults 2 and 1); the SNR keys are refused.
AdaptiveProtocol adaptive_protocol(const Protocol& protocol);

// The masker of an SNR track as a methods section states it: the noise, the
// level rule, the SNR's speech level, the stage and the timing ("" for a
// list variable, which mixes no noise).
std::string masker_description(const AdaptiveProtocol& adaptive);

}  // namespace avsi
