// A hunspell dictionary for keyword scoring (see hunspell_dictionary.h).
#include "hunspell_dictionary.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <fstream>
#include <map>

#include <fmt/format.h>
#include <hunspell/hunspell.hxx>

#include "avsi/core/error.h"

namespace avsi::analysis::detail {

namespace {

// The SET line of an .aff file ("" when absent: hunspell's default ISO8859-1).
std::string affix_encoding(const std::filesystem::path& aff) {
    std::ifstream in(aff);
    std::string line;
    while (std::getline(in, line)) {
        if (line.rfind("SET ", 0) == 0) {
            std::string value = line.substr(4);
            while (!value.empty() && (value.back() == '\r' || value.back() == ' ')) value.pop_back();
            return value;
        }
    }
    return "";
}

// UTF-8 -> Latin-1 for code points below 256; "" when one is not.
std::string utf8_to_latin1(const std::string& s) {
    std::string out;
    for (std::size_t i = 0; i < s.size(); ++i) {
        const auto b = static_cast<unsigned char>(s[i]);
        if (b < 0x80) {
            out += static_cast<char>(b);
        } else if ((b == 0xC2 || b == 0xC3) && i + 1 < s.size()) {
            out += static_cast<char>(((b & 0x03) << 6) | (static_cast<unsigned char>(s[++i]) & 0x3F));
        } else {
            return "";
        }
    }
    return out;
}

std::string latin1_to_utf8(const std::string& s) {
    std::string out;
    for (char ch : s) {
        const auto b = static_cast<unsigned char>(ch);
        if (b < 0x80) {
            out += ch;
        } else {
            out += static_cast<char>(0xC0 | (b >> 6));
            out += static_cast<char>(0x80 | (b & 0x3F));
        }
    }
    return out;
}

const std::map<std::string, std::string>& upper_of() {
    static const std::map<std::string, std::string> table = {
        {"ä", "Ä"}, {"ö", "Ö"}, {"ü", "Ü"}, {"å", "Å"}, {"é", "É"}};
    return table;
}

}  // namespace

std::string capitalised(const std::string& w) {
    if (w.empty()) return w;
    const auto b = static_cast<unsigned char>(w.front());
    if (b < 0x80) return std::string(1, static_cast<char>(std::toupper(b))) + w.substr(1);
    if (w.size() >= 2)
        if (auto it = upper_of().find(w.substr(0, 2)); it != upper_of().end()) return it->second + w.substr(2);
    return w;
}

std::string lower_cased(const std::string& w) {
    std::string out;
    for (std::size_t i = 0; i < w.size(); ++i) {
        const auto b = static_cast<unsigned char>(w[i]);
        if (b < 0x80) {
            out += static_cast<char>(std::tolower(b));
        } else if (b == 0xC3 && i + 1 < w.size()) {
            auto c = static_cast<unsigned char>(w[++i]);
            // U+00C0..U+00DE (except U+00D7 ×) have their lower case 0x20 above.
            if (c >= 0x80 && c <= 0x9E && c != 0x97) c = static_cast<unsigned char>(c + 0x20);
            out += static_cast<char>(b);
            out += static_cast<char>(c);
        } else {
            out += static_cast<char>(b);
        }
    }
    return out;
}

HunspellDictionary::HunspellDictionary(const std::string& name, const std::string& package) {
    const auto start = std::chrono::steady_clock::now();
    const std::filesystem::path dir = "/usr/share/hunspell";
    const auto aff = dir / (name + ".aff");
    m_dic = dir / (name + ".dic");
    for (const auto& f : {aff, m_dic})
        if (!std::filesystem::is_regular_file(f))
            throw InputError(f, fmt::format("cannot read the hunspell dictionary; install the Debian package {} "
                                            "(scripts/install-deps does)",
                                            package));
    const std::string encoding = affix_encoding(aff);
    if (encoding == "ISO8859-1" || encoding.empty()) m_latin1 = true;
    else if (encoding != "UTF-8")
        throw InputError(aff, fmt::format("expected a dictionary in UTF-8 or ISO8859-1 (its SET line), got \"{}\"",
                                          encoding));
    m_hunspell = std::make_unique<Hunspell>(aff.c_str(), m_dic.c_str());
    m_load_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
}

HunspellDictionary::~HunspellDictionary() = default;

std::shared_ptr<const HunspellDictionary> HunspellDictionary::shared(const std::string& name,
                                                                     const std::string& package) {
    static std::mutex mutex;
    static std::map<std::string, std::shared_ptr<const HunspellDictionary>> cache;
    std::lock_guard lock(mutex);
    auto& slot = cache[name];
    if (!slot) slot = std::make_shared<const HunspellDictionary>(name, package);
    return slot;
}

std::string HunspellDictionary::to_dictionary(const std::string& utf8) const {
    return m_latin1 ? utf8_to_latin1(utf8) : utf8;
}

std::string HunspellDictionary::from_dictionary(const std::string& text) const {
    return m_latin1 ? latin1_to_utf8(text) : text;
}

bool HunspellDictionary::spell(const std::string& word) const {
    std::lock_guard lock(m_mutex);
    for (const auto& form : {word, capitalised(word)}) {
        const std::string encoded = to_dictionary(form);
        if (!encoded.empty() && m_hunspell->spell(encoded)) return true;
    }
    return false;
}

std::vector<std::string> HunspellDictionary::stems(const std::string& word) const {
    std::lock_guard lock(m_mutex);
    std::vector<std::string> out;
    for (const auto& form : {word, capitalised(word)}) {
        const std::string encoded = to_dictionary(form);
        if (encoded.empty()) continue;
        for (const auto& s : m_hunspell->stem(encoded)) {
            std::string stem = lower_cased(from_dictionary(s));
            if (std::find(out.begin(), out.end(), stem) == out.end()) out.push_back(std::move(stem));
        }
    }
    return out;
}

}  // namespace avsi::analysis::detail
