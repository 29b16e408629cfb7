// Languages as data (protocols/languages/<lang>/): the Swedish and German
// phone tables join the project phone set with English's features for
// shared phones, their viseme classes agree with the viseme sets, their
// espeak-ng tables cover every mnemonic of the voice's phoneme table (read
// independently from espeak-ng-data/phontab), and real sentences through the
// sv and de voices give only phones of the language's table.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "avsi/core/phones.h"
#include "avsi/core/protocol.h"
#include "avsi/core/tts.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

namespace fs = std::filesystem;

const PhoneInventory& inv() { return PhoneInventory::builtin(); }

float feature(const std::string& symbol, Feature f) {
    return inv().features_of(Phone{symbol, 0.0, 0.1, false})[static_cast<std::size_t>(f)];
}

std::vector<std::string> labels(const std::vector<Phone>& phones) {
    std::vector<std::string> out;
    for (const auto& p : phones) out.push_back(phone_label(p, inv().is_vowel(p.symbol)));
    return out;
}

TEST(Languages, EnglishSwedishAndGermanHaveTables) {
    EXPECT_EQ(inv().languages(), (std::vector<std::string>{"de", "en", "sv"}));
    EXPECT_EQ(inv().language_phones("en").size(), 40u);  // CMUdict's 39 and sil
    EXPECT_FALSE(inv().has_language("fr"));
    try {
        (void)inv().language_phones("fr");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().field, "language");
        EXPECT_NE(std::string(e.what()).find("protocols/languages/fr/"), std::string::npos) << e.what();
    }
}

TEST(Languages, SwedishCloseFrontVowelsAreThreeWayInTheFeatures) {
    // Beskow §4.4's separate rounded and protruded features: spread /iː/,
    // outrounded /yː/, inrounded /ʉː/.
    EXPECT_EQ(feature("IY", Feature::Rounded), 0.0f);
    EXPECT_EQ(feature("IY", Feature::Protruded), 0.0f);
    EXPECT_EQ(feature("YY", Feature::Rounded), 1.0f);
    EXPECT_EQ(feature("YY", Feature::Protruded), 1.0f);
    EXPECT_EQ(feature("UX", Feature::Rounded), 1.0f);
    EXPECT_EQ(feature("UX", Feature::Protruded), 0.0f);
    for (const char* s : {"YY", "UX", "IY"}) EXPECT_EQ(feature(s, Feature::Open), 0.0f) << s;
    EXPECT_EQ(feature("YY", Feature::Front), 1.0f);
    EXPECT_EQ(feature("UX", Feature::Front), 0.5f);
    for (const char* s : {"RT", "RD", "RN", "RS", "RL"}) EXPECT_EQ(feature(s, Feature::Retroflex), 1.0f) << s;
    EXPECT_EQ(feature("RT", Feature::Stop), 1.0f);
    EXPECT_EQ(feature("RD", Feature::Voiced), 1.0f);
    EXPECT_EQ(feature("RN", Feature::Nasal), 1.0f);
    EXPECT_EQ(feature("RS", Feature::Fricative), 1.0f);
    EXPECT_EQ(feature("SJ", Feature::Protruded), 1.0f);
    EXPECT_EQ(feature("TJ", Feature::Protruded), 0.0f);
    EXPECT_EQ(feature("ICH", Feature::Front), 1.0f);
    EXPECT_EQ(feature("ACH", Feature::Velar), 1.0f);
    EXPECT_EQ(inv().info("UX").language, "sv");
    EXPECT_EQ(inv().info("P").language, "en");
}

// The viseme sets' class of every English phone, by set.
std::map<std::string, std::map<std::string, std::string>> viseme_classes() {
    std::map<std::string, std::map<std::string, std::string>> out;
    for (const char* set : {"mpeg4_14", "avsi_17"}) {
        const auto root = read_json_file(fs::path(AVSI_PROTOCOLS_DIR) / "visemes" / (std::string(set) + ".json"));
        for (const auto& v : root["visemes"])
            for (const auto& p : v["phones"]) out[set][p.get<std::string>()] = v["name"].get<std::string>();
    }
    return out;
}

TEST(Languages, SharedPhonesKeepEnglishVisemeClassesAndNewOnesNameRealClasses) {
    const auto classes = viseme_classes();
    std::set<std::string> mpeg4_names, avsi17_names;
    for (const auto& [p, name] : classes.at("mpeg4_14")) mpeg4_names.insert(name);
    for (const auto& [p, name] : classes.at("avsi_17")) avsi17_names.insert(name);
    for (const char* language : {"sv", "de"}) {
        for (const auto& symbol : inv().language_phones(language)) {
            SCOPED_TRACE(std::string(language) + " " + symbol);
            const PhoneInfo& info = inv().info(symbol);
            EXPECT_TRUE(mpeg4_names.count(info.mpeg4_viseme)) << info.mpeg4_viseme;
            EXPECT_TRUE(avsi17_names.count(info.avsi17_viseme)) << info.avsi17_viseme;
            if (info.language != "en") continue;
            EXPECT_EQ(info.mpeg4_viseme, classes.at("mpeg4_14").at(symbol));
            EXPECT_EQ(info.avsi17_viseme, classes.at("avsi_17").at(symbol));
        }
    }
}

// The mnemonics of a phoneme table and of the tables it inherits, read from
// espeak-ng's compiled phontab (synthdata.c's layout: a count, then per table
// its phoneme count, parent index, 32-byte name and 16-byte PHONEME_TAB
// entries whose first 4 bytes are the mnemonic).
std::set<std::string> phontab_mnemonics(const std::string& table) {
    const std::string data = read_text_file("/usr/lib/x86_64-linux-gnu/espeak-ng-data/phontab");
    struct Table {
        std::string name;
        int parent = 0;  // 1-based; 0 none
        std::vector<std::string> mnemonics;
    };
    std::vector<Table> tables;
    std::size_t p = 4;
    const int count = static_cast<unsigned char>(data.at(0));
    for (int t = 0; t < count; ++t) {
        Table tab;
        const int n = static_cast<unsigned char>(data.at(p));
        tab.parent = static_cast<unsigned char>(data.at(p + 1));
        p += 4;
        tab.name = std::string(data.c_str() + p);
        p += 32;
        for (int k = 0; k < n; ++k, p += 16) {
            std::string m(data.substr(p, 4).c_str());
            if (!m.empty() && static_cast<unsigned char>(m.back()) >= 0x20) tab.mnemonics.push_back(m);
        }
        tables.push_back(std::move(tab));
    }
    std::set<std::string> out;
    for (std::size_t t = 0; t < tables.size(); ++t) {
        if (tables[t].name != table) continue;
        for (std::size_t u = t + 1; u > 0; u = static_cast<std::size_t>(tables[u - 1].parent))
            out.insert(tables[u - 1].mnemonics.begin(), tables[u - 1].mnemonics.end());
    }
    return out;
}

TEST(Languages, EveryMnemonicOfTheVoicesPhonemeTablesIsMapped) {
    for (const char* language : {"sv", "de"}) {
        const auto mnemonics = phontab_mnemonics(language);
        ASSERT_GT(mnemonics.size(), 100u) << language;
        for (const auto& m : mnemonics) {
            if (m.find_first_of("'%,=") == 0 && inv().split_espeak_stress(m + "a", language).second) continue;
            EXPECT_NO_THROW((void)inv().from_espeak(m, "coverage", language)) << language << " " << m;
        }
    }
}

TEST(Languages, SwedishAndGermanMnemonicsMapToTheirPhones) {
    EXPECT_EQ(labels(inv().from_espeak("'y:", "t", "sv")), std::vector<std::string>{"YY1"});
    EXPECT_EQ(labels(inv().from_espeak("u-", "t", "sv")), std::vector<std::string>{"UX0"});
    EXPECT_EQ(labels(inv().from_espeak("'i:", "t", "sv")), std::vector<std::string>{"IY1"});
    EXPECT_EQ(labels(inv().from_espeak("8", "t", "sv")), std::vector<std::string>{"OX0"});
    EXPECT_EQ(labels(inv().from_espeak("sx", "t", "sv")), std::vector<std::string>{"SJ"});
    EXPECT_EQ(labels(inv().from_espeak("r", "t", "sv")), std::vector<std::string>{"RR"});
    EXPECT_EQ(labels(inv().from_espeak("r", "t", "de")), std::vector<std::string>{"RU"});
    EXPECT_EQ(labels(inv().from_espeak("pF", "t", "de")), (std::vector<std::string>{"P", "F"}));
    EXPECT_EQ(labels(inv().from_espeak("ts", "t", "de")), (std::vector<std::string>{"T", "S"}));
    EXPECT_EQ(labels(inv().from_espeak("'y", "t", "de")), std::vector<std::string>{"YH1"});
    EXPECT_TRUE(inv().from_espeak("?", "t", "de").empty());
    // English keeps its own table: the same mnemonic means another phone.
    EXPECT_EQ(labels(inv().from_espeak("r", "t")), std::vector<std::string>{"R"});
}

TEST(Languages, UnknownMnemonicNamesTheLanguageTable) {
    try {
        (void)inv().from_espeak("Zq", "text \"x\" (espeak-ng voice sv)", "sv");
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("\"Zq\""), std::string::npos) << what;
        EXPECT_NE(what.find("language sv"), std::string::npos) << what;
        EXPECT_NE(what.find("protocols/languages/sv/phone_map.tsv"), std::string::npos) << what;
    }
}

// A language table in a temporary folder beside a copy of English's.
fs::path language_fixture(const std::string& name, const std::string& phones_rows, const std::string& map_rows) {
    const fs::path dir = test::temp_dir(name);
    const fs::path en = fs::path(AVSI_PROTOCOLS_DIR) / "languages" / "en";
    fs::create_directories(dir / "en");
    fs::create_directories(dir / "xx");
    fs::copy_file(en / "phones.tsv", dir / "en" / "phones.tsv", fs::copy_options::overwrite_existing);
    fs::copy_file(en / "phone_map.tsv", dir / "en" / "phone_map.tsv", fs::copy_options::overwrite_existing);
    std::string header = "symbol\tclass\tipa\texample\tmpeg4_viseme\tavsi17_viseme";
    for (auto f : feature_names()) header += "\t" + std::string(f);
    write_text_file(dir / "xx" / "phones.tsv",
                    header + "\nsil\tsilence\t\t(pause)\tnone\tsil\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\n" +
                        phones_rows);
    write_text_file(dir / "xx" / "phone_map.tsv", "source\tsymbol\tphones\tnote\n" + map_rows);
    return dir;
}

TEST(Languages, ASharedPhoneWithOtherFeaturesIsRefusedNamingFileAndLine) {
    // P voiced: not English's /p/.
    const fs::path dir = language_fixture(
        "languages_features", "P\tconsonant\tp\txx p\tp_b_m\tp_b_m\t0\t1\t0\t0\t0\t0\t0\t0\t0\t1\t0\t1\t0\t0\t0\t0\t0\n",
        "espeak\tp\tP\tp\n");
    try {
        (void)PhoneInventory::load_languages(dir);
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 3);
        EXPECT_EQ(e.first().field, "symbol");
        EXPECT_NE(std::string(e.what()).find("other features than in the en table"), std::string::npos) << e.what();
    }
}

TEST(Languages, AMappingToAPhoneOutsideTheLanguagesTableIsRefused) {
    const fs::path dir = language_fixture("languages_map", "", "espeak\tp\tP\tp\n");
    try {
        (void)PhoneInventory::load_languages(dir);
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 2);
        EXPECT_EQ(e.first().field, "phones");
        EXPECT_NE(std::string(e.what()).find("\"P\" is not in the xx phone table"), std::string::npos) << e.what();
    }
}

TEST(Languages, ANewSymbolMustBeLettersWithoutAStressDigit) {
    const fs::path dir = language_fixture(
        "languages_symbol", "YY2\tvowel\ty\txx y\tU\tuw_uh\t1\t0\t0\t0\t0\t0\t0\t0\t0\t0\t0\t1\t0\t1\t1\t1\t0\n", "");
    try {
        (void)PhoneInventory::load_languages(dir);
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().line, 3);
        EXPECT_NE(std::string(e.what()).find("upper-case letters"), std::string::npos) << e.what();
    }
}

// Swedish prose written for this test (not the project's corpora): every
// retroflex, /ɕ ɧ/, the rounded vowels and long/short pairs.
const std::vector<std::string>& swedish_sentences() {
    static const std::vector<std::string> s = {
        "Stockholm är Sveriges huvudstad och ligger där Mälaren möter Östersjön.",
        "Sjuksköterskan skyndade sig till stationen för att hinna med tåget.",
        "Det tjocka köttet stektes länge i järnpannan.",
        "Hon köpte sju skjortor och en kjol på rean i lördags.",
        "Kortet låg på bordet bredvid den gamla lampan.",
        "Barnen byggde en stor snögubbe på gården efter skolan.",
        "Fyra fina fåglar flög över den frusna sjön i gryningen.",
        "Hunden sprang ut genom dörren och försvann i skogen.",
        "Syster Ylva tyckte om att sy kläder av ull.",
        "Kyrkan i byn byggdes av gråsten på tolvhundratalet.",
        "Hyran för lägenheten höjdes med sju procent i år.",
        "Mannen hade ett rött skägg och bar en grön hatt.",
        "Flickan i den korta kjolen sprang bort med pärlor och ett kors.",
    };
    return s;
}

const std::vector<std::string>& german_sentences() {
    static const std::vector<std::string> s = {
        "Ich möchte heute Abend ein Buch über Geschichte lesen.",
        "Die Kinder spielten fröhlich im Garten hinter dem Haus.",
        "Zwölf Boxkämpfer jagen Viktor quer über den großen Sylter Deich.",
        "Die Pflanzen brauchen Wasser, Licht und Wärme.",
        "Der Pfarrer predigte über Glück und Nächstenliebe.",
        "Ein Eichhörnchen sammelte Nüsse für den Winter.",
        "Öl und Essig gehören in einen guten Salat.",
        "Frau Müller trinkt gern heißen Kaffee mit Milch.",
        "Die Schüler lernten ein Gedicht von Goethe auswendig.",
        "Der Koch macht eine Suppe mit frischem Gemüse.",
    };
    return s;
}

std::set<std::string> spoken_phones(const std::string& voice, const std::vector<std::string>& sentences) {
    TtsSettings settings;
    set_tts_voice(settings, "espeak:" + voice);
    std::set<std::string> seen;
    for (const auto& text : sentences)
        for (const auto& p : synthesize_speech(text, settings).phones) seen.insert(p.symbol);
    return seen;
}

TEST(Languages, SwedishVoiceGivesOnlySwedishPhonesWithItsContrasts) {
    const auto seen = spoken_phones("sv", swedish_sentences());
    const auto& table = inv().language_phones("sv");
    const std::set<std::string> allowed(table.begin(), table.end());
    for (const auto& s : seen) EXPECT_TRUE(allowed.count(s)) << s;
    for (const char* want : {"IY", "YY", "YH", "UX", "OX", "EU", "OE", "AA", "A", "RR", "RT", "RD", "RN", "RS", "RL",
                             "TJ", "SJ"})
        EXPECT_TRUE(seen.count(want)) << want;
}

TEST(Languages, GermanVoiceGivesOnlyGermanPhonesWithItsContrasts) {
    const auto seen = spoken_phones("de", german_sentences());
    const auto& table = inv().language_phones("de");
    const std::set<std::string> allowed(table.begin(), table.end());
    for (const auto& s : seen) EXPECT_TRUE(allowed.count(s)) << s;
    for (const char* want : {"ICH", "ACH", "YY", "YH", "EU", "OE", "RU", "A"}) EXPECT_TRUE(seen.count(want)) << want;
}

TEST(Languages, TheVoiceNamesTheProtocolLanguage) {
    TtsSettings s;
    set_tts_voice(s, "espeak:sv");
    EXPECT_EQ(tts_voice_language(s), "sv");
    set_tts_voice(s, "espeak:en-gb-x-rp");
    EXPECT_EQ(tts_voice_language(s), "en");
    set_tts_voice(s, "festival:cmu_us_slt_arctic_hts");
    EXPECT_EQ(tts_voice_language(s), "en");
    set_tts_voice(s, "espeak:fr");
    EXPECT_EQ(tts_voice_language(s), "");
}

TEST(Languages, AVoiceWithoutATableIsRefusedNamingTheFolder) {
    TtsSettings s;
    set_tts_voice(s, "espeak:fr");
    try {
        (void)synthesize_speech("Bonjour tout le monde.", s);
        FAIL() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().field, "voice");
        EXPECT_NE(std::string(e.what()).find("protocols/languages/fr/"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace avsi
