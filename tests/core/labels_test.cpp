// Label files: Praat TextGrid (long and short text formats, UTF-8 and UTF-16),
// HTK .lab, TSV; their malformed forms; and phones from intervals.
#include "avsi/core/labels.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/rng.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

const fs::path data_dir = fs::path(AVSI_TEST_DATA_DIR) / "core";

// UTF-8 to UTF-16 with a BOM (test helper; input is valid UTF-8).
std::string to_utf16(const std::string& utf8, bool big_endian) {
    std::u32string cps;
    for (std::size_t i = 0; i < utf8.size();) {
        const auto c = static_cast<unsigned char>(utf8[i]);
        const int len = c < 0x80 ? 1 : (c >> 5) == 6 ? 2 : (c >> 4) == 14 ? 3 : 4;
        char32_t cp = len == 1 ? c : len == 2 ? (c & 0x1F) : len == 3 ? (c & 0x0F) : (c & 0x07);
        for (int k = 1; k < len; ++k) cp = (cp << 6) | (static_cast<unsigned char>(utf8[i + k]) & 0x3F);
        cps.push_back(cp);
        i += len;
    }
    std::string out;
    auto put = [&](char16_t u) {
        const char hi = static_cast<char>(u >> 8), lo = static_cast<char>(u & 0xFF);
        if (big_endian) { out += hi; out += lo; } else { out += lo; out += hi; }
    };
    put(0xFEFF);
    for (char32_t cp : cps) {
        if (cp >= 0x10000) {
            put(static_cast<char16_t>(0xD800 + ((cp - 0x10000) >> 10)));
            put(static_cast<char16_t>(0xDC00 + ((cp - 0x10000) & 0x3FF)));
        } else {
            put(static_cast<char16_t>(cp));
        }
    }
    return out;
}

TEST(TextGrid, ReadsLongFormat) {
    const TextGrid grid = read_textgrid(data_dir / "long.TextGrid");
    EXPECT_EQ(grid.start_s, 0.0);
    EXPECT_EQ(grid.end_s, 1.2);
    ASSERT_EQ(grid.tiers.size(), 3u);
    const Tier& words = grid.tier("words");
    ASSERT_EQ(words.items.size(), 3u);
    EXPECT_EQ(words.items[1].text, "say \"come\"");  // "" escapes
    EXPECT_EQ(words.items[1].start_s, 0.1);
    EXPECT_EQ(words.items[1].end_s, 0.5);
    EXPECT_EQ(words.items[1].line, 22);
    const Tier& phones = grid.tier("phones");
    ASSERT_EQ(phones.items.size(), 6u);
    EXPECT_EQ(phones.items[2].text, "AH1");
    const Tier& events = grid.tier("events");
    EXPECT_FALSE(events.is_interval);
    ASSERT_EQ(events.items.size(), 2u);
    EXPECT_EQ(events.items[0].start_s, 0.25);
    EXPECT_EQ(events.items[1].text, "two\nlines");  // strings may span lines
}

TEST(TextGrid, ShortFormatReadsTheSameAsLong) {
    EXPECT_EQ(read_textgrid(data_dir / "short.TextGrid"), read_textgrid(data_dir / "long.TextGrid"));
}

TEST(TextGrid, ReadsUtf16AndUtf8WithBom) {
    const std::string utf8 = read_text_file(data_dir / "mfa_ipa.TextGrid");
    const TextGrid want = read_textgrid(data_dir / "mfa_ipa.TextGrid");
    const fs::path dir = test::temp_dir("labels_test");
    write_text_file(dir / "le.TextGrid", to_utf16(utf8, false));
    write_text_file(dir / "be.TextGrid", to_utf16(utf8, true));
    write_text_file(dir / "bom.TextGrid", "\xEF\xBB\xBF" + utf8);
    for (const char* name : {"le.TextGrid", "be.TextGrid", "bom.TextGrid"}) {
        SCOPED_TRACE(name);
        const TextGrid got = read_textgrid(dir / name);
        EXPECT_EQ(got, want);
        EXPECT_EQ(got.tiers[0].items[0].text, "kʰ");
    }
    fs::remove_all(dir);
}

TEST(TextGrid, WrittenGridReadsBackIdentically) {
    TextGrid grid;
    grid.start_s = 0.0;
    grid.end_s = 1.0 / 3.0 + 2.0;
    Tier words{"words", true, 0.0, grid.end_s, {}};
    words.items = {{0.0, 0.1 + 0.2, "", 0}, {0.1 + 0.2, 1.0 / 7.0 + 1.0, "say \"hi\" — ünïcödé", 0},
                   {1.0 / 7.0 + 1.0, grid.end_s, "two\nlines", 0}};
    Tier marks{"marks", false, 0.0, grid.end_s, {{0.123456789012345, 0.123456789012345, "x", 0}}};
    grid.tiers = {words, marks};
    const fs::path dir = test::temp_dir("labels_test");
    write_textgrid(dir / "out.TextGrid", grid);
    EXPECT_EQ(read_textgrid(dir / "out.TextGrid"), grid);
    TextGrid empty;
    empty.end_s = 2.0;
    write_textgrid(dir / "empty.TextGrid", empty);
    EXPECT_EQ(read_textgrid(dir / "empty.TextGrid"), empty);
    fs::remove_all(dir);
}

struct MalformedCase {
    const char* file;
    int line;
    const char* message_part;
};

class MalformedLabels : public ::testing::TestWithParam<MalformedCase> {};

TEST_P(MalformedLabels, FailWithFileAndLine) {
    const MalformedCase& c = GetParam();
    const fs::path path = data_dir / c.file;
    try {
        (void)read_phones(path);
        FAIL() << "expected InputError for " << c.file;
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().path, path.string());
        EXPECT_EQ(e.first().line, c.line) << e.what();
        const std::string what = e.what();
        EXPECT_EQ(what.rfind(path.string() + ":" + std::to_string(c.line) + ": error: ", 0), 0u) << what;
        EXPECT_NE(what.find(c.message_part), std::string::npos) << what;
    }
}

INSTANTIATE_TEST_SUITE_P(
    Files, MalformedLabels,
    ::testing::Values(MalformedCase{"malformed_number.TextGrid", 17, "got \"abc\""},
                      MalformedCase{"malformed_truncated.TextGrid", 40, "end of the file"},
                      MalformedCase{"malformed_string.TextGrid", 68, "closing '\"'"},
                      MalformedCase{"malformed_key.TextGrid", 21, "expected the key 'xmax', got 'xmin'"},
                      MalformedCase{"malformed_overlap.TextGrid", 20, "previous interval's end"},
                      MalformedCase{"malformed_class.TextGrid", 2, "expected \"TextGrid\", got \"Sound\""},
                      MalformedCase{"unknown_phone.TextGrid", 44, "unknown phone label \"QQ9\""},
                      MalformedCase{"malformed.lab", 3, "x4000000"},
                      MalformedCase{"malformed.tsv", 3, "expected 3 fields"}));

TEST(TextGrid, DamagedFilesNeverCrash) {
    // Property: every truncation and seeded byte damage of a valid TextGrid
    // either reads or throws InputError naming the file.
    const fs::path dir = test::temp_dir("labels_test");
    const fs::path path = dir / "damaged.TextGrid";
    for (const char* name : {"long.TextGrid", "short.TextGrid"}) {
        const std::string good = read_text_file(data_dir / name);
        std::vector<std::string> variants;
        for (std::size_t n = 0; n < good.size(); n += 29) variants.push_back(good.substr(0, n));
        const std::uint64_t seed = 20240601;
        SCOPED_TRACE(::testing::Message() << name << " seed " << seed);
        Rng rng(seed);
        const std::string alphabet = "\"<>[]=:!-.0123456789 \nxabc\xC3\xFF";
        for (int k = 0; k < 150; ++k) {
            std::string damaged = good;
            for (int d = 0; d < 3; ++d)
                damaged[rng.uniform_int(damaged.size())] = alphabet[rng.uniform_int(alphabet.size())];
            variants.push_back(std::move(damaged));
        }
        for (const auto& text : variants) {
            std::ofstream(path, std::ios::binary | std::ios::trunc) << text;  // no fsync: fast
            try {
                (void)read_phones(path);
            } catch (const InputError& e) {
                EXPECT_EQ(e.first().path, path.string());
            }
        }
    }
    fs::remove_all(dir);
}

TEST(TextGrid, MissingTierListsTheTiers) {
    LabelReadOptions options;
    options.tier = "phone";
    try {
        (void)read_phones(data_dir / "long.TextGrid", options);
        FAIL();
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("'words', 'phones', 'events'"), std::string::npos) << what;
        EXPECT_NE(what.find("did you mean 'phones'"), std::string::npos) << what;
    }
    options.tier = "events";
    EXPECT_THROW((void)read_phones(data_dir / "long.TextGrid", options), InputError);  // a point tier
}

TEST(Labels, NonexistentAndUnsupportedFilesFail) {
    EXPECT_THROW((void)read_phones(data_dir / "no_such_file.TextGrid"), InputError);
    EXPECT_THROW((void)read_phones(data_dir / "README.md"), InputError);
}

TEST(Labels, PhonesFromArpabetTextGrid) {
    const PhoneSequence phones = read_phones(data_dir / "long.TextGrid");
    const PhoneSequence want = {{"sil", 0.0, 0.1, false}, {"K", 0.1, 0.2, false}, {"AH", 0.2, 0.35, true},
                                {"M", 0.35, 0.5, false}, {"sil", 0.5, 0.6, false}, {"HH", 0.6, 1.2, false}};
    EXPECT_EQ(phones, want);
}

TEST(Labels, PhonesFromMfaIpaFillGapsWithSilence) {
    const PhoneSequence phones = read_phones(data_dir / "mfa_ipa.TextGrid");
    const PhoneSequence want = {{"sil", 0.0, 0.05, false}, {"K", 0.05, 0.12, false},
                                {"AH", 0.12, 0.3, true},   {"sil", 0.3, 0.35, false},
                                {"M", 0.35, 0.42, false},  {"sil", 0.42, 0.5, false},
                                {"AY", 0.5, 0.7, false},   {"sil", 0.7, 0.9, false}};
    EXPECT_EQ(phones, want);
    EXPECT_NO_THROW(check_phone_sequence(phones, "mfa"));
}

TEST(Labels, ReadsHtkLabAndTsv) {
    const PhoneSequence want = {{"sil", 0.0, 0.15, false}, {"K", 0.15, 0.25, false},
                                {"AH", 0.25, 0.4, true}, {"M", 0.4, 0.55, false}};
    const PhoneSequence lab = read_phones(data_dir / "come.lab");
    const PhoneSequence tsv = read_phones(data_dir / "come.tsv");
    ASSERT_EQ(lab.size(), want.size());
    ASSERT_EQ(tsv.size(), want.size());
    for (std::size_t i = 0; i < want.size(); ++i) {
        EXPECT_EQ(lab[i].symbol, want[i].symbol);
        EXPECT_EQ(lab[i].stressed, want[i].stressed);
        EXPECT_NEAR(lab[i].start_s, want[i].start_s, 1e-12);
        EXPECT_NEAR(lab[i].end_s, want[i].end_s, 1e-12);
        EXPECT_EQ(tsv[i], want[i]);
    }
    const auto intervals = read_htk_lab(data_dir / "come.lab");
    EXPECT_EQ(intervals[2].text, "AH1");  // the score after the label is read and dropped
    EXPECT_EQ(intervals[2].line, 3);
}

TEST(Labels, MultiPhoneLabelsSplitTheInterval) {
    const PhoneSequence phones = phones_from_intervals({{0.0, 0.3, "n̩", 7}}, "x.tsv");
    ASSERT_EQ(phones.size(), 2u);
    EXPECT_EQ(phones[0].symbol, "AH");
    EXPECT_EQ(phones[1].symbol, "N");
    EXPECT_NEAR(phones[0].end_s, 0.15, 1e-12);
    EXPECT_EQ(phones[1].start_s, phones[0].end_s);
    try {
        (void)phones_from_intervals({{0.0, 0.1, "K", 3}, {0.05, 0.2, "AA1", 4}}, "x.tsv");
        FAIL() << "overlap accepted";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 4);
    }
}

TEST(Labels, PhoneFilesRoundTrip) {
    const PhoneSequence phones = {{"sil", 0.0, 0.1, false},       {"K", 0.1, 1.0 / 3.0, false},
                                  {"AH", 1.0 / 3.0, 0.4, true},    {"M", 0.4, 0.51, false},
                                  {"ER", 0.51, 0.6 + 1e-9, false}, {"sil", 0.6 + 1e-9, 0.9, false}};
    const fs::path dir = test::temp_dir("labels_test");
    write_phones_textgrid(dir / "p.TextGrid", phones);
    EXPECT_EQ(read_phones(dir / "p.TextGrid"), phones);
    write_phones_tsv(dir / "p.tsv", phones);
    const PhoneSequence tsv = read_phones(dir / "p.tsv");
    ASSERT_EQ(tsv.size(), phones.size());
    for (std::size_t i = 0; i < phones.size(); ++i) {
        EXPECT_EQ(tsv[i].symbol, phones[i].symbol);
        EXPECT_EQ(tsv[i].stressed, phones[i].stressed);
        EXPECT_NEAR(tsv[i].start_s, phones[i].start_s, 1e-6);
    }
    const std::string text = read_text_file(dir / "p.tsv");
    EXPECT_EQ(text.substr(0, text.find('\n')), "start_s\tend_s\tphone");
    EXPECT_NE(text.find("\tAH1\n"), std::string::npos);
    EXPECT_NE(text.find("\tER0\n"), std::string::npos);
    fs::remove_all(dir);
}

TEST(Labels, CheckPhoneSequenceFindsGapsAndEmptyPhones) {
    EXPECT_NO_THROW(check_phone_sequence({{"sil", 0, 0.1, false}, {"P", 0.1, 0.2, false}}, "x"));
    EXPECT_THROW(check_phone_sequence({{"sil", 0, 0.1, false}, {"P", 0.15, 0.2, false}}, "x"), InputError);
    EXPECT_THROW(check_phone_sequence({{"sil", 0, 0.1, false}, {"P", 0.1, 0.1, false}}, "x"), InputError);
    EXPECT_THROW(check_phone_sequence({{"XX", 0, 0.1, false}}, "x"), InputError);
}

}  // namespace
}  // namespace avsi
