// The report section "What each model conveys" (`avsi analyze --phonemes
// phonemes.csv`): per condition, the consonant and viseme confusion matrices
// as heat maps (row percentages, cairo), the information transmitted per
// feature with its bootstrap CI and a figure of RTI by feature and
// condition, the paired comparisons, and the phoneme-level mixed model
// script. docs/phoneme-analysis.md.
//
// Files written into the report folder beside index.html and report.md:
//   confusions.csv, information.csv, information_comparisons.csv
//                          (phoneme_information.h)
//   confusion_<condition>_<consonants|visemes>.png   heat maps
//   rti.png                RTI per feature grouping and condition, 95 % CI
//   phonemes_glmer.csv     one row per target phone: subject, condition,
//                          sentence, target, correct (0/1) and its voicing,
//                          manner, place, rounding and viseme class
// With objective_csv, a table of each model's objective viseme information
// (cross-validated LDA accuracy and RTI of its face) beside the listeners'.
//   glmer_phonemes.R       lme4::glmer(correct ~ condition * class + (1|subject)
//                          + (1|sentence) + (1|target)) per grouping, reading
//                          phonemes_glmer.csv
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace avsi::analysis {

struct PhonemeReportSettings {
    std::filesystem::path phonemes_csv;  // from `avsi score --phonemes`
    std::filesystem::path out_dir;       // the report folder (its index.html and report.md gain the section)
    std::size_t bootstrap = 2000;
    std::uint64_t seed = 42;
    std::string banner;  // shown above the section, e.g. "SIMULATED answers" ("" none)
    // Report order of the conditions (the protocol's); empty or for the rest:
    // first appearance in phonemes.csv.
    std::vector<std::string> conditions;
    // qc/viseme_information.csv of a stimulus set (build-stimuli writes it,
    // stimuli/viseme_information.h; optional): what
    // each model's face carries about the viseme class, shown beside the
    // listeners' viseme RTI.
    std::filesystem::path objective_csv;
};

// Writes the files above and appends the section to out_dir's report.md and
// index.html (before </body>), which must exist.
void append_phoneme_section(const PhonemeReportSettings& settings);

}  // namespace avsi::analysis
