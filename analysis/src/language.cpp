// The languages of keyword scoring (see language.h).
#include "avsi/analysis/language.h"

#include <fmt/format.h>

#include "avsi/core/error.h"

namespace avsi::analysis {

namespace {

std::filesystem::path protocols_dir() { return std::filesystem::path(AVSI_PROTOCOLS_DIR); }

std::filesystem::path language_file(const char* code, const char* name) {
    return protocols_dir() / "languages" / code / "scoring" / name;
}

const std::vector<ScoringLanguage>& languages() {
    static const std::vector<ScoringLanguage> table = {
        {"en", "English", protocols_dir() / "homophones.csv", protocols_dir() / "spelling_variants.csv", "", "",
         {"/usr/share/dict/american-english", "/usr/share/dict/british-english"}, "wamerican, wbritish"},
        {"sv", "Swedish", language_file("sv", "homophones.csv"), language_file("sv", "spelling_variants.csv"),
         "sv_SE", "hunspell-sv", {"/usr/share/dict/swedish"}, "wswedish"},
        {"de", "German", language_file("de", "homophones.csv"), language_file("de", "spelling_variants.csv"),
         "de_DE", "hunspell-de-de", {"/usr/share/dict/ngerman"}, "wngerman"},
    };
    return table;
}

}  // namespace

const std::vector<std::string>& scoring_language_codes() {
    static const std::vector<std::string> codes = [] {
        std::vector<std::string> out;
        for (const auto& l : languages()) out.push_back(l.code);
        return out;
    }();
    return codes;
}

const ScoringLanguage& scoring_language(std::string_view code) {
    for (const auto& l : languages())
        if (l.code == code) return l;
    const std::string hint = closest_match(std::string(code), scoring_language_codes());
    throw InputError(Diagnostic{"", 0, 0, "language",
                                fmt::format("keyword scoring has no tables for language '{}' (known: {}){}", code,
                                            fmt::join(scoring_language_codes(), ", "),
                                            hint.empty() ? "" : fmt::format("; did you mean '{}'?", hint))});
}

}  // namespace avsi::analysis
