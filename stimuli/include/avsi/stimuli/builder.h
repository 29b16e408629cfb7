// The stimulus-set builder (`avsi build-stimuli protocol.toml --out DIR`):
// for each sentence × condition of a protocol, phones → trajectory (the
// condition's control model) → frames → MP4 with the condition's audio
// (vocoded or clean). The audio-only condition shows the still neutral face
// (face = "still") or a blank screen (face = "none"). Stimuli are built in
// parallel, one renderer per worker thread; a stimulus whose inputs and
// settings are unchanged (same input hash in the manifest, same file hash on
// disk) is skipped. Writes DIR/<sentence>/<condition>.mp4 and .wav and
// DIR/manifest.json (path, duration, frame count, settings, seeds, SHA-256,
// and each model stimulus's articulation: bilabials closed k of n,
// labiodentals reached k of n, aperture range, violations) and the
// articulation QC page DIR/qc/articulation.html (articulation.h).
//
// Determinism: x264 runs single-threaded with bit-exact flags and the audio
// is produced from seeds, so the same inputs give byte-identical files and
// the manifest's SHA-256 of each MP4 is stable across builds.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "avsi/core/audio.h"
#include "avsi/core/phones.h"
#include "avsi/core/protocol.h"
#include "avsi/core/shards.h"
#include "avsi/stimuli/animation.h"
#include "avsi/stimuli/layers.h"
#include "avsi/stimuli/lod.h"
#include "avsi/synth/trajectory.h"
#include "avsi/vocoder/vocoder.h"

namespace avsi::stimuli {

struct BuildSettings {
    std::filesystem::path protocol_path;
    std::filesystem::path out_dir;
    int jobs = 0;            // worker threads; 0 = hardware concurrency
    bool force = false;      // rebuild everything
    std::size_t max_sentences = 0;  // 0 = all (for quick trials)
    // false: only what the design can show — when the corpus assigns lists,
    // spare sentences (no list) are skipped, warm-up sentences are built only
    // in the warm-up condition and practice sentences only in the practice
    // condition (all conditions when practice cycles through them).
    // true: every sentence × condition.
    bool all_sentences = false;
    // Level of detail of the rendered head (lod.h); default full detail.
    // Recorded in the manifest's render settings (and so in every input
    // hash) when not full detail.
    LodSettings lod;
    // A cluster build (shards.h): only shard K of N, with its shard
    // manifest instead of manifest.json; or, with `merge`, nothing built:
    // the shards' manifests merged into manifest.json and the QC page.
    ShardSpec shard;
    bool merge = false;
};

struct BuildReport {
    std::size_t total = 0;
    std::size_t rendered = 0;
    std::size_t skipped = 0;
    std::size_t not_needed = 0;  // sentence × condition pairs the design never shows (not built)
    std::size_t frames_rendered = 0;
    double elapsed_s = 0.0;
};

// Builds the stimulus set. Throws InputError for bad protocol, corpus, model
// or audio inputs (all found in the protocol are reported at once).
BuildReport build_stimuli(const BuildSettings& settings);

struct VerifyReport {
    std::size_t total = 0;     // stimuli the protocol asks for
    std::size_t verified = 0;  // those that passed every check
    std::vector<std::string> problems;  // "<path>: what is wrong", one per finding
    // Manifest entries the protocol does not ask for (built with
    // --all-sentences or for an earlier protocol): not a problem, listed.
    std::vector<std::string> extra;
};

// Checks a built set against its protocol and manifest.json without building
// anything (`avsi build-stimuli --verify`). For each stimulus the protocol
// asks for (the same selection as build_stimuli): a manifest entry; inputs
// and settings unchanged since it was built (else it is out of date); the MP4
// and WAV with the manifest's SHA-256; the MP4 decoding to the manifest's
// frame count at its frame rate, with an audio track as long as the video
// within one frame; and every model stimulus's articulation, measured afresh
// from its model and phones on the head: each segment that breaks a
// constraint is a problem. Manifest entries the protocol does not ask for are
// listed apart. Decodes on `jobs` threads. Throws InputError for a bad
// protocol, or a missing or unreadable manifest.
VerifyReport verify_stimuli(const BuildSettings& settings);

// The pre-rendered audio of a stimulus at one level of an adaptive list
// variable ([adaptive] variable = "bands" | "cutoff"): a WAV beside the MP4,
// "<sentence>/<condition>.<variable>-<level>.wav". The builder writes one per
// level of `levels` for every vocoded stimulus (the same vocoder settings and
// seed with that band count or envelope cutoff, at the corpus speech level)
// and lists them under "variants" of the stimulus's manifest entry with their
// SHA-256; --verify checks them; the lab runner plays the one of the track's
// current level while it shows the MP4's video.
std::filesystem::path variant_audio_path(const std::filesystem::path& video, const std::string& variable,
                                         double level);

// Adaptive SNR tracks with the masker added before vocoding ([adaptive]
// noise_stage = "before", the default): the speech of a vocoded stimulus
// before vocoding, at the corpus speech level, "<sentence>/<condition>.unvocoded.wav"
// beside the MP4 (listed under "unvocoded" in the manifest entry, checked by
// --verify). The lab runner mixes the noise into it and vocodes the mixture
// with protocol_vocoder_settings and the sentence's carrier seed.
std::filesystem::path unvocoded_audio_path(const std::filesystem::path& video);

// The protocol's [vocoder] settings as the builder applies them (InputError at the key).
vocoder::VocoderSettings protocol_vocoder_settings(const Protocol& protocol);
// A condition's vocoder settings: its [condition.vocoder] keys over [vocoder]'s
// (the protocol's settings for a condition without them; InputError at the key).
vocoder::VocoderSettings protocol_vocoder_settings(const Protocol& protocol, const ProtocolCondition& condition);
// The carrier seed of a sentence's vocoded audio (shared by its vocoded conditions).
std::uint64_t sentence_vocoder_seed(const vocoder::VocoderSettings& base, const std::string& sentence_id);

// One stimulus definition (a protocol's sentence × condition) as the builder
// makes it, without rendering: the condition's trajectory (the still face's
// neutral frames for face = "still" or "none"), the sentence's timed phones,
// the presented audio (clean or vocoded with the stimulus's seed, at the
// speech level) and the blink settings of the stimulus (its seed).
struct StimulusDefinition {
    std::string sentence;
    std::string condition;
    std::string face;                    // "model", "still" or "none"
    synth::Trajectory trajectory;
    PhoneSequence phones;
    Audio audio;
    BlinkSettings blinks;
    LayerSettings layers;                // the condition's stack (empty for a still face: the head at rest)
    LayerSeeds layer_seeds;              // the stimulus's seeds, as the builder derives them
    std::filesystem::path head_gltf;     // the protocol's own head, if any ([render])
    std::filesystem::path head_mapping;
    std::filesystem::path head_mesh;
    std::filesystem::path head_rig;
};

// Makes one stimulus definition of a protocol (for `avsi play`). Throws
// InputError naming the protocol and field if the sentence or condition is
// not in it, and for the same bad inputs as build_stimuli.
StimulusDefinition stimulus_definition(const std::filesystem::path& protocol_path, const std::string& sentence,
                                       const std::string& condition);

}  // namespace avsi::stimuli
