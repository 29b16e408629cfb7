// What the subject reads, per language (see ui_strings.h).
#include "avsi/core/ui_strings.h"

#include <memory>
#include <mutex>
#include <set>

#include <fmt/format.h>

#include "avsi/core/config.h"
#include "avsi/core/error.h"

namespace avsi {

namespace {

const std::vector<std::string>& sections() {
    static const std::vector<std::string> names = {"session", "runner", "web"};
    return names;
}

// The {names} of a text, in order of appearance.
std::set<std::string> placeholders(const std::string& text) {
    std::set<std::string> out;
    for (std::size_t open = text.find('{'); open != std::string::npos; open = text.find('{', open + 1)) {
        const std::size_t close = text.find('}', open);
        if (close == std::string::npos) break;
        out.insert(text.substr(open + 1, close - open - 1));
    }
    return out;
}

// `table` has the keys and placeholders of `reference`; problems otherwise.
void check_against(const UiStrings& table, const std::map<std::string, std::string>& texts,
                   const std::map<std::string, std::string>& reference, const std::string& path,
                   DiagnosticList& problems) {
    for (const auto& [key, text] : reference) {
        const auto it = texts.find(key);
        if (it == texts.end()) {
            problems.add(path, 0, 0, key, fmt::format("missing: every language's table has the keys of the English "
                                                      "one ({})",
                                                      ui_strings_file("en").string()));
            continue;
        }
        if (placeholders(it->second) != placeholders(text))
            problems.add(path, 0, 0, key,
                         fmt::format("expected the placeholders of the English text \"{}\", got \"{}\"", text,
                                     it->second));
    }
    for (const auto& [key, text] : texts)
        if (!reference.count(key))
            problems.add(path, 0, 0, key, fmt::format("unknown key (not in the English table {})",
                                                      ui_strings_file("en").string()));
    (void)table;
}

std::map<std::string, std::string> read_texts(const std::filesystem::path& file, DiagnosticList& problems) {
    const ConfigSection root = read_config(file);
    std::map<std::string, std::string> texts;
    for (const auto& name : sections()) {
        const ConfigSection* section = root.get_table(name, problems);
        if (!section) {
            problems.add(file.string(), 0, 0, name, "missing table");
            continue;
        }
        for (const auto& key : section->keys()) texts[name + "." + key] = section->get_string(key, "", problems);
    }
    root.check_unknown_keys(sections(), problems);
    return texts;
}

}  // namespace

std::filesystem::path ui_strings_file(const std::string& language) {
    return std::filesystem::path(AVSI_PROTOCOLS_DIR) / "languages" / language / "strings.toml";
}

UiStrings UiStrings::read(const std::filesystem::path& file, const std::string& language) {
    if (!std::filesystem::is_regular_file(file))
        throw InputError(file, fmt::format("no table of what the subject reads in language '{}' (expected {})",
                                           language, file.string()));
    DiagnosticList problems;
    UiStrings out;
    out.m_language = language;
    const auto texts = read_texts(file, problems);
    if (language != "en") {
        DiagnosticList english_problems;
        const auto english = read_texts(ui_strings_file("en"), english_problems);
        english_problems.throw_if_any();
        check_against(out, texts, english, file.string(), problems);
    }
    problems.throw_if_any();
    for (const auto& [key, text] : texts) out.m_texts[key] = text;
    return out;
}

const std::string& UiStrings::text(std::string_view section, std::string_view key) const {
    const auto it = m_texts.find(fmt::format("{}.{}", section, key));
    AVSI_ASSERT(it != m_texts.end());
    return it->second;
}

std::string UiStrings::fill(std::string_view section, std::string_view key,
                            const std::vector<std::pair<std::string, std::string>>& values) const {
    std::string out = text(section, key);
    for (const auto& [name, value] : values) {
        const std::string mark = "{" + name + "}";
        for (std::size_t at = out.find(mark); at != std::string::npos; at = out.find(mark, at + value.size()))
            out.replace(at, mark.size(), value);
    }
    return out;
}

std::vector<std::pair<std::string, std::string>> UiStrings::section(std::string_view section) const {
    std::vector<std::pair<std::string, std::string>> out;
    const std::string prefix = fmt::format("{}.", section);
    for (const auto& [key, text] : m_texts)
        if (key.rfind(prefix, 0) == 0) out.emplace_back(key.substr(prefix.size()), text);
    return out;
}

const UiStrings& ui_strings(const std::string& language) {
    static std::mutex mutex;
    static std::map<std::string, std::unique_ptr<const UiStrings>> cache;
    std::lock_guard lock(mutex);
    auto& slot = cache[language];
    if (!slot) slot = std::make_unique<const UiStrings>(UiStrings::read(ui_strings_file(language), language));
    return *slot;
}

}  // namespace avsi
