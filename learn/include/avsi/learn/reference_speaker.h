// A synthetic reference speaker, standing in for the motion-capture corpus of
// the reference study (Beskow §3: 287 sentences, 60 fps) that the project
// cannot ship. It shares no table and no mechanism with the control models
// it trains, so that Table 2 on it checks the training pipeline without
// favouring one model (docs/table2.md). It is a task-dynamic gesture model
// after Saltzman & Munhall (1989):
//
// - Task space: five tract variables of the lips and jaw, in millimetres on
//   the face: lip aperture (LA), lip width (LW), upper and lower lip
//   protrusion (UP, LP) and jaw opening (JO).
// - Gestures: each phone is a gesture whose targets are its row of
//   protocols/reference/task_targets.tsv (measured or estimated articulatory
//   postures with their provenance in task_targets.md; not the rule model's
//   table and not any model's); a tract variable the phone leaves
//   unspecified ("-") is not part of its gesture. A gesture is active over
//   its phone's acoustic segment (diphthongs: two gestures, split at the
//   centre), with 10 ms raised-cosine ramps, except that a vowel's gesture
//   starts together with the consonant right before it (onset consonant and
//   nucleus in phase, Browman & Goldstein 2000): the vowel shows through on
//   the tract variables that consonant leaves free. No gesture starts before
//   its acoustic segment otherwise: there is no fixed command lead.
// - Blending (gestural overlap): a tract variable's target at time t is the
//   mean of the targets of the gestures active on it, weighted by activation
//   × blending strength (consonants 100, vowels and silence 1: a consonant
//   all but suppresses the vowel on what it constrains), with a weak
//   attractor to rest (strength 0.01) where no gesture is active.
// - Dynamics: each tract variable follows its target as a critically damped
//   second-order system, z'' = (z* − z)/τ² − 2z'/τ, with τ per tract
//   variable (jittered per utterance); while a consonant gesture of
//   duration D is active on it, τ is at most D/6 (stiffer gestures in
//   shorter segments), so constrictions are made within their segments:
//   the bilabials' virtual target beyond contact (−2 mm) closes the lips.
// - Articulators: the 10 parameters are the least-cost solution of the
//   tract variables through the face's linear geometry, p = p₀ +
//   W⁻¹Jᵀ(JW⁻¹Jᵀ)⁻¹(z − z₀), J the tract variables' change per parameter
//   unit on the built-in head (measured with `avsi measure`; a stimuli test
//   checks it against the head), W the cost of moving each parameter; then
//   clamped to the parameters' ranges. jaw_thrust and jaw_shift are not
//   tract variables: posture offset, a slow jaw_shift drift and noise.
// - Variation: per utterance a speaking rate, an articulation scale (the
//   vowels' targets' distance from rest; consonants make their
//   constrictions as they are), a posture offset per parameter and the
//   time constants' jitter; per frame Gaussian sensor noise; stressed
//   vowels 10 % further from rest, unstressed 15 % less.
// - Timing from espeak-ng (avsi::synthesize_speech) over the sentences of
//   protocols/reference/sentences.txt (266 everyday English sentences).
//
// Everything is seeded: the same settings give byte-identical files.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "avsi/core/phones.h"
#include "avsi/core/rng.h"
#include "avsi/learn/articulatory_corpus.h"

namespace avsi::learn {

enum class TractVariable { LipAperture = 0, LipWidth, UpperProtrusion, LowerProtrusion, JawOpening, Count };
inline constexpr std::size_t tract_variable_count = static_cast<std::size_t>(TractVariable::Count);
std::string_view tract_variable_name(TractVariable tv);

// The tract variables as linear functions of the parameters on a face.
struct TaskGeometry {
    // mm per parameter unit, per tract variable (row) and parameter (column).
    std::array<std::array<double, param_count>, tract_variable_count> mm_per_unit{};
    std::array<double, tract_variable_count> at_rest_mm{};  // at the neutral pose
    std::array<double, param_count> cost{};                 // W: the cost of moving each parameter
};

// The built-in head's geometry (protocols/head), as `avsi measure` gives it.
const TaskGeometry& builtin_head_task_geometry();

// One phone's gesture targets (mm, as on the source speaker: task_targets.tsv).
struct GestureTargets {
    std::array<std::optional<double>, tract_variable_count> target_mm;
};
struct PhoneGestures {
    GestureTargets first;
    std::optional<GestureTargets> second;  // diphthongs
};

// Reads protocols/reference/task_targets.tsv (or `path`): phone → gestures.
std::map<std::string, PhoneGestures, std::less<>> read_task_targets(const std::filesystem::path& path = {});

struct ReferenceSpeakerSettings {
    std::uint64_t seed = 2004;
    // The language (a folder of protocols/languages/): "en", or "sv" for the
    // Swedish speaker — espeak-ng sv timing over languages/sv/reference_sentences.txt,
    // with languages/sv/task_targets.tsv's rows for the phones English lacks
    // added to the targets (resolve_reference_language sets these).
    std::string language = "en";
    std::filesystem::path sentences_path;   // empty: protocols/reference/sentences.txt
    std::filesystem::path targets_path;     // empty: protocols/reference/task_targets.tsv
    std::filesystem::path language_targets_path;  // more rows (a language's phones); empty: none
    std::size_t max_utterances = 0;          // 0: every sentence
    double fps = 60.0;
    std::string voice = "en-us";
    int rate_min_wpm = 140;
    int rate_max_wpm = 200;
    double articulation_scale_sd = 0.08;    // sd of the per-utterance scale around 1
    double offset_sd = 0.02;                // per-utterance posture offset, × range
    double time_constant_jitter = 0.10;     // τ × (1 ± this), uniform per utterance
    double jaw_shift_drift_sd = 0.06;       // sd of the slow jaw_shift drift, × range
    double sensor_noise_sd = 0.004;         // per-frame noise, × range
    double simulation_step_s = 0.001;
    std::uint64_t split_seed = 2004;
    double test_fraction = 0.3;
};

// How one utterance is varied (drawn from the settings by the generator).
struct UtteranceVariation {
    double articulation_scale = 1.0;
    std::array<double, param_count> offset{};       // added to every frame's parameters
    std::array<double, tract_variable_count> time_constant_scale{};  // 0 = 1
    bool add_noise = false;
};

// The tract variables' time constants τ (s), in TractVariable order.
const std::array<double, tract_variable_count>& reference_time_constants();

// The parameter trajectories of the reference speaker for a phone sequence
// (frames k/fps from 0 to the end of the last phone). `rng` feeds the
// jaw_shift drift and sensor noise when variation.add_noise is set.
ParamTrack simulate_reference_speaker(const PhoneSequence& phones, const UtteranceVariation& variation,
                                      const ReferenceSpeakerSettings& settings, Rng& rng);

// The tract variables of the simulation at each frame (mm), for tests and plots.
std::vector<std::array<double, tract_variable_count>> simulate_tract_variables(
    const PhoneSequence& phones, const UtteranceVariation& variation, const ReferenceSpeakerSettings& settings);

// The parameters the geometry gives a tract-variable vector (before clamping).
Frame parameters_of_tract_variables(const std::array<double, tract_variable_count>& z_mm,
                                    const TaskGeometry& geometry = builtin_head_task_geometry());

// Fills a non-English language's defaults: the voice (unless `voice_given`),
// the sentence list (unless set) and the added targets. Throws InputError
// (field "language") for a language without a table or reference files.
void resolve_reference_language(ReferenceSpeakerSettings& settings, bool voice_given);

// Reads a sentence list: one sentence per line, '#' comments, blank lines skipped.
std::vector<std::string> read_sentence_list(const std::filesystem::path& path);

// Generates the reference corpus into `out_dir`: corpus.json (synthetic),
// tracks/<id>.csv, labels/<id>.tsv, sentences.tsv (id, rate, text) and
// README.md. Returns the number of utterances written.
std::size_t write_reference_corpus(const std::filesystem::path& out_dir, const ReferenceSpeakerSettings& settings);

}  // namespace avsi::learn
