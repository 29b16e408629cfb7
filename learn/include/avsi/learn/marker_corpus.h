// An articulatory corpus from optical motion capture: each recording fitted
// to a head (marker_fit.h) and stored with its phone labels as a parameter-
// track corpus (articulatory_corpus.h) that `avsi train` and `avsi evaluate`
// read like any other; the fit's residual per marker and frame goes into the
// corpus's fit report with a plot per recording. docs/articulography.md,
// "Optical motion capture".
//
// The recording list (CSV, paths relative to it): columns id, markers (a
// .c3d, Qualisys .tsv or Motive .csv file), labels (TextGrid, HTK/MOCHA .lab,
// TIMIT .phn or TSV) and optionally audio and split ("train" / "test").
//
// Written to the output folder:
//   corpus.json                    the manifest ("kind": "parameters")
//   tracks/<id>.csv                the fitted parameter track (NaN: not fitted)
//   labels/<id>.<ext>, audio/…     copies of the labels (and audio)
//   fit/<id>.residual.csv, .svg    residual per marker and frame, its plot
//   fit/report.md                  per recording: reference frame, the
//                                  orientation fit's scale and error, frames
//                                  not fitted, dropouts and residual per marker
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "avsi/learn/marker_fit.h"

namespace avsi::learn {

struct MarkerCorpusSettings {
    std::filesystem::path list_path;
    std::filesystem::path out_dir;
    std::string name = "optical-corpus";
    std::string head_name;              // for the report: which head the tracks drive
    MarkerFitSettings fit;
    std::uint64_t split_seed = 2004;
    double test_fraction = 0.3;
};

struct MarkerCorpusSummary {
    std::size_t recordings = 0;
    std::size_t frames = 0;
    std::size_t frames_fitted = 0;
    double residual_rms_mm = 0.0;       // over every marker-frame fitted
};

// Fits every recording of the list to `model` and writes the corpus (see the
// file comment). Bad rows are reported all at once with the list's file:line.
MarkerCorpusSummary fit_marker_corpus(const MarkerCorpusSettings& settings, const synth::MarkerModel& model);

}  // namespace avsi::learn
