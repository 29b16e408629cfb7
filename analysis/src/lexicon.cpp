// The English lexicon of keyword scoring (see lexicon.h): Debian's SCOWL word
// lists read once per process into one sorted array of normalised words.
#include "avsi/analysis/lexicon.h"

#include <algorithm>
#include <cctype>
#include <chrono>
#include <map>
#include <mutex>

#include <fmt/format.h>

#include "avsi/analysis/text_normalize.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi::analysis {

namespace {

// The Debian package that ships a default list, for the error message.
std::string package_of(const std::filesystem::path& file) {
    const std::string name = file.filename().string();
    if (name == "american-english") return "wamerican";
    if (name == "british-english") return "wbritish";
    if (name == "swedish") return "wswedish";
    if (name == "ngerman") return "wngerman";
    return "";
}

}  // namespace

std::vector<std::filesystem::path> Lexicon::default_files() {
    return {"/usr/share/dict/american-english", "/usr/share/dict/british-english"};
}

Lexicon Lexicon::read(const std::vector<std::filesystem::path>& files, std::string_view language) {
    const bool keep_capitalised = language == "de";  // German nouns
    const auto start = std::chrono::steady_clock::now();
    Lexicon lexicon;
    lexicon.m_files = files;
    std::vector<std::string> folded;  // non-ASCII entries after normalisation (a few hundred)
    std::vector<std::pair<std::size_t, std::size_t>> spans;  // (offset, length) in the arena
    for (const auto& file : files) {
        std::string text;
        try {
            text = read_text_file(file);
        } catch (const InputError&) {
            const std::string package = package_of(file);
            throw InputError(file, package.empty()
                                       ? "cannot read the word list (a file of one word per line)"
                                       : fmt::format("cannot read the word list; install the Debian package {} "
                                                     "(scripts/install-deps does)",
                                                     package));
        }
        lexicon.m_arena.reserve(lexicon.m_arena.size() + text.size());
        std::size_t i = 0;
        while (i < text.size()) {
            std::size_t end = text.find('\n', i);
            if (end == std::string::npos) end = text.size();
            std::string_view line(text.data() + i, end - i);
            i = end + 1;
            if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
            if (line.empty()) continue;
            if (!keep_capitalised && std::isupper(static_cast<unsigned char>(line.front()))) continue;  // names
            if (line.find('\'') != std::string_view::npos) continue;  // possessives
            bool plain = true;
            for (char c : line) plain = plain && std::islower(static_cast<unsigned char>(c));
            if (plain) {
                spans.emplace_back(lexicon.m_arena.size(), line.size());
                lexicon.m_arena.insert(lexicon.m_arena.end(), line.begin(), line.end());
                lexicon.m_arena.push_back('\0');
            } else {
                const auto words = normalize_words(line, language);  // "café" -> "cafe" (English)
                if (words.size() == 1) folded.push_back(words.front());
            }
        }
    }
    for (const auto& w : folded) {
        spans.emplace_back(lexicon.m_arena.size(), w.size());
        lexicon.m_arena.insert(lexicon.m_arena.end(), w.begin(), w.end());
        lexicon.m_arena.push_back('\0');
    }
    // Views are taken after the arena stops growing (a vector's buffer survives moves).
    lexicon.m_words.reserve(spans.size());
    for (const auto& [offset, length] : spans) lexicon.m_words.emplace_back(lexicon.m_arena.data() + offset, length);
    std::sort(lexicon.m_words.begin(), lexicon.m_words.end());
    lexicon.m_words.erase(std::unique(lexicon.m_words.begin(), lexicon.m_words.end()), lexicon.m_words.end());
    lexicon.m_load_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    return lexicon;
}

std::shared_ptr<const Lexicon> Lexicon::shared(const std::vector<std::filesystem::path>& files,
                                               std::string_view language) {
    static std::mutex mutex;
    static std::map<std::pair<std::vector<std::filesystem::path>, std::string>, std::shared_ptr<const Lexicon>> cache;
    const std::vector<std::filesystem::path> paths = files.empty() ? default_files() : files;
    std::lock_guard lock(mutex);
    auto& slot = cache[{paths, std::string(language)}];
    if (!slot) slot = std::make_shared<const Lexicon>(read(paths, language));
    return slot;
}

bool Lexicon::contains(std::string_view normalized_word) const {
    return std::binary_search(m_words.begin(), m_words.end(), normalized_word);
}

}  // namespace avsi::analysis
