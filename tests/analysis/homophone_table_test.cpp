// The homophone tables against the project's pronunciation source,
// espeak-ng (the library core/tts.cpp links): every pair of the General
// American table (protocols/homophones.csv) has the same en-us phonemes once
// stress marks are removed, every pair of the RP table (homophones-rp.csv)
// the same en-gb-x-rp phonemes. Each table's header states its source and
// criteria. Known non-homophones of GA (cot–caught, non-rhotic pairs,
// been/bean, what/watt) must differ under en-us, which shows the check can
// fail, and must not be in the GA table.
#include <espeak-ng/speak_lib.h>

#include <mutex>
#include <set>

#include <gtest/gtest.h>

#include "avsi/analysis/scoring.h"
#include "avsi/analysis/text_normalize.h"
#include "avsi/core/csv.h"
#include "avsi/core/files.h"
#include "avsi/core/text.h"

namespace avsi::analysis {
namespace {

std::mutex g_espeak_mutex;
bool g_espeak_initialised = false;
std::string g_espeak_voice;  // the voice selected last (selecting one allocates)

// Releases espeak-ng's buffers when the test program ends (for LeakSanitizer).
class EspeakEnvironment : public ::testing::Environment {
public:
    void TearDown() override {
        std::lock_guard lock(g_espeak_mutex);
        if (g_espeak_initialised) espeak_Terminate();
        g_espeak_initialised = false;
        g_espeak_voice.clear();
    }
};
[[maybe_unused]] ::testing::Environment* const g_espeak_environment =
    ::testing::AddGlobalTestEnvironment(new EspeakEnvironment);

// IPA of one word under `voice`, stress marks (ˈ ˌ) and spaces removed.
std::string phonemes(const std::string& word, const std::string& voice) {
    std::lock_guard lock(g_espeak_mutex);
    bool& initialised = g_espeak_initialised;
    if (!initialised) {
        const int rate = espeak_Initialize(AUDIO_OUTPUT_SYNCHRONOUS, 0, nullptr, espeakINITIALIZE_DONT_EXIT);
        if (rate <= 0) return "";
        initialised = true;
    }
    if (voice != g_espeak_voice) {
        if (espeak_SetVoiceByName(voice.c_str()) != EE_OK) return "";
        g_espeak_voice = voice;
    }
    std::string out;
    const void* pointer = word.c_str();
    while (pointer) {
        const char* ipa = espeak_TextToPhonemes(&pointer, espeakCHARS_UTF8, espeakPHONEMES_IPA);
        if (!ipa) break;
        out += ipa;
    }
    for (const std::string mark : {"ˈ", "ˌ", " ", "\n"}) {
        std::size_t at;
        while ((at = out.find(mark)) != std::string::npos) out.erase(at, mark.size());
    }
    return out;
}

// The one normalised word of `word` in `language`.
std::string normalize_text_for(const std::string& word, const std::string& language) {
    const auto words = normalize_words(word, language);
    return words.empty() ? "" : words.front();
}

// GA's NORTH–FORCE (horse–hoarse) merger: espeak-ng's en-us keeps a FORCE
// vowel [oː] before r; the table's rows marked en-us+north-force use it.
std::string north_force(std::string ipa) {
    std::size_t at;
    while ((at = ipa.find("oːɹ")) != std::string::npos) ipa.replace(at, std::string("oː").size(), "ɔː");
    return ipa;
}

struct Group {
    std::vector<std::string> words;
    std::string basis;
    int line = 0;
};

std::vector<Group> groups(const std::string& file) {
    const CsvTable t = read_csv(std::filesystem::path(AVSI_PROTOCOLS_DIR) / file);
    std::vector<Group> out;
    for (const auto& r : t.rows) {
        Group g;
        g.line = r.line;
        g.basis = trim(r.fields[t.require_column("basis")]);
        std::string part;
        for (char c : r.fields[t.require_column("words")] + "|") {
            if (c == '|') {
                g.words.push_back(trim(part));
                part.clear();
            } else {
                part += c;
            }
        }
        out.push_back(std::move(g));
    }
    return out;
}

std::string header_of(const std::string& file) {
    const std::string text = read_text_file(std::filesystem::path(AVSI_PROTOCOLS_DIR) / file);
    std::string header;
    std::size_t i = 0;
    while (i < text.size() && text[i] == '#') {
        const std::size_t end = text.find('\n', i);
        header += text.substr(i, end - i) + "\n";
        i = end + 1;
    }
    return header;
}

TEST(HomophoneTable, GeneralAmericanPairsHaveIdenticalEnUsPhonemes) {
    ASSERT_FALSE(phonemes("bear", "en-us").empty()) << "espeak-ng (espeak-ng-data) is not usable";
    const auto table = groups("homophones.csv");
    ASSERT_GT(table.size(), 300u);
    std::size_t pairs = 0;
    for (const auto& g : table) {
        ASSERT_TRUE(g.basis == "en-us" || g.basis == "en-us+north-force") << "line " << g.line << ": " << g.basis;
        bool merger_used = false;
        for (std::size_t i = 1; i < g.words.size(); ++i, ++pairs) {
            std::string a = phonemes(g.words[0], "en-us"), b = phonemes(g.words[i], "en-us");
            if (g.basis == "en-us+north-force") {
                merger_used = merger_used || a != b;
                a = north_force(a);
                b = north_force(b);
            }
            EXPECT_EQ(a, b) << "homophones.csv:" << g.line << ": " << g.words[0] << " /" << a << "/ vs "
                            << g.words[i] << " /" << b << "/";
        }
        if (g.basis == "en-us+north-force") {
            EXPECT_TRUE(merger_used) << "homophones.csv:" << g.line << ": marked en-us+north-force needlessly";
        }
    }
    EXPECT_GT(pairs, 350u);
}

TEST(HomophoneTable, RpPairsHaveIdenticalRpPhonemes) {
    ASSERT_FALSE(phonemes("bear", "en-gb-x-rp").empty()) << "espeak-ng voice en-gb-x-rp is not usable";
    const auto table = groups("homophones-rp.csv");
    ASSERT_GT(table.size(), 300u);
    for (const auto& g : table) {
        EXPECT_EQ(g.basis, "en-gb-x-rp") << "line " << g.line;
        for (std::size_t i = 1; i < g.words.size(); ++i)
            EXPECT_EQ(phonemes(g.words[0], "en-gb-x-rp"), phonemes(g.words[i], "en-gb-x-rp"))
                << "homophones-rp.csv:" << g.line << ": " << g.words[0] << " / " << g.words[i];
    }
}

TEST(HomophoneTable, NonHomophonesOfGeneralAmericanDifferAndAreNotListed) {
    // cot–caught, non-rhotic, been/bean, what/watt, Mary–marry–merry.
    const std::vector<std::pair<std::string, std::string>> not_ga = {
        {"cot", "caught"}, {"don", "dawn"},   {"father", "farther"}, {"saw", "sore"},  {"caught", "court"},
        {"been", "bean"},  {"what", "watt"},  {"marry", "merry"},    {"pause", "pours"}, {"lava", "larva"}};
    const WordGroups ga = WordGroups::read(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "homophones.csv");
    for (const auto& [a, b] : not_ga) {
        EXPECT_NE(north_force(phonemes(a, "en-us")), north_force(phonemes(b, "en-us"))) << a << " / " << b;
        EXPECT_FALSE(ga.same_group(a, b)) << a << " / " << b << " is in the GA table";
    }
    // The RP table has the non-rhotic pairs the GA table must not.
    const WordGroups rp = WordGroups::read(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "homophones-rp.csv");
    EXPECT_TRUE(rp.same_group("saw", "sore"));
    EXPECT_TRUE(rp.same_group("been", "bean"));
    EXPECT_TRUE(rp.same_group("father", "farther"));
    EXPECT_FALSE(rp.same_group("cot", "caught"));
}

// The Swedish and German tables against espeak-ng's sv and de voices, and
// pairs of each language that are not homophones (vowel length, long e/ä,
// ß after a long vowel) against the same voices, so the check can fail.
void expect_language_table(const std::string& language, const std::vector<std::pair<std::string, std::string>>& not_homophones) {
    const std::string file = "languages/" + language + "/scoring/homophones.csv";
    ASSERT_FALSE(phonemes("hus", language).empty()) << "espeak-ng voice " << language << " is not usable";
    const auto table = groups(file);
    ASSERT_GE(table.size(), 10u);
    for (const auto& g : table) {
        EXPECT_EQ(g.basis, language) << file << ":" << g.line;
        for (std::size_t i = 1; i < g.words.size(); ++i)
            EXPECT_EQ(phonemes(g.words[0], language), phonemes(g.words[i], language))
                << file << ":" << g.line << ": " << g.words[0] << " / " << g.words[i];
    }
    const WordGroups groups_read = WordGroups::read(std::filesystem::path(AVSI_PROTOCOLS_DIR) / file, language);
    for (const auto& [a, b] : not_homophones) {
        EXPECT_NE(phonemes(a, language), phonemes(b, language)) << a << " / " << b;
        EXPECT_FALSE(groups_read.same_group(normalize_text_for(a, language), normalize_text_for(b, language)))
            << a << " / " << b << " is in " << file;
    }
    EXPECT_NE(header_of(file).find("Source:"), std::string::npos);
    EXPECT_NE(header_of(file).find("espeak-ng"), std::string::npos);
}

TEST(HomophoneTable, SwedishPairsHaveIdenticalSvPhonemes) {
    expect_language_table("sv", {{"vet", "vett"}, {"hel", "häl"}, {"gjorde", "jorde"}, {"kärna", "gärna"}});
}

TEST(HomophoneTable, GermanPairsHaveIdenticalDePhonemes) {
    expect_language_table("de", {{"Masse", "Maße"}, {"Ferse", "Verse"}, {"schon", "schön"}});
}

TEST(HomophoneTable, HeadersStateSourceAndCriteria) {
    for (const char* file : {"homophones.csv", "homophones-rp.csv"}) {
        const std::string h = header_of(file);
        SCOPED_TRACE(file);
        EXPECT_NE(h.find("Source:"), std::string::npos);
        EXPECT_NE(h.find("espeak-ng"), std::string::npos);
        EXPECT_NE(h.find("Criteria"), std::string::npos);
    }
    EXPECT_NE(header_of("homophones.csv").find("General American"), std::string::npos);
    EXPECT_NE(header_of("homophones-rp.csv").find("Received Pronunciation"), std::string::npos);
}

}  // namespace
}  // namespace avsi::analysis
