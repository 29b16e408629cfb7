// Pilot aid: find the vocoder band count and envelope cutoff whose mean
// objective intelligibility (ESTOI by default) over a corpus is closest to a
// target, by an exhaustive search over a grid, reporting the whole grid.
// Objective scores predict but do not replace a listening pilot.
#pragma once

#include <string>
#include <vector>

#include "avsi/core/audio.h"
#include "avsi/vocoder/vocoder.h"

namespace avsi::vocoder {

struct CalibrationSettings {
    double target = 0.5;                        // target mean (E)STOI
    bool extended = true;                       // ESTOI (true) or STOI
    int min_bands = 1;
    int max_bands = 32;
    std::vector<double> cutoffs_hz = {16.0, 50.0, 160.0, 500.0};  // Shannon et al. 1995's envelope cutoffs
    VocoderSettings base;                       // every other vocoder setting
    unsigned threads = 0;                       // 0: all cores
};

struct CalibrationCell {
    int bands = 0;
    double cutoff_hz = 0.0;
    double mean = 0.0;  // mean (E)STOI over the corpus
    double sd = 0.0;    // standard deviation over the corpus
};

struct CalibrationResult {
    std::vector<CalibrationCell> table;  // every cell searched, bands-major
    CalibrationCell best;                // closest mean to the target
    std::size_t files = 0;
    bool extended = true;
    double target = 0.0;

    // The table as text: one row per band count, one column per cutoff,
    // the best cell marked.
    std::string text() const;
};

// Vocodes every recording with every (bands, cutoff) cell and scores it
// against the original. Throws InputError for an empty corpus or bad settings.
CalibrationResult calibrate(const std::vector<Audio>& corpus, const CalibrationSettings& settings);

}  // namespace avsi::vocoder
