// Protocol loading and validation (see protocol.h and protocols/README.md).
#include "avsi/core/protocol.h"

#include <algorithm>
#include <limits>
#include <map>
#include <set>

#include <fmt/format.h>

#include "avsi/core/files.h"
#include "avsi/core/phones.h"
#include "avsi/core/ui_strings.h"

namespace avsi {

namespace {

namespace fs = std::filesystem;

constexpr long long max_seed = std::numeric_limits<long long>::max();

fs::path resolve(const fs::path& protocol_path, const std::string& relative) {
    const fs::path p(relative);
    if (p.is_absolute()) return p;
    return (protocol_path.parent_path() / p).lexically_normal();
}

// An empty section standing in for an absent table, located at the file start.
ConfigSection absent_section(const std::string& path, const std::string& name) {
    return ConfigSection(path, name, 1, 1);
}

const ConfigSection& section_or_empty(const ConfigSection& root, const std::string& key,
                                      ConfigSection& storage, DiagnosticList& problems) {
    if (const ConfigSection* s = root.get_table(key, problems)) return *s;
    storage = absent_section(root.path(), key);
    return storage;
}

// [corpus] tts = "<engine>:<voice>", or the older voice = "<espeak-ng voice>".
void read_tts(const ConfigSection& corpus, CorpusSettings& out, DiagnosticList& problems) {
    const std::string tts = corpus.get_string("tts", "", problems);
    const std::string voice = corpus.get_string("voice", "", problems);
    const ConfigValue* tts_value = corpus.find("tts");
    const ConfigValue* voice_value = corpus.find("voice");
    const bool has_tts = tts_value && tts_value->type == ConfigValue::Type::String;
    const bool has_voice = voice_value && voice_value->type == ConfigValue::Type::String;
    if (has_tts && has_voice) {
        corpus.report("voice",
                      fmt::format("expected either tts or voice, got both (voice = \"{}\" is the older spelling of "
                                  "tts = \"espeak:{}\"); remove voice",
                                  voice, voice),
                      problems);
        return;
    }
    TtsSettings settings;
    if (has_tts) {
        try {
            set_tts_voice(settings, tts);
        } catch (const InputError& e) {
            corpus.report("tts", e.first().message, problems);
            return;
        }
        out.tts_line = tts_value->line;
        out.tts_column = tts_value->column;
    } else if (has_voice) {
        if (voice.empty() || voice.find(':') != std::string::npos) {
            corpus.report("voice",
                          fmt::format("expected an espeak-ng voice name (en-us, en, ...), got \"{}\"{}", voice,
                                      voice.find(':') != std::string::npos
                                          ? fmt::format(" (did you mean tts = \"{}\"?)", voice)
                                          : ""),
                          problems);
            return;
        }
        settings.engine = TtsEngine::Espeak;
        settings.voice = voice;
        out.tts_line = voice_value->line;
        out.tts_column = voice_value->column;
    } else {
        return;  // the default voice
    }
    out.tts_engine = settings.engine;
    out.tts_voice = settings.voice;
}

// [corpus] language: the language of the sentences, the phone table, the
// scoring and what the subject reads (session.language is this one); by
// default the voice's (tts = "espeak:sv" -> "sv"). A language other than the
// voice's, or an espeak-ng voice of a language without tables, is an error
// (recordings with no voice named take the key's language).
void read_language(const ConfigSection& corpus, CorpusSettings& out, DiagnosticList& problems) {
    TtsSettings settings;
    settings.engine = out.tts_engine;
    settings.voice = out.tts_voice;
    const std::string voice_language = tts_voice_language(settings);
    out.language = voice_language.empty() ? "en" : voice_language;
    const char* voice_key = corpus.find("tts") ? "tts" : corpus.find("voice") ? "voice" : nullptr;
    if (voice_language.empty() && voice_key) {
        std::string tables;
        for (const auto& code : PhoneInventory::builtin().languages()) tables += (tables.empty() ? "" : ", ") + code;
        corpus.report(voice_key,
                      fmt::format("voice \"{}\" speaks no language with tables in protocols/languages/ ({}): no "
                                  "phones, scoring or texts of what the subject reads for it",
                                  out.tts_voice, tables),
                      problems);
        return;
    }
    if (!corpus.find("language")) return;
    const std::string language =
        corpus.get_choice("language", PhoneInventory::builtin().languages(), out.language, problems);
    // Recordings without a voice named: the default voice speaks none of
    // the stimuli, so the key alone says the language.
    const bool voice_speaks = voice_key || out.audio == CorpusAudio::Tts;
    if (!voice_language.empty() && language != voice_language && voice_speaks) {
        corpus.report("language",
                      voice_key ? fmt::format("expected the voice's language \"{}\" (tts = \"{}\"), got \"{}\"",
                                              voice_language, tts_voice_spec(settings), language)
                                : fmt::format("expected the default voice's language \"{}\" ({}), got \"{}\": the "
                                              "sentences are synthesised, so name a voice of it in tts (tts = "
                                              "\"espeak:{}\")",
                                              voice_language, tts_voice_spec(settings), language, language),
                      problems);
        return;
    }
    out.language = language;
}

// A model condition's post-processing policy, as a reader of the methods
// section would name it.
std::string policy_text(const ProtocolCondition& c) {
    return c.closure_hold ? fmt::format("closure = \"hold\" with closure_transition_s = {:g}", c.closure_transition_s)
                          : std::string("closure = \"off\"");
}

std::string joined(const std::vector<std::string>& names) {
    std::string out;
    for (std::size_t i = 0; i < names.size(); ++i)
        out += (i == 0 ? "" : i + 1 == names.size() ? " and " : ", ") + names[i];
    return out;
}

bool same_file(const fs::path& a, const fs::path& b) {
    std::error_code ea, eb;
    const fs::path ca = fs::weakly_canonical(a, ea), cb = fs::weakly_canonical(b, eb);
    return (ea || eb) ? a.lexically_normal() == b.lexically_normal() : ca == cb;
}

// The fair-comparison rule (DESIGN.md, "Validity checks"): the model
// conditions share one post-processing policy, except declared variants
// (variant_of), which must be the same model as their base under another
// policy, so that the policy is a factor of the design.
void check_condition_policies(const Protocol& p, const std::vector<const ConfigSection*>& sections,
                              DiagnosticList& problems) {
    std::map<std::string, std::vector<std::string>> by_policy;  // policy → base model conditions
    const ConfigSection* first_section = nullptr;  // the first held base condition's
    std::string first_name;
    for (std::size_t i = 0; i < p.conditions.size() && i < sections.size(); ++i) {
        const ProtocolCondition& c = p.conditions[i];
        const ConfigSection& section = *sections[i];
        if (c.variant_of.empty()) {
            if (c.face != FaceMode::Model) continue;
            by_policy[policy_text(c)].push_back(c.name);
            if (c.closure_hold && !first_section) {
                first_section = &section;
                first_name = c.name;
            }
            continue;
        }
        if (c.face != FaceMode::Model) {
            section.report("variant_of", "only a model condition can be a policy variant (it needs face = \"model\")",
                           problems);
            continue;
        }
        const int base_index = p.condition_index(c.variant_of);
        if (base_index < 0) {
            std::string message = fmt::format("expected the name of a [[condition]], got \"{}\"", c.variant_of);
            const std::string hint = closest_match(c.variant_of, p.condition_names());
            if (!hint.empty()) message += " (did you mean \"" + hint + "\"?)";
            section.report("variant_of", message, problems);
            continue;
        }
        const ProtocolCondition& base = p.conditions[static_cast<std::size_t>(base_index)];
        if (&base == &c)
            section.report("variant_of", "a condition cannot be a variant of itself", problems);
        else if (!base.variant_of.empty())
            section.report("variant_of",
                           fmt::format("\"{}\" is itself a variant: name the condition that shows the model as "
                                       "trained{}",
                                       base.name,
                                       p.condition_index(base.variant_of) >= 0
                                           ? fmt::format(" (variant_of = \"{}\")", base.variant_of)
                                           : std::string()),
                           problems);
        else if (base.face != FaceMode::Model || base.model.empty() || c.model.empty() ||
                 !same_file(base.model, c.model))
            section.report("variant_of",
                           fmt::format("a policy variant shows the same model as its base under another policy, but "
                                       "\"{}\" {}", base.name,
                                       base.face != FaceMode::Model ? std::string("has no model")
                                                                    : "uses " + base.model.filename().string() +
                                                                          ", this condition " +
                                                                          c.model.filename().string()),
                           problems);
        else if (policy_text(base) == policy_text(c))
            section.report("variant_of",
                           fmt::format("the same model under the same policy as \"{}\" ({}): a variant differs "
                                       "from its base in its post-processing",
                                       base.name, policy_text(c)),
                           problems);
    }
    if (by_policy.size() < 2) return;
    std::string parts;
    for (const auto& [policy, names] : by_policy)
        parts += fmt::format("{}{} on {}", parts.empty() ? "" : "; ", policy, joined(names));
    const ConfigSection& at = first_section ? *first_section : *sections.front();
    const std::string example = first_section ? first_name : p.conditions.front().name;
    at.report(first_section ? "closure" : "name",
              fmt::format("the model conditions are post-processed differently ({}): a policy must apply to every "
                          "model condition alike, or be a declared factor of the design. Show each model as "
                          "trained and add the held one as its own condition (name = \"{}+hold\", the same "
                          "model, closure = \"hold\", variant_of = \"{}\")",
                          parts, example, example),
              problems);
}

}  // namespace

std::string to_string(FaceMode face) {
    switch (face) {
        case FaceMode::Model: return "model";
        case FaceMode::Still: return "still";
        case FaceMode::None: return "none";
    }
    return "?";
}

std::string to_string(ConditionAudio audio) {
    return audio == ConditionAudio::Vocoded ? "vocoded" : "clean";
}

std::string to_string(Counterbalance counterbalance) {
    return counterbalance == Counterbalance::LatinSquare ? "latin-square" : "williams";
}

const std::vector<std::string>& protocol_rule_sets() {
    static const std::vector<std::string> names = {"strict", "loose", "lenient"};
    return names;
}

int Protocol::condition_index(const std::string& condition) const {
    for (std::size_t i = 0; i < conditions.size(); ++i)
        if (conditions[i].name == condition) return static_cast<int>(i);
    return -1;
}

std::vector<std::string> Protocol::condition_names() const {
    std::vector<std::string> names;
    for (const auto& c : conditions) names.push_back(c.name);
    return names;
}

namespace {

// [experiment]: the name and the seed.
void read_experiment_section(const ConfigSection& root, Protocol& p, DiagnosticList& problems) {
    ConfigSection experiment_storage;
    const ConfigSection& experiment = section_or_empty(root, "experiment", experiment_storage, problems);
    if (experiment.present()) {
        experiment.require("name", problems);
        p.name = experiment.get_string("name", "", problems);
        p.seed = static_cast<std::uint64_t>(experiment.get_int("seed", 1, 0, max_seed, problems));
        experiment.check_unknown_keys(problems);
    } else {
        problems.add(p.path.string(), 0, 0, "experiment", "missing required table [experiment]");
    }
}

// [corpus]: the sentences, their audio (TTS or recordings) and the speech level.
void read_corpus_section(const ConfigSection& root, Protocol& p, DiagnosticList& problems) {
    const fs::path& path = p.path;
    ConfigSection corpus_storage;
    const ConfigSection& corpus = section_or_empty(root, "corpus", corpus_storage, problems);
    if (corpus.present()) {
        if (corpus.require("sentences", problems)) {
            const std::string sentences = corpus.get_string("sentences", "", problems);
            if (!sentences.empty()) {
                p.corpus.sentences = resolve(path, sentences);
                if (!fs::is_regular_file(p.corpus.sentences))
                    corpus.report("sentences",
                                  fmt::format("expected an existing corpus file, got \"{}\" (resolved "
                                              "to {}, which does not exist)",
                                              sentences, p.corpus.sentences.string()),
                                  problems);
            }
        }
        p.corpus.audio = corpus.get_choice("audio", {"tts", "recordings"}, "tts", problems) == "recordings"
                             ? CorpusAudio::Recordings
                             : CorpusAudio::Tts;
        read_tts(corpus, p.corpus, problems);
        read_language(corpus, p.corpus, problems);
        p.corpus.level_dbfs = corpus.get_number("level_dbfs", p.corpus.level_dbfs, -60.0, -6.0, problems);
        if (const ConfigValue* level = corpus.find("level_dbfs")) {
            p.corpus.level_line = level->line;
            p.corpus.level_column = level->column;
        }
        corpus.check_unknown_keys(problems);
    } else {
        problems.add(p.path.string(), 0, 0, "corpus", "missing required table [corpus]");
    }
}

// One [[condition]]; `names` collects the names so far, to refuse a duplicate.
ProtocolCondition read_condition(const ConfigSection& c, const fs::path& path, std::set<std::string>& names,
                                 DiagnosticList& problems) {
    ProtocolCondition cond;
    cond.line = c.line();
    if (c.require("name", problems)) {
        cond.name = c.get_string("name", "", problems);
        if (c.find("name")->type == ConfigValue::Type::String) {
            if (cond.name.empty() ||
                cond.name.find_first_of("/\\ ,\"") != std::string::npos || cond.name == "." ||
                cond.name == "..")
                c.report("name",
                         fmt::format("expected a non-empty name without spaces, commas, quotes "
                                     "or slashes (it names files), got \"{}\"",
                                     cond.name),
                         problems);
            else if (!names.insert(cond.name).second)
                c.report("name", fmt::format("duplicate condition name \"{}\"", cond.name),
                         problems);
        }
    }
    const std::string model = c.get_string("model", "", problems);
    if (!model.empty()) cond.model = resolve(path, model);
    const std::string face =
        c.get_choice("face", {"model", "still", "none"}, model.empty() ? "still" : "model", problems);
    cond.face = face == "model" ? FaceMode::Model : face == "still" ? FaceMode::Still : FaceMode::None;
    if (cond.face == FaceMode::Model && model.empty() && c.has("face"))
        c.report("face", "face = \"model\" needs a control model: add model = \"<file>\"", problems);
    if (cond.face != FaceMode::Model && !model.empty() && c.has("face"))
        c.report("model",
                 fmt::format("a model is only used with face = \"model\", but face = \"{}\"", face),
                 problems);
    cond.audio = c.get_choice("audio", {"vocoded", "clean"}, "vocoded", problems) == "clean"
                     ? ConditionAudio::Clean
                     : ConditionAudio::Vocoded;
    cond.closure_hold = c.get_choice("closure", {"off", "hold"}, "off", problems) == "hold";
    cond.closure_transition_s = c.get_number("closure_transition_s", 0.025, 0.001, 0.2, problems);
    if (c.has("closure") && cond.face != FaceMode::Model)
        c.report("closure", "the closure mechanism acts on a control model: it needs face = \"model\"", problems);
    if (c.has("closure_transition_s") && !cond.closure_hold)
        c.report("closure_transition_s", "only used with closure = \"hold\"", problems);
    cond.variant_of = c.get_string("variant_of", "", problems);
    if (const ConfigSection* layers = c.get_table("layers", problems)) {
        cond.layers = *layers;
        if (cond.face != FaceMode::Model)
            c.report("layers", "animation layers animate a control model's face: they need face = \"model\"",
                     problems);
    }
    if (const ConfigSection* vocoder = c.get_table("vocoder", problems)) {
        cond.vocoder = *vocoder;
        cond.has_vocoder = true;
        if (cond.audio != ConditionAudio::Vocoded)
            c.report("vocoder", "a condition's vocoder settings need audio = \"vocoded\"", problems);
    }
    c.check_unknown_keys(problems);
    return cond;
}

// [design]: lists, sentences per list, warm-up and practice, counterbalancing.
void read_design_section(const ConfigSection& root, Protocol& p, DiagnosticList& problems) {
    const std::vector<std::string> condition_names = p.condition_names();
    ConfigSection design_storage;
    const ConfigSection& design = section_or_empty(root, "design", design_storage, problems);
    const int k = static_cast<int>(p.conditions.size());
    p.design.lists = static_cast<int>(design.get_int("lists", k > 0 ? k : 6, 1, 1000, problems));
    if (design.has("lists") && k > 0 && p.design.lists != k && design.find("lists")->type == ConfigValue::Type::Integer)
        design.report("lists",
                      fmt::format("expected the number of conditions ({}) so that each list is paired "
                                  "with one condition, got {}",
                                  k, p.design.lists),
                      problems);
    p.design.sentences_per_list =
        static_cast<int>(design.get_int("sentences_per_list", 15, 1, 100000, problems));
    p.design.warmup = static_cast<int>(design.get_int("warmup", 0, 0, 100000, problems));
    p.design.practice = static_cast<int>(design.get_int("practice", 0, 0, 100000, problems));
    auto condition_ref = [&](const char* key, std::string& out) {
        out = design.get_string(key, "", problems);
        if (out.empty() || condition_names.empty()) return;
        if (p.condition_index(out) < 0) {
            std::string message = fmt::format("expected the name of a [[condition]], got \"{}\"", out);
            const std::string hint = closest_match(out, condition_names);
            if (!hint.empty()) message += " (did you mean \"" + hint + "\"?)";
            design.report(key, message, problems);
        }
    };
    condition_ref("warmup_condition", p.design.warmup_condition);
    condition_ref("practice_condition", p.design.practice_condition);
    p.design.counterbalance =
        design.get_choice("counterbalance", {"latin-square", "williams"}, "latin-square", problems) ==
                "williams"
            ? Counterbalance::Williams
            : Counterbalance::LatinSquare;
    p.design.seed = static_cast<std::uint64_t>(
        design.get_int("seed", static_cast<long long>(p.seed), 0, max_seed, problems));
    design.check_unknown_keys(problems);
}

// [render]: frame rate, size, camera, background and the head's files.
void read_render_section(const ConfigSection& root, Protocol& p, DiagnosticList& problems) {
    const fs::path& path = p.path;
    ConfigSection render_storage;
    const ConfigSection& render = section_or_empty(root, "render", render_storage, problems);
    p.render.fps = static_cast<int>(render.get_int("fps", p.render.fps, 1, 240, problems));
    p.render.width = static_cast<int>(render.get_int("width", p.render.width, 16, 7680, problems));
    p.render.height = static_cast<int>(render.get_int("height", p.render.height, 16, 4320, problems));
    p.render.camera = render.get_string("camera", p.render.camera, problems);
    p.render.background = render.get_string("background", p.render.background, problems);
    // head_mesh and head_rig: a lab's own head, given together (the rig names mesh vertices).
    for (const auto& [key, target] : {std::pair<const char*, fs::path*>{"head_mesh", &p.render.head_mesh},
                                      std::pair<const char*, fs::path*>{"head_rig", &p.render.head_rig},
                                      std::pair<const char*, fs::path*>{"head_gltf", &p.render.head_gltf},
                                      std::pair<const char*, fs::path*>{"head_mapping", &p.render.head_mapping}}) {
        const std::string file = render.get_string(key, "", problems);
        if (file.empty()) continue;
        *target = resolve(path, file);
        if (!fs::is_regular_file(*target))
            render.report(key,
                          fmt::format("expected an existing file, got \"{}\" (resolved to {}, which does not exist)",
                                      file, target->string()),
                          problems);
    }
    if (render.has("head_mesh") != render.has("head_rig"))
        render.report(render.has("head_mesh") ? "head_mesh" : "head_rig",
                      "expected head_mesh and head_rig together (a rig belongs to its mesh), got only one",
                      problems);
    if (render.has("head_gltf") && render.has("head_mesh"))
        render.report("head_gltf", "expected either head_gltf or head_mesh + head_rig, got both", problems);
    if (render.has("head_mapping") && !render.has("head_gltf"))
        render.report("head_mapping", "expected head_gltf with it (the mapping drives a glTF head's blendshapes)", problems);
    p.render.check_articulation = render.get_bool("check_articulation", true, problems);
    render.check_unknown_keys(problems);
    p.render_section = render;
}

// [session]: the runner's screen, response mode, timing and texts.
// The session texts' defaults in the protocol's language ([corpus] language,
// by default the voice's: read_language; ui_strings.h).
void read_language_strings(Protocol& p, DiagnosticList& problems) {
    SessionSettings& s = p.session;
    s.language = p.corpus.language;
    // After an error elsewhere (a malformed tts among them) the voice may be
    // no voice at all: that error is the one to fix first.
    if (!problems.empty()) return;
    if (!fs::is_regular_file(ui_strings_file(s.language))) {
        problems.add(p.path.string(), p.corpus.tts_line, p.corpus.tts_column, "corpus.tts",
                     fmt::format("no table of what the subject reads in language '{}' (expected {})", s.language,
                                 ui_strings_file(s.language).string()));
        return;
    }
    try {
        const UiStrings& t = ui_strings(s.language);
        s.instructions = t.text("session", "instructions");
        s.practice_instructions = t.text("session", "practice_instructions");
        s.test_instructions = t.text("session", "test_instructions");
        s.break_text = t.text("session", "break_text");
        s.end_text = t.text("session", "end_text");
    } catch (const InputError& e) {
        for (const auto& d : e.diagnostics()) problems.add(d);
    }
}

void read_session_section(const ConfigSection& root, Protocol& p, DiagnosticList& problems) {
    ConfigSection session_storage;
    const ConfigSection& session = section_or_empty(root, "session", session_storage, problems);
    SessionSettings& s = p.session;
    read_language_strings(p, problems);
    s.fullscreen = session.get_bool("fullscreen", s.fullscreen, problems);
    s.monitor = static_cast<int>(session.get_int("monitor", s.monitor, 0, 16, problems));
    s.response_mode = session.get_choice("response_mode", {"subject", "experimenter"}, "subject",
                                         problems) == "experimenter"
                          ? ResponseMode::Experimenter
                          : ResponseMode::Subject;
    s.break_every = static_cast<int>(session.get_int("break_every", s.break_every, 0, 100000, problems));
    s.fixation_ms = session.get_number("fixation_ms", s.fixation_ms, 0.0, 10000.0, problems);
    s.response_delay_ms =
        session.get_number("response_delay_ms", s.response_delay_ms, 0.0, 10000.0, problems);
    s.show_progress = session.get_bool("show_progress", s.show_progress, problems);
    s.instructions = session.get_string("instructions", s.instructions, problems);
    s.practice_instructions = session.get_string("practice_instructions", s.practice_instructions, problems);
    s.test_instructions = session.get_string("test_instructions", s.test_instructions, problems);
    s.break_text = session.get_string("break_text", s.break_text, problems);
    s.end_text = session.get_string("end_text", s.end_text, problems);
    session.check_unknown_keys(problems);
    p.session_section = session;
}

// [scoring]: the rule set, the homophone table and split compounds.
void read_scoring_section(const ConfigSection& root, Protocol& p, DiagnosticList& problems) {
    const fs::path& path = p.path;
    ConfigSection scoring_storage;
    const ConfigSection& scoring = section_or_empty(root, "scoring", scoring_storage, problems);
    p.scoring.rules = scoring.get_choice("rules", protocol_rule_sets(), p.scoring.rules, problems);
    std::vector<std::string> compound_choices = protocol_rule_sets();
    compound_choices.push_back("never");
    p.scoring.split_compounds = scoring.get_choice("split_compounds", compound_choices, p.scoring.split_compounds, problems);
    if (const std::string table = scoring.get_string("homophones", "", problems); !table.empty()) {
        p.scoring.homophones = resolve(path, table);
        if (!fs::is_regular_file(p.scoring.homophones))
            scoring.report("homophones",
                           fmt::format("expected an existing homophone table, got \"{}\" (resolved to {}, which "
                                       "does not exist)",
                                       table, p.scoring.homophones.string()),
                           problems);
    }
    scoring.check_unknown_keys(problems);
}

}  // namespace

Protocol parse_protocol(std::string_view text, const fs::path& path) {
    const ConfigSection root = parse_config(text, path.string());
    const std::string file = path.string();
    DiagnosticList problems;
    Protocol p;
    p.path = path;
    read_experiment_section(root, p, problems);
    read_corpus_section(root, p, problems);
    // [[condition]]
    const auto conditions = root.get_table_array("condition", problems);
    if (conditions.empty() && !root.has("condition"))
        problems.add(file, 0, 0, "condition", "missing required tables [[condition]] (at least one)");
    std::set<std::string> names;
    for (const ConfigSection* c : conditions) p.conditions.push_back(read_condition(*c, path, names, problems));
    check_condition_policies(p, conditions, problems);
    // [vocoder] — validated by the vocoder module.
    if (const ConfigSection* v = root.get_table("vocoder", problems))
        p.vocoder = *v;
    else
        p.vocoder = absent_section(file, "vocoder");
    read_design_section(root, p, problems);
    read_render_section(root, p, problems);
    read_session_section(root, p, problems);
    read_scoring_section(root, p, problems);
    // [online] — validated by the experiment module (avsi export-web / import-web).
    if (const ConfigSection* o = root.get_table("online", problems))
        p.online = *o;
    else
        p.online = absent_section(file, "online");

    // [adaptive] — adaptive SRT tracks, validated by adaptive_protocol() (adaptive_protocol.h).
    if (const ConfigSection* a = root.get_table("adaptive", problems))
        p.adaptive = *a;
    else
        p.adaptive = absent_section(file, "adaptive");

    // Top-level keys.
    root.check_unknown_keys(
        {"experiment", "corpus", "condition", "vocoder", "design", "render", "session", "scoring", "online",
         "adaptive"},
        problems);

    // Report in reading order (line, then column); file-level problems first.
    try {
        problems.throw_if_any();
    } catch (const InputError& e) {
        std::vector<Diagnostic> sorted = e.diagnostics();
        std::stable_sort(sorted.begin(), sorted.end(), [](const Diagnostic& a, const Diagnostic& b) {
            return a.line != b.line ? a.line < b.line : a.column < b.column;
        });
        throw InputError(std::move(sorted));
    }
    return p;
}

Protocol load_protocol(const fs::path& path) {
    return parse_protocol(read_text_file(path), path);
}

}  // namespace avsi
