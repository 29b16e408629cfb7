// The stimulus-set builder (see builder.h).
#include "avsi/stimuli/builder.h"
#include "avsi/stimuli/gltf_head.h"
#include "build_shards.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <set>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "avsi/core/adaptive_protocol.h"
#include "avsi/core/audio.h"
#include "avsi/core/corpus.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "avsi/core/labels.h"
#include "avsi/core/log.h"
#include "avsi/core/protocol.h"
#include "avsi/core/rng.h"
#include "avsi/core/tts.h"
#include "avsi/stimuli/animation.h"
#include "avsi/stimuli/articulation.h"
#include "avsi/stimuli/layers.h"
#include "avsi/stimuli/lod.h"
#include "avsi/stimuli/video.h"
#include "avsi/stimuli/viseme_information.h"
#include "avsi/synth/control_model.h"
#include "avsi/synth/closure_constraint.h"
#include "avsi/vocoder/masking.h"
#include "avsi/vocoder/vocoder.h"

namespace avsi::stimuli {

namespace {

using nlohmann::json;

// The [vocoder] keys: the fields of vocoder::VocoderSettings.
const std::vector<std::string>& vocoder_keys() {
    static const std::vector<std::string> keys{
        "bands",           "low_hz",          "high_hz",          "spacing",
        "edges_hz",        "filter_order",    "zero_phase",       "envelope",
        "envelope_cutoff_hz", "envelope_filter_order", "carrier", "prefilter_carrier",
        "refilter_carrier", "low_noise_iterations", "match_band_rms", "match_output_rms",
        "seed",            "pulse_rate_hz",   "pulse_width_us",   "pulse_phase",
        "current_spread",  "spread_slope_db", "synthesis_filter_order", "insertion_shift_mm",
        "n_of_m",          "selection_frame_rate_hz"};
    return keys;
}

// Bumped when the output of the builder changes for the same inputs.
constexpr const char* builder_version = "avsi-stimuli-build-4";

std::array<float, 3> parse_colour(const std::string& hex, const Protocol& protocol) {
    unsigned r = 0, g = 0, b = 0;
    if (hex.size() != 7 || hex[0] != '#' || std::sscanf(hex.c_str() + 1, "%02x%02x%02x", &r, &g, &b) != 3)
        throw InputError(protocol.path, "render.background: expected a colour \"#rrggbb\", got \"" + hex + "\"");
    return {float(r) / 255.0f, float(g) / 255.0f, float(b) / 255.0f};
}

template <typename Enum>
std::vector<std::string> enum_names(std::initializer_list<Enum> values) {
    std::vector<std::string> names;
    for (Enum v : values) names.push_back(vocoder::to_string(v));
    return names;
}

// An enum key of [vocoder] by its name (vocoder::to_string), "did you mean" on a near miss.
template <typename Enum>
Enum get_enum(const ConfigSection& s, std::string_view key, Enum fallback, std::initializer_list<Enum> values,
              DiagnosticList& problems) {
    const std::string name = s.get_choice(key, enum_names(values), vocoder::to_string(fallback), problems);
    for (Enum v : values)
        if (vocoder::to_string(v) == name) return v;
    return fallback;
}

// The cochlear-implant simulation keys of [vocoder] (vocoder/ci_simulation.h);
// ranges and consistency are vocoder::validate_settings's.
void read_ci_settings(const ConfigSection& s, vocoder::VocoderSettings& v, DiagnosticList& problems) {
    using namespace vocoder;
    v.pulse_rate_hz = s.get_number("pulse_rate_hz", v.pulse_rate_hz, -1e9, 1e9, problems);
    v.pulse_width_us = s.get_number("pulse_width_us", v.pulse_width_us, -1e9, 1e9, problems);
    v.pulse_phase = get_enum(s, "pulse_phase", v.pulse_phase, {PulsePhase::Interleaved, PulsePhase::Simultaneous},
                             problems);
    v.current_spread = get_enum(s, "current_spread", v.current_spread,
                                {CurrentSpread::None, CurrentSpread::DbPerOctave, CurrentSpread::DbPerMm}, problems);
    v.spread_slope_db = s.get_number("spread_slope_db", v.spread_slope_db, -1e9, 1e9, problems);
    v.synthesis_filter_order =
        static_cast<int>(s.get_int("synthesis_filter_order", v.synthesis_filter_order, -1000, 1000, problems));
    v.insertion_shift_mm = s.get_number("insertion_shift_mm", v.insertion_shift_mm, -1e9, 1e9, problems);
    v.n_of_m = static_cast<int>(s.get_int("n_of_m", v.n_of_m, -1000, 1000, problems));
    v.selection_frame_rate_hz = s.get_number("selection_frame_rate_hz", v.selection_frame_rate_hz, -1e9, 1e9, problems);
}

// A vocoder table ([vocoder], or a condition's over it, `v` holding the
// values a key left out keeps): every field of vocoder::VocoderSettings
// under its own name. Unknown keys get "did you mean"; type, range and
// consistency problems (vocoder::validate_settings) are reported at the key's
// file:line:col, all at once.
vocoder::VocoderSettings read_vocoder_table(const ConfigSection& s, vocoder::VocoderSettings v,
                                            const Protocol& protocol) {
    using namespace vocoder;
    DiagnosticList problems;
    v.bands = static_cast<int>(s.get_int("bands", v.bands, 1, 64, problems));
    v.low_hz = s.get_number("low_hz", v.low_hz, 1e-3, 1e6, problems);
    v.high_hz = s.get_number("high_hz", v.high_hz, 1e-3, 1e6, problems);
    v.spacing = get_enum(s, "spacing", v.spacing,
                         {BandSpacing::Greenwood, BandSpacing::Log, BandSpacing::Linear, BandSpacing::Explicit},
                         problems);
    if (const ConfigValue* edges = s.find("edges_hz")) {
        v.edges_hz.clear();
        if (edges->type != ConfigValue::Type::Array) {
            s.report("edges_hz", "expected an array of frequencies in Hz, got " + edges->describe(), problems);
        } else {
            for (const auto& item : edges->items) {
                if (item.type == ConfigValue::Type::Integer) v.edges_hz.push_back(static_cast<double>(item.integer));
                else if (item.type == ConfigValue::Type::Float) v.edges_hz.push_back(item.number);
                else {
                    problems.add(s.path(), item.line, item.column, s.field("edges_hz"),
                                 "expected a frequency in Hz, got " + item.describe());
                }
            }
        }
    }
    v.filter_order = static_cast<int>(s.get_int("filter_order", v.filter_order, 1, 16, problems));
    v.zero_phase = s.get_bool("zero_phase", v.zero_phase, problems);
    v.envelope = get_enum(s, "envelope", v.envelope,
                          {EnvelopeMethod::HalfWaveRectify, EnvelopeMethod::FullWaveRectify, EnvelopeMethod::Hilbert},
                          problems);
    v.envelope_cutoff_hz = s.get_number("envelope_cutoff_hz", v.envelope_cutoff_hz, 1e-3, 1e6, problems);
    v.envelope_filter_order =
        static_cast<int>(s.get_int("envelope_filter_order", v.envelope_filter_order, 1, 16, problems));
    v.carrier = get_enum(s, "carrier", v.carrier,
                         {CarrierType::Noise, CarrierType::Sine, CarrierType::LowNoise, CarrierType::PulseTrain,
                          CarrierType::PoissonPulses, CarrierType::Pshc},
                         problems);
    v.prefilter_carrier = s.get_bool("prefilter_carrier", v.prefilter_carrier, problems);
    v.refilter_carrier = s.get_bool("refilter_carrier", v.refilter_carrier, problems);
    v.low_noise_iterations =
        static_cast<int>(s.get_int("low_noise_iterations", v.low_noise_iterations, 0, 100, problems));
    v.match_band_rms = s.get_bool("match_band_rms", v.match_band_rms, problems);
    v.match_output_rms = s.get_bool("match_output_rms", v.match_output_rms, problems);
    v.seed = static_cast<std::uint64_t>(s.get_int("seed", static_cast<long long>(v.seed), 0,
                                                  std::numeric_limits<long long>::max(), problems));
    read_ci_settings(s, v, problems);
    s.check_unknown_keys(vocoder_keys(), problems);
    problems.throw_if_any();
    // Consistency (edges against bands and range, …): the vocoder's own
    // check, its diagnostics moved to the offending key in the protocol.
    try {
        validate_settings(v, 0.0, protocol.path.string());
    } catch (const InputError& e) {
        for (const auto& d : e.diagnostics()) {
            std::string key = d.field.rfind("vocoder.", 0) == 0 ? d.field.substr(8) : d.field;
            key = key.substr(0, key.find('['));
            s.report(key, d.message, problems);
        }
        problems.throw_if_any();
        throw;
    }
    return v;
}

// The vocoder settings of [vocoder] (the seed defaults to experiment.seed).
vocoder::VocoderSettings vocoder_settings(const Protocol& protocol) {
    vocoder::VocoderSettings v;
    v.seed = protocol.seed;
    return read_vocoder_table(protocol.vocoder, v, protocol);
}

// A condition's vocoder: its [condition.vocoder] keys over [vocoder]'s.
vocoder::VocoderSettings condition_vocoder_settings(const Protocol& protocol, const ProtocolCondition& c,
                                                    const vocoder::VocoderSettings& base) {
    return c.has_vocoder ? read_vocoder_table(c.vocoder, base, protocol) : base;
}

// The cochlear-implant simulation keys, in the manifest only when one is
// used (so the manifests and input hashes of plain vocoders stay as they were).
void add_ci_json(json& j, const vocoder::VocoderSettings& v) {
    if (!vocoder::uses_ci_simulation(v)) return;
    j["pulse_rate_hz"] = v.pulse_rate_hz;
    j["pulse_width_us"] = v.pulse_width_us;
    j["pulse_phase"] = vocoder::to_string(v.pulse_phase);
    j["current_spread"] = vocoder::to_string(v.current_spread);
    j["spread_slope_db"] = v.spread_slope_db;
    j["synthesis_filter_order"] = v.synthesis_filter_order;
    j["insertion_shift_mm"] = v.insertion_shift_mm;
    j["n_of_m"] = v.n_of_m;
    j["selection_frame_rate_hz"] = v.selection_frame_rate_hz;
    j["carrier_edges_hz"] = vocoder::carrier_edges_hz(v);
}

json vocoder_json(const vocoder::VocoderSettings& v) {
    json j = {{"bands", v.bands},
            {"low_hz", v.low_hz},
            {"high_hz", v.high_hz},
            {"spacing", vocoder::to_string(v.spacing)},
            {"edges_hz", v.edges_hz},
            {"filter_order", v.filter_order},
            {"zero_phase", v.zero_phase},
            {"envelope", vocoder::to_string(v.envelope)},
            {"envelope_cutoff_hz", v.envelope_cutoff_hz},
            {"envelope_filter_order", v.envelope_filter_order},
            {"carrier", vocoder::to_string(v.carrier)},
            {"prefilter_carrier", v.prefilter_carrier},
            {"refilter_carrier", v.refilter_carrier},
            {"low_noise_iterations", v.low_noise_iterations},
            {"match_band_rms", v.match_band_rms},
            {"match_output_rms", v.match_output_rms},
            {"seed", v.seed}};
    add_ci_json(j, v);
    return j;
}

// One pre-rendered audio variant of a stimulus (adaptive list variable).
struct Variant {
    double level = 0.0;
    std::filesystem::path wav;
};

struct Job {
    const Sentence* sentence = nullptr;
    const ProtocolCondition* condition = nullptr;
    std::filesystem::path video;  // relative to out_dir
    std::filesystem::path wav;
    std::string input_hash;
    std::uint64_t vocoder_seed = 0;
    std::uint64_t blink_seed = 0;
    std::uint64_t gaze_seed = 0;  // layers: gaze and idle head motion
    std::uint64_t head_seed = 0;
    json entry;  // the manifest entry once built (or reused)
    std::vector<Variant> variants;  // adaptive list variable: the audio at each level
    std::filesystem::path unvocoded;  // adaptive SNR, noise before vocoding: the speech before vocoding
};

// The highest sample peak a stimulus may have after its level is set:
// headroom for the AAC encoder's overshoot.
constexpr double max_peak_dbfs = -1.0;

struct Level {
    double gain_db = 0.0;
    double peak_dbfs = 0.0;  // highest |sample| after the gain
};

double to_dbfs(double amplitude) { return 20.0 * std::log10(std::max(amplitude, 1e-12)); }

// Scales `audio` so that its active-speech RMS (20 ms frames within 40 dB of
// the loudest, pauses left out: vocoder::speech_level_rms) is `level_dbfs`.
Level set_speech_level(Audio& audio, double level_dbfs) {
    const std::vector<double> samples(audio.samples.begin(), audio.samples.end());
    const double rms =
        vocoder::speech_level_rms(samples, audio.sample_rate_hz, vocoder::SnrReference::ActiveFrames);
    Level level;
    if (!(rms > 0.0)) return level;  // silence stays silent
    const double gain = std::pow(10.0, level_dbfs / 20.0) / rms;
    double peak = 0.0;
    for (float& x : audio.samples) {
        x = static_cast<float>(double(x) * gain);
        peak = std::max(peak, std::fabs(double(x)));
    }
    level.gain_db = to_dbfs(gain);
    level.peak_dbfs = to_dbfs(peak);
    return level;
}

// The head's files as the manifest records them (a change to any rebuilds every stimulus).
nlohmann::json head_hashes(const Head& head, const std::filesystem::path& mapping) {
    if (head.obj_path.extension() == ".glb" || head.obj_path.extension() == ".gltf")
        return {{"gltf_sha256", sha256_file(head.obj_path)},
                {"mapping_sha256", sha256_file(mapping.empty() ? default_blendshape_mapping() : mapping)}};
    nlohmann::json j = {{"mesh_sha256", sha256_file(head.obj_path)}, {"rig_sha256", sha256_file(head.rig_path)}};
    if (!head.texture_path.empty()) j["texture_sha256"] = sha256_file(head.texture_path);
    return j;
}

// A TTS error about the voice, placed at the protocol's [corpus] tts (or voice) key.
InputError at_tts_key(const Protocol& protocol, const InputError& e) {
    if (e.first().field != "voice") return e;
    return InputError(protocol.path.string(), protocol.corpus.tts_line, protocol.corpus.tts_column, "corpus.tts",
                      e.first().message);
}

TtsSettings tts_settings(const Protocol& protocol) {
    TtsSettings tts;
    tts.engine = protocol.corpus.tts_engine;
    tts.voice = protocol.corpus.tts_voice;
    return tts;
}

// The closure constraint's settings, as hashed and recorded.
json closure_json(const synth::ClosureSettings& s) {
    return {{"constraint", "least change of the model's jaw and lip parameters (synth/closure_constraint.h)"},
            {"aperture_goal_mm", s.aperture_goal_mm},
            {"contact_goal_mm", s.contact_goal_mm},
            {"transition_s", s.transition_s},
            {"max_steps", s.max_steps}};
}

// What the closure constraint changed in one stimulus (or a condition's).
json closure_stats_json(const synth::ClosureStats& s) {
    json mean = json::object();
    for (const auto& info : synth::params())
        if (s.sum_abs_change[synth::index(info.param)] != 0.0)
            mean[std::string(info.name)] = std::round(s.mean_abs_change(info.param) * 1e6) / 1e6;
    return {{"frames", s.frames},
            {"frames_changed", s.frames_changed},
            {"segments", s.segments},
            {"segments_changed", s.segments_changed},
            {"segments_unmet", s.segments_unmet},
            {"mean_abs_change", mean}};
}

// A condition's post-processing policy, as the manifest records it.
json policy_json(const ProtocolCondition& c) {
    if (c.face != FaceMode::Model) return nullptr;
    json j = {{"closure", c.closure_hold ? "hold" : "off"},
              {"as_trained", !c.closure_hold},
              {"variant_of", c.variant_of.empty() ? json() : json(c.variant_of)}};
    if (c.closure_hold) j["closure_transition_s"] = c.closure_transition_s;
    return j;
}

// The synthesiser and voice with their versions, recorded in the manifest's
// settings and so hashed into every stimulus: another voice or version
// rebuilds. Null when the corpus brings its own recordings.
json tts_json(const Protocol& protocol) {
    if (protocol.corpus.audio != CorpusAudio::Tts) return nullptr;
    const TtsSettings tts = tts_settings(protocol);
    TtsVoiceInfo info;
    try {
        info = describe_tts_voice(tts);
    } catch (const InputError& e) {
        throw at_tts_key(protocol, e);
    }
    return {{"tts", tts_voice_spec(tts)}, {"engine", info.engine}, {"engine_version", info.engine_version},
            {"voice", info.voice}, {"voice_sha256", info.voice_sha256},
            {"phone_times", tts.align_onsets ? "the synthesiser's segments, obstruent onsets aligned to the audio"
                                             : "the synthesiser's segments"}};
}

// What a protocol asks to be built: the loaded protocol, corpus, head and
// models, the settings every stimulus shares, and one Job per sentence ×
// condition the design shows, with the hash of everything it depends on.
// Jobs point into the protocol and corpus, so a Plan stays where it is made.
struct Plan {
    Protocol protocol;
    Corpus corpus;
    RenderSettings render;
    double fps = 30.0;
    vocoder::VocoderSettings vocoder_base;
    // The conditions with their own [condition.vocoder] keys (over vocoder_base).
    std::map<std::string, vocoder::VocoderSettings> condition_vocoder;
    Head head;
    std::optional<LodResult> lod;  // the head simplified for rendering (BuildSettings::lod), when asked for
    std::optional<ArticulationMeter> meter;  // when [render] check_articulation
    std::map<std::string, std::shared_ptr<const synth::ControlModel>> models;  // as trained or hand-set
    // The closure constraint of each condition with closure = "hold".
    std::map<std::string, synth::ClosureSettings> closure;
    synth::LipTaskFunction lip_tasks;  // the head's lip tasks (the meter's), for the constraint
    // Each model condition's animation layers ([condition.layers]; speech and blinks when absent).
    std::map<std::string, LayerSettings> layers;
    json settings_json;
    std::vector<Job> jobs;
    AdaptiveProtocol adaptive;  // a list variable's levels are pre-rendered
    std::size_t not_needed = 0;  // pairs the design never shows

    explicit Plan(const BuildSettings& settings);
    Plan(const Plan&) = delete;
    // The construction's steps, in order (each a function below the constructor).
    void choose_head(const BuildSettings& settings);
    std::map<std::string, std::string> load_models();
    void load_layers();
    void describe_settings(const BuildSettings& settings);
    // Every band count or cutoff an adaptive track steps to is a valid vocoder
    // for each vocoded condition (n-of-m within the bands, pulses that fit, …).
    void check_adaptive_vocoders() const;
    void plan_jobs(const BuildSettings& settings, const std::map<std::string, std::string>& model_hash);
    // The trajectory a condition shows: its model's, under the condition's
    // policy (the closure constraint for closure = "hold"; `stats` gets what
    // the constraint changed).
    synth::Trajectory trajectory(const ProtocolCondition& condition, const PhoneSequence& phones,
                                 synth::ClosureStats* stats = nullptr) const;
    // The timed phones of a sentence: from the TTS front end, or its labels.
    PhoneSequence phones(const Sentence& sentence) const;
    // A condition's vocoder settings: its own keys over [vocoder]'s.
    const vocoder::VocoderSettings& vocoder_for(const ProtocolCondition& condition) const {
        const auto own = condition_vocoder.find(condition.name);
        return own != condition_vocoder.end() ? own->second : vocoder_base;
    }
    // The articulation of a model stimulus: its trajectory (with the
    // condition's layers: its blended poses) measured on the head and checked.
    ArticulationSummary articulation(const Job& job, const synth::Trajectory& trajectory, const PhoneSequence& phones,
                                     std::vector<ArticulationMeasures>* measures = nullptr) const;
    // The layered animation of a model stimulus whose condition has [condition.layers].
    Animation animation(const Job& job, const synth::Trajectory& trajectory, const PhoneSequence& phones) const;
    Plan& operator=(const Plan&) = delete;
};

Plan::Plan(const BuildSettings& settings)
    : protocol(load_protocol(settings.protocol_path)), corpus(read_corpus(protocol.corpus.sentences)) {
    const auto& pr = protocol.render;
    render.width = pr.width;
    render.height = pr.height;
    render.camera = camera_view_from_name(pr.camera);
    render.background = parse_colour(pr.background, protocol);
    fps = pr.fps;
    vocoder_base = vocoder_settings(protocol);
    for (const auto& c : protocol.conditions)
        if (c.has_vocoder) condition_vocoder[c.name] = condition_vocoder_settings(protocol, c, vocoder_base);
    adaptive = adaptive_protocol(protocol);
    check_adaptive_vocoders();
    choose_head(settings);
    const std::map<std::string, std::string> model_hash = load_models();
    load_layers();
    describe_settings(settings);
    plan_jobs(settings, model_hash);
}

// The protocol's own head ([render] head_gltf, or head_mesh + head_rig) or
// the built-in one, its level of detail, and the articulation meter.
void Plan::choose_head(const BuildSettings& settings) {
    const auto& pr = protocol.render;
    if (!pr.head_gltf.empty())
        head = load_gltf_head(pr.head_gltf, pr.head_mapping.empty() ? default_blendshape_mapping() : pr.head_mapping);
    else head = pr.head_mesh.empty() ? load_default_head() : load_head(pr.head_mesh, pr.head_rig);
    // Level of detail: simplified once here, drawn by every worker; the
    // articulation is measured on the full head (the simplified head's rig
    // and landmarks are the same vertices: lod.h).
    if (!settings.lod.full_detail())
        lod.emplace(level_of_detail(head, settings.lod, render.height, double(render.framing_mm)));
    if (pr.check_articulation) {
        try {
            meter.emplace(head);
        } catch (const InputError& e) {
            throw InputError(e.first().path, e.first().line, e.first().column, e.first().field,
                             e.first().message + "; or set check_articulation = false in [render] of " +
                                 protocol.path.string() + " to build without the articulation check");
        }
    }
}

// Models, loaded once per condition (synthesis is const), and each model
// condition's hash: the model as loaded (a rule model's external target
// table included) and the condition's post-processing policy.
std::map<std::string, std::string> Plan::load_models() {
    std::map<std::string, std::string> model_hash;
    if (meter)
        lip_tasks = [this](const synth::Frame& frame) {
            Pose pose;
            pose.params = frame;
            const ArticulationMeasures m = meter->measure(pose);
            return synth::LipTaskMeasures{m.aperture_max_mm, m.lip_to_incisors_mm};
        };
    for (const auto& c : protocol.conditions)
        if (c.face == FaceMode::Model) {
            if (c.model.empty())
                throw InputError(protocol.path.string(), c.line, 0, "condition." + c.name + ".model",
                                 "expected a model file for face = \"model\"");
            std::shared_ptr<const synth::ControlModel> model = synth::load_model(c.model);
            json key = {{"model", sha256_hex(model->to_json_text())}};
            if (c.closure_hold) {
                if (!meter)
                    throw InputError(protocol.path.string(), c.line, 0, "condition." + c.name + ".closure",
                                     "closure = \"hold\" measures the lips on the head, but [render] "
                                     "check_articulation = false: the head has no articulation landmarks to "
                                     "measure");
                synth::ClosureSettings hold;
                hold.transition_s = c.closure_transition_s;
                closure[c.name] = hold;
                key["closure"] = closure_json(hold);
            }
            models[c.name] = model;
            model_hash[c.name] = sha256_hex(key.dump());
        }
    return model_hash;
}

// Animation layers of the model conditions, validated all at once.
void Plan::load_layers() {
    DiagnosticList problems;
    for (const auto& c : protocol.conditions)
        if (c.face == FaceMode::Model)
            layers[c.name] = parse_layer_settings(c.layers, protocol.path.parent_path(), problems);
    problems.throw_if_any();
}

void Plan::check_adaptive_vocoders() const {
    if (!adaptive.list_variable()) return;
    DiagnosticList problems;
    for (const auto& c : protocol.conditions) {
        if (c.audio != ConditionAudio::Vocoded) continue;
        for (const double level : adaptive.levels) {
            vocoder::VocoderSettings v = vocoder_for(c);
            if (adaptive.variable == AdaptiveVariable::Bands) v.bands = static_cast<int>(level);
            else v.envelope_cutoff_hz = level;
            try {
                vocoder::validate_settings(v, 0.0, protocol.path.string());
            } catch (const InputError& e) {
                for (const auto& d : e.diagnostics())
                    protocol.adaptive.report("levels",
                                             fmt::format("condition {} at {} = {}: {}: {}", c.name,
                                                         to_string(adaptive.variable), level, d.field, d.message),
                                             problems);
            }
        }
    }
    problems.throw_if_any();
}

// The settings every stimulus depends on (hashed into each job's input hash).
void Plan::describe_settings(const BuildSettings& settings) {
    const auto& pr = protocol.render;
    settings_json = {
        {"builder", builder_version},
        {"render", {{"fps", fps}, {"width", pr.width}, {"height", pr.height}, {"camera", pr.camera},
                    {"background", pr.background}, {"samples", render.samples}, {"fxaa", render.fxaa},
                    {"lighting", render.per_pixel_lighting ? "per-pixel" : "per-vertex"}}},
        {"video", {{"codec", "h264 (libx264)"}, {"pixel_format", "yuv420p"}, {"crf", VideoSettings{}.crf},
                   {"preset", VideoSettings{}.preset}, {"audio", "aac"}}},
        {"vocoder", vocoder_json(vocoder_base)},
        {"head", head_hashes(head, pr.head_mapping)},
        {"tts", tts_json(protocol)},
        {"level", {{"speech_dbfs", protocol.corpus.level_dbfs},
                   {"measure", "active-speech RMS: 20 ms frames within 40 dB of the loudest"},
                   {"max_peak_dbfs", max_peak_dbfs}}},
        {"articulation", pr.check_articulation ? json{{"closure_mm", ArticulationLimits{}.closure_mm},
                                                      {"labiodental_mm", ArticulationLimits{}.labiodental_mm},
                                                      {"interpenetration_mm", ArticulationLimits{}.interpenetration_mm}}
                                               : json("not checked ([render] check_articulation = false)")}};

    // Recorded (and hashed) only when not at full detail, so a default
    // build's manifest and input hashes stay as they were.
    if (lod) {
        json j = {{"chosen_by", lod->chosen_by},
                  {"level", lod->level},
                  {"triangles", lod->triangles},
                  {"full_triangles", lod->full_triangles},
                  {"kept_triangles", lod->kept_triangles},
                  {"vertices", lod->head.mesh.positions.size()},
                  {"error_mm", lod->error_mm},
                  {"simplifier", lod_simplifier()}};
        if (settings.lod.max_triangles) j["max_triangles"] = settings.lod.max_triangles;
        if (settings.lod.automatic) {
            j["max_error_px"] = settings.lod.max_error_px;
            j["head_height_px"] = lod->head_height_px;
        }
        settings_json["render"]["lod"] = j;
    }
}

// Every stimulus and the hash of everything it depends on.
void Plan::plan_jobs(const BuildSettings& settings, const std::map<std::string, std::string>& model_hash) {
    const std::size_t n_sentences = settings.max_sentences ? std::min(settings.max_sentences, corpus.sentences.size())
                                                           : corpus.sentences.size();
    // What the design can show (see BuildSettings::all_sentences). Without
    // list assignments in the corpus the design takes sentences in corpus
    // order, so every sentence may be needed.
    const bool corpus_has_lists = std::any_of(corpus.sentences.begin(), corpus.sentences.end(),
                                              [](const Sentence& s) { return !s.list.empty(); });
    const auto& design = protocol.design;
    const std::string warmup_condition = !design.warmup_condition.empty() ? design.warmup_condition
                                         : protocol.conditions.empty()    ? std::string()
                                                                          : protocol.conditions.front().name;
    const auto shown = [&](const Sentence& s, const ProtocolCondition& c) {
        if (settings.all_sentences || !corpus_has_lists) return true;
        if (s.list.empty()) return false;
        if (s.list == "warmup") return c.name == warmup_condition;
        if (s.list == "practice") return design.practice_condition.empty() || c.name == design.practice_condition;
        return true;
    };
    for (std::size_t si = 0; si < n_sentences; ++si) {
        const Sentence& s = corpus.sentences[si];
        const std::string audio_key = protocol.corpus.audio == CorpusAudio::Tts
                                          ? "tts:" + tts_voice_spec(tts_settings(protocol)) + ":" + s.text
                                          : "rec:" + sha256_file(s.audio) + ":" + sha256_file(s.labels);
        for (const auto& c : protocol.conditions) {
            if (!shown(s, c)) {
                ++not_needed;
                continue;
            }
            Job job;
            job.sentence = &s;
            job.condition = &c;
            job.video = std::filesystem::path(s.id) / (c.name + ".mp4");
            job.wav = std::filesystem::path(s.id) / (c.name + ".wav");
            job.vocoder_seed = sentence_vocoder_seed(vocoder_for(c), s.id);
            job.blink_seed = derive_seed(protocol.seed, "blinks/" + s.id + "/" + c.name);
            job.gaze_seed = derive_seed(protocol.seed, "gaze/" + s.id + "/" + c.name);
            job.head_seed = derive_seed(protocol.seed, "head-motion/" + s.id + "/" + c.name);
            json variants_key = nullptr;
            if (adaptive.list_variable() && c.audio == ConditionAudio::Vocoded) {
                const std::string variable = to_string(adaptive.variable);
                for (const double level : adaptive.levels)
                    job.variants.push_back({level, variant_audio_path(job.video, variable, level)});
                variants_key = {{"variable", variable}, {"levels", adaptive.levels}};
            }
            if (adaptive.enabled && !adaptive.list_variable() &&
                adaptive.noise_stage == MaskerStage::BeforeVocoding && c.audio == ConditionAudio::Vocoded)
                job.unvocoded = unvocoded_audio_path(job.video);
            json key = {{"settings", settings_json},
                              {"audio", audio_key},
                              {"condition", {{"face", to_string(c.face)}, {"audio", to_string(c.audio)},
                                             {"model", model_hash.count(c.name) ? model_hash.at(c.name) : ""}}},
                              {"seeds", {{"vocoder", job.vocoder_seed}, {"blinks", job.blink_seed}}}};
            if (!variants_key.is_null()) key["variants"] = variants_key;
            if (!job.unvocoded.empty()) key["unvocoded"] = true;
            // A condition's own vocoder (only then, so other stimuli keep their hashes).
            if (c.has_vocoder) key["condition_vocoder"] = vocoder_json(vocoder_for(c));
            // Layers (only when the condition has them, so speech-only stimuli keep their hashes).
            if (layers.count(c.name) && layers.at(c.name).configured)
                key["layers"] = {{"stack", json::parse(layer_settings_json(layers.at(c.name)))},
                                 {"seeds", {job.blink_seed, job.gaze_seed, job.head_seed}}};
            job.input_hash = sha256_hex(key.dump());
            jobs.push_back(std::move(job));
        }
    }
}

PhoneSequence Plan::phones(const Sentence& sentence) const {
    if (protocol.corpus.audio != CorpusAudio::Tts) return read_phones(sentence.labels);
    return synthesize_speech(sentence.text, tts_settings(protocol)).phones;
}

Animation Plan::animation(const Job& job, const synth::Trajectory& trajectory, const PhoneSequence& phones) const {
    LayerSeeds seeds;
    seeds.blink = job.blink_seed;
    seeds.gaze = job.gaze_seed;
    seeds.head = job.head_seed;
    return animate(head, trajectory, &phones, layers.at(job.condition->name), seeds);
}

synth::Trajectory Plan::trajectory(const ProtocolCondition& condition, const PhoneSequence& phones,
                                   synth::ClosureStats* stats) const {
    synth::Trajectory t = models.at(condition.name)->synthesize(phones, fps);
    for (std::size_t k = 0; k < t.size(); ++k)
        for (const auto& info : synth::params())
            if (!std::isfinite(t.value(k, info.param)))
                throw InputError(condition.model,
                                 fmt::format("condition {}: the model gives {} a non-finite value ({}) at {:.3f} s "
                                             "(frame {}): the model file is broken",
                                             condition.name, info.name, t.value(k, info.param), t.time_s(k), k));
    const auto held = closure.find(condition.name);
    if (held != closure.end()) {
        std::vector<double> times(t.size());
        for (std::size_t k = 0; k < times.size(); ++k) times[k] = t.time_s(k);
        const auto changed = synth::constrain_closure(phones, times, lip_tasks, held->second, t.frames);
        if (stats) *stats = changed;
    }
    return t;
}

ArticulationSummary Plan::articulation(const Job& job, const synth::Trajectory& trajectory, const PhoneSequence& phones,
                                       std::vector<ArticulationMeasures>* measures) const {
    AVSI_ASSERT(meter);
    std::vector<ArticulationMeasures> m;
    if (layers.at(job.condition->name).configured) {
        // The blended poses: every layer's channels on the head (the head's
        // rotation is rigid and does not change the measures).
        for (const auto& pose : animation(job, trajectory, phones).poses) m.push_back(meter->measure(pose));
    } else {
        m = meter->measure(trajectory);
    }
    auto summary = check_articulation(phones, trajectory.fps, m);
    if (measures) *measures = std::move(m);
    return summary;
}

// The manifest's record of a stimulus's articulation.
json articulation_json(const ArticulationSummary& s) {
    json problems = json::array();
    for (const auto& p : s.problems()) problems.push_back(p);
    json j = {{"bilabials", s.bilabials},
              {"bilabials_closed", s.bilabials_closed},
              {"labiodentals", s.labiodentals},
              {"labiodentals_reached", s.labiodentals_reached},
              {"aperture_min_mm", std::round(s.aperture_min_mm * 1e4) / 1e4},
              {"aperture_max_mm", std::round(s.aperture_max_mm * 1e4) / 1e4},
              {"interpenetrating_frames", s.interpenetrating_frames},
              {"violations", problems}};
    if (s.rounding_checked)
        j["rounding"] = {{"width_rounded_mm", s.width_rounded_mm}, {"width_spread_mm", s.width_spread_mm},
                         {"protrusion_rounded_mm", s.protrusion_rounded_mm},
                         {"protrusion_spread_mm", s.protrusion_spread_mm}, {"ok", s.rounding_ok}};
    return j;
}

// The entries of an earlier build's manifest by path: none when there is no
// manifest, none and `unreadable` set when it cannot be parsed.
std::map<std::string, json> manifest_entries(const std::filesystem::path& manifest_path, bool& unreadable) {
    std::map<std::string, json> entries;
    unreadable = false;
    if (!std::filesystem::exists(manifest_path)) return entries;
    try {
        const json old = read_json_file(manifest_path);
        for (const auto& e : old.at("stimuli")) entries[e.at("path").get<std::string>()] = e;
    } catch (const std::exception&) {
        entries.clear();
        unreadable = true;
    }
    return entries;
}

// The checks of verify_stimuli for one stimulus; findings go to `out`.
void verify_one(const Job& job, const std::map<std::string, json>& entries, const std::filesystem::path& out_dir,
                std::vector<std::string>& out) {
    const std::string path = job.video.generic_string();
    const auto add = [&](const std::string& what) { out.push_back(path + ": " + what); };
    const auto it = entries.find(path);
    if (it == entries.end()) {
        add("not in the manifest (not built)");
        return;
    }
    const json& e = it->second;
    if (json_string(e, "input_sha256") != job.input_hash)
        add("out of date: its inputs or settings changed since it was built (run build-stimuli)");
    const auto video = out_dir / job.video;
    const auto wav = out_dir / job.wav;
    if (!std::filesystem::exists(video)) {
        add("the MP4 is missing");
        return;
    }
    if (sha256_file(video) != json_string(e, "sha256")) add("the MP4 differs from the one built (SHA-256)");
    if (!std::filesystem::exists(wav)) add("the WAV " + job.wav.generic_string() + " is missing");
    else if (sha256_file(wav) != json_string(e, "wav_sha256"))
        add("the WAV " + job.wav.generic_string() + " differs from the one built (SHA-256)");
    std::map<std::string, std::string> listed;  // variant path → SHA-256 in the manifest
    if (e.contains("variants") && e["variants"].is_object() && e["variants"].contains("files") &&
        e["variants"]["files"].is_array())
        for (const auto& v : e["variants"]["files"])
            if (v.is_object()) listed[json_string(v, "wav")] = json_string(v, "sha256");
    for (const auto& variant : job.variants) {
        const std::string name = variant.wav.generic_string();
        const auto l = listed.find(name);
        if (l == listed.end()) add(fmt::format("the variant {} is not listed in the manifest", name));
        else if (!std::filesystem::exists(out_dir / variant.wav)) add("the variant " + name + " is missing");
        else if (sha256_file(out_dir / variant.wav) != l->second)
            add("the variant " + name + " differs from the one built (SHA-256)");
    }
    if (!job.unvocoded.empty()) {
        const std::string name = job.unvocoded.generic_string();
        const json u = e.value("unvocoded", json());
        if (!u.is_object()) add(fmt::format("the unvocoded speech {} is not listed in the manifest", name));
        else if (!std::filesystem::exists(out_dir / job.unvocoded)) add("the unvocoded speech " + name + " is missing");
        else if (sha256_file(out_dir / job.unvocoded) != json_string(u, "sha256"))
            add("the unvocoded speech " + name + " differs from the one built (SHA-256)");
    }
    try {
        const DecodedVideo v = decode_video(video);
        // Integers only: a float such as 1e300 converted to a count is undefined.
        const auto frames_json = e.value("frames", json());
        const auto frames = frames_json.is_number_unsigned() ? frames_json.get<std::size_t>() : std::size_t{0};
        if (!frames_json.is_number_unsigned()) add("the manifest's frames is not a count: " + frames_json.dump());
        const double fps = e.value("fps", 0.0);
        if (v.frame_count != frames)
            add(fmt::format("decodes to {} frames, the manifest says {}", v.frame_count, frames));
        if (std::fabs(v.fps - fps) > 1e-9) add(fmt::format("plays at {} fps, the manifest says {}", v.fps, fps));
        if (!v.has_audio) add("has no audio track");
        else if (v.fps > 0 && std::fabs(v.audio.duration_s() - v.video_duration_s) > 1.0 / v.fps)
            add(fmt::format("audio lasts {:.3f} s, video {:.3f} s: more than one frame apart",
                            v.audio.duration_s(), v.video_duration_s));
    } catch (const std::exception& error) {
        add(std::string("cannot be decoded: ") + error.what());
    }
}

// How many stimuli the QC page plots besides every one with a violation.
constexpr std::size_t qc_plots = 12;

// A model condition's policy as the QC page and the methods text name it.
std::string policy_text(const Plan& plan, const ProtocolCondition& c) {
    const std::string method = plan.models.at(c.name)->provenance().method;
    std::string text = c.closure_hold ? fmt::format("closure hold (σ {:g} ms)", 1000.0 * c.closure_transition_s)
                                      : method == "trained" ? "as trained" : "as " + method;
    if (!c.variant_of.empty()) text += ", variant of " + c.variant_of;
    return text;
}

// The articulation of every model stimulus of the plan, measured afresh
// (synthesis and landmark posing: ~1 ms a stimulus), in plan order; the
// phones of each sentence are made once (`phones` may hold some already).
std::vector<QcStimulus> measure_set(const Plan& plan, bool keep_measures,
                                    std::map<std::string, PhoneSequence> phones = {}) {
    std::vector<QcStimulus> out;
    for (const auto& job : plan.jobs) {
        const auto& c = *job.condition;
        if (c.face != FaceMode::Model) continue;
        const Sentence& s = *job.sentence;
        if (!phones.count(s.id)) phones[s.id] = plan.phones(s);
        QcStimulus q;
        q.path = job.video.generic_string();
        q.condition = c.name;
        q.sentence = s.id;
        q.text = s.text;
        q.policy = policy_text(plan, c);
        q.closure_required = c.closure_hold;
        const auto trajectory = plan.trajectory(c, phones[s.id], &q.closure_change);
        q.summary = plan.articulation(job, trajectory, phones[s.id], keep_measures ? &q.measures : nullptr);
        if (keep_measures) q.phones = phones[s.id];
        out.push_back(std::move(q));
    }
    return out;
}

// The manifest's record of a condition's articulation over the set.
json condition_articulation_json(const ConditionArticulation& c) {
    auto worst = [](const std::vector<WorstSegment>& list) {
        json out = json::array();
        for (const auto& w : list)
            out.push_back({{"path", w.path}, {"sentence", w.sentence}, {"phone", w.phone},
                           {"start_s", std::round(w.start_s * 1e4) / 1e4}, {"end_s", std::round(w.end_s * 1e4) / 1e4},
                           {"distance_mm", std::round(w.distance_mm * 1e3) / 1e3}, {"within_limit", w.met}});
        return out;
    };
    json j = {{"stimuli", c.stimuli},
              {"bilabials", c.bilabials},
              {"bilabials_closed", c.bilabials_closed},
              {"closure_rate", std::round(c.closure_rate() * 1e4) / 1e4},
              {"labiodentals", c.labiodentals},
              {"labiodentals_reached", c.labiodentals_reached},
              {"contact_rate", std::round(c.contact_rate() * 1e4) / 1e4},
              {"interpenetrating_frames", c.interpenetrating_frames},
              {"failing_stimuli", c.failing},
              {"worst_bilabials", worst(c.worst_bilabials)},
              {"worst_labiodentals", worst(c.worst_labiodentals)}};
    if (c.closure_required) j["closure_change"] = closure_stats_json(c.closure_change);
    return j;
}

// The manifest's record of a condition's objective viseme information.
json viseme_information_json(const VisemeInformation& v) {
    const auto round6 = [](double x) { return std::round(x * 1e6) / 1e6; };
    return {{"segments", v.segments},
            {"sentences", v.sentences},
            {"folds", viseme_folds},
            {"lda_accuracy", round6(v.accuracy)},
            {"majority_class", round6(v.majority_class)},
            {"t_bits", round6(v.t.t_corrected)},
            {"h_x_bits", round6(v.t.h_x_corrected)},
            {"rti", round6(v.t.rti)},
            {"classes", v.classes},
            {"confusion", v.confusion}};
}

// Writes <out>/qc/viseme_information.html (.csv, viseme_confusions.csv,
// viseme_segments.csv): what each model condition's face carries about the
// viseme class of each phone, from the measures of every model stimulus
// (viseme_information.h). Returns the conditions that could be cross-validated.
std::vector<VisemeInformation> write_viseme_qc(const Plan& plan, const std::filesystem::path& out_dir,
                                               const std::vector<QcStimulus>& stimuli) {
    const auto started = std::chrono::steady_clock::now();
    std::vector<VisemeSegment> all;
    std::vector<VisemeInformation> results;
    for (const auto& c : plan.protocol.conditions) {
        if (c.face != FaceMode::Model) continue;
        std::vector<VisemeSegment> segments;
        for (const auto& q : stimuli)
            if (q.condition == c.name)
                for (auto& s : viseme_segments(q.condition, q.sentence, q.phones, q.measures, plan.fps))
                    segments.push_back(std::move(s));
        auto r = viseme_information(c.name, segments);
        if (r) {
            log_info("viseme information: {}: LDA accuracy {:.1f} % of {} segments (majority class {:.1f} %), "
                     "RTI {:.3f}",
                     c.name, 100.0 * r->accuracy, r->segments, 100.0 * r->majority_class, r->t.rti);
            results.push_back(std::move(*r));
        } else {
            log_info("viseme information: {}: not computed ({} segments in fewer than two sentences, or a fold "
                     "without training data)",
                     c.name, segments.size());
        }
        all.insert(all.end(), std::make_move_iterator(segments.begin()), std::make_move_iterator(segments.end()));
    }
    const auto qc = out_dir / "qc";
    write_viseme_segments_csv(qc / "viseme_segments.csv", all, results);
    write_viseme_information_csv(qc / "viseme_information.csv", results);
    write_viseme_confusions_csv(qc / "viseme_confusions.csv", results);
    const std::string intro = fmt::format(
        "What each model condition's face carries about the viseme class of each phone, before any listener: for "
        "every model stimulus of the set, each speech phone is one segment, the mean over its frames ({:g} fps) of "
        "six articulation measures as rendered (closure hold and animation layers included): midline lip aperture, "
        "mouth width, upper and lower lip protrusion, jaw opening, lower lip to upper incisors (mm), labelled with "
        "its viseme class (core's VisemeClass from the phone's features). Per condition, a linear discriminant "
        "analysis (pooled within-class covariance, ridge {:g} of its mean variance, priors from the training "
        "folds), cross-validated over {} folds of sentences (sentence ids sorted by name, the i-th in fold i mod "
        "{}); T and RTI of its confusion matrix with the Miller-Madow correction, as avsi analyze --phonemes "
        "computes them for listeners. The majority class is the chance level.",
        plan.fps, viseme_ridge, viseme_folds, viseme_folds);
    write_text_file(qc / "viseme_information.html",
                    viseme_information_html("Objective viseme information — " + plan.protocol.name, intro, results));
    log_info("viseme information: {} segments of {} conditions in {:.2f} s (QC page {})", all.size(), results.size(),
             std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count(),
             (qc / "viseme_information.html").string());
    return results;
}

// What write_articulation_qc returns for the manifest.
struct SetArticulation {
    std::vector<ConditionArticulation> conditions;
    std::vector<VisemeInformation> visemes;
};

// Writes <out>/qc/articulation.html: the set's articulation by condition,
// every failure, each condition's worst segments, and the aperture plots of
// the worst stimuli; and the objective viseme information beside it
// (write_viseme_qc). Returns the per-condition records for the manifest.
SetArticulation write_articulation_qc(const Plan& plan, const std::filesystem::path& out_dir,
                                      std::map<std::string, PhoneSequence> phones) {
    auto stimuli = measure_set(plan, true, std::move(phones));
    SetArticulation out;
    out.visemes = write_viseme_qc(plan, out_dir, stimuli);
    std::vector<std::size_t> order(stimuli.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
        return worse_articulation(stimuli[a].summary, stimuli[b].summary);
    });
    std::vector<bool> plotted(stimuli.size(), false);
    for (std::size_t k = 0; k < order.size(); ++k)
        plotted[order[k]] = k < qc_plots ||
                            !stimuli[order[k]].summary.failures(stimuli[order[k]].closure_required).empty();
    std::vector<QcStimulus> page;
    for (std::size_t k = 0; k < order.size(); ++k) {
        QcStimulus q = std::move(stimuli[order[k]]);
        if (!plotted[order[k]]) {
            q.measures.clear();
            q.phones.clear();
        }
        page.push_back(std::move(q));
    }
    const auto path = out_dir / "qc" / "articulation.html";
    write_text_file(path, articulation_qc_html("Articulation QC — " + plan.protocol.name, page, {},
                                               "viseme_information.html"));
    out.conditions = articulation_by_condition(page);
    std::size_t failing = 0;
    for (const auto& c : out.conditions) {
        failing += c.failing;
        log_info("articulation: {} ({}): /p b m/ closed {} of {}, /f v/ in contact {} of {}", c.condition, c.policy,
                 c.bilabials_closed, c.bilabials, c.labiodentals_reached, c.labiodentals);
    }
    if (failing)
        log_warning("{} of {} model stimuli fail an articulation check (see {}; build-stimuli --verify lists them)",
                    failing, page.size(), path.string());
    else
        log_info("articulation: no model stimulus fails (QC page {})", path.string());
    return out;
}

// describe()'s "Label:      text" lines as a Markdown list of "Label: text".
std::string methods_list(const std::string& lines) {
    std::string m;
    for (std::size_t a = 0; a < lines.size();) {
        const std::size_t b = lines.find('\n', a);
        std::string line = lines.substr(a, b == std::string::npos ? std::string::npos : b - a);
        const std::size_t colon = line.find(':');
        if (colon != std::string::npos) {
            const std::size_t text = line.find_first_not_of(' ', colon + 1);
            line = line.substr(0, colon + 1) + (text == std::string::npos ? "" : " " + line.substr(text));
        }
        if (!line.empty()) m += "- " + line + "\n";
        if (b == std::string::npos) break;
        a = b + 1;
    }
    return m;
}

// The methods sentence on the objective viseme information ("" when no
// condition has it): each model's cross-validated accuracy and RTI.
std::string methods_visemes(const json& manifest) {
    std::vector<std::string> parts;
    double majority = 0.0;
    for (const auto& c : manifest["conditions"]) {
        const json v = c.value("viseme_information", json());
        if (!v.is_object()) continue;
        parts.push_back(fmt::format("{} {:.1f} % (RTI {:.3f})", c["name"].get<std::string>(),
                                    100.0 * v["lda_accuracy"].get<double>(), v["rti"].get<double>()));
        majority = std::max(majority, v["majority_class"].get<double>());
    }
    if (parts.empty()) return "";
    std::string list;
    for (std::size_t i = 0; i < parts.size(); ++i)
        list += (i == 0 ? "" : i + 1 == parts.size() ? " and " : ", ") + parts[i];
    return fmt::format(
        "Before any listener, the information each face carries about the viseme class of each phone was "
        "measured on the rendered articulation: a linear discriminant analysis of six lip and jaw measures per "
        "speech phone, cross-validated over {} folds of sentences, classified the viseme class correctly in {} "
        "(majority class {:.1f} %; RTI with the Miller-Madow correction; qc/viseme_information.html).\n\n",
        viseme_folds, list, 100.0 * majority);
}

// The stimuli's methods paragraph (methods.md beside the manifest): the
// speech, the conditions with each model and its policy, what each model
// put on the lips, the animation and the audio processing.
std::string methods_text(const Plan& plan, const json& manifest, const std::filesystem::path& out_dir) {
    const Protocol& p = plan.protocol;
    std::string m = fmt::format("# Methods: the stimuli of {}\n\n", p.name);
    std::set<std::string> seen;
    for (const auto& e : manifest["stimuli"]) seen.insert(e["sentence"].get<std::string>());
    const std::size_t sentences = seen.size();
    m += fmt::format("{} sentences were {}; each stimulus's speech was set to an active-speech level of {:g} dBFS. ",
                     sentences,
                     p.corpus.audio == CorpusAudio::Tts ? "synthesised with " + tts_voice_spec(tts_settings(p))
                                                        : std::string("taken from recordings with their phone labels"),
                     p.corpus.level_dbfs);
    m += fmt::format("The face was rendered at {} × {} pixels, {} frames per second. ", p.render.width,
                     p.render.height, p.render.fps);
    std::vector<std::string> plain, held;
    for (const auto& c : p.conditions)
        if (c.face == FaceMode::Model) (c.closure_hold ? held : plain).push_back(c.name);
    m += "\n\nConditions:\n\n";
    for (const auto& c : manifest["conditions"]) {
        const std::string name = c["name"].get<std::string>();
        const std::string audio = c["audio"] == "clean" ? "clean audio" : "vocoded audio";
        if (c["face"] != "model") {
            m += fmt::format("- {}: {} face, {}.\n", name, c["face"] == "still" ? "a still neutral" : "no", audio);
            continue;
        }
        m += fmt::format("- {}: control model {} ({}), {}", name, c["model"].get<std::string>(),
                         c["policy_text"].get<std::string>(), audio);
        const json& a = c["articulation"];
        if (a.is_object())
            m += fmt::format("; measured on the rendered face, the lips closed in {} of {} /p b m/ segments ({:.1f} %) "
                             "and the lower lip reached the upper incisors in {} of {} /f v/ segments ({:.1f} %)",
                             a["bilabials_closed"].get<std::size_t>(), a["bilabials"].get<std::size_t>(),
                             100.0 * a["closure_rate"].get<double>(), a["labiodentals_reached"].get<std::size_t>(),
                             a["labiodentals"].get<std::size_t>(), 100.0 * a["contact_rate"].get<double>());
        m += ".\n";
    }
    m += "\n" + methods_visemes(manifest);
    if (held.empty())
        m += "Every control model was shown as trained (or as hand-set); no condition post-processed its model.\n";
    else if (plain.empty())
        m += "Every model condition was constrained to lip closure in /p b m/ and labiodental contact in /f v/ by "
             "the least change of its own jaw and lip parameters (closure = \"hold\").\n";
    else
        m += "The closure constraint (least change of the model's own jaw and lip parameters to closure in /p b m/ "
             "and contact in /f v/) was a factor of the design: each held condition is the same model as the "
             "condition it is a variant of.\n";
    // The vocoder's settings as a methods section reports them, at the rate
    // of the vocoded stimuli: [vocoder]'s, then each condition's own.
    for (const auto& e : manifest["stimuli"]) {
        if (e.value("audio", "") != "vocoded") continue;
        const Audio vocoded = read_audio(out_dir / e["wav"].get<std::string>());
        const bool shared = std::any_of(p.conditions.begin(), p.conditions.end(), [](const ProtocolCondition& c) {
            return c.audio == ConditionAudio::Vocoded && !c.has_vocoder;
        });
        if (shared)
            m += "\nAudio of the vocoded conditions:\n\n" +
                 methods_list(vocoder::describe(plan.vocoder_base, vocoded.sample_rate_hz));
        for (const auto& c : p.conditions)
            if (c.has_vocoder)
                m += fmt::format("\nAudio of condition {} (its own vocoder):\n\n", c.name) +
                     methods_list(vocoder::describe(plan.vocoder_for(c), vocoded.sample_rate_hz));
        break;
    }
    return m;
}

}  // namespace

std::filesystem::path variant_audio_path(const std::filesystem::path& video, const std::string& variable,
                                         double level) {
    return video.parent_path() / fmt::format("{}.{}-{:g}.wav", video.stem().string(), variable, level);
}

std::filesystem::path unvocoded_audio_path(const std::filesystem::path& video) {
    return video.parent_path() / (video.stem().string() + ".unvocoded.wav");
}

vocoder::VocoderSettings protocol_vocoder_settings(const Protocol& protocol) { return vocoder_settings(protocol); }

vocoder::VocoderSettings protocol_vocoder_settings(const Protocol& protocol, const ProtocolCondition& condition) {
    return condition_vocoder_settings(protocol, condition, vocoder_settings(protocol));
}

std::uint64_t sentence_vocoder_seed(const vocoder::VocoderSettings& base, const std::string& sentence_id) {
    return derive_seed(base.seed, "vocoder/" + sentence_id);
}

namespace {

// Speech per sentence. The audio a condition presents — clean or vocoded
// (the vocoder's seed is derived from the sentence id), at the speech level —
// depends only on the sentence and that kind, so each is made once and shared.
struct PresentedAudio {
    Audio audio;
    Level level;
};
struct SentenceSpeech {
    Audio audio;
    PhoneSequence phones;
    // One presented version per vocoder (settings and seed; "" for clean).
    struct Version {
        std::once_flag once;
        PresentedAudio presented;
    };
    std::mutex versions_mutex;
    std::map<std::string, std::unique_ptr<Version>> versions;
    // The audio the conditions with `kind` and these vocoder settings present,
    // at the protocol's speech level.
    const PresentedAudio& as(ConditionAudio kind, const vocoder::VocoderSettings& base, std::uint64_t seed,
                             double level_dbfs) {
        vocoder::VocoderSettings v = base;
        v.seed = seed;
        const bool vocoded = kind == ConditionAudio::Vocoded;
        Version* version = nullptr;
        {
            std::lock_guard lock(versions_mutex);
            auto& slot = versions[vocoded ? vocoder_json(v).dump() : std::string()];
            if (!slot) slot = std::make_unique<Version>();
            version = slot.get();
        }
        std::call_once(version->once, [&] {
            PresentedAudio& p = version->presented;
            p.audio = vocoded ? vocoder::vocode(audio, v).audio : audio;
            p.level = set_speech_level(p.audio, level_dbfs);
        });
        return version->presented;
    }
};

// The worker threads for `tasks` tasks: --jobs, or one per core, at most one per task.
int worker_count(const BuildSettings& settings, std::size_t tasks) {
    return std::max(1, std::min<int>(settings.jobs > 0 ? settings.jobs
                                                       : static_cast<int>(std::thread::hardware_concurrency()),
                                     static_cast<int>(tasks)));
}

// The plan's stimuli as the shard split and the merge see them (build_shards.h).
std::vector<detail::PlannedStimulus> planned_stimuli(const Plan& plan) {
    std::vector<detail::PlannedStimulus> planned;
    std::map<std::string, double> duration_s;  // per sentence (a recording's labels are read once)
    for (const auto& job : plan.jobs) {
        auto [it, added] = duration_s.emplace(job.sentence->id, 0.0);
        if (added) it->second = detail::expected_duration_s(*job.sentence, plan.protocol);
        planned.push_back({job.sentence->id, job.video.generic_string(), job.wav.generic_string(), job.input_hash,
                           it->second * plan.fps});
    }
    return planned;
}

// The jobs whose video must be (re)built: those the previous manifest (and,
// for a shard, its earlier shard manifest) does not list with the same input
// hash and an intact video. The others take their previous entry and count
// as skipped. A shard's build leaves the other shards' jobs alone.
std::vector<std::size_t> jobs_to_build(Plan& plan, const BuildSettings& settings, BuildReport& report) {
    const auto manifest_path = settings.out_dir / "manifest.json";
    std::map<std::string, json> previous;
    if (!settings.force) {
        bool unreadable = false;
        previous = manifest_entries(manifest_path, unreadable);
        if (unreadable) log_warning("{}: unreadable manifest, rebuilding everything", manifest_path.string());
        if (settings.shard.sharded())
            for (auto& [path, entry] : detail::shard_entries(settings.out_dir, settings.shard))
                previous.insert_or_assign(path, std::move(entry));
    }
    const std::vector<bool> member = settings.shard.sharded()
                                         ? detail::shard_members(planned_stimuli(plan), settings.shard)
                                         : std::vector<bool>(plan.jobs.size(), true);
    report.total = static_cast<std::size_t>(std::count(member.begin(), member.end(), true));
    report.not_needed = plan.not_needed;
    if (plan.not_needed)
        log_info("{} sentence × condition pairs the design never shows are not built (spare sentences, warm-up and "
                 "practice sentences in other conditions); --all-sentences builds them",
                 plan.not_needed);
    std::vector<std::size_t> todo;
    for (std::size_t i = 0; i < plan.jobs.size(); ++i) {
        if (!member[i]) continue;
        auto& job = plan.jobs[i];
        const auto it = previous.find(job.video.generic_string());
        const auto video = settings.out_dir / job.video;
        if (it != previous.end() && json_string(it->second, "input_sha256") == job.input_hash &&
            std::filesystem::exists(video) && sha256_file(video) == json_string(it->second, "sha256")) {
            job.entry = it->second;
            ++report.skipped;
        } else {
            todo.push_back(i);
        }
    }
    return todo;
}

// The speech of every sentence the jobs `todo` need, synthesised on several
// threads (espeak-ng serialises its calls itself, Festival's run in parallel
// processes); recordings are read the same way.
void speak_sentences(const Plan& plan, const BuildSettings& settings, const std::vector<std::size_t>& todo,
                     std::map<std::string, SentenceSpeech>& speech) {
    const Protocol& protocol = plan.protocol;
    std::vector<std::pair<const Sentence*, SentenceSpeech*>> to_speak;
    for (const auto i : todo) {
        const Sentence& s = *plan.jobs[i].sentence;
        if (!speech.count(s.id)) to_speak.emplace_back(&s, &speech[s.id]);
    }
    const auto speech_start = std::chrono::steady_clock::now();
    const int threads = worker_count(settings, to_speak.size());
    const TtsSettings tts = tts_settings(protocol);
    std::atomic<std::size_t> next_sentence{0};
    std::mutex speak_error_mutex;
    std::exception_ptr speak_error;
    auto speak = [&] {
        for (std::size_t k; (k = next_sentence.fetch_add(1)) < to_speak.size();) {
            {
                std::lock_guard lock(speak_error_mutex);
                if (speak_error) return;
            }
            const auto [sentence, sp] = to_speak[k];
            try {
                if (protocol.corpus.audio == CorpusAudio::Tts) {
                    auto r = synthesize_speech(sentence->text, tts);
                    sp->audio = std::move(r.audio);
                    sp->phones = std::move(r.phones);
                } else {
                    sp->audio = read_audio(sentence->audio);
                    sp->phones = read_phones(sentence->labels);
                }
            } catch (const InputError& e) {
                std::lock_guard lock(speak_error_mutex);
                if (!speak_error) speak_error = std::make_exception_ptr(at_tts_key(protocol, e));
                return;
            } catch (...) {
                std::lock_guard lock(speak_error_mutex);
                if (!speak_error) speak_error = std::current_exception();
                return;
            }
        }
    };
    std::vector<std::thread> speakers;
    for (int t = 1; t < threads; ++t) speakers.emplace_back(speak);
    speak();
    for (auto& t : speakers) t.join();
    if (speak_error) std::rethrow_exception(speak_error);
    if (!to_speak.empty())
        log_info("build-stimuli: speech for {} sentences ({}) in {:.1f} s on {} thread(s)", to_speak.size(),
                 protocol.corpus.audio == CorpusAudio::Tts ? tts_voice_spec(tts) : "recordings",
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - speech_start).count(), threads);
}

// The adaptive list variable's levels of a job: the same vocoder and seed
// with that band count or cutoff, at the speech level; their manifest records
// (null without levels).
json render_variants(const Plan& plan, const BuildSettings& settings, const Job& job, const SentenceSpeech& sp) {
    const Protocol& protocol = plan.protocol;
    if (job.variants.empty()) return nullptr;
    json variants = json::array();
    for (const auto& variant : job.variants) {
        vocoder::VocoderSettings v = plan.vocoder_for(*job.condition);
        v.seed = job.vocoder_seed;
        if (plan.adaptive.variable == AdaptiveVariable::Bands)
            v.bands = static_cast<int>(variant.level);
        else
            v.envelope_cutoff_hz = variant.level;
        Audio rendered = vocoder::vocode(sp.audio, v).audio;
        const Level vl = set_speech_level(rendered, protocol.corpus.level_dbfs);
        if (vl.peak_dbfs > max_peak_dbfs)
            throw InputError(protocol.path.string(), protocol.corpus.level_line, protocol.corpus.level_column,
                             "corpus.level_dbfs",
                             fmt::format("expected a speech level at which every stimulus peaks at or "
                                         "below {:.1f} dBFS; at {:.1f} dBFS sentence '{}' with {} = {} "
                                         "peaks at {:.2f} dBFS",
                                         max_peak_dbfs, protocol.corpus.level_dbfs, job.sentence->id,
                                         to_string(plan.adaptive.variable), variant.level, vl.peak_dbfs));
        write_audio(settings.out_dir / variant.wav, rendered);
        variants.push_back({{"level", variant.level},
                            {"wav", variant.wav.generic_string()},
                            {"gain_db", vl.gain_db},
                            {"peak_dbfs", vl.peak_dbfs},
                            {"sha256", sha256_file(settings.out_dir / variant.wav)}});
    }
    return variants;
}

// Noise before vocoding: the runner vocodes speech + noise, so it needs the
// speech as it was before the vocoder, at the speech level; its manifest
// record (null when the job has none).
json render_unvocoded(const Plan& plan, const BuildSettings& settings, const Job& job, SentenceSpeech& sp) {
    if (job.unvocoded.empty()) return nullptr;
    const PresentedAudio& clean =
        sp.as(ConditionAudio::Clean, plan.vocoder_base, job.vocoder_seed, plan.protocol.corpus.level_dbfs);
    write_audio(settings.out_dir / job.unvocoded, clean.audio);
    return {{"wav", job.unvocoded.generic_string()},
            {"gain_db", clean.level.gain_db},
            {"peak_dbfs", clean.level.peak_dbfs},
            {"sha256", sha256_file(settings.out_dir / job.unvocoded)}};
}

// The audio a job presents, at the protocol's speech level; throws
// InputError naming corpus.level_dbfs when it would peak above the limit.
const PresentedAudio& presented_audio(const Plan& plan, const Job& job, SentenceSpeech& sp) {
    const Protocol& protocol = plan.protocol;
    const auto& c = *job.condition;
    const PresentedAudio& presented = sp.as(c.audio, plan.vocoder_for(c), job.vocoder_seed, protocol.corpus.level_dbfs);
    const Level& level = presented.level;
    if (level.peak_dbfs > max_peak_dbfs)
        throw InputError(
            protocol.path.string(), protocol.corpus.level_line, protocol.corpus.level_column, "corpus.level_dbfs",
            fmt::format("expected a speech level at which every stimulus peaks at or below {:.1f} dBFS; "
                        "at {:.1f} dBFS sentence '{}' ({} audio) peaks at {:.2f} dBFS: set level_dbfs "
                        "to {:.1f} or lower",
                        max_peak_dbfs, protocol.corpus.level_dbfs, job.sentence->id, to_string(c.audio),
                        level.peak_dbfs,
                        std::floor((protocol.corpus.level_dbfs - (level.peak_dbfs - max_peak_dbfs)) * 10.0) / 10.0));
    return presented;
}

// A job's video: the model's animation (layered, or the trajectory with
// blinks), or a still face or blank screen as one frame repeated. Returns
// the layers' record for the manifest (null without layers).
json render_stimulus_video(const Plan& plan, OffscreenRenderer& renderer, const Job& job, const SentenceSpeech& sp,
                           const synth::Trajectory& trajectory, const Audio& audio,
                           const std::filesystem::path& video_path, const BlinkSettings& blinks) {
    const auto& c = *job.condition;
    const RenderSettings& render = plan.render;
    VideoSettings video;
    video.fps = plan.fps;
    if (c.face == FaceMode::Model && plan.layers.at(c.name).configured) {
        const Animation animation = plan.animation(job, trajectory, sp.phones);
        for (const auto& w : animation.warnings) log_warning("build-stimuli: {}: {}", c.name, w);
        render_pose_video(renderer, animation.poses, plan.fps, &audio, video_path, video);
        return json::parse(animation.record_json);
    }
    if (c.face == FaceMode::Model) {
        render_video(renderer, trajectory, &audio, video_path, blinks, video, &sp.phones);
        return nullptr;
    }
    // A still face (or a blank screen) is one frame repeated.
    Image frame;
    if (c.face == FaceMode::Still) {
        renderer.render(Pose{}, frame);
    } else {
        frame.width = render.width;
        frame.height = render.height;
        frame.rgb.resize(static_cast<std::size_t>(frame.width) * static_cast<std::size_t>(frame.height) * 3);
        for (std::size_t p = 0; p < frame.rgb.size(); ++p)
            frame.rgb[p] = static_cast<std::uint8_t>(std::lround(render.background[p % 3] * 255.0f));
    }
    VideoWriter writer(video_path, render.width, render.height, trajectory.size(), &audio, video);
    writer.write(frame);
    for (std::size_t k = 1; k < trajectory.size(); ++k) writer.repeat_last();
    writer.finish();
    return nullptr;
}

// Builds one stimulus (its audio, adaptive variants and video) and sets the
// job's manifest entry; returns the frames rendered.
std::size_t build_stimulus(const Plan& plan, const BuildSettings& settings, OffscreenRenderer& renderer, Job& job,
                           SentenceSpeech& sp) {
    const auto& c = *job.condition;
    const double fps = plan.fps;
    const PresentedAudio& presented = presented_audio(plan, job, sp);
    const Audio& audio = presented.audio;
    const Level& level = presented.level;
    synth::Trajectory trajectory;
    json articulation = nullptr;
    json closure_change = nullptr;
    if (c.face == FaceMode::Model) {
        synth::ClosureStats changed;
        trajectory = plan.trajectory(c, sp.phones, &changed);
        if (c.closure_hold) closure_change = closure_stats_json(changed);
        if (plan.meter) articulation = articulation_json(plan.articulation(job, trajectory, sp.phones));
    } else {
        trajectory.fps = fps;
        trajectory.frames.assign(synth::frame_count(audio.duration_s(), fps), synth::Frame{});
    }
    const auto video_path = settings.out_dir / job.video;
    write_audio(settings.out_dir / job.wav, audio);
    const json variants = render_variants(plan, settings, job, sp);
    const json unvocoded = render_unvocoded(plan, settings, job, sp);
    BlinkSettings blinks;
    blinks.seed = job.blink_seed;
    blinks.enabled = c.face == FaceMode::Model;
    const json layers_record =
        render_stimulus_video(plan, renderer, job, sp, trajectory, audio, video_path, blinks);
    job.entry = {{"sentence", job.sentence->id},
                 {"condition", c.name},
                 {"path", job.video.generic_string()},
                 {"wav", job.wav.generic_string()},
                 {"duration_s", trajectory.duration_s()},
                 {"audio_duration_s", audio.duration_s()},
                 {"level", {{"gain_db", level.gain_db}, {"peak_dbfs", level.peak_dbfs}}},
                 {"frames", trajectory.size()},
                 {"fps", fps},
                 {"face", to_string(c.face)},
                 {"audio", to_string(c.audio)},
                 {"model", c.model.empty() ? "" : c.model.filename().string()},
                 {"closure", c.face != FaceMode::Model ? json() : json(c.closure_hold ? "hold" : "off")},
                 {"policy", policy_json(c)},
                 {"articulation", articulation},
                 {"seeds", {{"vocoder", c.audio == ConditionAudio::Vocoded ? json(job.vocoder_seed) : json()},
                            {"blinks", blinks.enabled ? json(job.blink_seed) : json()}}},
                 {"input_sha256", job.input_hash},
                 {"sha256", sha256_file(video_path)},
                 {"wav_sha256", sha256_file(settings.out_dir / job.wav)}};
    if (!layers_record.is_null()) job.entry["layers"] = layers_record;
    if (!closure_change.is_null()) job.entry["closure_change"] = closure_change;
    if (!variants.is_null())
        job.entry["variants"] = {{"variable", to_string(plan.adaptive.variable)},
                                 {"unit", plan.adaptive.unit()},
                                 {"files", variants}};
    if (!unvocoded.is_null()) job.entry["unvocoded"] = unvocoded;
    return trajectory.size();
}

// Builds the jobs `todo` on worker threads, each with its own renderer; the
// first error stops the others and is rethrown. Returns the frames rendered.
std::size_t build_jobs(Plan& plan, const BuildSettings& settings, const BuildReport& report,
                       const std::vector<std::size_t>& todo, std::map<std::string, SentenceSpeech>& speech) {
    const int workers = worker_count(settings, todo.size());
    // llvmpipe starts its own rasteriser threads per context (one per core,
    // LP_NUM_THREADS). With one worker per core they would only compete with
    // the workers, so each worker rasterises on its own thread instead —
    // unless the user set LP_NUM_THREADS. Read once, at the first context.
    if (workers > 1 && std::getenv("LP_NUM_THREADS") == nullptr) setenv("LP_NUM_THREADS", "0", 0);
    log_info("build-stimuli: {} stimuli, {} to build, {} unchanged; {} worker(s)", report.total, todo.size(),
             report.skipped, workers);
    Progress progress("build-stimuli", todo.size());
    std::atomic<std::size_t> next{0};
    std::atomic<std::size_t> frames_total{0};
    std::mutex error_mutex;
    std::exception_ptr error;
    auto worker = [&] {
        try {
            OffscreenRenderer renderer(plan.lod ? plan.lod->head : plan.head, plan.render);
            while (true) {
                const std::size_t t = next.fetch_add(1);
                if (t >= todo.size()) break;
                {
                    std::lock_guard lock(error_mutex);
                    if (error) break;
                }
                Job& job = plan.jobs[todo[t]];
                frames_total += build_stimulus(plan, settings, renderer, job, speech.at(job.sentence->id));
                progress.advance();
            }
        } catch (...) {
            std::lock_guard lock(error_mutex);
            if (!error) error = std::current_exception();
        }
    };
    std::vector<std::thread> threads;
    for (int w = 0; w < workers; ++w) threads.emplace_back(worker);
    for (auto& t : threads) t.join();
    progress.finish();
    if (error) std::rethrow_exception(error);
    return frames_total;
}

// manifest.json (every stimulus's entry and each condition: its policy and,
// measured on the head, what its model puts on the lips over the set,
// written with the QC page) and methods.md.
void write_manifest(const Plan& plan, const BuildSettings& settings,
                    const std::map<std::string, SentenceSpeech>& speech) {
    const Protocol& protocol = plan.protocol;
    json manifest = {{"format", "avsi-stimuli-manifest"},
                     {"version", 1},
                     {"protocol", protocol.path.filename().string()},
                     {"experiment", protocol.name},
                     {"seed", protocol.seed},
                     {"settings", plan.settings_json},
                     {"stimuli", json::array()}};
    for (const auto& job : plan.jobs) manifest["stimuli"].push_back(job.entry);
    std::map<std::string, json> articulation_of, visemes_of;
    if (plan.meter) {
        std::map<std::string, PhoneSequence> phones;
        for (const auto& [id, sp] : speech) phones[id] = sp.phones;
        const SetArticulation set = write_articulation_qc(plan, settings.out_dir, std::move(phones));
        for (const auto& c : set.conditions) articulation_of[c.condition] = condition_articulation_json(c);
        for (const auto& v : set.visemes) visemes_of[v.condition] = viseme_information_json(v);
    }
    manifest["conditions"] = json::array();
    for (const auto& c : protocol.conditions) {
        json j = {{"name", c.name},
                  {"face", to_string(c.face)},
                  {"audio", to_string(c.audio)},
                  {"model", c.model.empty() ? json() : json(c.model.filename().string())},
                  {"policy", policy_json(c)}};
        if (c.has_vocoder) j["vocoder"] = vocoder_json(plan.vocoder_for(c));
        if (c.face == FaceMode::Model) {
            j["policy_text"] = policy_text(plan, c);
            if (plan.closure.count(c.name)) j["closure_constraint"] = closure_json(plan.closure.at(c.name));
            const auto a = articulation_of.find(c.name);
            j["articulation"] = a != articulation_of.end() ? a->second : json();
            const auto v = visemes_of.find(c.name);
            j["viseme_information"] = v != visemes_of.end() ? v->second : json();
        }
        manifest["conditions"].push_back(j);
    }
    // The methods paragraph goes into the manifest (`avsi analyze --stimuli`
    // puts it in the study report) and beside it as methods.md.
    const std::string methods = methods_text(plan, manifest, settings.out_dir);
    manifest["methods"] = methods;
    write_text_file(settings.out_dir / "manifest.json", manifest.dump(2) + "\n");
    write_text_file(settings.out_dir / "methods.md", methods);
}

// A shard's manifest: the entries of its jobs (shards.h).
void write_shard_manifest(const Plan& plan, const BuildSettings& settings) {
    const auto planned = planned_stimuli(plan);
    const std::vector<bool> member = detail::shard_members(planned, settings.shard);
    std::vector<json> entries;
    for (std::size_t i = 0; i < plan.jobs.size(); ++i)
        if (member[i]) entries.push_back(plan.jobs[i].entry);
    detail::write_shard_manifest(settings.out_dir, settings.shard,
                                 detail::plan_identity(settings.protocol_path, planned, builder_version), entries);
}

// `--merge`: every job's entry from the shard manifests, checked
// (build_shards.h), then manifest.json, the QC page and methods.md as a
// one-machine build writes them.
BuildReport merge_shards(Plan& plan, const BuildSettings& settings) {
    const auto planned = planned_stimuli(plan);
    std::vector<json> entries = detail::merge_shard_entries(
        settings.out_dir, detail::plan_identity(settings.protocol_path, planned, builder_version), planned);
    BuildReport report;
    report.total = plan.jobs.size();
    report.skipped = plan.jobs.size();
    report.not_needed = plan.not_needed;
    for (std::size_t i = 0; i < plan.jobs.size(); ++i) plan.jobs[i].entry = std::move(entries[i]);
    write_manifest(plan, settings, {});
    log_info("build-stimuli: merged {} stimuli from the shards into {}", report.total,
             (settings.out_dir / "manifest.json").string());
    return report;
}

}  // namespace

BuildReport build_stimuli(const BuildSettings& settings) {
    const auto start = std::chrono::steady_clock::now();
    Plan plan(settings);
    BuildReport report;
    if (settings.merge) return merge_shards(plan, settings);
    const std::vector<std::size_t> todo = jobs_to_build(plan, settings, report);
    std::map<std::string, SentenceSpeech> speech;
    speak_sentences(plan, settings, todo, speech);
    report.frames_rendered = build_jobs(plan, settings, report, todo, speech);
    if (settings.shard.sharded()) write_shard_manifest(plan, settings);
    else write_manifest(plan, settings, speech);
    report.rendered = todo.size();
    report.elapsed_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    log_info("build-stimuli: built {} stimuli ({} frames) in {:.1f} s, {} unchanged", report.rendered,
             report.frames_rendered, report.elapsed_s, report.skipped);
    return report;
}

ShardPlan plan_shards(const BuildSettings& settings, std::size_t shards) {
    const Plan plan(settings);
    return detail::shard_plan(planned_stimuli(plan), shards);
}

VerifyReport verify_stimuli(const BuildSettings& settings) {
    Plan plan(settings);
    const auto manifest_path = settings.out_dir / "manifest.json";
    if (!std::filesystem::exists(manifest_path))
        throw InputError(manifest_path, "no manifest.json: nothing was built in this folder (run build-stimuli first)");
    bool unreadable = false;
    std::map<std::string, json> entries = manifest_entries(manifest_path, unreadable);
    if (unreadable) throw InputError(manifest_path, "cannot read the manifest: expected JSON with a \"stimuli\" array");

    VerifyReport report;
    report.total = plan.jobs.size();
    std::vector<std::vector<std::string>> found(plan.jobs.size());  // per job, in plan order
    Progress progress("verify-stimuli", plan.jobs.size());
    std::atomic<std::size_t> next{0};
    auto check = [&] {
        while (true) {
            const std::size_t i = next.fetch_add(1);
            if (i >= plan.jobs.size()) break;
            try {
                verify_one(plan.jobs[i], entries, settings.out_dir, found[i]);
            } catch (const std::exception& error) {  // an unreadable file
                found[i].push_back(plan.jobs[i].video.generic_string() + ": cannot be checked: " + error.what());
            }
            progress.advance();
        }
    };
    const int workers = std::max(1, settings.jobs > 0 ? settings.jobs
                                                      : static_cast<int>(std::thread::hardware_concurrency()));
    std::vector<std::thread> threads;
    for (int w = 0; w < workers; ++w) threads.emplace_back(check);
    for (auto& t : threads) t.join();
    progress.finish();

    // The articulation of every model stimulus, measured afresh from its
    // model and phones: each violation is a problem naming the segment.
    if (plan.meter) {
        std::map<std::string, std::size_t> index_of;
        for (std::size_t i = 0; i < plan.jobs.size(); ++i) index_of[plan.jobs[i].video.generic_string()] = i;
        for (const auto& q : measure_set(plan, false))
            for (const auto& p : q.summary.failures(q.closure_required))
                found[index_of.at(q.path)].push_back(q.path + ": articulation: " + p);
    }
    for (std::size_t i = 0; i < plan.jobs.size(); ++i) {
        entries.erase(plan.jobs[i].video.generic_string());
        if (found[i].empty()) ++report.verified;
        for (auto& line : found[i]) report.problems.push_back(std::move(line));
    }
    for (const auto& [path, entry] : entries) report.extra.push_back(path);
    return report;
}

namespace {

// " (did you mean \"x\"?)" for a near miss, else the choices.
std::string suggestion(const std::string& word, const std::vector<std::string>& candidates) {
    const std::string close = closest_match(word, candidates);
    if (!close.empty()) return fmt::format(" (did you mean \"{}\"?)", close);
    std::string list;
    for (const auto& c : candidates) list += (list.empty() ? "" : ", ") + c;
    return " (" + list + ")";
}

}  // namespace

StimulusDefinition stimulus_definition(const std::filesystem::path& protocol_path, const std::string& sentence,
                                       const std::string& condition) {
    BuildSettings settings;
    settings.protocol_path = protocol_path;
    settings.all_sentences = true;
    Plan plan(settings);
    const Job* job = nullptr;
    std::vector<std::string> sentences, conditions;
    for (const auto& s : plan.corpus.sentences) sentences.push_back(s.id);
    for (const auto& c : plan.protocol.conditions) conditions.push_back(c.name);
    if (std::find(sentences.begin(), sentences.end(), sentence) == sentences.end())
        throw InputError(plan.protocol.corpus.sentences.string(), 0, 0, "id",
                         fmt::format("expected a sentence id of the corpus{}, got \"{}\"",
                                     suggestion(sentence, sentences), sentence));
    if (std::find(conditions.begin(), conditions.end(), condition) == conditions.end())
        throw InputError(protocol_path.string(), 0, 0, "condition",
                         fmt::format("expected a condition of the protocol{}, got \"{}\"",
                                     suggestion(condition, conditions), condition));
    for (const auto& j : plan.jobs)
        if (j.sentence->id == sentence && j.condition->name == condition) job = &j;
    AVSI_ASSERT(job);
    const ProtocolCondition& c = *job->condition;
    StimulusDefinition d;
    d.sentence = sentence;
    d.condition = condition;
    d.face = to_string(c.face);
    Audio speech;
    if (plan.protocol.corpus.audio == CorpusAudio::Tts) {
        try {
            auto r = synthesize_speech(job->sentence->text, tts_settings(plan.protocol));
            speech = std::move(r.audio);
            d.phones = std::move(r.phones);
        } catch (const InputError& e) {
            throw at_tts_key(plan.protocol, e);
        }
    } else {
        speech = read_audio(job->sentence->audio);
        d.phones = read_phones(job->sentence->labels);
    }
    if (c.audio == ConditionAudio::Vocoded) {
        vocoder::VocoderSettings v = plan.vocoder_for(c);
        v.seed = job->vocoder_seed;
        d.audio = vocoder::vocode(speech, v).audio;
    } else {
        d.audio = std::move(speech);
    }
    set_speech_level(d.audio, plan.protocol.corpus.level_dbfs);
    if (c.face == FaceMode::Model) {
        d.trajectory = plan.trajectory(c, d.phones);
    } else {
        d.trajectory.fps = plan.fps;
        d.trajectory.frames.assign(synth::frame_count(d.audio.duration_s(), plan.fps), synth::Frame{});
    }
    d.blinks.seed = job->blink_seed;
    d.blinks.enabled = c.face == FaceMode::Model;
    if (c.face == FaceMode::Model) d.layers = plan.layers.at(c.name);
    d.layer_seeds.blink = job->blink_seed;
    d.layer_seeds.gaze = job->gaze_seed;
    d.layer_seeds.head = job->head_seed;
    const auto& pr = plan.protocol.render;
    d.head_gltf = pr.head_gltf;
    d.head_mapping = pr.head_mapping;
    d.head_mesh = pr.head_mesh;
    d.head_rig = pr.head_rig;
    return d;
}

}  // namespace avsi::stimuli
