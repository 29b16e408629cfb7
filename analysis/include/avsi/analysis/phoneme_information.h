// What each condition conveys, from phonemes.csv (phoneme_scoring.h):
// confusion matrices and information transmitted per phonetic feature.
// docs/phoneme-analysis.md.
//
// Confusion matrices per condition: consonants, vowels and viseme classes
// (core's VisemeClass, from the language's phone features: sentence_profile.h),
// target × response category, counts and row percentages. A deleted phone
// is the response category "-"; a consonant answered by a vowel is "vowel"
// in the consonant matrix (and the other way round). Insertions have no
// target and are left out.
//
// Information transmitted (Miller & Nicely 1955) per condition and feature
// grouping x of the target phone, y of the response (deletion its own
// category "-"), p from the pooled counts n_xy of N target phones:
//   T(x;y) = Σ p(x,y) log2 [p(x,y) / (p(x) p(y))]        bits
//   H(x)   = −Σ p(x) log2 p(x)
// with the Miller-Madow correction of each entropy (Miller 1955: the
// plug-in entropy of m occupied categories is low by (m − 1) / (2 N ln 2)),
// which for T = H(x) + H(y) − H(x,y) gives
//   T_MM = T − (m_xy − m_x − m_y + 1) / (2 N ln 2),   H_MM(x) = H(x) + (m_x − 1) / (2 N ln 2),
//   RTI  = T_MM / H_MM(x).
// Perfect transmission (m_xy = m_x = m_y) gives T_MM = H_MM(x), RTI exactly 1;
// independent targets and responses give T = 0 and T_MM ≤ 0 (kept as computed,
// not clamped). Groupings (consonant-only ones count consonant targets):
//   voicing   consonants: voiced / voiceless
//   manner    consonants: stop, affricate, fricative, nasal, approximant
//   place     consonants: bilabial, labiodental, dental, alveolar (+ postalveolar),
//             retroflex, velar, labial-velar (W), other place (HH, Y)
//   rounding  all phones: rounded (rounded or protruded ≥ 0.5) / spread
//   viseme    all phones: the VisemeClass
// A response phone outside the grouping's targets (a vowel for a consonant
// grouping) is the category "other".
//
// Confidence intervals: subject-level bootstrap (subjects drawn with
// replacement, their phones pooled, RTI recomputed; percentile 95 % CI).
// Comparison of two conditions: the paired bootstrap of the RTI difference on
// the same drawn subjects, a 95 % CI and the two-sided p = 2 · min(share ≤ 0,
// share ≥ 0) (at least 1/B), Holm-adjusted over the pairs of one feature.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "avsi/analysis/phoneme_scoring.h"
#include "avsi/core/information.h"
#include "avsi/core/phones.h"

namespace avsi::analysis {

// A target × response count table.
struct ConfusionMatrix {
    std::string condition, kind;              // kind: consonants, vowels, visemes, or a feature grouping
    std::vector<std::string> rows, columns;   // target categories; response categories
    std::vector<std::vector<double>> counts;  // rows × columns
};

// The names of the feature groupings, in report order.
const std::vector<std::string>& feature_grouping_names();
// The category of a phone under a grouping; "" when the grouping does not
// apply to it as a target (a vowel under voicing), "other" as a response.
std::string feature_category(const std::string& grouping, const PhoneInfo& phone, bool as_response);

// Consonant, vowel and viseme matrices of one condition's rows. `rows` may
// hold the whole study: the phone matrices' rows and columns are the phones
// of the language all its phones are of (English first, then the other
// tables), so every condition's matrix has the same ones.
std::vector<ConfusionMatrix> confusion_matrices(const std::string& condition, const std::vector<PhonemeRow>& rows);
// The target × response table of one grouping (only the categories seen).
ConfusionMatrix feature_matrix(const std::string& condition, const std::string& grouping,
                               const std::vector<PhonemeRow>& rows);

// T, H and RTI of a count table, as the header states: core's
// (information.h), shared with the stimulus set's objective viseme information.
using avsi::Transmission;
using avsi::information_transmitted;

struct InformationSettings {
    std::size_t bootstrap = 2000;  // bootstrap replicates (0: no intervals, no comparisons)
    std::uint64_t seed = 42;
};

struct InformationRow {
    std::string condition, feature;
    std::size_t subjects = 0;
    Transmission t;
    double ci_low = 0.0, ci_high = 0.0;  // 95 % subject-bootstrap CI of RTI (NaN without bootstrap)
};
struct InformationComparison {
    std::string feature, condition_a, condition_b;
    double rti_a = 0.0, rti_b = 0.0, difference = 0.0;  // a − b
    double ci_low = 0.0, ci_high = 0.0, p = 1.0, p_holm = 1.0;
};
struct InformationResult {
    std::vector<InformationRow> rows;
    std::vector<InformationComparison> comparisons;
    std::size_t bootstrap = 0;
    std::uint64_t seed = 0;
};

// Every condition (first-appearance order) × grouping, with intervals and
// paired comparisons of every pair of conditions.
InformationResult information_by_condition(const std::vector<PhonemeRow>& rows,
                                           const InformationSettings& settings = {});

// confusions.csv: condition,kind,target,response,count,row_percent (every cell);
// information.csv and information_comparisons.csv (the rows and comparisons above).
void write_confusions_csv(const std::filesystem::path& path, const std::vector<ConfusionMatrix>& matrices);
void write_information_csv(const std::filesystem::path& path, const InformationResult& result);
void write_information_comparisons_csv(const std::filesystem::path& path, const InformationResult& result);

// Reads phonemes.csv back (the columns write_phonemes_csv writes); errors name file and line.
std::vector<PhonemeRow> read_phonemes_csv(const std::filesystem::path& path);

}  // namespace avsi::analysis
