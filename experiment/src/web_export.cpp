// `avsi export-web`: the protocol's lists and stimuli as a jsPsych 8 study
// folder and a JATOS study archive (see web_study.h). The browser side
// (web/src: index.html, avsi-study.js, avsi-study.css) and the vendored
// jsPsych files (web/node_modules, installed by scripts/install-deps from
// web/package-lock.json) are copied as they are; study.json carries
// everything that depends on the protocol.
//
// JATOS study archive (JATOS docs, "JATOS Study Archive (JZIP)"): a ZIP with
// one study-properties file `<dirName>.jas` ({"version": "3", "data": {uuid,
// title, dirName, componentList, batchList, …}}) and one folder, the study
// assets, at its root.
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <map>
#include <set>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "avsi/core/audio.h"
#include "avsi/core/corpus.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "avsi/core/log.h"
#include "avsi/core/rng.h"
#include "avsi/core/ui_strings.h"
#include "avsi/experiment/design.h"
#include "avsi/experiment/runner.h"
#include "avsi/experiment/web_study.h"
#include "avsi/stimuli/video.h"
#include "zip_archive.h"

#ifndef AVSI_WEB_DIR
#error "AVSI_WEB_DIR (the source tree's web/ folder) must be defined by the build"
#endif

namespace avsi::experiment {

namespace fs = std::filesystem;
using nlohmann::ordered_json;

namespace {

// The files the study takes from web/: runtime sources and vendored jsPsych.
struct WebFile {
    const char* from;  // relative to web/
    const char* to;    // relative to the study folder
};
constexpr WebFile runtime_files[] = {
    {"src/index.html", "index.html"},
    {"src/avsi-study.js", "avsi-study.js"},
    {"src/avsi-study.css", "avsi-study.css"},
};
// package folder (under node_modules), file in it, name in the study's lib/
struct VendoredFile {
    const char* package;
    const char* file;
    const char* to;
};
constexpr VendoredFile vendored_files[] = {
    {"jspsych", "dist/index.browser.min.js", "lib/jspsych.js"},
    {"jspsych", "css/jspsych.css", "lib/jspsych.css"},
    {"@jspsych/plugin-preload", "dist/index.browser.min.js", "lib/plugin-preload.js"},
    {"@jspsych/plugin-html-button-response", "dist/index.browser.min.js", "lib/plugin-html-button-response.js"},
};

// A UUID-formatted name from a SHA-256 (stable across exports of one study,
// so JATOS recognises a re-import as an update of the same study).
std::string uuid_from(const std::string& name) {
    std::string h = sha256_hex(name).substr(0, 32);
    h[12] = '5';  // version nibble (name-based)
    const char variant[] = "89ab";
    h[16] = variant[std::stoi(h.substr(16, 1), nullptr, 16) % 4];
    return h.substr(0, 8) + "-" + h.substr(8, 4) + "-" + h.substr(12, 4) + "-" + h.substr(16, 4) + "-" + h.substr(20, 12);
}

// A JATOS study folder name: letters, digits, '-' and '_'.
std::string dir_name_for(const std::string& experiment) {
    std::string out;
    for (char c : experiment) out += (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_') ? c : '_';
    return out.empty() ? "avsi_study" : out;
}

// Checks that every subject's trials in lists.csv are the protocol's design
// for that subject (the same computation as `avsi design`), reporting at the
// file's lines.
std::map<int, std::vector<PlannedTrial>> check_lists(const Protocol& protocol, const Corpus& corpus,
                                                     const fs::path& lists_path) {
    const std::vector<PlannedTrial> rows = read_lists_csv(lists_path);
    const CsvTable table = read_csv(lists_path);
    std::map<int, std::vector<PlannedTrial>> subjects;
    std::map<int, int> first_line;
    for (std::size_t i = 0; i < rows.size(); ++i) {
        subjects[rows[i].subject].push_back(rows[i]);
        first_line.emplace(rows[i].subject, i < table.rows.size() ? table.rows[i].line : 0);
    }
    if (subjects.empty()) throw InputError(lists_path, "no trials: the lists file has no rows");
    const ListAssignment assignment = assign_lists(corpus, protocol.design);
    DiagnosticList problems;
    std::size_t row_index = 0;
    for (auto& [subject, trials] : subjects) {
        if (subject < 1) {
            problems.add(lists_path.string(), first_line[subject], 0, "subject",
                         fmt::format("expected a subject number ≥ 1, got {}", subject));
            continue;
        }
        const std::vector<PlannedTrial> designed = design_subject(protocol, assignment, subject);
        if (trials == designed) continue;
        std::string detail;
        for (std::size_t i = 0; i < std::max(trials.size(), designed.size()); ++i) {
            if (i >= trials.size()) {
                detail = fmt::format("the design has {} trials, the file {}", designed.size(), trials.size());
                break;
            }
            if (i >= designed.size() || !(trials[i] == designed[i])) {
                detail = i >= designed.size()
                             ? fmt::format("the design has {} trials, the file {}", designed.size(), trials.size())
                             : fmt::format("trial {} is {} {} {} in the file, the design has {} {} {}", i + 1,
                                           to_string(trials[i].phase), trials[i].condition, trials[i].sentence,
                                           to_string(designed[i].phase), designed[i].condition, designed[i].sentence);
                break;
            }
        }
        problems.add(lists_path.string(), first_line[subject], 0, "subject",
                     fmt::format("subject {}'s trials are not the design of {} ({}); make the lists again with "
                                 "`avsi design` for this protocol",
                                 subject, protocol.path.string(), detail));
        (void)row_index;
    }
    problems.throw_if_any();
    return subjects;
}

void copy_into(const fs::path& from, const fs::path& to) {
    fs::create_directories(to.parent_path());
    fs::copy_file(from, to, fs::copy_options::overwrite_existing);
}

// The study folder is written as `<out>.partial` and renamed into place.
class StagingFolder {
public:
    explicit StagingFolder(fs::path target) : m_target(std::move(target)) {
        m_path = m_target;
        m_path += ".partial";
        fs::remove_all(m_path);
        fs::create_directories(m_path);
    }
    ~StagingFolder() {
        if (!m_committed) {
            std::error_code ignored;
            fs::remove_all(m_path, ignored);
        }
    }
    const fs::path& path() const { return m_path; }
    void commit() {
        if (fs::exists(m_target)) fs::remove_all(m_target);
        fs::rename(m_path, m_target);
        m_committed = true;
    }

private:
    fs::path m_target;
    fs::path m_path;
    bool m_committed = false;
};

// Up to `n` items spread evenly over `items`.
std::vector<std::string> spread(const std::vector<std::string>& items, std::size_t n) {
    if (items.size() <= n) return items;
    std::vector<std::string> out;
    for (std::size_t i = 0; i < n; ++i) out.push_back(items[i * items.size() / n]);
    return out;
}

}  // namespace

namespace {

// The web runtime (avsi's web/ folder) and the vendored jsPsych are all there.
void check_web_runtime(const fs::path& web) {
    DiagnosticList missing;
    for (const auto& f : runtime_files)
        if (!fs::is_regular_file(web / f.from))
            missing.add((web / f.from).string(), 0, 0, "", "missing: the study runtime is part of avsi's web/ folder");
    for (const auto& f : vendored_files)
        if (!fs::is_regular_file(web / "node_modules" / f.package / f.file))
            missing.add((web / "node_modules" / f.package / f.file).string(), 0, 0, "",
                        "missing: jsPsych is not installed; run scripts/install-deps (it runs `npm ci` in web/)");
    missing.throw_if_any();
}

// The stimuli the exported subjects use, sorted.
std::vector<std::string> used_stimuli(const std::map<int, std::vector<PlannedTrial>>& subjects) {
    std::vector<std::string> used;
    std::set<std::string> seen;
    for (const auto& [subject, trials] : subjects)
        for (const auto& t : trials)
            if (seen.insert(t.stimulus).second) used.push_back(t.stimulus);
    std::sort(used.begin(), used.end());
    return used;
}

// The study folder to write: new, or a study an earlier `avsi export-web` wrote.
fs::path study_out_dir(const ExportWebSettings& settings) {
    if (settings.out_dir.empty()) throw UsageError("--out: give the study folder to write");
    const fs::path out = settings.out_dir.lexically_normal();
    if (fs::exists(out) && !fs::is_regular_file(out / "study.json"))
        throw InputError(out, "exists and is not a study written by `avsi export-web` (no study.json); choose "
                              "another --out or remove it");
    if (fs::exists(out)) {
        nlohmann::json previous;
        try {
            previous = read_json_file(out / "study.json");
        } catch (const InputError&) {
        }
        if (!previous.is_object() || json_string(previous, "format") != "avsi-web-study")
            throw InputError(out / "study.json", "not an avsi study export; choose another --out or remove the folder");
    }
    return out;
}

// Copies the runtime and the vendored files, with each package's version
// and licence recorded in lib/VENDORED.txt (the npm packages ship no
// separate licence file); returns the packages' versions.
ordered_json copy_runtime(const fs::path& web, const fs::path& dir, ExportWebResult& result) {
    for (const auto& f : runtime_files) copy_into(web / f.from, dir / f.to);
    ordered_json vendored = ordered_json::object();
    std::string vendored_txt = "Files in this folder come from the npm registry (installed by avsi's scripts/install-deps):\n\n";
    for (const auto& f : vendored_files) {
        copy_into(web / "node_modules" / f.package / f.file, dir / f.to);
        result.vendored.push_back(f.to);
        const fs::path package_json = web / "node_modules" / f.package / "package.json";
        const nlohmann::json package = read_json_file(package_json);
        vendored[f.package] = json_string(package, "version");
        vendored_txt += fmt::format("{}  <-  {}@{} ({}), licence {}, {}\n", f.to, f.package, json_string(package, "version", "?"),
                                    f.file, json_string(package, "license", "?"), json_string(package, "homepage"));
    }
    write_text_file(dir / "lib" / "VENDORED.txt", vendored_txt);
    return vendored;
}

// A stimulus browsers cannot play as it is, transcoded with the builder's
// decoder and encoder (H.264 Constrained Baseline + AAC).
void transcode_stimulus(const std::string& stimulus, const MediaProbe& probe, const fs::path& source,
                        const fs::path& target) {
    log_info("export-web: {} is {}; transcoding to H.264 Constrained Baseline + AAC", stimulus,
             probe.describe());
    const stimuli::DecodedVideo video = stimuli::decode_video(source, true);
    if (video.width % 2 || video.height % 2)
        throw InputError(source, fmt::format("the video is {}x{}; browsers' H.264 needs even sizes",
                                             video.width, video.height));
    stimuli::VideoSettings vs;
    vs.fps = video.fps;
    fs::create_directories(target.parent_path());
    stimuli::VideoWriter writer(target, video.width, video.height, video.frames.size(),
                                video.has_audio ? &video.audio : nullptr, vs);
    for (const auto& frame : video.frames) writer.write(frame);
    writer.finish();
}

// Stimuli: copied when browsers play them as they are, else transcoded;
// returns study.json's record of each.
ordered_json copy_stimuli(const ExportWebSettings& settings, const StimulusFolderOpener& folder,
                          const std::vector<std::string>& used, const fs::path& dir, ExportWebResult& result) {
    ordered_json stimuli = ordered_json::object();
    Progress progress("export-web: stimuli", used.size());
    for (const auto& stimulus : used) {
        const ManifestEntry& entry = folder.manifest().stimuli.at(stimulus);
        const fs::path source = settings.stimuli_dir / stimulus;
        const fs::path target = dir / "stimuli" / stimulus;
        const MediaProbe probe = probe_media(source);
        bool transcoded = false;
        if (probe.browser_ready()) {
            copy_into(source, target);
        } else {
            transcode_stimulus(stimulus, probe, source, target);
            transcoded = true;
            ++result.transcoded;
        }
        ordered_json s;
        s["file"] = "stimuli/" + stimulus;
        s["sha256"] = entry.sha256;
        s["file_sha256"] = transcoded ? sha256_file(target) : entry.sha256;
        s["frames"] = entry.frames;
        s["fps"] = entry.fps;
        s["transcoded"] = transcoded;
        stimuli[stimulus] = s;
        progress.advance();
    }
    return stimuli;
}

// Screening and calibration sounds; returns study.json's record of them.
ordered_json write_sounds(const ExportWebSettings& settings, const Protocol& protocol, const OnlineSettings& online,
                          const std::vector<std::string>& used, const fs::path& dir) {
    const double level = protocol.corpus.level_dbfs;
    ordered_json sounds = ordered_json::object();
    const std::uint64_t seed = derive_seed(protocol.seed, "online/sounds");
    auto write_sound = [&](const std::string& name, const Audio& audio) {
        write_audio(dir / "sounds" / name, audio, SampleFormat::Pcm16);
        return "sounds/" + name;
    };
    if (online.antiphase)
        sounds["antiphase"] = {{"standard", write_sound("tone_standard.wav", antiphase_tone(online, level, 0.0, false))},
                               {"soft", write_sound("tone_soft.wav", antiphase_tone(online, level, -6.0, false))},
                               {"antiphase", write_sound("tone_antiphase.wav", antiphase_tone(online, level, 0.0, true))}};
    if (online.huggins) {
        ordered_json pitch = ordered_json::array(), noise = ordered_json::array();
        for (int i = 1; i <= 3; ++i) {
            pitch.push_back(write_sound(fmt::format("huggins_pitch{}.wav", i),
                                        huggins_noise(online, level, true, derive_seed(seed, fmt::format("pitch{}", i)))));
            noise.push_back(write_sound(fmt::format("huggins_noise{}.wav", i),
                                        huggins_noise(online, level, false, derive_seed(seed, fmt::format("noise{}", i)))));
        }
        sounds["huggins"] = {{"pitch", pitch}, {"noise", noise}};
    }
    if (online.level_setting) {
        // The long-term spectrum of up to 24 stimuli spread over the set.
        std::vector<std::vector<float>> speech;
        int rate = 0;
        for (const auto& stimulus : spread(used, 24)) {
            const stimuli::DecodedVideo video = stimuli::decode_video(settings.stimuli_dir / stimulus, false);
            if (!video.has_audio) continue;
            if (rate == 0) rate = video.audio.sample_rate_hz;
            if (video.audio.sample_rate_hz == rate) speech.push_back(video.audio.mono());
        }
        if (speech.empty())
            throw InputError(settings.stimuli_dir, "level_setting: no stimulus has audio to shape the calibration "
                                                   "noise from; set [online] level_setting = false");
        sounds["calibration"] = write_sound(
            "calibration.wav", shaped_noise(speech, rate, level, online.calibration_s, derive_seed(seed, "calibration"),
                                            online.sample_rate_hz));
    }
    return sounds;
}

// Each subject's plan (practice sentences with their text, for the
// feedback screen; no other sentence text reaches the browser).
ordered_json study_plans(const std::map<int, std::vector<PlannedTrial>>& subjects, const Corpus& corpus,
                         ExportWebResult& result) {
    ordered_json plans = ordered_json::object();
    for (const auto& [subject, trials] : subjects) {
        ordered_json list = ordered_json::array();
        for (const auto& t : trials) {
            ordered_json j = {{"position", t.position}, {"phase", to_string(t.phase)}, {"block", t.block},
                              {"list", t.list},         {"condition", t.condition},    {"sentence", t.sentence},
                              {"stimulus", t.stimulus}};
            if (t.phase == Phase::Practice) j["text"] = corpus.sentence(t.sentence).text;
            list.push_back(j);
            ++result.trials;
        }
        plans[std::to_string(subject)] = list;
    }
    return plans;
}

// study.json: what the runtime reads.
ordered_json study_json(const Protocol& protocol, const OnlineSettings& online, const ExportWebResult& result,
                        const std::string& protocol_sha, const std::string& lists_sha, const std::string& manifest_sha,
                        const ordered_json& vendored, const ordered_json& sounds, const ordered_json& stimuli,
                        const ordered_json& plans) {
    const SessionSettings& session = protocol.session;
    ordered_json study;
    study["format"] = "avsi-web-study";
    study["version"] = 1;
    study["study_id"] = result.study_id;
    study["experiment"] = protocol.name;
    study["protocol_sha256"] = protocol_sha;
    study["lists_sha256"] = lists_sha;
    study["manifest_sha256"] = manifest_sha;
    study["vendored"] = vendored;
    study["session"] = {{"fixation_ms", session.fixation_ms},
                        {"response_delay_ms", session.response_delay_ms},
                        {"break_every", session.break_every},
                        {"show_progress", session.show_progress},
                        {"instructions", session.instructions},
                        {"practice_instructions", session.practice_instructions},
                        {"test_instructions", session.test_instructions},
                        {"break_text", session.break_text},
                        {"end_text", session.end_text}};
    // What the participant reads, in the protocol's language (ui_strings.h).
    const UiStrings& strings = ui_strings(session.language);
    study["language"] = session.language;
    for (const char* section : {"runner", "web"}) {
        ordered_json texts = ordered_json::object();
        for (const auto& [key, text] : strings.section(section)) texts[key] = text;
        study["strings"][section] = texts;
    }
    study["online"] = {{"completion_url", online.completion_url},
                       {"screening_fail_url", online.screening_fail_url},
                       {"results_url", online.results_url},
                       {"antiphase", online.antiphase ? ordered_json{{"trials", online.antiphase_trials},
                                                                     {"pass", online.antiphase_pass}}
                                                      : ordered_json()},
                       {"huggins", online.huggins ? ordered_json{{"trials", online.huggins_trials},
                                                                 {"pass", online.huggins_pass}}
                                                  : ordered_json()},
                       {"tone_ms", online.tone_ms},
                       {"gap_ms", online.gap_ms},
                       {"huggins_ms", online.huggins_ms},
                       {"end_on_screening_fail", online.end_on_screening_fail},
                       {"level_setting", online.level_setting},
                       {"preload_timeout_s", online.preload_timeout_s}};
    study["sounds"] = sounds;
    study["stimuli"] = stimuli;
    study["subjects"] = plans;
    return study;
}

// The JATOS study description (<dirName>.jas).
ordered_json jatos_study(const ExportWebSettings& settings, const Protocol& protocol, const OnlineSettings& online,
                         const ExportWebResult& result, const std::string& dir_name) {
    ordered_json jas;
    jas["version"] = "3";
    ordered_json data;
    data["uuid"] = uuid_from("avsi-study/" + protocol.name);
    data["title"] = online.jatos_title.empty() ? "avsi: " + protocol.name : online.jatos_title;
    data["description"] = fmt::format("Exported by `avsi export-web` from {} (study id {}, {} subjects)",
                                      settings.protocol.filename().string(), result.study_id, result.subjects);
    data["groupStudy"] = false;
    data["linearStudy"] = false;
    data["allowPreview"] = false;
    data["dirName"] = dir_name;
    data["comments"] = "Results: export them (data only, or the results archive) and run `avsi import-web`.";
    data["jsonData"] = nullptr;
    data["endRedirectUrl"] = online.completion_url;
    data["studyEntryMsg"] = nullptr;
    data["componentList"] = ordered_json::array(
        {{{"uuid", uuid_from("avsi-component/" + protocol.name)},
          {"title", "Session"},
          {"htmlFilePath", "index.html"},
          // Reloadable: a reload continues the same study run at the first unanswered trial.
          {"reloadable", true},
          {"active", true},
          {"comments", "The whole session: screening, warm-up, practice and test blocks."},
          {"jsonData", nullptr}}});
    data["batchList"] = ordered_json::array(
        {{{"uuid", uuid_from("avsi-batch/" + protocol.name)},
          {"title", "Default"},
          {"active", true},
          {"maxActiveMembers", nullptr},
          {"maxTotalMembers", nullptr},
          {"maxTotalWorkers", nullptr},
          {"allowedWorkerTypes", {"PersonalSingle", "PersonalMultiple", "GeneralSingle", "Jatos"}},
          {"comments", nullptr},
          {"jsonData", nullptr}}});
    jas["data"] = data;
    return jas;
}

// The JATOS archive: <dirName>.jas + <dirName>/ (the study assets, read
// from the staged folder when the archive is written).
void write_jzip(const fs::path& path, const fs::path& dir, const std::string& dir_name, const ordered_json& jas) {
    detail::ZipWriter zip(path);
    zip.add_text(dir_name + ".jas", jas.dump(4) + "\n");
    zip.add_folder(dir_name + "/");
    std::vector<fs::path> files;
    for (const auto& e : fs::recursive_directory_iterator(dir)) files.push_back(e.path());
    std::sort(files.begin(), files.end());
    for (const auto& f : files) {
        const std::string name = dir_name + "/" + f.lexically_relative(dir).generic_string();
        if (fs::is_directory(f))
            zip.add_folder(name + "/");
        else
            zip.add_file(name, f, f.extension() != ".mp4");
    }
    zip.commit();
}

}  // namespace

ExportWebResult export_web(const ExportWebSettings& settings) {
    const Protocol protocol = load_protocol(settings.protocol);
    // Adaptive SRT tracks need live scoring and mixing between trials; the
    // web study presents fixed stimuli only.
    if (protocol.adaptive.present())
        throw InputError(settings.protocol, protocol.adaptive.line(), protocol.adaptive.column(), "adaptive",
                         "adaptive SRT tracks run in the lab runner (`avsi run`) only; the web study does not "
                         "implement them (export a protocol without [adaptive])");
    const OnlineSettings online = read_online_settings(protocol);
    const Corpus corpus = read_corpus(protocol.corpus.sentences);
    const auto subjects = check_lists(protocol, corpus, settings.lists);
    const fs::path web = settings.web_dir.empty() ? fs::path(AVSI_WEB_DIR) : settings.web_dir;
    check_web_runtime(web);
    // The stimuli the exported subjects use, checked against the manifest.
    StimulusFolderOpener folder(settings.stimuli_dir);
    if (!folder.manifest().experiment.empty() && folder.manifest().experiment != protocol.name)
        throw InputError(settings.stimuli_dir / "manifest.json", 0, 0, "experiment",
                         fmt::format("expected stimuli built for experiment \"{}\", got \"{}\"", protocol.name,
                                     folder.manifest().experiment));
    const std::vector<std::string> used = used_stimuli(subjects);
    folder.verify(used);
    const fs::path out = study_out_dir(settings);
    StagingFolder staging(out);
    const fs::path dir = staging.path();
    ExportWebResult result;
    const ordered_json vendored = copy_runtime(web, dir, result);
    const ordered_json stimuli = copy_stimuli(settings, folder, used, dir, result);
    result.stimuli = static_cast<int>(used.size());
    const ordered_json sounds = write_sounds(settings, protocol, online, used, dir);
    const std::string protocol_sha = sha256_file(settings.protocol);
    const std::string lists_sha = sha256_file(settings.lists);
    const ordered_json plans = study_plans(subjects, corpus, result);
    result.subjects = static_cast<int>(subjects.size());
    result.study_id = sha256_hex(protocol_sha + "\n" + lists_sha + "\n" + folder.manifest().sha256 + "\n" + stimuli.dump() +
                                 "\n" + plans.dump())
                          .substr(0, 16);
    const ordered_json study = study_json(protocol, online, result, protocol_sha, lists_sha, folder.manifest().sha256,
                                          vendored, sounds, stimuli, plans);
    write_text_file(dir / "study.json", study.dump(1) + "\n");
    copy_into(settings.lists, dir / "lists.csv");
    copy_into(settings.stimuli_dir / "manifest.json", dir / "manifest.json");
    const std::string dir_name = dir_name_for(protocol.name);
    result.jzip = settings.jzip.empty() ? fs::path(out.string() + ".jzip") : settings.jzip;
    write_jzip(result.jzip, dir, dir_name, jatos_study(settings, protocol, online, result, dir_name));
    // The archive was written from the staged files, before the folder moves into place.
    staging.commit();
    return result;
}

}  // namespace avsi::experiment
