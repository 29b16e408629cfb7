// A corpus of measured articulation for training and evaluating control
// models (Beskow §3–4: 287 sentences, 200 train / 87 test): per utterance a
// parameter track (CSV) or raw sensor data (EST .ema as MOCHA-TIMIT ships
// it, a Haskins IEEE rate database .mat, or sensor CSV, mapped by
// sensor_mapping.h), phone labels (TextGrid, HTK or MOCHA .lab, TIMIT .phn or
// TSV; a Haskins .mat carries its own) and an optional WAV, listed in a
// manifest with a seeded, reproducible split. docs/articulography.md.
//
// Manifest `corpus.json` in the corpus folder (paths relative to it):
//
//     {
//       "format": "avsi-articulatory-corpus", "version": 1,
//       "name": "my-lab-speaker1",
//       "split": {"seed": 2004, "test_fraction": 0.3},
//       "sensor_mapping": { … SensorMappingSettings fields, for sensor files … },
//       "utterances": [
//         {"id": "s001", "track": "tracks/s001.csv", "labels": "labels/s001.TextGrid",
//          "audio": "wav/s001.wav", "kind": "parameters", "split": "train"}, …
//       ]
//     }
//
// or `corpus.csv` with columns id, track, labels and optionally audio, kind,
// split (the split seed and fraction then come from the caller). "kind" is
// "parameters" or "sensors" (default: sensors for .ema/.est/.track/.mat
// files, parameters otherwise); "split" fixes an utterance to "train" or
// "test". "labels" may be left out for a .mat track (its PHONES are used).
// "sensor_mapping" may start from a "preset" ("mocha", "haskins"); without
// one, .mat tracks use the "haskins" preset.
//
// Parameter track CSV: a `time_s` (or `time`) column at a constant step and
// any subset of the 10 parameter columns (parameters.h). Parameters without a
// column are missing; an empty or "nan" cell is a missing value at one frame.
// Missing values are left out of training and of every error measure.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "avsi/core/phones.h"
#include "avsi/learn/sensor_mapping.h"
#include "avsi/synth/parameters.h"
#include "avsi/synth/trajectory.h"

namespace avsi::learn {

// learn builds on synth's parameters, trajectories and control models.
using namespace avsi::synth;

// The value of a measured sample the data cannot give (a lost sensor frame, a
// parameter the sensors do not measure).
inline constexpr double missing_value = std::numeric_limits<double>::quiet_NaN();

// Measured parameter values at a constant frame rate; NaN marks a missing value.
struct ParamTrack {
    double fps = 60.0;
    double start_s = 0.0;                      // time of frame 0
    std::vector<Frame> frames;
    std::array<bool, param_count> present{};   // the parameter has a column at all

    std::size_t size() const { return frames.size(); }
    double time_s(std::size_t k) const { return start_s + static_cast<double>(k) / fps; }
    bool has(Param p) const { return present[index(p)]; }
};

// Reads a parameter track CSV (see the file comment). Unknown columns, a
// non-constant time step and bad numbers throw InputError with file:line.
ParamTrack read_param_track_csv(const std::filesystem::path& path);
// Writes `time_s` and the present parameters' columns; NaN is written empty.
void write_param_track_csv(const std::filesystem::path& path, const ParamTrack& track);

enum class TrackKind { Parameters, Sensors };
enum class SplitPart { Train, Test };

struct CorpusEntry {
    std::string id;
    std::filesystem::path track;    // absolute paths
    TrackKind kind = TrackKind::Parameters;
    std::filesystem::path labels;
    std::filesystem::path audio;    // empty when there is none
    std::optional<SplitPart> fixed_split;
};

struct ArticulatoryCorpus {
    std::filesystem::path dir;
    std::filesystem::path manifest;
    std::string name;
    std::vector<CorpusEntry> entries;
    SensorMappingSettings sensor_mapping;
    bool sensor_mapping_given = false;  // the manifest has "sensor_mapping" (else .mat tracks use the "haskins" preset)
    std::uint64_t split_seed = 2004;
    double test_fraction = 0.3;
    // SHA-256 over the manifest and every file it names (in manifest order).
    std::string hash;
    // The manifest's "synthetic": true: the tracks were generated (the
    // reference speaker), not measured on a person; `avsi evaluate` then says
    // that its table checks the training pipeline.
    bool synthetic = false;
};

struct SplitSettings {
    std::optional<std::uint64_t> seed;          // default: the manifest's
    std::optional<double> test_fraction;        // default: the manifest's
};

struct CorpusSplit {
    std::uint64_t seed = 0;
    double test_fraction = 0.0;
    std::vector<std::string> train_ids;   // in manifest order
    std::vector<std::string> test_ids;
};

// One utterance ready for training: phones and the measured parameters.
struct CorpusUtterance {
    std::string id;
    PhoneSequence phones;
    ParamTrack track;
};

// Loads a manifest (corpus.json or corpus.csv in `dir`, or the file itself).
// Every problem (missing files, duplicate ids, bad fields) is reported at once.
ArticulatoryCorpus load_articulatory_corpus(const std::filesystem::path& dir_or_manifest);

// The seeded split: utterances with a fixed split keep it; the others are
// shuffled with avsi::Rng(seed) and the first round(n·test_fraction) are test.
CorpusSplit split_corpus(const ArticulatoryCorpus& corpus, const SplitSettings& settings = {});

// Reads one utterance's labels and track (mapping sensor data to parameters).
CorpusUtterance load_corpus_utterance(const ArticulatoryCorpus& corpus, const CorpusEntry& entry);
// Reads the named utterances (in parallel), in the order given.
std::vector<CorpusUtterance> load_corpus_utterances(const ArticulatoryCorpus& corpus,
                                                    const std::vector<std::string>& ids);

// Writes corpus.json for entries whose paths lie inside `dir` (with
// "synthetic": true for generated tracks).
void write_corpus_manifest(const std::filesystem::path& dir, const std::string& name,
                           const std::vector<CorpusEntry>& entries, std::uint64_t split_seed,
                           double test_fraction, bool synthetic = false);

// The index of the phone a time falls in (start ≤ t < end; the last phone
// also takes t == end), or nullopt outside the labels.
std::optional<std::size_t> phone_at(const PhoneSequence& phones, double time_s);

}  // namespace avsi::learn
