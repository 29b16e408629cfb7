// Articulography as labs have it (issue 20): MOCHA-TIMIT's EMA as distributed
// (binary EST track, and the same as ASCII, no FrameShift line, per-frame time and presence flag,
// 20 channels in blocks with two named "****", 500 Hz, 1/100 mm; MOCHA .lab
// in seconds with sil/breath) and the Haskins IEEE rate database (one MATLAB
// v5 .mat per utterance written here with matio: a struct array named after
// the file, AUDIO + 8 sensors, SIGNAL N × 6, WORDS/PHONES of LABEL and OFFS).
// Each is read, mapped with head-motion removal, trained on and evaluated
// through `avsi train` / `avsi evaluate`, training only the parameters the
// source can drive; a damaged copy of each is refused at file:line.
#include <matio.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <map>
#include <numbers>
#include <set>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/learn/articulatory_corpus.h"
#include "avsi/learn/evaluation.h"
#include "avsi/learn/haskins_mat.h"
#include "avsi/learn/reference_speaker.h"
#include "avsi/learn/sensor_mapping.h"
#include "avsi/learn/training.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
using namespace avsi;
using namespace avsi::synth;
using namespace avsi::learn;

namespace {

constexpr double pi = std::numbers::pi;

// Removes a test's folder when the test ends, passed or failed.
struct Cleanup {
    fs::path dir;
    ~Cleanup() { fs::remove_all(dir); }
};

using test::temp_dir;

// Five short utterances of phones in the project set (times in seconds).
std::vector<PhoneSequence> utterance_phones() {
    const std::vector<std::vector<std::pair<std::string, double>>> words = {
        {{"sil", 0.25}, {"B", 0.07}, {"AA", 0.18}, {"P", 0.08}, {"IY", 0.16}, {"M", 0.07}, {"UW", 0.2}, {"sil", 0.25}},
        {{"sil", 0.2}, {"W", 0.08}, {"IY", 0.15}, {"F", 0.1}, {"AO", 0.2}, {"T", 0.07}, {"sil", 0.3}},
        {{"sil", 0.3}, {"M", 0.08}, {"AE", 0.2}, {"N", 0.07}, {"OW", 0.22}, {"V", 0.08}, {"IH", 0.1}, {"sil", 0.2}},
        {{"sil", 0.2}, {"P", 0.08}, {"UW", 0.18}, {"L", 0.08}, {"AA", 0.2}, {"B", 0.07}, {"EH", 0.14}, {"sil", 0.3}},
        {{"sil", 0.25}, {"S", 0.1}, {"IY", 0.16}, {"M", 0.08}, {"AO", 0.2}, {"F", 0.09}, {"AE", 0.15}, {"sil", 0.25}},
    };
    std::vector<PhoneSequence> out;
    for (const auto& w : words) {
        PhoneSequence p;
        double t = 0.0;
        for (const auto& [symbol, d] : w) {
            p.push_back({symbol, t, t + d, symbol != "sil"});
            t += d;
        }
        out.push_back(p);
    }
    return out;
}

// The reference speaker's articulation of `phones` at `fps` (no noise).
ParamTrack articulation(const PhoneSequence& phones, double fps, std::uint64_t seed) {
    ReferenceSpeakerSettings s;
    s.fps = fps;
    UtteranceVariation v;
    v.time_constant_scale.fill(1.0);
    Rng rng(seed);
    return simulate_reference_speaker(phones, v, s, rng);
}

// Head-frame sensor positions (mm; x forward, z up, y to the speaker's left)
// that the mapping turns back into the parameters.
struct Sensors {
    double jaw_x, jaw_y, jaw_z, ul_x, ul_z, ll_x, ll_y, ll_z, ml_y;
};
Sensors forward(const Frame& f) {
    auto p = [&](Param q) { return f[index(q)]; };
    const double gap = 20.0 * p(Param::JawRotation);
    Sensors s{};
    s.jaw_x = -0.3 * gap + 5.0 * p(Param::JawThrust);
    s.jaw_y = 5.0 * p(Param::JawShift);
    s.jaw_z = -gap;
    s.ul_x = 8.0 - 6.0 * p(Param::UpperLipRetraction);
    s.ul_z = 3.0 + 10.0 * p(Param::UpperLipRaise);
    s.ll_x = s.jaw_x + 8.0 - 6.0 * p(Param::LowerLipRetraction);
    s.ll_y = s.jaw_y;
    s.ll_z = s.jaw_z - 2.0 - 10.0 * p(Param::LowerLipDepression);
    s.ml_y = 25.0 + 8.0 * p(Param::MouthCornerStretchLeft) + 0.5 * s.jaw_y;
    return s;
}

// ---------------------------------------------------------------- MOCHA

// MOCHA's channel layout: x of five sensors, y of the same five, then x and y
// of the next five, two coil slots unused and named "****".
const std::vector<std::string> mocha_channels = {"ui_x", "li_x", "ul_x", "ll_x", "tt_x", "ui_y", "li_y", "ul_y",
                                                 "ll_y", "tt_y", "tb_x", "td_x", "v_x",  "****", "bn_x", "tb_y",
                                                 "td_y", "v_y",  "****", "bn_y"};

// Writes a MOCHA-style binary EST track (big-endian float32, as the corpus
// ships) of the articulation, the head moving, coordinates in 1/100 mm with x
// pointing back; every 97th frame a dropout (flag 0).
void write_mocha_ema(const fs::path& path, const ParamTrack& track) {
    std::string header = "EST_File Track\nDataType binary\nByteOrder 10\nNumFrames " + std::to_string(track.size()) +
                         "\nNumChannels 20\nNumAuxChannels 0\nEqualSpace 1\nBreaksPresent true\nCommentChar ;\n\n";
    for (std::size_t c = 0; c < mocha_channels.size(); ++c)
        header += "Channel_" + std::to_string(c) + " " + mocha_channels[c] + "\n";
    header += "EST_Header_End\n";
    std::string data;
    auto put = [&](float v) {
        std::uint32_t u;
        std::memcpy(&u, &v, 4);
        if constexpr (std::endian::native == std::endian::little)
            u = ((u & 0xff) << 24) | ((u & 0xff00) << 8) | ((u >> 8) & 0xff00) | (u >> 24);
        data.append(reinterpret_cast<const char*>(&u), 4);
    };
    for (std::size_t k = 0; k < track.size(); ++k) {
        const double t = track.time_s(k);
        const Sensors s = forward(track.frames[k]);
        // (x, y) in the head frame per sensor; MOCHA's y is vertical.
        const std::map<std::string, std::pair<double, double>> pos = {
            {"ui", {0, 0}},           {"li", {s.jaw_x, s.jaw_z}}, {"ul", {s.ul_x, s.ul_z}}, {"ll", {s.ll_x, s.ll_z}},
            {"tt", {-10, 2}},         {"tb", {-25, 8}},          {"td", {-40, 10}},        {"v", {-60, 5}},
            {"bn", {10, 40}}};
        const double angle = 0.06 * std::sin(2 * pi * 0.7 * t), tx = 3.0 * std::sin(2 * pi * 0.4 * t),
                     ty = 2.0 * std::cos(2 * pi * 0.3 * t);
        const bool dropout = k % 97 == 50;
        put(static_cast<float>(t));
        put(dropout ? 0.0f : 1.0f);
        for (const std::string& name : mocha_channels) {
            if (name == "****" || dropout) {
                put(0.0f);
                continue;
            }
            const auto [x, y] = pos.at(name.substr(0, name.size() - 2));
            const double rx = std::cos(angle) * x - std::sin(angle) * y + tx + 100;
            const double ry = std::sin(angle) * x + std::cos(angle) * y + ty - 50;
            put(static_cast<float>(name.back() == 'x' ? -rx * 100.0 : ry * 100.0));
        }
    }
    write_text_file(path, header + data);
}

// MOCHA's label set for the project phones used here.
std::string mocha_symbol(const Phone& p) {
    static const std::map<std::string, std::string> m = {
        {"sil", "sil"}, {"B", "b"}, {"AA", "aa"}, {"P", "p"}, {"IY", "ii"}, {"M", "m"},  {"UW", "uu"},
        {"W", "w"},     {"F", "f"}, {"AO", "oo"}, {"T", "t"}, {"AE", "a"},  {"N", "n"},  {"OW", "ou"},
        {"V", "v"},     {"IH", "i"}, {"L", "l"},  {"EH", "e"}, {"S", "s"}};
    return m.at(p.symbol);
}

void write_mocha_lab(const fs::path& path, const PhoneSequence& phones) {
    std::string text;
    for (std::size_t i = 0; i < phones.size(); ++i) {
        const bool last = i + 1 == phones.size();
        text += fmt::format("{:.4f} {:.4f} {}\n", phones[i].start_s, phones[i].end_s,
                            last ? std::string("breath") : mocha_symbol(phones[i]));
    }
    write_text_file(path, text);
}

fs::path write_mocha_corpus(const std::string& name) {
    const fs::path dir = temp_dir(name);
    nlohmann::json manifest = {{"format", "avsi-articulatory-corpus"},
                               {"version", 1},
                               {"name", "mocha-layout"},
                               {"sensor_mapping", {{"preset", "mocha"}}},
                               {"utterances", nlohmann::json::array()}};
    const auto all = utterance_phones();
    for (std::size_t i = 0; i < all.size(); ++i) {
        const std::string id = fmt::format("fsew0_{:03}", i + 1);
        write_mocha_ema(dir / (id + ".ema"), articulation(all[i], 500.0, i + 1));
        write_mocha_lab(dir / (id + ".lab"), all[i]);
        manifest["utterances"].push_back(
            {{"id", id}, {"track", id + ".ema"}, {"labels", id + ".lab"}, {"split", i < 3 ? "train" : "test"}});
    }
    write_text_file(dir / "corpus.json", manifest.dump(2));
    return dir;
}

// ---------------------------------------------------------------- Haskins

struct VarFree {
    void operator()(matvar_t* v) const { Mat_VarFree(v); }
};

matvar_t* mat_text(const std::string& s) {
    std::size_t dims[2] = {1, s.size()};
    return Mat_VarCreate(nullptr, MAT_C_CHAR, MAT_T_UINT8, 2, dims, const_cast<char*>(s.data()), 0);
}
matvar_t* mat_numbers(std::size_t rows, std::size_t cols, std::vector<double> v) {
    std::size_t dims[2] = {rows, cols};
    return Mat_VarCreate(nullptr, MAT_C_DOUBLE, MAT_T_DOUBLE, 2, dims, v.empty() ? nullptr : v.data(), 0);
}
matvar_t* mat_segments(const std::vector<Interval>& items) {
    const char* fields[] = {"LABEL", "OFFS", nullptr};
    std::size_t dims[2] = {1, items.size()};
    matvar_t* s = Mat_VarCreateStruct2(nullptr, 2, dims, fields);
    for (std::size_t j = 0; j < items.size(); ++j) {
        Mat_VarSetStructFieldByName(s, "LABEL", j, mat_text(items[j].text));
        Mat_VarSetStructFieldByName(s, "OFFS", j, mat_numbers(1, 2, {items[j].start_s, items[j].end_s}));
    }
    return s;
}

const std::vector<std::string> haskins_sensors = {"TR", "TB", "TT", "UL", "LL", "ML", "JAW", "JAWL"};

// Writes a recording in the Haskins layout: a struct array named after the
// file, AUDIO first (44.1 kHz), then the 8 sensors at 100 Hz, N × 6 each.
// `sensor_columns` lets a test damage one sensor (TT) to fewer columns.
void write_haskins_mat(const fs::path& path, const PhoneSequence& phones, const ParamTrack& track,
                       std::size_t tt_columns = 6) {
    const char* fields[] = {"NAME", "SRATE", "SIGNAL", "SOURCE", "SENTENCE", "WORDS", "PHONES", "LABELS", nullptr};
    std::size_t dims[2] = {1, 1 + haskins_sensors.size()};
    std::unique_ptr<matvar_t, VarFree> rec(
        Mat_VarCreateStruct2(path.stem().string().c_str(), 2, dims, fields));
    // AUDIO: silence of the utterance's length, the sentence, words and phones.
    const std::size_t audio_n = static_cast<std::size_t>(phones.back().end_s * 44100.0);
    std::vector<Interval> words = {{phones.front().end_s, phones.back().start_s, "TESTWORD", 0}};
    std::vector<Interval> phone_items;
    for (const Phone& p : phones) {
        const bool vowel = PhoneInventory::builtin().is_vowel(p.symbol);
        phone_items.push_back({p.start_s, p.end_s, p.symbol == "sil" ? "sp" : p.symbol + (vowel ? "1" : ""), 0});
    }
    Mat_VarSetStructFieldByName(rec.get(), "NAME", 0, mat_text("AUDIO"));
    Mat_VarSetStructFieldByName(rec.get(), "SRATE", 0, mat_numbers(1, 1, {44100.0}));
    Mat_VarSetStructFieldByName(rec.get(), "SIGNAL", 0, mat_numbers(audio_n, 1, std::vector<double>(audio_n, 0.0)));
    Mat_VarSetStructFieldByName(rec.get(), "SOURCE", 0, mat_text("test"));
    Mat_VarSetStructFieldByName(rec.get(), "SENTENCE", 0, mat_text("a test sentence"));
    Mat_VarSetStructFieldByName(rec.get(), "WORDS", 0, mat_segments(words));
    Mat_VarSetStructFieldByName(rec.get(), "PHONES", 0, mat_segments(phone_items));
    Mat_VarSetStructFieldByName(rec.get(), "LABELS", 0, mat_numbers(0, 0, {}));
    const std::size_t n = track.size();
    for (std::size_t s = 0; s < haskins_sensors.size(); ++s) {
        const std::string& name = haskins_sensors[s];
        const std::size_t cols = name == "TT" ? tt_columns : 6;
        std::vector<double> signal(n * cols, 0.0);  // column-major
        for (std::size_t k = 0; k < n; ++k) {
            const Sensors p = forward(track.frames[k]);
            double x = -20, y = 0, z = 5;  // tongue and the jaw's left side: not used by the mapping
            if (name == "UL") x = p.ul_x, y = 0, z = p.ul_z;
            if (name == "LL") x = p.ll_x, y = p.ll_y, z = p.ll_z;
            if (name == "JAW") x = p.jaw_x, y = p.jaw_y, z = p.jaw_z;
            if (name == "ML") x = 4, y = p.ml_y, z = 0.5 * (p.ul_z + p.ll_z);
            const double xyz[3] = {x, y, z};
            for (std::size_t a = 0; a < std::min<std::size_t>(cols, 3); ++a) signal[a * n + k] = xyz[a];
            if (k == 37) signal[k] = std::nan("");  // one missing coordinate
        }
        const std::size_t e = s + 1;
        Mat_VarSetStructFieldByName(rec.get(), "NAME", e, mat_text(name));
        Mat_VarSetStructFieldByName(rec.get(), "SRATE", e, mat_numbers(1, 1, {100.0}));
        Mat_VarSetStructFieldByName(rec.get(), "SIGNAL", e, mat_numbers(n, cols, signal));
        Mat_VarSetStructFieldByName(rec.get(), "SOURCE", e, mat_text("test"));
        for (const char* f : {"SENTENCE", "WORDS", "PHONES", "LABELS"})
            Mat_VarSetStructFieldByName(rec.get(), f, e, mat_numbers(0, 0, {}));
    }
    mat_t* mat = Mat_CreateVer(path.string().c_str(), nullptr, MAT_FT_MAT5);
    ASSERT_NE(mat, nullptr);
    ASSERT_EQ(Mat_VarWrite(mat, rec.get(), MAT_COMPRESSION_NONE), 0);
    Mat_Close(mat);
}

fs::path write_haskins_corpus(const std::string& name) {
    const fs::path dir = temp_dir(name);
    nlohmann::json manifest = {{"format", "avsi-articulatory-corpus"},
                               {"version", 1},
                               {"name", "haskins-layout"},
                               {"utterances", nlohmann::json::array()}};
    const auto all = utterance_phones();
    for (std::size_t i = 0; i < all.size(); ++i) {
        const std::string id = fmt::format("F01_B01_S{:02}_R01_N", i + 1);
        write_haskins_mat(dir / (id + ".mat"), all[i], articulation(all[i], 100.0, i + 11));
        // No "labels": the .mat holds the phones.
        manifest["utterances"].push_back({{"id", id}, {"track", id + ".mat"}, {"split", i < 3 ? "train" : "test"}});
    }
    write_text_file(dir / "corpus.json", manifest.dump(2));
    return dir;
}

// ---------------------------------------------------------------- CLI

// The per-parameter RMSE of one model over all non-silence frames, from evaluate's CSV.
std::map<std::string, std::string> evaluated_rmse(const fs::path& csv, const std::string& model) {
    const CsvTable t = read_csv(csv);
    std::map<std::string, std::string> out;
    const std::size_t c_model = t.require_column("model"), c_subset = t.require_column("subset"),
                      c_param = t.require_column("parameter"), c_rmse = t.require_column("rmse_percent");
    for (const auto& row : t.rows)
        if (row.fields[c_model] == model && row.fields[c_subset] == "all non-silence") out[row.fields[c_param]] = row.fields[c_rmse];
    return out;
}

std::set<std::string> names_of(const std::array<bool, param_count>& flags) {
    std::set<std::string> out;
    for (const auto& info : params())
        if (flags[index(info.param)]) out.emplace(info.name);
    return out;
}

}  // namespace

TEST(MochaLayout, BinaryEstWithStarChannelsAndFlagsReadsAndMaps) {
    const fs::path dir = temp_dir("mocha_read");
    const Cleanup cleanup{dir};
    const PhoneSequence phones = utterance_phones()[0];
    const ParamTrack truth = articulation(phones, 500.0, 1);
    write_mocha_ema(dir / "fsew0_001.ema", truth);
    const EstTrack t = read_est_track(dir / "fsew0_001.ema");
    ASSERT_EQ(t.channels.size(), 20u);
    EXPECT_EQ(t.channels[13], "****");
    EXPECT_EQ(t.channels[18], "****");
    EXPECT_EQ(t.frame_count(), truth.size());
    EXPECT_NEAR(t.times_s[1], 1.0 / 500.0, 1e-9);  // the per-frame time (float32)
    EXPECT_FALSE(t.present[50]);                  // the flag
    EXPECT_TRUE(t.present[51]);

    // Mapped with head-motion removal: the drivable parameters follow the truth (60 fps).
    const ParamTrack p = map_sensors_to_params(t, *sensor_mapping_preset("mocha"), "fsew0_001.ema");
    EXPECT_EQ(names_of(p.present), names_of(drivable_parameters(*sensor_mapping_preset("mocha"))));
    EXPECT_FALSE(p.has(Param::JawShift));
    EXPECT_FALSE(p.has(Param::MouthCornerStretchLeft));
    double worst = 0.0;
    std::size_t compared = 0;
    for (std::size_t k = 0; k < p.size(); ++k) {
        const double v = p.frames[k][index(Param::JawRotation)];
        if (!std::isfinite(v)) continue;
        const auto j = static_cast<std::size_t>(std::lround(p.time_s(k) * 500.0));
        if (j >= truth.size()) continue;
        // The mapping measures the opening from its 5th percentile (the rest).
        worst = std::max(worst, std::abs(v - truth.frames[j][index(Param::JawRotation)]));
        ++compared;
    }
    EXPECT_GT(compared, 60u);
    EXPECT_LT(worst, 0.06);

    // The same track as an ASCII EST file, as MOCHA's tools also write it:
    // no FrameShift, "time flag v1 … v20" per line, the "****" channels.
    std::string ascii = "EST_File Track\nDataType ascii\nNumFrames " + std::to_string(t.frame_count()) +
                        "\nNumChannels 20\nNumAuxChannels 0\nEqualSpace 1\nBreaksPresent true\nCommentChar ;\n\n";
    for (std::size_t c = 0; c < mocha_channels.size(); ++c)
        ascii += "Channel_" + std::to_string(c) + " " + mocha_channels[c] + "\n";
    ascii += "EST_Header_End\n";
    const int first_frame_line = 1 + static_cast<int>(std::count(ascii.begin(), ascii.end(), '\n'));
    for (std::size_t k = 0; k < t.frame_count(); ++k) {
        ascii += fmt::format("{:.9g} {}", t.times_s[k], t.present[k] ? 1 : 0);
        for (float v : t.values[k]) ascii += fmt::format(" {:.9g}", v);
        ascii += "\n";
    }
    write_text_file(dir / "fsew0_001_ascii.ema", ascii);
    const EstTrack a = read_est_track(dir / "fsew0_001_ascii.ema");
    EXPECT_EQ(a.channels, t.channels);
    EXPECT_EQ(a.present, t.present);
    ASSERT_EQ(a.frame_count(), t.frame_count());
    for (std::size_t k = 0; k < a.frame_count(); ++k) {
        ASSERT_FLOAT_EQ(static_cast<float>(a.times_s[k]), static_cast<float>(t.times_s[k])) << k;
        ASSERT_EQ(a.values[k], t.values[k]) << k;  // float32 printed with 9 digits reads back exactly
    }
    // Damaged ASCII copy: frame 3 lost its last value.
    std::string cut = ascii;
    std::size_t at = 0;
    for (int l = 1; l < first_frame_line + 2; ++l) at = cut.find('\n', at) + 1;
    cut.erase(cut.rfind(' ', cut.find('\n', at)), cut.find('\n', at) - cut.rfind(' ', cut.find('\n', at)));
    write_text_file(dir / "ascii_damaged.ema", cut);
    try {
        (void)read_est_track(dir / "ascii_damaged.ema");
        FAIL() << "the damaged ASCII track was read";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, first_frame_line + 2) << e.what();
        EXPECT_NE(std::string(e.what()).find("expected 22 values (time, break flag, 20 channels), got 21"),
                  std::string::npos)
            << e.what();
    }

    // Damaged: a header line (NumChannels) garbled.
    std::string bytes = read_text_file(dir / "fsew0_001.ema");
    bytes.replace(bytes.find("NumChannels 20"), 14, "NumChannels 2O");
    write_text_file(dir / "damaged.ema", bytes);
    try {
        (void)read_est_track(dir / "damaged.ema");
        FAIL() << "the damaged track was read";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 5) << e.what();
        EXPECT_NE(std::string(e.what()).find("damaged.ema:5:"), std::string::npos) << e.what();
    }
}

TEST(MochaLayout, TrainAndEvaluateOnlyTheDrivableParameters) {
    const fs::path dir = write_mocha_corpus("mocha_train");
    const Cleanup cleanup{dir};
    const fs::path out = dir / "out";
    fs::create_directories(out);
    test::CliResult r = test::run_avsi({"train", "--model", "cohen-massaro", "--corpus", dir.string(), "--out",
                                        (out / "cm.json").string(), "--max-iterations", "8", "--threads", "2"});
    ASSERT_EQ(r.exit_code, 0) << r.output();
    EXPECT_NE(r.output().find("not measured, kept from the default model: mouth_corner_stretch_left, "
                            "mouth_corner_stretch_right, jaw_shift"),
              std::string::npos)
        << r.output();
    const auto model = nlohmann::json::parse(read_text_file(out / "cm.json"));
    EXPECT_NE(model.dump().find("Not measured, so kept from the initial model: mouth_corner_stretch_left"),
              std::string::npos);

    // The library call agrees on what was trained.
    TrainCommandSettings s;
    s.training.model = "cohen-massaro";
    s.training.max_iterations = 2;
    s.training.threads = 2;
    s.corpus = dir;
    s.out = out / "cm2.json";
    const TrainingReport report = run_training(s);
    EXPECT_EQ(names_of(report.trained), names_of(drivable_parameters(*sensor_mapping_preset("mocha"))));

    r = test::run_avsi({"evaluate", "--corpus", dir.string(), "--models", (out / "cm.json").string(), "--out",
                        (out / "table").string()});
    ASSERT_EQ(r.exit_code, 0) << r.output();
    auto rmse = evaluated_rmse(out / "table.csv", "cm");
    ASSERT_FALSE(rmse.empty()) << read_text_file(out / "table.csv");
    for (const char* p : {"jaw_rotation", "lip_rounding", "upper_lip_raise", "lower_lip_depression", "jaw_thrust"})
        EXPECT_TRUE(parse_double(rmse.at(p)).has_value()) << p << ": " << rmse.at(p);
    // Parameters the corpus does not measure are not scored (no row).
    for (const char* p : {"jaw_shift", "mouth_corner_stretch_left", "mouth_corner_stretch_right"})
        EXPECT_EQ(rmse.count(p), 0u) << p << " was scored without data: " << rmse[p];
}

TEST(HaskinsLayout, MatReadThroughMatio) {
    const fs::path dir = temp_dir("haskins_read");
    const Cleanup cleanup{dir};
    const PhoneSequence phones = utterance_phones()[1];
    write_haskins_mat(dir / "F01_B01_S01_R01_N.mat", phones, articulation(phones, 100.0, 5));
    const HaskinsRecording rec = read_haskins_mat(dir / "F01_B01_S01_R01_N.mat");
    EXPECT_EQ(rec.variable, "F01_B01_S01_R01_N");
    EXPECT_EQ(rec.sentence, "a test sentence");
    EXPECT_EQ(rec.audio_rate_hz, 44100.0);
    EXPECT_EQ(rec.sensor_rate_hz, 100.0);
    EXPECT_EQ(rec.sensors, haskins_sensors);
    ASSERT_EQ(rec.phones.size(), phones.size());
    EXPECT_EQ(rec.phones[0].text, "sp");
    EXPECT_EQ(rec.phones[1].text, "W");
    EXPECT_EQ(rec.phones[2].text, "IY1");
    EXPECT_DOUBLE_EQ(rec.phones[2].start_s, phones[2].start_s);
    ASSERT_EQ(rec.words.size(), 1u);
    EXPECT_EQ(rec.track.channels[9], "UL_x");
    EXPECT_EQ(rec.track.channels[11], "UL_z");
    EXPECT_TRUE(std::isnan(rec.track.values[37][0]));  // TR_x at frame 37

    // The mapping: 9 of the 10 parameters (no right mouth corner sensor).
    const SensorMappingSettings haskins = *sensor_mapping_preset("haskins");
    const ParamTrack p = map_sensors_to_params(rec.track, haskins, "F01.mat");
    EXPECT_TRUE(p.has(Param::JawShift));
    EXPECT_TRUE(p.has(Param::MouthCornerStretchLeft));
    EXPECT_FALSE(p.has(Param::MouthCornerStretchRight));
    EXPECT_EQ(names_of(p.present).size(), 9u);

    // Damaged: TT's SIGNAL has 2 columns (element 4 of the struct array).
    write_haskins_mat(dir / "F01_B01_S02_R01_N.mat", phones, articulation(phones, 100.0, 5), 2);
    try {
        (void)read_haskins_mat(dir / "F01_B01_S02_R01_N.mat");
        FAIL() << "the damaged recording was read";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 4) << e.what();
        EXPECT_EQ(e.first().field, "element 4 (TT) SIGNAL");
        EXPECT_NE(std::string(e.what()).find("F01_B01_S02_R01_N.mat:4:"), std::string::npos) << e.what();
    }
    // A truncated copy (a broken download) is an error, not a crash.
    std::string bytes = read_text_file(dir / "F01_B01_S01_R01_N.mat");
    for (std::size_t keep : {bytes.size() / 2, std::size_t{200}, std::size_t{130}}) {
        write_text_file(dir / "F01_B01_S04_R01_N.mat", bytes.substr(0, keep));
        EXPECT_THROW((void)read_haskins_mat(dir / "F01_B01_S04_R01_N.mat"), InputError) << keep << " bytes";
    }
    // Not a MAT file at all.
    write_text_file(dir / "F01_B01_S03_R01_N.mat", "not a MATLAB file\n");
    EXPECT_THROW((void)read_haskins_mat(dir / "F01_B01_S03_R01_N.mat"), InputError);
}

TEST(HaskinsLayout, TrainAndEvaluateOnlyTheDrivableParameters) {
    const fs::path dir = write_haskins_corpus("haskins_train");
    const Cleanup cleanup{dir};
    const fs::path out = dir / "out";
    fs::create_directories(out);
    test::CliResult r = test::run_avsi({"train", "--model", "cohen-massaro", "--corpus", dir.string(), "--out",
                                        (out / "cm.json").string(), "--max-iterations", "8", "--threads", "2"});
    ASSERT_EQ(r.exit_code, 0) << r.output();
    EXPECT_NE(r.output().find("measures 9 of the 10 parameters"), std::string::npos) << r.output();
    EXPECT_NE(r.output().find("kept from the default model: mouth_corner_stretch_right"), std::string::npos)
        << r.output();

    r = test::run_avsi({"evaluate", "--corpus", dir.string(), "--models", (out / "cm.json").string(), "--out",
                        (out / "table").string()});
    ASSERT_EQ(r.exit_code, 0) << r.output();
    const auto rmse = evaluated_rmse(out / "table.csv", "cm");
    for (const char* p : {"jaw_rotation", "jaw_shift", "mouth_corner_stretch_left"})
        EXPECT_TRUE(parse_double(rmse.at(p)).has_value()) << p << ": " << rmse.at(p);
    EXPECT_EQ(rmse.count("mouth_corner_stretch_right"), 0u);
}

TEST(HaskinsLayout, DamagedPhonesInACorpusNameTheFileAndElement) {
    const fs::path dir = temp_dir("haskins_bad_phones");
    const Cleanup cleanup{dir};
    PhoneSequence phones = utterance_phones()[2];
    phones[3].symbol = "AX";  // not an ARPAbet phone of the project set
    write_haskins_mat(dir / "F01_B01_S09_R01_N.mat", phones, articulation(utterance_phones()[2], 100.0, 9));
    write_text_file(dir / "corpus.json",
                    R"({"format": "avsi-articulatory-corpus", "version": 1,
                        "utterances": [{"id": "u", "track": "F01_B01_S09_R01_N.mat"}]})");
    const ArticulatoryCorpus corpus = load_articulatory_corpus(dir);
    try {
        (void)load_corpus_utterance(corpus, corpus.entries[0]);
        FAIL() << "the unknown phone was accepted";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 4) << e.what();  // PHONES element 4
        EXPECT_NE(std::string(e.what()).find("F01_B01_S09_R01_N.mat:4:"), std::string::npos) << e.what();
    }
}
