// The project phone set and its mappings, loaded from the language tables
// protocols/languages/<lang>/phones.tsv and phone_map.tsv. Features follow
// Beskow §4.4: consonant/vowel, six place features, five manner features,
// four 3-valued vowel features, stress.
#include "avsi/core/phones.h"

#include <algorithm>
#include <cctype>
#include <functional>
#include <mutex>
#include <set>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi {

namespace {

constexpr std::array<std::string_view, feature_count> k_feature_names = {
    "vowel",    "bilabial",  "labiodental", "dental", "retroflex", "alveolar",
    "velar",    "nasal",     "fricative",   "stop",   "release",   "voiced",
    "open",     "front",     "rounded",     "protruded", "stress"};

// One non-comment line of a tab-separated protocol file.
struct TsvLine {
    int line = 0;
    std::vector<std::string> fields;
};

// Splits a tab-separated file into lines of fields (no quoting: symbols such
// as `"` and `'` are data). Blank lines and lines starting with '#' are skipped.
std::vector<TsvLine> read_tsv_lines(const std::filesystem::path& path) {
    std::string text = read_text_file(path);
    if (text.size() >= 3 && text.compare(0, 3, "\xEF\xBB\xBF") == 0) text.erase(0, 3);
    std::vector<TsvLine> lines;
    int number = 0;
    std::size_t pos = 0;
    while (pos <= text.size()) {
        std::size_t end = text.find('\n', pos);
        if (end == std::string::npos) end = text.size();
        std::string line = text.substr(pos, end - pos);
        ++number;
        pos = end + 1;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (line.empty() || line[0] == '#') {
            if (end == text.size()) break;
            continue;
        }
        TsvLine parsed;
        parsed.line = number;
        std::size_t start = 0;
        for (;;) {
            const std::size_t tab = line.find('\t', start);
            parsed.fields.push_back(line.substr(start, tab == std::string::npos ? std::string::npos
                                                                                 : tab - start));
            if (tab == std::string::npos) break;
            start = tab + 1;
        }
        lines.push_back(std::move(parsed));
        if (end == text.size()) break;
    }
    return lines;
}

std::vector<std::string> split_spaces(std::string_view text) {
    std::vector<std::string> out;
    std::size_t i = 0;
    while (i < text.size()) {
        while (i < text.size() && text[i] == ' ') ++i;
        std::size_t j = i;
        while (j < text.size() && text[j] != ' ') ++j;
        if (j > i) out.emplace_back(text.substr(i, j - i));
        i = j;
    }
    return out;
}

std::string upper(std::string_view s) {
    std::string out(s);
    for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
    return out;
}

// Decodes the last code point of a UTF-8 string; returns {code point, byte length}.
std::pair<char32_t, std::size_t> last_code_point(std::string_view s) {
    std::size_t start = s.size();
    while (start > 0) {
        --start;
        const auto c = static_cast<unsigned char>(s[start]);
        if ((c & 0xC0) != 0x80) break;
    }
    const std::size_t len = s.size() - start;
    const auto* p = reinterpret_cast<const unsigned char*>(s.data() + start);
    char32_t cp = 0;
    if (len == 1) cp = p[0];
    else if (len == 2) cp = ((p[0] & 0x1F) << 6) | (p[1] & 0x3F);
    else if (len == 3) cp = ((p[0] & 0x0F) << 12) | ((p[1] & 0x3F) << 6) | (p[2] & 0x3F);
    else if (len == 4)
        cp = ((p[0] & 0x07) << 18) | ((p[1] & 0x3F) << 12) | ((p[2] & 0x3F) << 6) | (p[3] & 0x3F);
    return {cp, len};
}

// IPA modifiers that do not change which project phone a label is:
// spacing modifier letters (ʰ ʲ ʷ ː ˞ …) and combining diacritics (̪ ̩ ̃ ̥ …).
bool is_ipa_modifier(char32_t cp) {
    return (cp >= 0x02B0 && cp <= 0x02FF && cp != 0x02C8 && cp != 0x02CC) ||
           (cp >= 0x0300 && cp <= 0x036F) || cp == 0x1DBF;
}

// Interprets mapping targets ("AY", "AH0", "-") as phones; a vowel without a
// digit takes `stress` (only the first such vowel: later ones are unstressed).
std::vector<Phone> make_phones(const PhoneInventory& inventory,
                               const std::vector<std::string>& targets, bool stress) {
    std::vector<Phone> out;
    bool stress_used = false;
    for (const auto& target : targets) {
        if (target == "-") continue;
        Phone phone = inventory.parse_label(target, "phone_map.tsv");
        const bool has_digit = std::isdigit(static_cast<unsigned char>(target.back())) != 0;
        if (inventory.is_vowel(phone.symbol) && !has_digit) {
            phone.stressed = stress && !stress_used;
            stress_used = true;
        }
        out.push_back(std::move(phone));
    }
    return out;
}

}  // namespace

std::string phone_label(const Phone& phone, bool is_vowel) {
    if (!is_vowel) return phone.symbol;
    return phone.symbol + (phone.stressed ? "1" : "0");
}

const std::array<std::string_view, feature_count>& feature_names() { return k_feature_names; }

const PhoneInventory& PhoneInventory::builtin() {
    static const PhoneInventory inventory =
        load_languages(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "languages");
    return inventory;
}

namespace {

// A row of the phone table (symbol, class, IPA, example, then the
// features from column `first_feature`); `known` tells a symbol already
// read (a duplicate). Problems are added, the row read as far as it goes.
PhoneInfo parse_phone_row(const TsvLine& row, std::size_t first_feature, const std::string& ppath,
                          const std::function<bool(const std::string&)>& known, DiagnosticList& problems) {
    PhoneInfo info;
    info.symbol = row.fields[0];
    const std::string& cls = row.fields[1];
    if (cls == "vowel") info.phone_class = PhoneClass::Vowel;
    else if (cls == "consonant") info.phone_class = PhoneClass::Consonant;
    else if (cls == "silence") info.phone_class = PhoneClass::Silence;
    else
        problems.add(ppath, row.line, 0, "class",
                     fmt::format("expected vowel, consonant or silence, got \"{}\"", cls));
    info.ipa = row.fields[2];
    info.example = row.fields[3];
    if (info.symbol.empty() ||
        (info.symbol != "sil" && info.symbol != upper(info.symbol)))
        problems.add(ppath, row.line, 0, "symbol",
                     fmt::format("expected an upper-case ARPAbet symbol or sil, got \"{}\"",
                                 info.symbol));
    if (known(info.symbol))
        problems.add(ppath, row.line, 0, "symbol",
                     fmt::format("duplicate phone \"{}\"", info.symbol));
    for (std::size_t f = 0; f < feature_count; ++f) {
        const std::string& text = row.fields[first_feature + f];
        const bool three_valued = f >= static_cast<std::size_t>(Feature::Open) &&
                                  f <= static_cast<std::size_t>(Feature::Protruded);
        const auto value = parse_double(text);
        const bool ok = value && (*value == 0.0 || *value == 1.0 ||
                                  (three_valued && *value == 0.5));
        if (!ok) {
            problems.add(ppath, row.line, 0, std::string(k_feature_names[f]),
                         fmt::format("expected {}, got \"{}\"",
                                     three_valued ? "0, 0.5 or 1" : "0 or 1", text));
            continue;
        }
        info.features[f] = static_cast<float>(*value);
    }
    const float stress = info.features[static_cast<std::size_t>(Feature::Stress)];
    if (stress != 0.0f)
        problems.add(ppath, row.line, 0, "stress",
                     "expected 0 (stress is set per phone token, e.g. AA1 vs AA0), got 1");
    const bool vowel_feature = info.features[static_cast<std::size_t>(Feature::Vowel)] == 1.0f;
    if (vowel_feature != (info.phone_class == PhoneClass::Vowel))
        problems.add(ppath, row.line, 0, "vowel",
                     fmt::format("expected {} for class {}, got {}",
                                 info.phone_class == PhoneClass::Vowel ? 1 : 0, cls,
                                 vowel_feature ? 1 : 0));
    return info;
}

}  // namespace

PhoneInventory PhoneInventory::load(const std::filesystem::path& phones_tsv,
                                    const std::filesystem::path& map_tsv) {
    PhoneInventory inv;
    DiagnosticList problems;
    const std::string ppath = phones_tsv.string();

    // Step 1: the phone table, header first.
    const auto lines = read_tsv_lines(phones_tsv);
    const std::vector<std::string> fixed = {"symbol", "class", "ipa", "example"};
    std::vector<std::string> expected_header = fixed;
    for (auto name : k_feature_names) expected_header.emplace_back(name);
    if (lines.empty()) throw InputError(phones_tsv, "expected a header line and phones, got an empty file");
    if (lines[0].fields != expected_header) {
        std::string want, got;
        for (const auto& h : expected_header) want += (want.empty() ? "" : " ") + h;
        for (const auto& h : lines[0].fields) got += (got.empty() ? "" : " ") + h;
        throw InputError(ppath, lines[0].line, 0, "header",
                         fmt::format("expected columns \"{}\", got \"{}\"", want, got));
    }
    for (std::size_t li = 1; li < lines.size(); ++li) {
        const auto& row = lines[li];
        if (row.fields.size() != expected_header.size()) {
            problems.add(ppath, row.line, 0, "",
                         fmt::format("expected {} tab-separated fields, got {}",
                                     expected_header.size(), row.fields.size()));
            continue;
        }
        PhoneInfo info = parse_phone_row(row, fixed.size(), ppath,
                                         [&](const std::string& symbol) { return inv.m_index.count(symbol) > 0; },
                                         problems);
        info.language = "en";
        inv.m_index[info.symbol] = inv.m_phones.size();
        inv.m_english_phones.push_back(info.symbol);
        inv.m_phones.push_back(std::move(info));
    }
    if (!inv.m_index.count("sil"))
        problems.add(ppath, 0, 0, "symbol", "expected a phone \"sil\" (silence), got none");
    problems.throw_if_any();

    // Step 2: the mapping table.
    const std::string mpath = map_tsv.string();
    const auto map_lines = read_tsv_lines(map_tsv);
    const std::vector<std::string> map_header = {"source", "symbol", "phones", "note"};
    if (map_lines.empty() || map_lines[0].fields != map_header)
        throw InputError(mpath, map_lines.empty() ? 0 : map_lines[0].line, 0, "header",
                         "expected columns \"source symbol phones note\"");
    for (std::size_t li = 1; li < map_lines.size(); ++li) {
        const auto& row = map_lines[li];
        if (row.fields.size() < 3 || row.fields.size() > 4) {
            problems.add(mpath, row.line, 0, "",
                         fmt::format("expected 3 or 4 tab-separated fields, got {}", row.fields.size()));
            continue;
        }
        const std::string& source = row.fields[0];
        std::string symbol = row.fields[1];
        if (symbol == "<empty>") symbol.clear();
        const std::string& phones_text = row.fields[2];
        if (source == "espeak" && phones_text.rfind("stress=", 0) == 0) {
            if (phones_text != "stress=1" && phones_text != "stress=0") {
                problems.add(mpath, row.line, 0, "phones",
                             fmt::format("expected stress=1 or stress=0, got \"{}\"", phones_text));
                continue;
            }
            inv.m_espeak_stress[symbol] = phones_text == "stress=1";
            continue;
        }
        std::map<std::string, std::vector<std::string>, std::less<>>* table = nullptr;
        if (source == "espeak") table = &inv.m_espeak;
        else if (source == "espeak-en") table = &inv.m_espeak_en;
        else if (source == "ipa") table = &inv.m_ipa;
        else if (source == "festival") table = &inv.m_festival;
        else if (source == "timit") table = &inv.m_timit;
        else if (source == "mocha") table = &inv.m_mocha;
        else {
            problems.add(mpath, row.line, 0, "source",
                         fmt::format("expected espeak, espeak-en, ipa, festival, timit or mocha, got \"{}\"", source));
            continue;
        }
        auto targets = split_spaces(phones_text);
        if (targets.empty()) {
            problems.add(mpath, row.line, 0, "phones", "expected one or more phones or '-', got nothing");
            continue;
        }
        bool ok = true;
        for (const auto& target : targets) {
            if (target == "-") continue;
            try {
                (void)inv.parse_label(target, mpath);
            } catch (const InputError& e) {
                problems.add(mpath, row.line, 0, "phones", e.first().message);
                ok = false;
            }
        }
        if (table->count(symbol)) {
            problems.add(mpath, row.line, 0, "symbol",
                         fmt::format("duplicate {} symbol \"{}\"", source, symbol));
            ok = false;
        }
        if (ok) (*table)[symbol] = std::move(targets);
    }
    problems.throw_if_any();
    return inv;
}

bool PhoneInventory::contains(std::string_view symbol) const { return m_index.count(symbol) > 0; }

const PhoneInfo& PhoneInventory::info(std::string_view symbol, std::string_view where) const {
    const auto it = m_index.find(symbol);
    if (it != m_index.end()) return m_phones[it->second];
    std::vector<std::string> names;
    for (const auto& p : m_phones) names.push_back(p.symbol);
    const std::string close = closest_match(std::string(symbol), names);
    throw InputError(std::string(where), 0, 0, "phone",
                     fmt::format("unknown phone \"{}\"{}", symbol,
                                 close.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", close)));
}

bool PhoneInventory::is_vowel(std::string_view symbol) const {
    const auto it = m_index.find(symbol);
    return it != m_index.end() && m_phones[it->second].phone_class == PhoneClass::Vowel;
}

FeatureVector PhoneInventory::features_of(const Phone& phone) const {
    const PhoneInfo& pi = info(phone.symbol);
    FeatureVector features = pi.features;
    features[static_cast<std::size_t>(Feature::Stress)] =
        (phone.stressed && pi.phone_class == PhoneClass::Vowel) ? 1.0f : 0.0f;
    return features;
}

Phone PhoneInventory::parse_label(std::string_view label, std::string_view where) const {
    Phone phone;
    const std::string up = upper(label);
    if (up.empty() || up == "SIL" || up == "SP") {
        phone.symbol = "sil";
        return phone;
    }
    std::string base = up;
    std::optional<char> digit;
    if (std::isdigit(static_cast<unsigned char>(base.back()))) {
        digit = base.back();
        base.pop_back();
    }
    const auto it = m_index.find(base);
    if (it == m_index.end() || base == "SIL") {
        std::vector<std::string> names;
        for (const auto& p : m_phones) names.push_back(p.symbol);
        const std::string close = closest_match(base, names);
        throw InputError(std::string(where), 0, 0, "phone",
                         fmt::format("unknown phone \"{}\": expected an ARPAbet phone of the project "
                                     "set (AA1, P, sil, …){}",
                                     label, close.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", close)));
    }
    const PhoneInfo& pi = m_phones[it->second];
    if (digit) {
        if (pi.phone_class != PhoneClass::Vowel || *digit > '2')
            throw InputError(std::string(where), 0, 0, "phone",
                             fmt::format("unknown phone \"{}\": only vowels carry a stress digit "
                                         "(0, 1 or 2)", label));
        phone.stressed = *digit != '0';
    }
    phone.symbol = pi.symbol;
    return phone;
}

std::pair<std::string, std::optional<bool>> PhoneInventory::split_espeak_stress(
    std::string_view mnemonic, std::string_view variant) const {
    const LanguageTable* language = variant == "en" ? nullptr : language_table(variant);
    const auto& marks = language ? language->espeak_stress : m_espeak_stress;
    std::optional<bool> stress;
    // Strip the longest stress mark at the front, repeatedly ("'" then ",").
    for (;;) {
        std::size_t best = 0;
        bool best_value = false;
        for (const auto& [mark, value] : marks) {
            if (mark.size() > best && mnemonic.size() > mark.size() &&
                mnemonic.substr(0, mark.size()) == mark) {
                best = mark.size();
                best_value = value;
            }
        }
        if (best == 0) break;
        stress = stress.value_or(false) || best_value;
        mnemonic.remove_prefix(best);
    }
    return {std::string(mnemonic), stress};
}

std::vector<Phone> PhoneInventory::from_espeak(std::string_view mnemonic, std::string_view where,
                                               std::string_view variant) const {
    const auto [base, stress] = split_espeak_stress(mnemonic, variant);
    if (const LanguageTable* language = variant == "en" ? nullptr : language_table(variant)) {
        const auto it = language->espeak.find(base);
        if (it != language->espeak.end()) return make_phones(*this, it->second, stress.value_or(false));
        std::vector<std::string> names;
        for (const auto& [k, v] : language->espeak) names.push_back(k);
        const std::string close = closest_match(base, names);
        throw InputError(std::string(where), 0, 0, "espeak phoneme",
                         fmt::format("unknown espeak-ng phoneme mnemonic \"{}\" for language {}: not in {}{}", base,
                                     variant, language->map_path,
                                     close.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", close)));
    }
    const std::vector<std::string>* targets = nullptr;
    if (variant == "en") {
        const auto it = m_espeak_en.find(base);
        if (it != m_espeak_en.end()) targets = &it->second;
    }
    if (!targets) {
        const auto it = m_espeak.find(base);
        if (it != m_espeak.end()) targets = &it->second;
    }
    if (!targets) {
        std::vector<std::string> names;
        for (const auto& [k, v] : m_espeak) names.push_back(k);
        const std::string close = closest_match(base, names);
        throw InputError(std::string(where), 0, 0, "espeak phoneme",
                         fmt::format("unknown espeak-ng phoneme mnemonic \"{}\": not in "
                                     "protocols/languages/en/phone_map.tsv{}",
                                     base, close.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", close)));
    }
    return make_phones(*this, *targets, stress.value_or(false));
}

std::vector<Phone> PhoneInventory::from_festival(std::string_view name, bool stressed,
                                                std::string_view where) const {
    const auto it = m_festival.find(name);
    if (it == m_festival.end()) {
        std::vector<std::string> names;
        for (const auto& [k, v] : m_festival) names.push_back(k);
        const std::string close = closest_match(std::string(name), names);
        throw InputError(std::string(where), 0, 0, "festival phone",
                         fmt::format("unknown Festival phone \"{}\": not in protocols/languages/en/phone_map.tsv{}", name,
                                     close.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", close)));
    }
    return make_phones(*this, it->second, stressed);
}

namespace {

// One symbol of a label phone set (timit, mocha) from its table.
std::vector<Phone> from_label_set(const PhoneInventory& inventory,
                                  const std::map<std::string, std::vector<std::string>, std::less<>>& table,
                                  std::string_view symbol, std::string_view set_name, std::string_view where) {
    const auto it = table.find(symbol);
    if (it == table.end()) {
        std::vector<std::string> names;
        for (const auto& [k, v] : table) names.push_back(k);
        const std::string close = closest_match(std::string(symbol), names);
        throw InputError(std::string(where), 0, 0, "phone",
                         fmt::format("unknown {} phone \"{}\": not in protocols/languages/en/phone_map.tsv{}", set_name, symbol,
                                     close.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", close)));
    }
    return make_phones(inventory, it->second, false);
}

}  // namespace

std::vector<Phone> PhoneInventory::from_timit(std::string_view symbol, std::string_view where) const {
    return from_label_set(*this, m_timit, symbol, "TIMIT", where);
}

std::vector<Phone> PhoneInventory::from_mocha(std::string_view symbol, std::string_view where) const {
    return from_label_set(*this, m_mocha, symbol, "MOCHA", where);
}

bool PhoneInventory::knows_ipa(std::string_view ipa) const {
    try {
        (void)from_ipa(ipa, "");
        return true;
    } catch (const InputError&) {
        return false;
    }
}

std::vector<Phone> PhoneInventory::from_ipa(std::string_view ipa, std::string_view where) const {
    std::string_view label = ipa;
    bool stress = false;
    // A leading primary (ˈ U+02C8) or secondary (ˌ U+02CC) stress mark.
    for (std::string_view mark : {std::string_view("\xCB\x88"), std::string_view("\xCB\x8C")}) {
        if (label.size() > mark.size() && label.substr(0, mark.size()) == mark) {
            label.remove_prefix(mark.size());
            stress = true;
        }
    }
    std::string_view key = label;
    for (;;) {
        const auto it = m_ipa.find(key);
        if (it != m_ipa.end()) {
            return make_phones(*this, it->second, stress);
        }
        if (key.empty()) break;
        const auto [cp, len] = last_code_point(key);
        if (!is_ipa_modifier(cp) || len >= key.size()) break;
        key.remove_suffix(len);
    }
    throw InputError(std::string(where), 0, 0, "phone",
                     fmt::format("unknown phone label \"{}\": neither an ARPAbet phone (AA1, P, sil) "
                                 "nor an IPA label in protocols/languages/en/phone_map.tsv",
                                 ipa));
}

// ---- Languages as data (protocols/languages/<lang>/) ----

PhoneInventory PhoneInventory::load_languages(const std::filesystem::path& languages_dir) {
    PhoneInventory inv = load(languages_dir / "en" / "phones.tsv", languages_dir / "en" / "phone_map.tsv");
    std::vector<std::string> codes;
    std::error_code ec;
    for (const auto& entry : std::filesystem::directory_iterator(languages_dir, ec))
        if (entry.is_directory() && entry.path().filename() != "en") codes.push_back(entry.path().filename().string());
    if (ec) throw InputError(languages_dir.string(), fmt::format("cannot list the language tables: {}", ec.message()));
    std::sort(codes.begin(), codes.end());
    for (const auto& code : codes)
        inv.add_language(code, languages_dir / code / "phones.tsv", languages_dir / code / "phone_map.tsv");
    return inv;
}

void PhoneInventory::add_language(const std::string& code, const std::filesystem::path& phones_tsv,
                                  const std::filesystem::path& map_tsv) {
    if (code.empty() || code == "en" || m_languages.count(code))
        throw InputError(phones_tsv.string(), 0, 0, "language",
                         fmt::format("expected a new language code, got \"{}\" (already loaded)", code));
    LanguageTable table;
    // Messages name a shipped table as protocols/languages/<code>/phone_map.tsv.
    const std::string shipped = (std::filesystem::path(AVSI_PROTOCOLS_DIR) / "languages").generic_string() + "/";
    table.map_path = map_tsv.generic_string();
    if (table.map_path.rfind(shipped, 0) == 0)
        table.map_path = "protocols/languages/" + table.map_path.substr(shipped.size());
    read_language_phones(code, phones_tsv, table);
    read_language_map(code, map_tsv, table);
    m_languages.emplace(code, std::move(table));
}

namespace {

bool is_phone_symbol_text(const std::string& symbol) {
    if (symbol == "sil") return true;
    if (symbol.empty() || symbol.size() > 8) return false;
    for (char c : symbol)
        if (c < 'A' || c > 'Z') return false;
    return true;
}

}  // namespace

// The phones of a language table: the English header with mpeg4_viseme and
// avsi17_viseme after `example`. A phone English (or an earlier language)
// defined must have the same class and features.
void PhoneInventory::read_language_phones(const std::string& code, const std::filesystem::path& phones_tsv,
                                          LanguageTable& table) {
    DiagnosticList problems;
    const std::string ppath = phones_tsv.generic_string();
    const auto lines = read_tsv_lines(phones_tsv);
    const std::vector<std::string> fixed = {"symbol", "class", "ipa", "example", "mpeg4_viseme", "avsi17_viseme"};
    std::vector<std::string> header = fixed;
    for (auto name : k_feature_names) header.emplace_back(name);
    if (lines.empty()) throw InputError(phones_tsv, "expected a header line and phones, got an empty file");
    if (lines[0].fields != header) {
        std::string want;
        for (const auto& h : header) want += (want.empty() ? "" : " ") + h;
        throw InputError(ppath, lines[0].line, 0, "header", fmt::format("expected columns \"{}\"", want));
    }
    std::set<std::string> seen;
    for (std::size_t li = 1; li < lines.size(); ++li) {
        const auto& row = lines[li];
        if (row.fields.size() != header.size()) {
            problems.add(ppath, row.line, 0, "",
                         fmt::format("expected {} tab-separated fields, got {}", header.size(), row.fields.size()));
            continue;
        }
        PhoneInfo info = parse_phone_row(
            row, fixed.size(), ppath, [&](const std::string& symbol) { return seen.count(symbol) > 0; }, problems);
        if (!is_phone_symbol_text(info.symbol)) {
            problems.add(ppath, row.line, 0, "symbol",
                         fmt::format("expected 1 to 8 upper-case letters A-Z or sil, got \"{}\"", info.symbol));
            continue;
        }
        seen.insert(info.symbol);
        info.language = code;
        info.mpeg4_viseme = row.fields[4];
        info.avsi17_viseme = row.fields[5];
        for (std::size_t v : {std::size_t{4}, std::size_t{5}})
            if (row.fields[v].empty())
                problems.add(ppath, row.line, 0, fixed[v], "expected a viseme class name, got nothing");
        table.phones.push_back(info.symbol);
        const auto it = m_index.find(info.symbol);
        if (it == m_index.end()) {
            m_index[info.symbol] = m_phones.size();
            m_phones.push_back(std::move(info));
            continue;
        }
        PhoneInfo& known = m_phones[it->second];
        if (known.phone_class != info.phone_class || known.features != info.features)
            problems.add(ppath, row.line, 0, "symbol",
                         fmt::format("phone \"{}\" has other features than in the {} table; a phone has one "
                                     "feature vector in every language (give this one a new symbol)",
                                     info.symbol, known.language));
        if (known.mpeg4_viseme.empty()) {
            known.mpeg4_viseme = info.mpeg4_viseme;
            known.avsi17_viseme = info.avsi17_viseme;
        } else if (known.mpeg4_viseme != info.mpeg4_viseme || known.avsi17_viseme != info.avsi17_viseme) {
            problems.add(ppath, row.line, 0, "mpeg4_viseme",
                         fmt::format("phone \"{}\" is in visemes {} / {} in the {} table, got {} / {}", info.symbol,
                                     known.mpeg4_viseme, known.avsi17_viseme, known.language, info.mpeg4_viseme,
                                     info.avsi17_viseme));
        }
    }
    if (!seen.count("sil")) problems.add(ppath, 0, 0, "symbol", "expected a phone \"sil\" (silence), got none");
    problems.throw_if_any();
}

// The espeak-ng rows of a language's mapping table; every target must be a
// phone of that language's own table.
void PhoneInventory::read_language_map(const std::string& code, const std::filesystem::path& map_tsv,
                                       LanguageTable& table) {
    DiagnosticList problems;
    const std::string mpath = map_tsv.generic_string();
    const auto lines = read_tsv_lines(map_tsv);
    const std::vector<std::string> header = {"source", "symbol", "phones", "note"};
    if (lines.empty() || lines[0].fields != header)
        throw InputError(mpath, lines.empty() ? 0 : lines[0].line, 0, "header",
                         "expected columns \"source symbol phones note\"");
    const std::set<std::string> own(table.phones.begin(), table.phones.end());
    for (std::size_t li = 1; li < lines.size(); ++li) {
        const auto& row = lines[li];
        if (row.fields.size() < 3 || row.fields.size() > 4) {
            problems.add(mpath, row.line, 0, "",
                         fmt::format("expected 3 or 4 tab-separated fields, got {}", row.fields.size()));
            continue;
        }
        const std::string& symbol = row.fields[1];
        const std::string& phones_text = row.fields[2];
        if (row.fields[0] == "sequence") {
            const auto pair = split_spaces(symbol);
            const auto result = split_spaces(phones_text);
            const auto own_phone = [&](const std::string& p) { return own.count(p) > 0; };
            if (pair.size() != 2 || result.size() != 1 || !own_phone(pair[0]) || !own_phone(pair[1]) ||
                !own_phone(result[0])) {
                problems.add(mpath, row.line, 0, "symbol",
                             fmt::format("expected two phones of the {} table and the one they become (\"RR T\" -> "
                                         "\"RT\"), got \"{}\" -> \"{}\"",
                                         code, symbol, phones_text));
                continue;
            }
            table.sequences.push_back({pair[0], pair[1], result[0]});
            continue;
        }
        if (row.fields[0] != "espeak") {
            problems.add(mpath, row.line, 0, "source",
                         fmt::format("expected espeak or sequence (a language table maps espeak-ng voice {}), got "
                                     "\"{}\"",
                                     code, row.fields[0]));
            continue;
        }
        if (table.espeak.count(symbol) || table.espeak_stress.count(symbol)) {
            problems.add(mpath, row.line, 0, "symbol", fmt::format("duplicate espeak symbol \"{}\"", symbol));
            continue;
        }
        if (phones_text == "stress=1" || phones_text == "stress=0") {
            table.espeak_stress[symbol] = phones_text == "stress=1";
            continue;
        }
        auto targets = split_spaces(phones_text);
        if (targets.empty())
            problems.add(mpath, row.line, 0, "phones", "expected one or more phones or '-', got nothing");
        bool ok = !targets.empty();
        for (const auto& target : targets) {
            if (target == "-") continue;
            try {
                const Phone phone = parse_label(target, mpath);
                if (!own.count(phone.symbol)) {
                    problems.add(mpath, row.line, 0, "phones",
                                 fmt::format("phone \"{}\" is not in the {} phone table ({})", phone.symbol, code,
                                             (map_tsv.parent_path() / "phones.tsv").generic_string()));
                    ok = false;
                }
            } catch (const InputError& e) {
                problems.add(mpath, row.line, 0, "phones", e.first().message);
                ok = false;
            }
        }
        if (ok) table.espeak[symbol] = std::move(targets);
    }
    problems.throw_if_any();
}

const PhoneInventory::LanguageTable* PhoneInventory::language_table(std::string_view code) const {
    if (code.empty() || code == "en") return nullptr;
    const auto it = m_languages.find(code);
    return it == m_languages.end() ? nullptr : &it->second;
}

std::vector<std::string> PhoneInventory::languages() const {
    std::vector<std::string> out{"en"};
    for (const auto& [code, table] : m_languages) out.push_back(code);
    std::sort(out.begin(), out.end());
    return out;
}

bool PhoneInventory::has_language(std::string_view code) const {
    return code == "en" || m_languages.count(code) > 0;
}

const std::vector<std::string>& PhoneInventory::language_phones(std::string_view code) const {
    if (code == "en") return m_english_phones;
    if (const LanguageTable* table = language_table(code)) return table->phones;
    std::string list;
    for (const auto& l : languages()) list += (list.empty() ? "" : ", ") + l;
    throw InputError("", 0, 0, "language",
                     fmt::format("no phone table for language \"{}\" (protocols/languages/{}/); languages: {}", code,
                                 code, list));
}

std::string PhoneInventory::nearest_by_features(std::string_view symbol,
                                                const std::function<bool(const std::string&)>& has) const {
    const FeatureVector& target = info(symbol).features;
    std::string best;
    double best_distance = 0.0;
    for (const auto& candidate : m_phones) {
        if (candidate.symbol == symbol || !has(candidate.symbol)) continue;
        double d = 0.0;
        for (std::size_t f = 0; f < feature_count; ++f)
            d += double(candidate.features[f] - target[f]) * double(candidate.features[f] - target[f]);
        if (best.empty() || d < best_distance) {
            best = candidate.symbol;
            best_distance = d;
        }
    }
    return best;
}

const std::vector<PhoneInventory::SequenceRule>& PhoneInventory::sequence_rules(std::string_view code) const {
    static const std::vector<SequenceRule> none;
    const LanguageTable* table = language_table(code);
    return table ? table->sequences : none;
}

std::string PhoneInventory::language_map_path(std::string_view code) const {
    if (const LanguageTable* table = language_table(code)) return table->map_path;
    return "protocols/languages/en/phone_map.tsv";
}

}  // namespace avsi
