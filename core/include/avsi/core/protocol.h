// The experiment protocol: one TOML file that the stimulus builder, the
// design and the session runner all read (DESIGN.md "The protocol file";
// every field is documented in protocols/README.md). Loading validates the
// whole file and reports every problem at once as
//   file:line:col: error: section.key: expected …, got …
// with "did you mean" for unknown keys and near-miss choices.
//
// Sections: [experiment], [corpus], [[condition]], [vocoder] (kept as a
// ConfigSection; the vocoder module validates it), [design], [render],
// [session], [scoring], [online] (kept as a ConfigSection; the experiment
// module's web study export validates it), [adaptive] (kept as a ConfigSection;
// adaptive_protocol.h validates it). Paths in the file are relative to the protocol file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "avsi/core/config.h"
#include "avsi/core/tts.h"

namespace avsi {

enum class CorpusAudio { Tts, Recordings };
enum class FaceMode { Model, Still, None };
enum class ConditionAudio { Vocoded, Clean };
enum class Counterbalance { LatinSquare, Williams };

struct CorpusSettings {
    std::filesystem::path sentences;  // resolved against the protocol folder
    CorpusAudio audio = CorpusAudio::Tts;
    // The synthesiser and voice for audio = "tts": `tts = "festival:cmu_us_slt_arctic_hts"`
    // or `"espeak:en-us"`; the older `voice = "<espeak-ng voice>"` means
    // tts = "espeak:<voice>". Without either: espeak:en-us.
    TtsEngine tts_engine = TtsEngine::Espeak;
    std::string tts_voice = "en-us";
    int tts_line = 0, tts_column = 0;  // where tts (or voice) is set (0: the default)
    // The language of the sentences, phone table and scoring: `[corpus]
    // language = "sv"` (a folder of protocols/languages/), by default the
    // voice's (espeak:sv -> "sv"; espeak:en-us and Festival -> "en").
    std::string language = "en";
    // Every stimulus's speech level after the condition's processing: the
    // active-speech RMS (vocoder::speech_level_rms, ActiveFrames) in dBFS,
    // 20·log10(RMS) with full scale 1.0; set by the stimulus builder.
    double level_dbfs = -26.0;
    int level_line = 0, level_column = 0;  // where level_dbfs is set (0: the default)
};

struct ProtocolCondition {
    std::string name;
    std::filesystem::path model;  // control model file, resolved; empty when absent
    FaceMode face = FaceMode::Still;
    ConditionAudio audio = ConditionAudio::Vocoded;
    // Post-processing policy (synth/closure_constraint.h): "hold" constrains
    // this condition's model to lip closure in /p b m/ and labiodental
    // contact in /f v/ by the least change of its own frames; "off"
    // (default) shows the model as trained or hand-set. A policy applies to
    // every model condition alike, or is a declared factor (variant_of).
    bool closure_hold = false;
    double closure_transition_s = 0.025;  // the hold's fall-off outside the segment
    // The condition this one is a declared policy variant of: the same model
    // file under another policy ("ann2+hold" of "ann2"), so the policy is a
    // factor of the design rather than a difference between models. Empty: none.
    std::string variant_of;
    // [condition.layers]: the animation layers over the speech (stimuli/layers.h
    // validates it; absent: speech and blinks only). Needs face = "model".
    ConfigSection layers;
    // [condition.vocoder]: this condition's vocoder keys over [vocoder]'s
    // (validated by the stimulus builder); only with audio = "vocoded".
    ConfigSection vocoder;
    bool has_vocoder = false;
    int line = 0;                 // where its [[condition]] table starts
};

struct DesignSettings {
    int lists = 6;                 // test lists; must equal the number of conditions
    int sentences_per_list = 15;
    int warmup = 15;               // unscored warm-up sentences at the start
    std::string warmup_condition;  // condition of the warm-up trials ("" → the first condition)
    int practice = 6;              // practice sentences, shown with their text
    std::string practice_condition;  // "" → practice cycles through the conditions
    Counterbalance counterbalance = Counterbalance::LatinSquare;
    std::uint64_t seed = 0;        // defaults to experiment.seed
};

struct RenderSettings {
    int fps = 30;
    int width = 640;
    int height = 480;
    std::string camera = "front";
    std::string background = "#808080";
    // A lab's own head: OBJ mesh and rig JSON, resolved against the protocol
    // folder; both empty = the built-in head.
    std::filesystem::path head_mesh;
    std::filesystem::path head_rig;
    // Or a glTF head with ARKit-named morph targets and its blendshape
    // mapping (empty: protocols/head/arkit_mapping.json).
    std::filesystem::path head_gltf;
    std::filesystem::path head_mapping;
    // Measure every model stimulus's articulation (lip closure, labiodental
    // contact, no interpenetration) into the manifest; needs the head's
    // articulation landmarks. false only for a head without them.
    bool check_articulation = true;
};

// [scoring]: how typed answers are scored (`avsi score`, live scoring).
struct ScoringProtocol {
    // Keyword-scoring rule set, one of protocol_rule_sets(): "strict",
    // "loose" or "lenient" (analysis/include/avsi/analysis/scoring.h).
    std::string rules = "strict";
    // Homophone table, resolved against the protocol folder; empty: the
    // shipped General American table (protocols/homophones.csv).
    std::filesystem::path homophones;
    // The first rule set that credits a compound keyword typed as separate
    // words ("bil nyckel" for "bilnyckel"): "strict", "loose", "lenient",
    // or "never" (default).
    std::string split_compounds = "never";
};

// The rule-set names [scoring] rules accepts.
const std::vector<std::string>& protocol_rule_sets();

enum class ResponseMode { Subject, Experimenter };

struct SessionSettings {
    // The language of what the subject reads: corpus.language, the one
    // language of a protocol (by default its voice's; ui_strings.h); the
    // texts below default to its table's [session].
    std::string language = "en";
    bool fullscreen = true;
    int monitor = 0;                       // 0 = primary
    ResponseMode response_mode = ResponseMode::Subject;  // who types the answer
    int break_every = 0;                   // trials between breaks; 0 = between blocks only
    double fixation_ms = 500.0;            // fixation cross before each stimulus
    double response_delay_ms = 300.0;      // after the stimulus ends, before the answer box
    bool show_progress = true;
    std::string instructions =
        "You will see and hear a talking face saying short sentences in noise.\n"
        "After each sentence, type every word you heard, then press Enter.\n"
        "Guess if you are unsure.";
    std::string practice_instructions =
        "First a few practice sentences. The sentence is shown as text after you answer.";
    std::string test_instructions = "Now the test begins. The text is no longer shown.";
    std::string break_text = "Take a short break. Press Space to continue.";
    std::string end_text = "Thank you! The session is complete.";
};

struct Protocol {
    std::filesystem::path path;  // the protocol file
    std::string name;
    std::uint64_t seed = 0;
    CorpusSettings corpus;
    std::vector<ProtocolCondition> conditions;
    DesignSettings design;
    RenderSettings render;
    SessionSettings session;
    ScoringProtocol scoring;
    // The raw sections, for modules that validate their own settings.
    ConfigSection vocoder;         // [vocoder], validated by the vocoder module
    ConfigSection render_section;  // [render]
    ConfigSection session_section; // [session]
    ConfigSection online;          // [online], validated by the experiment module (web study export/import)
    ConfigSection adaptive;        // [adaptive], adaptive SRT tracks, validated by adaptive_protocol() (adaptive_protocol.h)

    // Index of the condition with that name, or -1.
    int condition_index(const std::string& name) const;
    std::vector<std::string> condition_names() const;
};

// Loads and validates a protocol file (corpus file must exist; model files
// are resolved but not opened). Throws InputError with every problem found.
Protocol load_protocol(const std::filesystem::path& path);
// Same from text; relative paths are resolved against `path`'s folder.
Protocol parse_protocol(std::string_view text, const std::filesystem::path& path);

std::string to_string(FaceMode face);
std::string to_string(ConditionAudio audio);
std::string to_string(Counterbalance counterbalance);

}  // namespace avsi
