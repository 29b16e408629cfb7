// What each model's face carries about the viseme class of each phone, before
// any listener is tested: the objective counterpart of the listeners' viseme
// RTI (`avsi analyze --phonemes`, docs/phoneme-analysis.md), computed by
// build-stimuli from the articulation it measures on every model stimulus
// (what is rendered: a condition's closure hold and animation layers
// included).
//
// Segments: each speech phone of a stimulus (not silence) is one segment,
// the mean over its frames (frame k at k / fps, start ≤ t < end) of six
// measures — midline lip aperture, mouth width, upper and lower lip
// protrusion, jaw opening, lower lip to upper incisors (mm) — or the frame
// nearest its centre when no frame falls inside it; labelled with core's
// VisemeClass of the phone (viseme_class() from the phone's features in the
// language tables, sentence_profile.h: the grouping the listeners' viseme
// RTI uses, for every language of protocols/languages/).
//
// Per condition, a linear discriminant analysis: class means, the pooled
// within-class covariance (sum of squares over n − K, n training segments,
// K classes) plus a ridge of 1e-3 of its mean variance on the diagonal,
// priors the training shares; a segment goes to the class of the largest
//   x' S⁻¹ μ_k − ½ μ_k' S⁻¹ μ_k + ln π_k    (ties: the first class by name).
// Cross-validated over 5 folds by sentence: the condition's sentence ids
// sorted by name, the i-th (from 0) in fold i mod 5, so no sentence is in
// both training and test. A class with fewer than two segments in a fold's
// training data is left out of that fold's classifier. From the
// cross-validated predictions: the accuracy, the confusion matrix (true ×
// predicted class, the classes seen, sorted by name), T and RTI of that
// matrix with the Miller-Madow correction (core/information.h, as for
// listeners), and the majority class's share as the chance level.
//
// scripts/viseme-information is an independent numpy implementation of the
// same computation on viseme_segments.csv (ctest -R VisemeInformation).
#pragma once

#include <array>
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "avsi/core/information.h"
#include "avsi/core/phones.h"
#include "avsi/synth/articulation_check.h"

namespace avsi::stimuli {

inline constexpr std::size_t viseme_measure_count = 6;
inline constexpr std::size_t viseme_folds = 5;
inline constexpr double viseme_ridge = 1e-3;

// The measures' column names ("aperture_mid_mm", …), as avsi measure writes them.
const std::array<const char*, viseme_measure_count>& viseme_measure_names();

struct VisemeSegment {
    std::string condition, sentence;
    std::string phone;   // base symbol
    std::string viseme;  // to_string(VisemeClass)
    std::array<double, viseme_measure_count> measures{};
};

// The segments of one stimulus: its phones and its frames' measures at `fps`.
std::vector<VisemeSegment> viseme_segments(const std::string& condition, const std::string& sentence,
                                           const PhoneSequence& phones,
                                           const std::vector<synth::ArticulationMeasures>& frames, double fps);

struct VisemeInformation {
    std::string condition;
    std::size_t segments = 0, sentences = 0;
    double accuracy = 0.0;        // cross-validated
    double majority_class = 0.0;  // share of the commonest class
    std::vector<std::string> classes;            // sorted by name
    std::vector<std::vector<double>> confusion;  // true × predicted, over `classes`
    Transmission t;               // of `confusion`
    std::vector<std::size_t> fold;       // per segment (in the order given)
    std::vector<std::string> predicted;  // per segment
};

// The cross-validated LDA of one condition's segments (the header states it).
// Empty when the segments cannot be cross-validated: fewer than two
// sentences, or a fold whose training data has no class of two segments.
std::optional<VisemeInformation> viseme_information(const std::string& condition,
                                                    const std::vector<VisemeSegment>& segments);

// viseme_segments.csv: condition, sentence, phone, viseme, the six measures,
// and the fold and predicted class of each segment (`results` in the order
// of the conditions of `segments`; a condition without a result gets empty
// fold and prediction).
void write_viseme_segments_csv(const std::filesystem::path& path, const std::vector<VisemeSegment>& segments,
                               const std::vector<VisemeInformation>& results);
// viseme_information.csv: condition, segments, lda_accuracy, majority_class,
// t_bits, rti (the columns `avsi analyze --viseme-information` reads), then
// sentences, h_x_bits.
void write_viseme_information_csv(const std::filesystem::path& path, const std::vector<VisemeInformation>& results);
// viseme_confusions.csv: condition, viseme, predicted, count, row_percent.
void write_viseme_confusions_csv(const std::filesystem::path& path, const std::vector<VisemeInformation>& results);
// The QC page (self-contained HTML): the table and each condition's confusion
// matrix shaded by row percentage; `intro` (plain text) says what was measured.
std::string viseme_information_html(const std::string& title, const std::string& intro,
                                    const std::vector<VisemeInformation>& results);

}  // namespace avsi::stimuli
