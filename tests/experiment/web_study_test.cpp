// The online study without a browser: the export's folder and JATOS archive
// (against JATOS' documented study-archive layout), the generated screening
// and calibration sounds, the [online] section's validation, and the import
// of results (JSON Lines, JATOS results archive) against the design —
// including the refusals (truncated, another study's, out of plan order,
// wrong stimulus, contradicting a stored answer) that must leave the
// database unchanged, and the migration of a schema-1 lab database.
#include <zip.h>

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <cstdlib>
#include <fstream>
#include <numbers>
#include <regex>
#include <set>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <unsupported/Eigen/FFT>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/experiment/design.h"
#include "avsi/experiment/runner.h"
#include "avsi/experiment/store.h"
#include "avsi/experiment/web_study.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace avsi::experiment {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;
using test::temp_dir;

const fs::path web_data = fs::path(AVSI_TEST_DATA_DIR) / "web";
const fs::path web_protocol = web_data / "protocol.toml";

// The stimuli of the web test protocol (built once with `avsi build-stimuli`)
// and lists for 3 subjects.
class WebStudy : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        s_dir = temp_dir("web_study");
        // The stimuli are built once into the build folder and reused: build-stimuli
        // rebuilds nothing unchanged, and flock serialises the parallel test processes.
        s_stimuli = fs::path(AVSI_WEB_TEST_STIMULI);
        using test::shell_quote;
        const test::CliResult built =
            test::run_command("flock " + shell_quote(s_stimuli.string() + ".lock") + " " + shell_quote(AVSI_CLI_PATH) +
                              " build-stimuli " + shell_quote(web_protocol.string()) + " --out " +
                              shell_quote(s_stimuli.string()));
        ASSERT_EQ(built.exit_code, 0) << built.output();
        const Protocol p = load_protocol(web_protocol);
        write_lists_csv(s_dir / "lists.csv", make_design(p, read_corpus(p.corpus.sentences), 3));
    }
    static fs::path stimuli() { return s_stimuli; }
    static fs::path lists() { return s_dir / "lists.csv"; }

    static ExportWebResult export_to(const fs::path& out, const fs::path& stimuli_dir = stimuli(),
                                     const fs::path& lists_csv = lists()) {
        ExportWebSettings s;
        s.protocol = web_protocol;
        s.stimuli_dir = stimuli_dir;
        s.lists = lists_csv;
        s.out_dir = out;
        return export_web(s);
    }

    static inline fs::path s_dir;
    static inline fs::path s_stimuli;
};

// Every entry of a ZIP archive: name → bytes.
std::map<std::string, std::string> read_zip(const fs::path& path) {
    int error = 0;
    zip_t* z = zip_open(path.c_str(), ZIP_RDONLY, &error);
    EXPECT_NE(z, nullptr) << path;
    std::map<std::string, std::string> out;
    if (!z) return out;
    for (zip_int64_t i = 0; i < zip_get_num_entries(z, 0); ++i) {
        zip_stat_t st;
        zip_stat_index(z, static_cast<zip_uint64_t>(i), 0, &st);
        std::string bytes(static_cast<std::size_t>(st.size), '\0');
        if (st.size > 0) {
            zip_file_t* f = zip_fopen_index(z, static_cast<zip_uint64_t>(i), 0);
            zip_fread(f, bytes.data(), bytes.size());
            zip_fclose(f);
        }
        out[st.name] = bytes;
    }
    zip_close(z);
    return out;
}

void write_zip(const fs::path& path, const std::map<std::string, std::string>& entries) {
    int error = 0;
    zip_t* z = zip_open(path.c_str(), ZIP_CREATE | ZIP_TRUNCATE, &error);
    ASSERT_NE(z, nullptr);
    for (const auto& [name, bytes] : entries) {
        zip_source_t* s = zip_source_buffer(z, bytes.data(), bytes.size(), 0);
        ASSERT_GE(zip_file_add(z, name.c_str(), s, ZIP_FL_ENC_UTF_8), 0);
    }
    ASSERT_EQ(zip_close(z), 0);
}

TEST_F(WebStudy, JzipHasJatosStudyArchiveLayout) {
    const fs::path out = temp_dir("web_jzip") / "study";
    const ExportWebResult r = export_to(out);
    EXPECT_EQ(r.subjects, 3);
    EXPECT_EQ(r.trials, 12);
    const auto entries = read_zip(r.jzip);
    // Root: exactly one .jas file and one folder (the study assets).
    std::set<std::string> root_files, root_folders;
    for (const auto& [name, bytes] : entries) {
        const auto slash = name.find('/');
        if (slash == std::string::npos) root_files.insert(name);
        else root_folders.insert(name.substr(0, slash));
    }
    ASSERT_EQ(root_files.size(), 1u);
    ASSERT_EQ(root_folders.size(), 1u);
    const std::string jas_name = *root_files.begin();
    EXPECT_EQ(fs::path(jas_name).extension(), ".jas");
    // The .jas: JATOS' documented schema (version, data with the required fields and types).
    const json jas = json::parse(entries.at(jas_name));
    ASSERT_TRUE(jas.at("version").is_string());
    EXPECT_EQ(jas["version"], "3");
    const json& data = jas.at("data");
    for (const char* key : {"uuid", "title", "dirName"}) EXPECT_TRUE(data.at(key).is_string()) << key;
    for (const char* key : {"groupStudy", "linearStudy", "allowPreview"}) EXPECT_TRUE(data.at(key).is_boolean()) << key;
    EXPECT_TRUE(data.at("endRedirectUrl").is_string());
    EXPECT_EQ(data["endRedirectUrl"], "/complete?cc=TEST42");
    EXPECT_EQ(data["dirName"], *root_folders.begin());
    EXPECT_EQ(data["uuid"].get<std::string>().size(), 36u);
    ASSERT_TRUE(data.at("componentList").is_array());
    ASSERT_EQ(data["componentList"].size(), 1u);
    const json& component = data["componentList"][0];
    for (const char* key : {"uuid", "title", "htmlFilePath"}) EXPECT_TRUE(component.at(key).is_string()) << key;
    EXPECT_TRUE(component.at("reloadable").get<bool>());  // a reload must continue the same run
    EXPECT_TRUE(component.at("active").get<bool>());
    EXPECT_TRUE(entries.count(data["dirName"].get<std::string>() + "/" + component["htmlFilePath"].get<std::string>()));
    ASSERT_TRUE(data.at("batchList").is_array());
    ASSERT_EQ(data["batchList"].size(), 1u);
    for (const char* key : {"uuid", "title"}) EXPECT_TRUE(data["batchList"][0].at(key).is_string()) << key;
    EXPECT_TRUE(data["batchList"][0].at("allowedWorkerTypes").is_array());
    // The assets folder is the study folder, file for file, stimuli byte-exact.
    const std::string dir = data["dirName"].get<std::string>() + "/";
    int files = 0;
    for (const auto& e : fs::recursive_directory_iterator(out)) {
        if (!e.is_regular_file()) continue;
        ++files;
        const std::string name = dir + e.path().lexically_relative(out).generic_string();
        ASSERT_TRUE(entries.count(name)) << name;
        EXPECT_EQ(sha256_hex(entries.at(name)), sha256_file(e.path())) << name;
    }
    const StimulusManifest manifest = read_stimulus_manifest(stimuli());
    for (const auto& [path, entry] : manifest.stimuli)
        if (entries.count(dir + "stimuli/" + path)) {
            EXPECT_EQ(sha256_hex(entries.at(dir + "stimuli/" + path)), entry.sha256) << path;
        }
    EXPECT_GT(files, 15);
}

TEST_F(WebStudy, FolderIsSelfContainedAndHidesTestSentences) {
    const fs::path out = temp_dir("web_folder") / "study";
    export_to(out);
    // Everything index.html loads is in the folder (jatos.js is JATOS' own).
    const std::string html = read_text_file(out / "index.html");
    int references = 0;
    for (const std::string attr : {"src=\"", "href=\""}) {
        for (std::size_t p = html.find(attr); p != std::string::npos; p = html.find(attr, p + 1)) {
            const std::string ref = html.substr(p + attr.size(), html.find('"', p + attr.size()) - p - attr.size());
            EXPECT_EQ(ref.find("//"), std::string::npos) << "remote reference " << ref;
            if (ref != "jatos.js") {
                EXPECT_TRUE(fs::is_regular_file(out / ref)) << ref;
            }
            ++references;
        }
    }
    EXPECT_GE(references, 6);
    const json study = json::parse(read_text_file(out / "study.json"));
    EXPECT_EQ(study["format"], "avsi-web-study");
    EXPECT_EQ(study["vendored"]["jspsych"].get<std::string>().substr(0, 2), "8.");
    for (const auto& [subject, trials] : study["subjects"].items())
        for (const auto& t : trials) {
            EXPECT_EQ(t.contains("text"), t["phase"] == "practice") << subject << " " << t.dump();
            const json& s = study["stimuli"][t["stimulus"].get<std::string>()];
            EXPECT_EQ(sha256_file(out / s["file"].get<std::string>()), s["file_sha256"].get<std::string>());
        }
    for (const char* sound : {"tone_standard.wav", "tone_soft.wav", "tone_antiphase.wav", "huggins_pitch1.wav",
                              "huggins_noise3.wav", "calibration.wav"})
        EXPECT_TRUE(fs::is_regular_file(out / "sounds" / sound)) << sound;
}

TEST_F(WebStudy, RefusesListsNotFromTheDesignAndChangedStimuli) {
    const fs::path dir = temp_dir("web_refuse");
    // A lists file whose subject 2 has its test blocks swapped.
    std::string text = read_text_file(lists());
    const auto a = text.find("2,3,test,1,"), b = text.find("2,4,test,2,");
    ASSERT_NE(a, std::string::npos);
    ASSERT_NE(b, std::string::npos);
    std::string swapped = text;
    swapped.replace(a, 11, "2,3,test,2,");
    write_text_file(dir / "lists.csv", swapped);
    try {
        export_to(dir / "study", stimuli(), dir / "lists.csv");
        FAIL() << "exported lists that are not the design";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("lists.csv:6:"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("subject 2's trials are not the design"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(dir / "study"));
    EXPECT_FALSE(fs::exists(dir / "study.partial"));
    // A stimulus changed after the build.
    fs::copy(stimuli(), dir / "stimuli", fs::copy_options::recursive);
    std::ofstream(dir / "stimuli" / "t01" / "rule.mp4", std::ios::app) << "x";
    try {
        export_to(dir / "study", dir / "stimuli");
        FAIL() << "exported a changed stimulus";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("rule.mp4: error: sha256"), std::string::npos) << e.what();
    }
    // An existing folder that is not an earlier export is never replaced.
    fs::create_directories(dir / "mine");
    write_text_file(dir / "mine" / "notes.txt", "keep");
    EXPECT_THROW(export_to(dir / "mine"), InputError);
    EXPECT_EQ(read_text_file(dir / "mine" / "notes.txt"), "keep");
}

TEST_F(WebStudy, TranscodesOnlyWhatBrowsersCannotPlay) {
    const fs::path dir = temp_dir("web_transcode");
    fs::copy(stimuli(), dir / "stimuli", fs::copy_options::recursive);
    EXPECT_TRUE(probe_media(dir / "stimuli" / "t01" / "rule.mp4").browser_ready());
    // Re-encode one clip as H.264 High 4:4:4 (what an editing tool may give), then fix its manifest entry.
    const fs::path clip = dir / "stimuli" / "t01" / "rule.mp4";
    const std::string command =
        fmt::format("ffmpeg -v error -y -i '{}' -c:v libx264 -profile:v high444 -pix_fmt yuv444p -c:a aac '{}' && mv '{}' '{}'",
                    clip.string(), (dir / "high.mp4").string(), (dir / "high.mp4").string(), clip.string());
    ASSERT_EQ(std::system(command.c_str()), 0);
    const MediaProbe high = probe_media(clip);
    EXPECT_FALSE(high.browser_ready()) << high.describe();
    json manifest = json::parse(read_text_file(dir / "stimuli" / "manifest.json"));
    for (auto& s : manifest["stimuli"])
        if (s["path"] == "t01/rule.mp4") s["sha256"] = sha256_file(clip);
    write_text_file(dir / "stimuli" / "manifest.json", manifest.dump(1));
    const ExportWebResult r = export_to(dir / "study", dir / "stimuli");
    EXPECT_EQ(r.transcoded, 1);
    const MediaProbe out = probe_media(dir / "study" / "stimuli" / "t01" / "rule.mp4");
    EXPECT_TRUE(out.browser_ready()) << out.describe();
    const json study = json::parse(read_text_file(dir / "study" / "study.json"));
    EXPECT_TRUE(study["stimuli"]["t01/rule.mp4"]["transcoded"].get<bool>());
    EXPECT_EQ(study["stimuli"]["t01/rule.mp4"]["sha256"], sha256_file(clip));  // the source's hash is what is checked
    EXPECT_FALSE(study["stimuli"]["t02/rule.mp4"]["transcoded"].get<bool>());
}

// ---- sounds ----

double rms_of(const std::vector<float>& x, std::size_t from, std::size_t to) {
    double sum = 0.0;
    for (std::size_t i = from; i < to; ++i) sum += static_cast<double>(x[i]) * x[i];
    return std::sqrt(sum / static_cast<double>(to - from));
}

TEST(WebSounds, AntiphaseTonesAreInvertedAndTheSoftOneIsSixDbDown) {
    OnlineSettings s;
    const Audio standard = antiphase_tone(s, -26.0, 0.0, false);
    const Audio soft = antiphase_tone(s, -26.0, -6.0, false);
    const Audio anti = antiphase_tone(s, -26.0, 0.0, true);
    ASSERT_EQ(standard.channels, 2);
    EXPECT_EQ(standard.frames(), 44100u);
    const auto l = standard.channel(0), r = standard.channel(1), al = anti.channel(0), ar = anti.channel(1);
    const std::size_t a = 4410 + 100, b = 44100 - 4410 - 100;  // the steady part (100 ms ramps)
    EXPECT_NEAR(20.0 * std::log10(rms_of(l, a, b)), -26.0, 0.05);
    EXPECT_NEAR(20.0 * std::log10(rms_of(soft.channel(0), a, b) / rms_of(l, a, b)), -6.0, 0.01);
    for (std::size_t i = 0; i < l.size(); ++i) {
        ASSERT_EQ(l[i], r[i]);
        ASSERT_EQ(al[i], -ar[i]);
    }
    // 200 Hz: a zero crossing every 2.5 ms.
    int crossings = 0;
    for (std::size_t i = a + 1; i < b; ++i) crossings += (l[i - 1] < 0) != (l[i] < 0);
    EXPECT_NEAR(crossings, 2.0 * 200.0 * (b - a) / 44100.0, 2.0);
}

TEST(WebSounds, HugginsNoiseInvertsOnlyTheBandInOneEar) {
    OnlineSettings s;
    const Audio pitch = huggins_noise(s, -26.0, true, 7);
    const Audio diotic = huggins_noise(s, -26.0, false, 7);
    const auto l = pitch.channel(0), r = pitch.channel(1);
    EXPECT_EQ(diotic.channel(0), diotic.channel(1));
    // Compare the two ears' spectra over the steady part.
    const std::size_t a = 4410, n = 44100 - 2 * 4410;
    std::vector<double> x(l.begin() + a, l.begin() + a + n), y(r.begin() + a, r.begin() + a + n);
    Eigen::FFT<double> fft;
    std::vector<std::complex<double>> X, Y;
    fft.fwd(X, x);
    fft.fwd(Y, y);
    double in_band_correlation = 0, in_band_power = 0, out_band_correlation = 0, out_band_power = 0;
    for (std::size_t k = 1; k < n / 2; ++k) {
        const double hz = static_cast<double>(k) * 44100.0 / n;
        const double c = std::real(X[k] * std::conj(Y[k])), p = std::norm(X[k]);
        if (hz > 600 * 0.95 && hz < 600 * 1.05) { in_band_correlation += c; in_band_power += p; }
        if (hz < 400 || hz > 800) { out_band_correlation += c; out_band_power += p; }
    }
    EXPECT_LT(in_band_correlation / in_band_power, -0.8);   // opposite phase in the band
    EXPECT_GT(out_band_correlation / out_band_power, 0.99);  // identical elsewhere
    EXPECT_NEAR(20.0 * std::log10(rms_of(l, a, a + n)), -26.0, 0.3);
}

TEST(WebSounds, CalibrationNoiseFollowsTheSpeechSpectrumAtTheSpeechLevel) {
    // "Speech": a 300 Hz-rich signal with little above 2 kHz.
    std::vector<float> speech(22050 * 2);
    for (std::size_t i = 0; i < speech.size(); ++i)
        speech[i] = static_cast<float>(0.3 * std::sin(2 * std::numbers::pi * 300.0 * i / 22050.0) +
                                       0.003 * std::sin(2 * std::numbers::pi * 3000.0 * i / 22050.0));
    const Audio noise = shaped_noise({speech}, 22050, -30.0, 2.0, 3, 44100);
    ASSERT_EQ(noise.sample_rate_hz, 44100);
    const auto l = noise.channel(0);
    EXPECT_EQ(l, noise.channel(1));
    EXPECT_NEAR(20.0 * std::log10(rms_of(l, 0, l.size())), -30.0, 0.01);
    std::vector<double> x(l.begin(), l.end());
    Eigen::FFT<double> fft;
    std::vector<std::complex<double>> X;
    fft.fwd(X, x);
    auto band = [&](double lo, double hi) {
        double p = 0;
        for (std::size_t k = 1; k < X.size() / 2; ++k) {
            const double hz = static_cast<double>(k) * 44100.0 / X.size();
            if (hz >= lo && hz < hi) p += std::norm(X[k]);
        }
        return p;
    };
    EXPECT_GT(band(250, 350) / band(2900, 3100), 1000.0);  // 40 dB in the speech, kept in the noise
    EXPECT_LT(band(12000, 20000) / band(250, 350), 1e-9);  // nothing above the speech's Nyquist
}

TEST(OnlineSettings, ReportsEveryBadKeyWithItsLine) {
    const fs::path dir = temp_dir("online_settings");
    std::string text = read_text_file(web_protocol);
    text = text.substr(0, text.find("\n[online]") + 1);
    text += "[online]\nheadphone_check = [\"antiphse\"]\nantiphase_trials = 4\nantiphase_pass = 5\n"
            "completion_url = \"prolific.com/x\"\non_screening_fail = \"stop\"\nlevel_setting = true\nresult_url = \"/r\"\n";
    text = std::regex_replace(text, std::regex("\\.\\./"), (web_data / "..").string() + "/");
    write_text_file(dir / "p.toml", text);
    const Protocol p = load_protocol(dir / "p.toml");
    try {
        read_online_settings(p);
        FAIL();
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_EQ(e.diagnostics().size(), 5u) << what;
        EXPECT_NE(what.find("online.headphone_check: expected a list of \"antiphase\" and/or \"huggins\" ([] for none), got "
                            "\"antiphse\" (did you mean \"antiphase\"?)"),
                  std::string::npos)
            << what;
        EXPECT_NE(what.find("online.antiphase_pass: expected at most antiphase_trials (4), got 5"), std::string::npos) << what;
        EXPECT_NE(what.find("online.completion_url: expected an http(s):// URL"), std::string::npos) << what;
        EXPECT_NE(what.find("online.on_screening_fail"), std::string::npos) << what;
        EXPECT_NE(what.find("online.result_url: unknown key (did you mean \"results_url\"?)"), std::string::npos) << what;
    }
}

// ---- import ----

// The records a browser would send for `subject` answering the first `answered` trials.
// `run` (a browser's run id, "" for none) and `hour` (of the records' times) make a second browser's run.
std::vector<json> browser_records(int subject, int answered, const StimulusManifest& manifest,
                                  const std::string& session = "s1", const std::string& run = "", int hour = 10) {
    const Protocol p = load_protocol(web_protocol);
    const auto plan = design_subject(p, assign_lists(read_corpus(p.corpus.sentences), p.design), subject);
    std::vector<json> out;
    int seq = 0;
    auto base = [&](const char* kind) {
        json r{{"avsi", kind},        {"study", "0123456789abcdef"}, {"experiment", p.name}, {"subject", subject},
               {"session", session}, {"seq", ++seq},                {"time_utc", fmt::format("2026-11-24T{:02}:00:{:02}.000Z", hour, seq)}};
        if (!run.empty()) r["run"] = run;
        return r;
    };
    json s = base("session");
    s["position"] = 1;
    s["browser"] = {{"user_agent", "test"}, {"refresh_hz", 60}};
    out.push_back(s);
    for (int i = 1; i <= 3; ++i) {
        json t = base("screening-trial");
        t.update({{"test", "antiphase"}, {"trial", i}, {"answer", 2}, {"response", i == 3 ? 1 : 2}, {"correct", i != 3},
                  {"response_time_ms", 800}});
        out.push_back(t);
    }
    json summary = base("screening");
    summary.update({{"test", "antiphase"}, {"trials", 3}, {"correct", 2}, {"required", 3}, {"passed", false}});
    out.push_back(summary);
    for (int i = 0; i < answered; ++i) {
        const PlannedTrial& t = plan[static_cast<std::size_t>(i)];
        json r = base("trial");
        const ManifestEntry& m = manifest.stimuli.at(t.stimulus);
        json frames = json::array();
        for (int k = 0; k < m.frames; ++k) frames.push_back({k, k / m.fps, 5.0 + k / m.fps, 1.5});
        r.update({{"position", t.position}, {"phase", to_string(t.phase)}, {"block", t.block}, {"list", t.list},
                  {"condition", t.condition}, {"sentence", t.sentence}, {"stimulus", t.stimulus},
                  {"stimulus_sha256", m.sha256}, {"response", fmt::format("answer {}", t.position)},
                  {"response_time_ms", 1234.5}, {"confirmed_empty", false}, {"frames", frames},
                  {"timing", {{"audio_onset_s", 5.0}, {"video_onset_s", 5.0}, {"duration_s", m.frames / m.fps},
                              {"refresh_hz", 60.0}, {"frames_total", m.frames}, {"frames_shown", m.frames},
                              {"dropped_frames", 0}, {"repeated_frames", 0}, {"mean_offset_ms", 1.5},
                              {"max_abs_offset_ms", 1.5}, {"frame_callbacks", true}, {"presented_frames", m.frames},
                              {"missed_callbacks", 0}, {"browser_dropped_frames", 0},
                              {"browser_total_frames", m.frames}, {"output_latency_ms", 32.0},
                              {"base_latency_ms", 10.0}, {"audio_path_ms", 36.0}, {"audio_path_measured", true}}}});
        out.push_back(r);
    }
    return out;
}

std::string lines(const std::vector<json>& records) {
    std::string out;
    for (const auto& r : records) out += r.dump() + "\n";
    return out;
}

// Everything the database holds, as the export's CSV files.
std::string dump(const fs::path& db, const fs::path& dir) {
    const Store store(db);
    std::string out;
    for (const auto& f : export_store(store, dir)) out += f.filename().string() + "\n" + read_text_file(f);
    return out;
}

ImportWebResult import(const std::vector<fs::path>& files, const fs::path& db, const fs::path& stimuli,
                       const std::string& runs = "", bool require_complete = false) {
    ImportWebSettings s;
    s.results = files;
    s.protocol = web_protocol;
    s.database = db;
    s.stimuli = stimuli;
    if (!runs.empty()) s.runs = parse_run_choice(runs);
    s.require_complete = require_complete;
    return import_web(s);
}

TEST_F(WebStudy, ImportsJsonLinesAndTheJatosResultsArchiveAlike) {
    const fs::path dir = temp_dir("web_import");
    const StimulusManifest manifest = read_stimulus_manifest(stimuli());
    write_text_file(dir / "results.txt", lines(browser_records(1, 4, manifest)));
    const ImportWebResult r = import({dir / "results.txt"}, dir / "a.sqlite", stimuli());
    EXPECT_EQ(r.trials_added, 4);
    EXPECT_EQ(r.screening_failed, 1);  // recorded, not excluded
    // The same lines in JATOS' results archive layout, split over two component results.
    const auto records = browser_records(1, 4, manifest);
    const std::vector<json> first(records.begin(), records.begin() + 6), second(records.begin() + 6, records.end());
    write_zip(dir / "results.jrzip", {{"metadata.json", R"({"apiVersion":"1.0.0","data":[]})"},
                                      {"study_result_7/comp-result_9/data.txt", lines(first)},
                                      {"study_result_7/comp-result_10/data.txt", lines(second)},
                                      {"study_result_7/comp-result_11/data.txt", ""}});
    EXPECT_EQ(import({dir / "results.jrzip"}, dir / "b.sqlite", stimuli()).trials_added, 4);
    const Store a(dir / "a.sqlite"), b(dir / "b.sqlite");
    ASSERT_EQ(a.responses().size(), 4u);
    for (std::size_t i = 0; i < 4; ++i) {
        EXPECT_EQ(a.responses()[i].response.text, b.responses()[i].response.text);
        EXPECT_EQ(a.responses()[i].response.text, fmt::format("answer {}", i + 1));
        EXPECT_EQ(a.responses()[i].mode, "online");
    }
    EXPECT_EQ(a.timing(true).size(), 4u);
    EXPECT_EQ(a.web_timing().size(), 4u);
    EXPECT_EQ(a.screening().size(), 1u);
    EXPECT_FALSE(a.screening()[0].result.passed);
    EXPECT_EQ(a.screening_trials().size(), 3u);
    EXPECT_EQ(a.sessions(1).at(0).mode, "online");
    EXPECT_EQ(a.sessions(1).at(0).end_reason, "completed");
}

// Expects the import to fail with `message`, leaving the database as it was.
void expect_refused(const std::vector<fs::path>& files, const fs::path& db, const fs::path& stimuli,
                    const std::string& message, const fs::path& scratch) {
    const std::string before = dump(db, scratch / "before");
    try {
        import(files, db, stimuli);
        ADD_FAILURE() << "imported; expected: " << message;
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(message), std::string::npos) << e.what();
    }
    EXPECT_EQ(dump(db, scratch / "after"), before);
}

TEST_F(WebStudy, RefusesBadResultsAndLeavesTheDatabaseUnchanged) {
    const fs::path dir = temp_dir("web_refusals");
    const StimulusManifest manifest = read_stimulus_manifest(stimuli());
    const fs::path db = dir / "study.sqlite";
    // Subject 1 is stored already (half the session).
    write_text_file(dir / "s1.txt", lines(browser_records(1, 2, manifest)));
    ASSERT_EQ(import({dir / "s1.txt"}, db, stimuli()).trials_added, 2);

    // Truncated: subject 2's file cut in the middle of a record.
    const std::string s2 = lines(browser_records(2, 4, manifest));
    write_text_file(dir / "truncated.txt", s2.substr(0, s2.size() - 200));
    expect_refused({dir / "truncated.txt"}, db, stimuli(), "truncated.txt:9:", dir);
    expect_refused({dir / "truncated.txt"}, db, stimuli(),
                   "error: not valid JSON, the file is truncated or damaged (syntax error while parsing", dir);
    // A truncated results archive.
    write_zip(dir / "whole.zip", {{"study_result_1/comp-result_1/data.txt", s2}});
    const std::string zip_bytes = read_text_file(dir / "whole.zip");
    write_text_file(dir / "cut.zip", zip_bytes.substr(0, zip_bytes.size() / 2));
    expect_refused({dir / "cut.zip"}, db, stimuli(), "cut.zip: error: not a readable ZIP archive", dir);

    // Another study's results (another experiment).
    auto other = browser_records(2, 4, manifest);
    for (auto& r : other) r["experiment"] = "pilot-2025";
    write_text_file(dir / "other.txt", lines(other));
    expect_refused({dir / "other.txt"}, db, stimuli(),
                   "other.txt:1:1: error: experiment: expected \"web-test\" (the protocol's experiment), got "
                   "\"pilot-2025\": these are another study's results (9 records of ",
                   dir);
    // One error for the cause, not one per record.
    try {
        import({dir / "other.txt"}, db, stimuli());
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_EQ(std::count(what.begin(), what.end(), '\n') <= 1 && what.find("another study") == what.rfind("another study"),
                  true)
            << what;
    }

    // Trials out of plan order: trial 3 sent before trial 2.
    auto swapped = browser_records(2, 4, manifest);
    std::swap(swapped[6]["seq"], swapped[7]["seq"]);
    write_text_file(dir / "order.txt", lines(swapped));
    expect_refused({dir / "order.txt"}, db, stimuli(), "subject 2: expected trial 2 next in plan order, got trial 3", dir);

    // A trial that is not the design's (condition swapped), and a stimulus hash that is not the manifest's.
    auto wrong = browser_records(2, 4, manifest);
    ASSERT_EQ(wrong.size(), 9u);  // session, 3 screening trials, screening, 4 trials
    wrong[7]["condition"] = wrong[7]["condition"] == "rule" ? "audio-only" : "rule";
    wrong[8]["stimulus_sha256"] = std::string(64, '0');
    write_text_file(dir / "wrong.txt", lines(wrong));
    expect_refused({dir / "wrong.txt"}, db, stimuli(), "subject 2 trial 3 is test", dir);
    expect_refused({dir / "wrong.txt"}, db, stimuli(), "stimulus_sha256: expected", dir);
    // Every trial with another build's hash: one error for the cause, with the count.
    auto rebuilt = browser_records(2, 4, manifest);
    for (auto& r : rebuilt)
        if (r["avsi"] == "trial") r["stimulus_sha256"] = std::string(64, 'f');
    write_text_file(dir / "rebuilt.txt", lines(rebuilt));
    expect_refused({dir / "rebuilt.txt"}, db, stimuli(),
                   "the participant saw another file (and 3 more of subject 2's trials: 4 in all with a stimulus hash "
                   "not in ",
                   dir);
    try {
        import({dir / "rebuilt.txt"}, db, stimuli());
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_EQ(what.find("stimulus_sha256"), what.rfind("stimulus_sha256")) << what;
    }
    // Subject 2's records from two exports (another study id): one error with the count.
    auto mixed = browser_records(2, 4, manifest);
    for (std::size_t i = 5; i < mixed.size(); ++i) mixed[i]["study"] = "fedcba9876543210";
    write_text_file(dir / "mixed.txt", lines(mixed));
    expect_refused({dir / "mixed.txt"}, db, stimuli(),
                   "mixed.txt:6:1: error: study: subject 2 has records of two study exports (0123456789abcdef and "
                   "fedcba9876543210, the first at ",
                   dir);
    expect_refused({dir / "mixed.txt"}, db, stimuli(), "; 4 records of fedcba9876543210); import each export's", dir);

    // An answer that contradicts the stored one for subject 1.
    auto changed = browser_records(1, 4, manifest);
    changed[5]["response"] = "something else";
    write_text_file(dir / "changed.txt", lines(changed));
    // The error names the results file and line, and says which database holds the other answer.
    expect_refused({dir / "changed.txt"}, db, stimuli(),
                   "changed.txt:6:1: error: response: subject 1 trial 1: the answer \"something else\" differs from the "
                   "one already in " + db.string() + " (\"answer 1\", online session",
                   dir);

    // A good file still imports after all that, adding only what is new.
    write_text_file(dir / "s1-all.txt", lines(browser_records(1, 4, manifest)));
    const ImportWebResult r = import({dir / "s1-all.txt"}, db, stimuli());
    EXPECT_EQ(r.trials_added, 2);
    EXPECT_EQ(r.trials_present, 2);
}

TEST_F(WebStudy, KeepsOneRunOfASubjectInTwoBrowsersByEachRule) {
    const fs::path dir = temp_dir("web_runs");
    const StimulusManifest manifest = read_stimulus_manifest(stimuli());
    // Browser A answered all 4 trials at 10:00; browser B, opened at 11:00, restarted and answered 2, with the
    // same words (only the times and sessions differ).
    auto both = browser_records(1, 4, manifest, "sa", "runA", 10);
    for (const auto& r : browser_records(1, 2, manifest, "sb", "runB", 11)) both.push_back(r);
    for (auto& r : both)
        if (r["avsi"] == "trial") r["response"] = fmt::format("the same words {}", r["position"].get<int>());
    write_text_file(dir / "both.txt", lines(both));

    expect_refused({dir / "both.txt"}, dir / "none.sqlite", stimuli(),
                   "subject 1 took the study in 2 browser runs (run runA (started 2026-11-24T10:00:01.000Z, 4 trials, "
                   "sessions sa); run runB (started 2026-11-24T11:00:01.000Z, 2 trials, sessions sb)); choose the run "
                   "to keep with --runs first|last|most-complete|session=ID",
                   dir);
    struct Case {
        std::string rule, kept, left_out;
        int kept_trials, left_trials;
    };
    for (const Case& c : {Case{"first", "runA", "runB", 4, 2}, Case{"last", "runB", "runA", 2, 4},
                          Case{"most-complete", "runA", "runB", 4, 2}, Case{"session=sb", "runB", "runA", 2, 4}}) {
        SCOPED_TRACE(c.rule);
        const fs::path db = dir / (c.kept + c.rule.substr(0, 4) + ".sqlite");
        const ImportWebResult r = import({dir / "both.txt"}, db, stimuli(), c.rule);
        EXPECT_EQ(r.trials_added, c.kept_trials);
        ASSERT_EQ(r.left_out.size(), 1u);
        EXPECT_EQ(r.left_out[0].run, c.left_out);
        EXPECT_EQ(r.left_out[0].kept_run, c.kept);
        EXPECT_EQ(r.left_out[0].trials, c.left_trials);
        EXPECT_EQ(r.left_out[0].kept_trials, c.kept_trials);
        const Store store(db);
        ASSERT_EQ(store.responses().size(), static_cast<std::size_t>(c.kept_trials));
        EXPECT_EQ(store.sessions(1).size(), 1u);
        // The other run's identical answers are the same answers: importing it next never calls them different.
        const ImportWebResult again = import({dir / "both.txt"}, db, stimuli(), c.rule == "first" ? "last" : "first");
        EXPECT_EQ(again.trials_present, c.rule == "most-complete" ? 4 : 2);
        EXPECT_EQ(again.trials_added, c.kept == "runB" ? 2 : 0);
    }
    try {
        import({dir / "both.txt"}, dir / "none.sqlite", stimuli(), "session=nosuch");
        ADD_FAILURE() << "imported with an unknown session";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("--runs session=…: subject 1 has 0 runs holding the given sessions"),
                  std::string::npos)
            << e.what();
    }
    EXPECT_THROW(parse_run_choice("latest"), UsageError);
    EXPECT_THROW(parse_run_choice("session="), UsageError);
    EXPECT_EQ(parse_run_choice("session=a,b").sessions, (std::vector<std::string>{"a", "b"}));
}

TEST_F(WebStudy, AnIdenticalAnswerSentAgainFromAnotherPageLoadIsOneAnswer) {
    const fs::path dir = temp_dir("web_resend");
    const StimulusManifest manifest = read_stimulus_manifest(stimuli());
    auto records = browser_records(1, 4, manifest);
    json resent = records[5];  // trial 1, sent again by a later page load: another session, time and seq
    resent["session"] = "s1-reload";
    resent["seq"] = 100;
    resent["time_utc"] = "2026-11-24T10:30:00.000Z";
    records.push_back(resent);
    write_text_file(dir / "resent.txt", lines(records));
    const ImportWebResult r = import({dir / "resent.txt"}, dir / "a.sqlite", stimuli());
    EXPECT_EQ(r.trials_added, 4);
    EXPECT_EQ(r.duplicates, 1);
}

TEST_F(WebStudy, ListsIncompleteSubjectsAndRequireCompleteRefusesThem) {
    const fs::path dir = temp_dir("web_incomplete");
    const StimulusManifest manifest = read_stimulus_manifest(stimuli());
    auto records = browser_records(1, 4, manifest);
    for (const auto& r : browser_records(2, 1, manifest, "s2")) records.push_back(r);
    write_text_file(dir / "results.txt", lines(records));
    const ImportWebResult r = import({dir / "results.txt"}, dir / "a.sqlite", stimuli());
    ASSERT_EQ(r.incomplete.size(), 1u);
    EXPECT_EQ(r.incomplete[0].subject, 2);
    EXPECT_EQ(r.incomplete[0].answered, 1);
    EXPECT_EQ(r.incomplete[0].planned, 4);
    try {
        import({dir / "results.txt"}, dir / "b.sqlite", stimuli(), "", true);
        ADD_FAILURE() << "imported with --require-complete";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("results.txt: error: --require-complete: 1 subject with fewer trials than "
                                             "the design: subject 2 (1 of 4); nothing was imported"),
                  std::string::npos)
            << e.what();
    }
    EXPECT_FALSE(fs::exists(dir / "b.sqlite") && !Store(dir / "b.sqlite").responses().empty());
}

TEST_F(WebStudy, TheTextExportAndTheResultsArchiveTogetherCountEachRecordOnce) {
    const fs::path dir = temp_dir("web_both_formats");
    const StimulusManifest manifest = read_stimulus_manifest(stimuli());
    const auto records = browser_records(1, 4, manifest);
    write_text_file(dir / "results.txt", lines(records));
    write_zip(dir / "results.jrzip", {{"study_result_7/comp-result_9/data.txt", lines(records)}});
    const ImportWebResult r = import({dir / "results.txt", dir / "results.jrzip"}, dir / "a.sqlite", stimuli());
    EXPECT_EQ(r.trials_added, 4);
    EXPECT_EQ(r.duplicates, static_cast<int>(records.size()));
    EXPECT_EQ(r.screening_failed, 1);  // one failed check, not one per copy
}

TEST_F(WebStudy, TimingCertificateJudgesEachParticipantAgainstTheTolerances) {
    const fs::path dir = temp_dir("web_timing_certificate");
    const StimulusManifest manifest = read_stimulus_manifest(stimuli());
    // Subject 1: every frame 1.5 ms late (within tolerance). Subject 2: the sound 60 ms ahead on every frame
    // (> 45 ms). Subject 3: in sync, but 4 frames of each clip (about 10 %) never shown.
    auto records = browser_records(1, 4, manifest, "s1");
    for (auto r : browser_records(2, 4, manifest, "s2")) {
        if (r["avsi"] == "trial")
            for (auto& f : r["frames"]) f[3] = 60.0;
        records.push_back(r);
    }
    for (auto r : browser_records(3, 4, manifest, "s3")) {
        if (r["avsi"] == "trial") {
            for (int k = 0; k < 4; ++k) r["frames"].erase(r["frames"].size() - 1);
            const int total = r["timing"]["frames_total"].get<int>();
            r["timing"]["frames_shown"] = total - 4;
            r["timing"]["dropped_frames"] = 4;
        }
        records.push_back(r);
    }
    write_text_file(dir / "results.txt", lines(records));
    const ImportWebResult r = import({dir / "results.txt"}, dir / "a.sqlite", stimuli());
    ASSERT_EQ(r.timing.size(), 3u);
    EXPECT_EQ(r.timing[0].verdict, TimingVerdict::Pass);
    EXPECT_DOUBLE_EQ(r.timing[0].offset_median_ms, 1.5);
    EXPECT_EQ(r.timing[0].dropped_frames, 0);
    EXPECT_DOUBLE_EQ(*r.timing[0].output_latency_ms, 32.0);
    EXPECT_DOUBLE_EQ(r.timing[0].refresh_hz, 60.0);
    EXPECT_EQ(r.timing[1].verdict, TimingVerdict::Fail);
    EXPECT_EQ(r.timing[1].audio_leading_frames, r.timing[1].offset_frames);
    ASSERT_EQ(r.timing[1].reasons.size(), 1u);
    EXPECT_NE(r.timing[1].reasons[0].find("100.0 % of frames outside [-125, +45] ms"), std::string::npos)
        << r.timing[1].reasons[0];
    EXPECT_EQ(r.timing[2].verdict, TimingVerdict::Fail);
    EXPECT_EQ(r.timing[2].dropped_frames, 16);
    EXPECT_NE(describe(r.timing[2]).find("of frames dropped (16 of"), std::string::npos) << describe(r.timing[2]);

    // The export carries the same verdicts.
    const auto files = export_store(Store(dir / "a.sqlite"), dir / "export");
    ASSERT_TRUE(fs::exists(dir / "export" / "timing_certificate.csv"));
    const CsvTable table = read_csv(dir / "export" / "timing_certificate.csv");
    const auto verdict = table.require_column("verdict");
    ASSERT_EQ(table.rows.size(), 3u);
    EXPECT_EQ(table.rows[0].fields[verdict], "pass");
    EXPECT_EQ(table.rows[1].fields[verdict], "fail");
    EXPECT_EQ(table.rows[2].fields[verdict], "fail");
    EXPECT_EQ(table.rows[0].fields[table.require_column("tolerance_audio_lead_ms")], "45");
}

TEST_F(WebStudy, MigratesASchemaOneLabDatabaseAndKeepsItsData) {
    const fs::path dir = temp_dir("web_migrate");
    fs::copy_file(web_data / "schema1-lab.sqlite", dir / "lab.sqlite");
    {
        const Store store(dir / "lab.sqlite");
        // Migrated through every version (2: online sessions, 3: adaptive tracks).
        EXPECT_EQ(store.schema_version(), 3);
        EXPECT_TRUE(store.adaptive_trials().empty());
        const auto responses = store.responses();
        ASSERT_EQ(responses.size(), 4u);
        EXPECT_EQ(responses[0].response.text, "first answer");
        EXPECT_EQ(responses[3].response.text, "fourth one");
        EXPECT_EQ(responses[0].mode, "lab");
        EXPECT_EQ(store.sessions(2).at(0).mode, "lab");
        EXPECT_EQ(store.timing(true).at(0).presentation.flips.size(), 30u);
    }
    // Online subject 1 joins lab subject 2; a lab subject's number is refused for online data.
    const StimulusManifest manifest = read_stimulus_manifest(stimuli());
    write_text_file(dir / "s1.txt", lines(browser_records(1, 4, manifest)));
    EXPECT_EQ(import({dir / "s1.txt"}, dir / "lab.sqlite", stimuli()).trials_added, 4);
    write_text_file(dir / "s2.txt", lines(browser_records(2, 4, manifest)));
    expect_refused({dir / "s2.txt"}, dir / "lab.sqlite", stimuli(), "(\"first answer\", lab session", dir);
    const CsvTable sessions = read_csv(export_store(Store(dir / "lab.sqlite"), dir / "export")[4]);
    const auto mode = sessions.require_column("mode");
    std::set<std::string> modes;
    for (const auto& row : sessions.rows) modes.insert(row.fields[mode]);
    EXPECT_EQ(modes, (std::set<std::string>{"lab", "online"}));
}

}  // namespace
}  // namespace avsi::experiment
