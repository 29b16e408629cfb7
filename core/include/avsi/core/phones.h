// The project phone set (ARPAbet with stress on vowels, silence `sil`, and
// the phones other languages add: YY for /yː/, RT for /ʈ/, …), the 17
// phonetic features of the reference study (Beskow, §4.4), timed phone
// sequences, and mappings from espeak-ng mnemonics, MFA-style IPA and
// Festival's US English phone set.
// The data are languages as data, one folder per language under
// protocols/languages/<lang>/ (phones.tsv, phone_map.tsv; documented in
// protocols/languages/README.md). English (`en`) holds the ARPAbet set and
// every label-set mapping; another language's folder lists every phone its
// voice uses (a phone shared with English has English's features, checked)
// and its espeak-ng mnemonics.
#pragma once

#include <array>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace avsi {

// One timed phone. `symbol` is an ARPAbet base symbol in upper case ("AA",
// "P") or "sil"; vowels carry stress in `stressed` (on disk as AA1 / AA0).
struct Phone {
    std::string symbol;
    double start_s = 0.0;
    double end_s = 0.0;
    bool stressed = false;

    double duration_s() const { return end_s - start_s; }
    double centre_s() const { return 0.5 * (start_s + end_s); }
    bool operator==(const Phone&) const = default;
};

using PhoneSequence = std::vector<Phone>;

// The phone's written form: vowels get a stress digit (AA1, AA0), others as is.
std::string phone_label(const Phone& phone, bool is_vowel);

// The 17 features in the study's order. Binary features are 0/1; the four
// vowel features are 3-valued (0, 0.5, 1); stress is 0/1.
enum class Feature : int {
    Vowel = 0,  // consonant (0) / vowel (1)
    Bilabial, Labiodental, Dental, Retroflex, Alveolar, Velar,
    Nasal, Fricative, Stop, Release, Voiced,
    Open, Front, Rounded, Protruded,
    Stress,
    Count
};
inline constexpr std::size_t feature_count = static_cast<std::size_t>(Feature::Count);
static_assert(feature_count == 17);
using FeatureVector = std::array<float, feature_count>;

// The feature names as written in the inventory file header.
const std::array<std::string_view, feature_count>& feature_names();

enum class PhoneClass { Silence, Vowel, Consonant };

struct PhoneInfo {
    std::string symbol;      // ARPAbet base symbol or "sil"
    PhoneClass phone_class = PhoneClass::Consonant;
    std::string ipa;         // primary IPA symbol
    std::string example;     // an example word
    FeatureVector features{};  // Stress is 0 here; set per Phone by features_of()
    std::string language;    // the language table that first defined it ("en", "sv")
    // The viseme class in the MPEG-4 set (protocols/visemes/mpeg4_14.json) and
    // in avsi's 17 (avsi_17.json), as a language table writes it; English's
    // phones are classed by those files themselves (empty here).
    std::string mpeg4_viseme;
    std::string avsi17_viseme;
};

// The project phone set, read from the language tables (English's phones.tsv
// with mappings from espeak-ng phoneme mnemonics, IPA and Festival phones in
// its phone_map.tsv; each other language's phones and espeak-ng mnemonics).
class PhoneInventory {
public:
    // The inventory shipped in protocols/languages/ (loaded once): English
    // and every other language folder.
    static const PhoneInventory& builtin();
    // Loads an inventory and its mapping table; throws InputError naming file:line.
    static PhoneInventory load(const std::filesystem::path& phones_tsv,
                               const std::filesystem::path& map_tsv);
    // Loads languages/en/ and then every other folder of `languages_dir`
    // (sorted) with add_language.
    static PhoneInventory load_languages(const std::filesystem::path& languages_dir);
    // Adds a language's table: its phones (the English columns plus
    // mpeg4_viseme and avsi17_viseme), new ones joining the project set and
    // shared ones checked against their first definition, and its espeak-ng
    // mnemonics (`espeak` rows, stress marks included). Throws InputError
    // naming file:line and field.
    void add_language(const std::string& code, const std::filesystem::path& phones_tsv,
                      const std::filesystem::path& map_tsv);

    // The language codes with a table ("de", "en", "sv"), sorted.
    std::vector<std::string> languages() const;
    bool has_language(std::string_view code) const;
    // The phones a language uses (English: its whole table), in table order.
    // Throws InputError (field "language") for a language without a table.
    const std::vector<std::string>& language_phones(std::string_view code) const;
    // Among the phones `has` accepts, the one nearest `symbol` by its 17
    // features (squared distance; ties: the first in the project set's
    // order), for starting a model's entry for a phone it lacks; "" if none.
    std::string nearest_by_features(std::string_view symbol,
                                    const std::function<bool(const std::string&)>& has) const;
    // A language's within-word sequence rules (`sequence` rows of its
    // phone_map.tsv): two phones in a row of one word that are one phone
    // ("RR T" -> "RT", Central Swedish retroflexion). Empty for English.
    struct SequenceRule {
        std::string first, second, result;
    };
    const std::vector<SequenceRule>& sequence_rules(std::string_view code) const;
    // The phone table of a language, for messages ("protocols/languages/sv/phone_map.tsv").
    std::string language_map_path(std::string_view code) const;

    bool contains(std::string_view symbol) const;
    // Throws InputError (path/where, field "phone") if the symbol is unknown.
    const PhoneInfo& info(std::string_view symbol, std::string_view where = {}) const;
    const std::vector<PhoneInfo>& phones() const { return m_phones; }
    bool is_vowel(std::string_view symbol) const;

    // The 17 features of a timed phone (the Stress feature from phone.stressed).
    FeatureVector features_of(const Phone& phone) const;

    // Parses a written phone label ("AA1", "aa0", "P", "sil", "sp") into a
    // base symbol and stress; throws InputError naming `where` if unknown.
    Phone parse_label(std::string_view label, std::string_view where) const;

    // Maps one espeak-ng phoneme mnemonic (as reported in its phoneme events)
    // to one or more project phones (none for internal markers such as ":");
    // leading stress marks ("'V", ",aU") set the vowel stress. `variant` picks
    // table-specific rows ("en" for the non-rhotic English tables) before the
    // shared ones; another language's code ("sv", "de") uses that language's
    // table alone. Throws InputError naming the mnemonic and the table if it
    // has no mapping.
    std::vector<Phone> from_espeak(std::string_view mnemonic, std::string_view where,
                                   std::string_view variant = {}) const;
    // Splits leading espeak-ng stress marks off a mnemonic: ("'V") -> ("V", true),
    // ("%@") -> ("@", false), ("k") -> ("k", nullopt).
    // `variant` as for from_espeak.
    std::pair<std::string, std::optional<bool>> split_espeak_stress(std::string_view mnemonic,
                                                                    std::string_view variant = {}) const;
    // Maps one IPA phone label as the Montreal Forced Aligner's English models
    // write it ("ɑː", "tʃ", "ɹ", "spn", "") to project phones. A leading ˈ or ˌ
    // marks the vowel stressed; a label not in the table is retried without
    // trailing modifiers (tʰ -> t, kʷ -> k, d̪ -> d). Throws InputError naming
    // the label and `where` if it has no mapping.
    std::vector<Phone> from_ipa(std::string_view ipa, std::string_view where) const;
    // Maps one phone of Festival's US English phone set (radio: "k", "ax",
    // "el", "pau") to project phones; `stressed` is the stress of its syllable
    // and applies to a mapped vowel without a digit. Throws InputError naming
    // the phone and `where` if it has no mapping.
    std::vector<Phone> from_festival(std::string_view name, bool stressed, std::string_view where) const;
    // Maps one symbol of TIMIT's 61-phone set ("ix", "bcl", "h#"; rows
    // `timit`) or of MOCHA-TIMIT's label set ("@@", "ii", "breath"; rows
    // `mocha`) to project phones (none for "q"). Throws InputError naming the
    // symbol and `where` if it has no mapping.
    std::vector<Phone> from_timit(std::string_view symbol, std::string_view where) const;
    std::vector<Phone> from_mocha(std::string_view symbol, std::string_view where) const;
    // True if `ipa` (after the fallbacks above) has a mapping.
    bool knows_ipa(std::string_view ipa) const;

private:
    using Table = std::map<std::string, std::vector<std::string>, std::less<>>;
    // A language's own mapping table (every language but English).
    struct LanguageTable {
        std::string map_path;
        std::vector<std::string> phones;
        Table espeak;
        std::map<std::string, bool, std::less<>> espeak_stress;
        std::vector<SequenceRule> sequences;
    };
    const LanguageTable* language_table(std::string_view code) const;
    void read_language_phones(const std::string& code, const std::filesystem::path& phones_tsv,
                              LanguageTable& table);
    void read_language_map(const std::string& code, const std::filesystem::path& map_tsv,
                           LanguageTable& table);

    std::vector<PhoneInfo> m_phones;
    std::vector<std::string> m_english_phones;
    std::map<std::string, LanguageTable, std::less<>> m_languages;
    std::map<std::string, std::size_t, std::less<>> m_index;
    // Mapping targets as written in the table ("AH0", "AY", "-" for none).
    std::map<std::string, std::vector<std::string>, std::less<>> m_espeak;
    std::map<std::string, std::vector<std::string>, std::less<>> m_espeak_en;
    std::map<std::string, std::vector<std::string>, std::less<>> m_ipa;
    std::map<std::string, std::vector<std::string>, std::less<>> m_festival;
    std::map<std::string, std::vector<std::string>, std::less<>> m_timit;
    std::map<std::string, std::vector<std::string>, std::less<>> m_mocha;
    std::map<std::string, bool, std::less<>> m_espeak_stress;  // mark -> stressed
};

}  // namespace avsi
