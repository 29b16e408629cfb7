// A synthetic reference speaker, standing in for the motion-capture corpus of
// the reference study (Beskow §3: 287 sentences, 60 fps) that the project
// cannot ship. Its trajectories come from a mechanism none of the control
// models share, so training and evaluating them on it is a fair test:
//
// - Articulator dynamics: per parameter a critically damped second-order
//   system  x'' = (u(t) − x)/τ² − 2·x'/τ  (time constant τ per parameter,
//   jittered per utterance), driven by a piecewise-constant command u(t).
// - Targets: u(t) is the target of the phone active at t + lead, i.e. each
//   phone's command switches in `anticipation_s` (per parameter) before its
//   segment starts. Short segments therefore undershoot their targets (the
//   system never gets there), long ones reach them — except the lips'
//   constrictions: a bilabial aims beyond contact (a virtual target) and its
//   closing gesture (jaw, upper lip raise, lower lip depression) starts as
//   early as it must for the lip aperture to be closure_margin_mm beyond
//   contact from closure_hold_s before the segment's centre to as long after
//   (the release comes no earlier), and a labiodental's gesture (jaw, lower
//   lip retraction and depression) as early as it must for the lower lip to
//   be within 1 mm of its height under the upper incisors, as real speakers
//   close the lips for every /p b m/ (the planning is in
//   simulate_reference_speaker; the aperture and height are linear in the
//   parameters as the built-in head's rig makes them).
// - Phone targets: a fixed table per phone (reference_speaker.cpp). A
//   consonant leaves the parameters its place of articulation does not
//   constrain unspecified; they take the next vowel's target (look-ahead).
//   Diphthongs (AW AY EY OW OY) move from a first to a second target halfway
//   through. Stressed vowels are articulated 10 % further from neutral,
//   unstressed ones 15 % less far.
// - Variation: per utterance a speaking rate (espeak-ng words per minute,
//   uniform in [rate_min_wpm, rate_max_wpm]), an articulation scale
//   (hypo/hyper-articulation, normal around 1), a per-parameter offset
//   (posture), and a slow random drift of jaw_shift; per frame Gaussian
//   sensor noise.
// - Timing from espeak-ng (avsi::synthesize_speech) over the sentences of
//   protocols/reference/sentences.txt (266 everyday English sentences).
//
// Everything is seeded: the same settings give byte-identical files.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "avsi/core/phones.h"
#include "avsi/core/rng.h"
#include "avsi/learn/articulatory_corpus.h"

namespace avsi::learn {

struct ArticulatorDynamics {
    double time_constant_s;  // τ of the critically damped system
    double anticipation_s;   // command switches this long before segment onset
};

// The reference speaker's dynamics per parameter (study order).
const std::array<ArticulatorDynamics, param_count>& reference_dynamics();

struct ReferenceSpeakerSettings {
    std::uint64_t seed = 2004;
    std::filesystem::path sentences_path;   // empty: protocols/reference/sentences.txt
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
    // Bilabials: the lip aperture (reference_speaker.cpp) at the segment's
    // centre is at least this far beyond contact; a bilabial's or
    // labiodental's gesture starts up to max_closure_lead_s earlier than the
    // parameters' anticipation.
    double closure_margin_mm = 2.0;
    double max_closure_lead_s = 0.15;
    // ... from this long before the centre to this long after it (a closure
    // a video frame can show, whatever the frame rate from 25 fps up).
    double closure_hold_s = 0.02;
    std::uint64_t split_seed = 2004;
    double test_fraction = 0.3;
};

// How one utterance is varied (drawn from the settings by the generator).
struct UtteranceVariation {
    double articulation_scale = 1.0;
    std::array<double, param_count> offset{};       // added to every target
    std::array<double, param_count> time_constant_scale{};
    bool add_noise = false;
};

// The parameter trajectories of the reference speaker for a phone sequence
// (frames k/fps from 0 to the end of the last phone). `rng` feeds the
// jaw_shift drift and sensor noise when variation.add_noise is set.
ParamTrack simulate_reference_speaker(const PhoneSequence& phones, const UtteranceVariation& variation,
                                      const ReferenceSpeakerSettings& settings, Rng& rng);

// Reads a sentence list: one sentence per line, '#' comments, blank lines skipped.
std::vector<std::string> read_sentence_list(const std::filesystem::path& path);

// Generates the reference corpus into `out_dir`: corpus.json, tracks/<id>.csv,
// labels/<id>.tsv, sentences.tsv (id, rate, text) and README.md. Returns the
// number of utterances written.
std::size_t write_reference_corpus(const std::filesystem::path& out_dir, const ReferenceSpeakerSettings& settings);

}  // namespace avsi::learn
