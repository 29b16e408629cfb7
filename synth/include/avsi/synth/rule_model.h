// The rule-based model (Beskow 1995, "Rules for visual speech synthesis"):
// each phone has a target vector that may leave parameters unspecified.
// Per parameter, the specified targets are placed at their segments'
// centres, the utterance edges (start of the first phone, end of the last)
// are anchored at the neutral value, unspecified segments take the value
// linearly interpolated between the neighbouring specified targets, and
// the resulting piecewise-linear track is smoothed by a Gaussian of
// standard deviation σ (smoothing_sigma_s, default 25 ms). The convolution
// is evaluated in closed form (a piecewise-linear function convolved with a
// Gaussian), so the result is a continuous-time function and identical at
// shared time points for every frame rate. Beskow's rules articulate
// clearly: the specified targets of the "held" phones (the default file's
// /p b m f v/) are reached in every segment and held through it, the track
// returning to the smoothed one outside with a Gaussian fall-off of the same
// σ (target_hold.h), so a bilabial closes however short it is.
//
// Model file (kind "rule"): targets embedded,
//     {"kind": "rule", "version": 1, "provenance": {…}, "smoothing_sigma_s": 0.025,
//      "held_phones": ["P", "B", "M", "F", "V"],               // optional, default none
//      "targets": {"P": {"jaw_rotation": 0.1, "lip_rounding": null, …}, …}}
// or read from a TSV (phone, then the 10 parameters, "-" = unspecified):
//     {…, "targets_file": "../rule_targets.tsv"}   // relative to the model file
// or from several, a language's additions after English's (a phone in two
// files is an error):
//     {…, "targets_file": ["../../rule_targets.tsv", "../../languages/sv/rule_targets.tsv"]}
#pragma once

#include <array>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <string>

#include "avsi/synth/control_model.h"

namespace avsi::synth {

using RuleTarget = std::array<std::optional<double>, param_count>;

// Reads a rule target TSV (header `phone jaw_rotation …`, "-" unspecified);
// errors name file:line and column.
std::map<std::string, RuleTarget, std::less<>> read_rule_targets_tsv(const std::filesystem::path& path);

class RuleModel : public ControlModel {
public:
    using Table = std::map<std::string, RuleTarget, std::less<>>;

    RuleModel(Table targets, double smoothing_sigma_s, std::set<std::string, std::less<>> held_phones = {})
        : m_targets(std::move(targets)), m_sigma_s(smoothing_sigma_s), m_held(std::move(held_phones)) {}

    std::string_view kind() const override { return "rule"; }
    void evaluate(const PhoneSequence& phones, std::span<const double> times_s,
                  std::vector<Frame>& out) const override;
    std::string to_json_text() const override;

    // The piecewise-linear track before smoothing (for tests and plots).
    void interpolated(const PhoneSequence& phones, std::span<const double> times_s,
                      std::vector<Frame>& out) const;

    const Table& targets() const { return m_targets; }
    double smoothing_sigma_s() const { return m_sigma_s; }
    const std::set<std::string, std::less<>>& held_phones() const { return m_held; }

private:
    Table m_targets;
    double m_sigma_s;
    std::set<std::string, std::less<>> m_held;
};

}  // namespace avsi::synth
