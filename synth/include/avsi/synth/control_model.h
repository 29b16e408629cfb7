// The control-model interface: a timed phone sequence → articulatory
// parameter trajectories at any frame rate (Beskow §4), and the JSON model
// files every model kind shares:
//
//     {
//       "kind": "cohen-massaro",            // rule | cohen-massaro | mpeg4-cohen-massaro | ohman
//       "version": 1,
//       "provenance": {"method": "hand-set", "data": "", "split": "",
//                      "errors": {}, "notes": "…"},
//       …kind-specific tables, keyed by phone…
//     }
//
// Phone keys are project phone symbols (protocols/languages/en/phones.tsv): a base symbol
// ("AA", "P", "sil") applies to every token of that phone; a vowel may also
// have stress-specific keys ("AA1" stressed, "AA0" unstressed) that take
// precedence over the base key, as in the stress-inclusive symbol set of the
// reference study (§4).
//
// Usage:
//     auto model = avsi::synth::load_model("protocols/models/cohen-massaro.json");
//     avsi::synth::Trajectory z = model->synthesize(phones, 60.0);
#pragma once

#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "avsi/core/phones.h"
#include "avsi/synth/trajectory.h"

namespace avsi::synth {

// How a model's parameters were set: by hand, or trained on which data.
struct ModelProvenance {
    std::string method = "hand-set";  // "hand-set", "trained", …
    std::string data;                 // corpus name or path, empty if none
    std::string split;                // e.g. "200 train / 87 test, seed 2004"
    std::map<std::string, double> errors;  // e.g. {"rmse_percent": 7.1}
    std::string notes;
};

class ControlModel {
public:
    virtual ~ControlModel() = default;

    // The model kind as written in its file ("cohen-massaro", …).
    virtual std::string_view kind() const = 0;

    // Parameter values at each of `times_s` (ascending) for the utterance;
    // `out` gets one frame per time. Throws InputError if the sequence is
    // empty, badly timed, or holds a phone the model has no entry for.
    virtual void evaluate(const PhoneSequence& phones, std::span<const double> times_s,
                          std::vector<Frame>& out) const = 0;

    // The trajectory at `fps`: frames k / fps for k < frame_count(end of
    // the last phone, fps) (trajectory.h), each the model evaluated there.
    Trajectory synthesize(const PhoneSequence& phones, double fps) const;

    // The model file as JSON text (the format load_model reads).
    virtual std::string to_json_text() const = 0;

    const ModelProvenance& provenance() const { return m_provenance; }
    void set_provenance(ModelProvenance provenance) { m_provenance = std::move(provenance); }

private:
    ModelProvenance m_provenance;
};

// The model kinds load_model understands.
const std::vector<std::string>& model_kinds();

// Reads a model file and builds the model of its "kind". Throws InputError
// naming the file and the JSON pointer of every bad field (unknown phone,
// missing parameter, out-of-range value, unknown kind with "did you mean").
std::unique_ptr<ControlModel> load_model(const std::filesystem::path& path);

// Writes `model` as its JSON file (atomically).
void save_model(const ControlModel& model, const std::filesystem::path& path);

// Throws InputError (naming `source`) unless phones is non-empty, every
// phone has end > start, and phones do not overlap or go backwards in time.
void check_phones_for_synthesis(const PhoneSequence& phones, std::string_view source = {});

// The table key that applies to a phone: "AA1"/"AA0" if present for a
// stressed/unstressed vowel, else the base symbol. Returns nullptr if none.
template <typename T>
const T* find_phone_entry(const std::map<std::string, T, std::less<>>& table, const Phone& phone) {
    const auto stressed = table.find(phone.symbol + (phone.stressed ? "1" : "0"));
    if (stressed != table.end()) return &stressed->second;
    const auto base = table.find(phone.symbol);
    return base == table.end() ? nullptr : &base->second;
}

}  // namespace avsi::synth
