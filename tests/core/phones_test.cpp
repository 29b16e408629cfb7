// The phone inventory (protocols/languages/en/phones.tsv): phone set, 17 features (Beskow
// §4.4), label parsing, and the espeak-ng / MFA IPA mappings (phone_map.tsv).
#include "avsi/core/phones.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <set>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

const PhoneInventory& inv() { return PhoneInventory::builtin(); }

float feature(const std::string& symbol, Feature f, bool stressed = false) {
    return inv().features_of(Phone{symbol, 0.0, 0.1, stressed})[static_cast<std::size_t>(f)];
}

std::vector<std::string> labels(const std::vector<Phone>& phones) {
    std::vector<std::string> out;
    for (const auto& p : phones) out.push_back(phone_label(p, inv().is_vowel(p.symbol)));
    return out;
}

TEST(PhoneInventory, HoldsCmudictSetAndSilence) {
    const std::vector<std::string> vowels = {"AA", "AE", "AH", "AO", "AW", "AY", "EH", "ER",
                                             "EY", "IH", "IY", "OW", "OY", "UH", "UW"};
    const std::vector<std::string> consonants = {"B", "CH", "D",  "DH", "F", "G", "HH", "JH",
                                                 "K", "L",  "M",  "N",  "NG", "P", "R", "S",
                                                 "SH", "T", "TH", "V",  "W", "Y", "Z", "ZH"};
    EXPECT_EQ(inv().language_phones("en").size(), vowels.size() + consonants.size() + 1);
    for (const auto& v : vowels) EXPECT_TRUE(inv().is_vowel(v)) << v;
    for (const auto& c : consonants) {
        EXPECT_TRUE(inv().contains(c)) << c;
        EXPECT_FALSE(inv().is_vowel(c)) << c;
    }
    EXPECT_EQ(inv().info("sil").phone_class, PhoneClass::Silence);
    EXPECT_EQ(inv().info("TH").ipa, "θ");
    EXPECT_FALSE(inv().info("UW").example.empty());
}

TEST(PhoneInventory, FeaturesArePhoneticallyRight) {
    // Place.
    for (auto s : {"P", "B", "M"}) EXPECT_EQ(feature(s, Feature::Bilabial), 1.0f) << s;
    for (auto s : {"F", "V"}) EXPECT_EQ(feature(s, Feature::Labiodental), 1.0f) << s;
    for (auto s : {"TH", "DH"}) EXPECT_EQ(feature(s, Feature::Dental), 1.0f) << s;
    for (auto s : {"T", "D", "N", "S", "Z", "L"}) EXPECT_EQ(feature(s, Feature::Alveolar), 1.0f) << s;
    for (auto s : {"K", "G", "NG"}) EXPECT_EQ(feature(s, Feature::Velar), 1.0f) << s;
    EXPECT_EQ(feature("R", Feature::Retroflex), 1.0f);
    EXPECT_EQ(feature("P", Feature::Alveolar), 0.0f);
    // Manner and voicing.
    for (auto s : {"M", "N", "NG"}) EXPECT_EQ(feature(s, Feature::Nasal), 1.0f) << s;
    for (auto s : {"P", "B", "T", "D", "K", "G"}) {
        EXPECT_EQ(feature(s, Feature::Stop), 1.0f) << s;
        EXPECT_EQ(feature(s, Feature::Fricative), 0.0f) << s;
    }
    for (auto s : {"F", "V", "S", "Z", "SH", "ZH", "TH", "DH", "HH"})
        EXPECT_EQ(feature(s, Feature::Fricative), 1.0f) << s;
    for (auto s : {"CH", "JH"}) EXPECT_EQ(feature(s, Feature::Release), 1.0f) << s;
    for (auto pair : {std::pair{"P", "B"}, {"T", "D"}, {"K", "G"}, {"F", "V"}, {"S", "Z"}, {"CH", "JH"}}) {
        EXPECT_EQ(feature(pair.first, Feature::Voiced), 0.0f) << pair.first;
        EXPECT_EQ(feature(pair.second, Feature::Voiced), 1.0f) << pair.second;
    }
    // Vowel qualities: open/front/rounded/protruded.
    EXPECT_EQ(feature("AA", Feature::Open), 1.0f);
    EXPECT_EQ(feature("IY", Feature::Open), 0.0f);
    EXPECT_EQ(feature("IY", Feature::Front), 1.0f);
    EXPECT_EQ(feature("UW", Feature::Front), 0.0f);
    EXPECT_EQ(feature("AH", Feature::Open), 0.5f);
    EXPECT_EQ(feature("UW", Feature::Rounded), 1.0f);
    EXPECT_EQ(feature("UW", Feature::Protruded), 1.0f);
    EXPECT_EQ(feature("IY", Feature::Rounded), 0.0f);
    EXPECT_EQ(feature("W", Feature::Rounded), 1.0f);
    EXPECT_EQ(feature("SH", Feature::Protruded), 1.0f);
    for (const auto& p : inv().phones()) {
        const auto f = inv().features_of(Phone{p.symbol, 0, 1, false});
        EXPECT_EQ(f[0], p.phone_class == PhoneClass::Vowel ? 1.0f : 0.0f) << p.symbol;
        if (p.phone_class == PhoneClass::Vowel) {
            EXPECT_EQ(f[static_cast<int>(Feature::Voiced)], 1.0f) << p.symbol;
        }
    }
    const auto sil = inv().features_of(Phone{"sil", 0, 1, false});
    for (float v : sil) EXPECT_EQ(v, 0.0f);
}

TEST(PhoneInventory, ConsonantFeatureVectorsAreUnique) {
    std::set<FeatureVector> seen;
    for (const auto& p : inv().phones()) {
        if (p.phone_class == PhoneClass::Vowel) continue;
        EXPECT_TRUE(seen.insert(p.features).second) << p.symbol << " shares its features";
    }
}

TEST(PhoneInventory, StressIsPerTokenAndOnlyOnVowels) {
    EXPECT_EQ(feature("AA", Feature::Stress, true), 1.0f);
    EXPECT_EQ(feature("AA", Feature::Stress, false), 0.0f);
    EXPECT_EQ(feature("P", Feature::Stress, true), 0.0f);
    EXPECT_EQ(feature_names()[16], "stress");
    EXPECT_EQ(feature_names()[0], "vowel");
}

TEST(PhoneInventory, ParsesWrittenLabels) {
    EXPECT_EQ(inv().parse_label("AA1", "x"), (Phone{"AA", 0, 0, true}));
    EXPECT_EQ(inv().parse_label("aa0", "x"), (Phone{"AA", 0, 0, false}));
    EXPECT_EQ(inv().parse_label("ER2", "x"), (Phone{"ER", 0, 0, true}));
    EXPECT_EQ(inv().parse_label("P", "x").symbol, "P");
    EXPECT_EQ(inv().parse_label("sil", "x").symbol, "sil");
    EXPECT_EQ(inv().parse_label("SP", "x").symbol, "sil");
    EXPECT_EQ(inv().parse_label("", "x").symbol, "sil");
    EXPECT_EQ(phone_label(Phone{"AA", 0, 0, true}, true), "AA1");
    EXPECT_EQ(phone_label(Phone{"AA", 0, 0, false}, true), "AA0");
    EXPECT_EQ(phone_label(Phone{"P", 0, 0, false}, false), "P");
}

TEST(PhoneInventory, UnknownLabelNamesSymbolAndSource) {
    try {
        (void)inv().parse_label("AX1", "words.tsv");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().path, "words.tsv");
        EXPECT_NE(std::string(e.what()).find("\"AX1\""), std::string::npos) << e.what();
    }
    EXPECT_THROW((void)inv().parse_label("P1", "x"), InputError);  // consonants carry no stress
    EXPECT_THROW((void)inv().info("QQ", "x"), InputError);
}

TEST(PhoneMap, EspeakMnemonicsMapWithStress) {
    EXPECT_EQ(labels(inv().from_espeak("k", "t")), std::vector<std::string>{"K"});
    EXPECT_EQ(labels(inv().from_espeak("'V", "t")), std::vector<std::string>{"AH1"});
    EXPECT_EQ(labels(inv().from_espeak("V", "t")), std::vector<std::string>{"AH0"});
    EXPECT_EQ(labels(inv().from_espeak(",aU", "t")), std::vector<std::string>{"AW1"});
    EXPECT_EQ(labels(inv().from_espeak("%aU", "t")), std::vector<std::string>{"AW0"});
    EXPECT_EQ(labels(inv().from_espeak("'@", "t")), std::vector<std::string>{"AH0"});  // schwa never stressed
    EXPECT_EQ(labels(inv().from_espeak("'aI3", "t")), (std::vector<std::string>{"AY1", "ER0"}));
    EXPECT_EQ(labels(inv().from_espeak("dZ", "t")), std::vector<std::string>{"JH"});
    EXPECT_EQ(labels(inv().from_espeak("n-", "t")), (std::vector<std::string>{"AH0", "N"}));
    EXPECT_EQ(labels(inv().from_espeak("t#", "t")), std::vector<std::string>{"T"});
    EXPECT_EQ(labels(inv().from_espeak("?", "t")), std::vector<std::string>{"T"});
    EXPECT_EQ(labels(inv().from_espeak("_:", "t")), std::vector<std::string>{"sil"});
    EXPECT_TRUE(inv().from_espeak(":", "t").empty());
    // Rhotic (en-us, default) and non-rhotic (en) tables.
    EXPECT_EQ(labels(inv().from_espeak("'i@3", "t")), (std::vector<std::string>{"IH1", "R"}));
    EXPECT_EQ(labels(inv().from_espeak("'i@3", "t", "en")), (std::vector<std::string>{"IH1", "AH0"}));
    EXPECT_EQ(labels(inv().from_espeak("3", "t", "en")), std::vector<std::string>{"AH0"});
    EXPECT_EQ(labels(inv().from_espeak("k", "t", "en")), std::vector<std::string>{"K"});
}

TEST(PhoneMap, EveryEnglishEspeakMnemonicIsCovered) {
    // The mnemonics of espeak-ng 1.51's en and en-us phoneme tables (read from
    // espeak-ng-data/phontab) and the base consonants English rules produce.
    const std::vector<std::string> mnemonics = {
        "@", "@2", "@5", "@L", "@#", "3", "3:", "a", "a#", "a2", "aa", "A:", "A#", "A@", "A~",
        "E", "E#", "E2", "I", "I#", "I2", "I2#", "0", "0#", "02", "O2", "O", "O:", "O@", "o@",
        "O~", "V", "VR", "U", "U@", "u:", "i", "i:", "i@", "i@3", "IR", "aU", "aU@", "oU", "oU#",
        "aI", "aI@", "aI3", "eI", "OI", "e@", "o:", "e:", "e#", "a#2", "t#", "t2", "d#", "z#",
        "z/2", "w#", "r-", "r/", "?", "p", "b", "t", "d", "k", "g", "m", "n", "N", "f", "v", "T",
        "D", "s", "z", "S", "Z", "h", "tS", "dZ", "l", "r", "w", "j", "x", "n-", "m-", "l-",
        "_", "_:", "_!", "_|", ":", ";", "-"};
    for (const auto& m : mnemonics) {
        EXPECT_NO_THROW((void)inv().from_espeak(m, "coverage")) << m;
        EXPECT_NO_THROW((void)inv().from_espeak(m, "coverage", "en")) << m;
    }
}

TEST(PhoneMap, UnknownEspeakMnemonicNamesItAndTheSource) {
    try {
        (void)inv().from_espeak("Zq", "text \"x\" (espeak-ng voice en-us)");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("\"Zq\""), std::string::npos) << what;
        EXPECT_NE(what.find("espeak-ng voice en-us"), std::string::npos) << what;
    }
}

TEST(PhoneMap, MfaIpaLabelsMap) {
    // The phones of MFA's english_mfa / english_us_arpa IPA output.
    const std::vector<std::pair<std::string, std::vector<std::string>>> cases = {
        {"ɑ", {"AA0"}}, {"ɑː", {"AA0"}}, {"æ", {"AE0"}}, {"ʌ", {"AH1"}}, {"ə", {"AH0"}},
        {"ɚ", {"ER0"}}, {"ɝ", {"ER1"}}, {"ɔ", {"AO0"}}, {"aw", {"AW0"}}, {"aj", {"AY0"}},
        {"ɛ", {"EH0"}}, {"ej", {"EY0"}}, {"ɪ", {"IH0"}}, {"i", {"IY0"}}, {"iː", {"IY0"}},
        {"ow", {"OW0"}}, {"ɔj", {"OY0"}}, {"ʊ", {"UH0"}}, {"u", {"UW0"}}, {"uː", {"UW0"}},
        {"b", {"B"}}, {"d", {"D"}}, {"dʒ", {"JH"}}, {"ð", {"DH"}}, {"f", {"F"}}, {"ɡ", {"G"}},
        {"h", {"HH"}}, {"j", {"Y"}}, {"k", {"K"}}, {"l", {"L"}}, {"m", {"M"}}, {"n", {"N"}},
        {"ŋ", {"NG"}}, {"p", {"P"}}, {"ɹ", {"R"}}, {"s", {"S"}}, {"ʃ", {"SH"}}, {"t", {"T"}},
        {"tʃ", {"CH"}}, {"θ", {"TH"}}, {"v", {"V"}}, {"w", {"W"}}, {"z", {"Z"}}, {"ʒ", {"ZH"}},
        {"ɾ", {"T"}}, {"ʔ", {"T"}}, {"ɫ", {"L"}}, {"m̩", {"AH0", "M"}}, {"n̩", {"AH0", "N"}},
        {"l̩", {"AH0", "L"}}, {"spn", {"sil"}}, {"sil", {"sil"}}, {"", {"sil"}},
        // Fallbacks: modifiers dropped, stress marks honoured.
        {"tʰ", {"T"}}, {"kʷ", {"K"}}, {"pʲ", {"P"}}, {"d̪", {"D"}}, {"ˈɑ", {"AA1"}}, {"ˌow", {"OW1"}}};
    for (const auto& [ipa, want] : cases) {
        SCOPED_TRACE(ipa);
        EXPECT_EQ(labels(inv().from_ipa(ipa, "t")), want);
    }
}

TEST(PhoneMap, UnknownIpaNamesTheLabel) {
    try {
        (void)inv().from_ipa("ʘ", "align.TextGrid");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().path, "align.TextGrid");
        EXPECT_NE(std::string(e.what()).find("\"ʘ\""), std::string::npos) << e.what();
    }
    EXPECT_FALSE(inv().knows_ipa("ʘ"));
    EXPECT_TRUE(inv().knows_ipa("tʃ"));
}

TEST(PhoneInventoryLoad, MalformedTablesReportFileAndLine) {
    const fs::path dir = test::temp_dir("phones_test");
    const std::string header =
        "symbol\tclass\tipa\texample\tvowel\tbilabial\tlabiodental\tdental\tretroflex\talveolar\tvelar\t"
        "nasal\tfricative\tstop\trelease\tvoiced\topen\tfront\trounded\tprotruded\tstress\n";
    write_text_file(dir / "phones.tsv",
                    "# comment\n" + header +
                        "sil\tsilence\t\t-\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\n"
                        "P\tconsonant\tp\tpea\t0\t1\t0\t0\t0\t0\t0\t0\t0\t1\t0\t0.5\t0\t0\t0\t0\t0\n");
    write_text_file(dir / "map.tsv", "source\tsymbol\tphones\tnote\nespeak\tp\tP\tp\n");
    try {
        (void)PhoneInventory::load(dir / "phones.tsv", dir / "map.tsv");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 4);
        EXPECT_EQ(e.first().field, "voiced");
    }
    write_text_file(dir / "phones.tsv",
                    header + "sil\tsilence\t\t-\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\n");
    write_text_file(dir / "map.tsv", "source\tsymbol\tphones\tnote\nespeak\tp\tP\tp\n");
    try {
        (void)PhoneInventory::load(dir / "phones.tsv", dir / "map.tsv");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 2);
        EXPECT_NE(std::string(e.what()).find("\"P\""), std::string::npos) << e.what();
    }
    fs::remove_all(dir);
}

}  // namespace
}  // namespace avsi
