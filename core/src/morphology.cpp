// English inflectional morphology (see morphology.h): the regular spellings
// of the suffixes, and the bases a form can come from, found by taking each
// suffix off every way its spelling rules allow and keeping the bases whose
// regular form is the word.
#include "avsi/core/morphology.h"

#include <algorithm>

namespace avsi {

namespace {

bool is_vowel(char c) { return c == 'a' || c == 'e' || c == 'i' || c == 'o' || c == 'u'; }

bool has_suffix(const std::string& s, std::string_view suffix) {
    return s.size() >= suffix.size() && s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Vowel groups (a rough syllable count: "stop" 1, "visit" 2, "travel" 2).
std::size_t vowel_groups(const std::string& b) {
    std::size_t groups = 0;
    bool in_vowel = false;
    for (char c : b) {
        const bool v = is_vowel(c) || (c == 'y' && groups > 0);
        if (v && !in_vowel) ++groups;
        in_vowel = v;
    }
    return groups;
}

// consonant + single vowel + consonant (not w, x, y) at the end: the final
// consonant may double before a suffix that starts with a vowel.
bool ends_cvc(const std::string& b) {
    const std::size_t n = b.size();
    if (n < 3) return false;
    const char last = b[n - 1];
    return !is_vowel(last) && last != 'w' && last != 'x' && last != 'y' && is_vowel(b[n - 2]) &&
           !is_vowel(b[n - 3]);
}

// -ed and -ing after a final consonant that may double: doubled in one
// syllable, either way in longer words.
std::vector<std::string> doubling(const std::string& b, const std::string& ending) {
    if (vowel_groups(b) == 1) return {b + b.back() + ending};
    return {b + b.back() + ending, b + ending};
}

}  // namespace

PartsOfSpeech parts_of_speech(std::string_view letters) {
    PartsOfSpeech pos;
    for (const char c : letters) {
        if (c == 'n') pos.noun = true;
        else if (c == 'v') pos.verb = true;
        else if (c == 'a') pos.adjective = true;
    }
    return pos;
}

std::vector<std::string> regular_forms(const std::string& b, Suffix suffix) {
    const std::size_t n = b.size();
    const bool consonant_y = n >= 2 && b[n - 1] == 'y' && !is_vowel(b[n - 2]);
    switch (suffix) {
    case Suffix::S:
        if (has_suffix(b, "s") || has_suffix(b, "x") || has_suffix(b, "z") || has_suffix(b, "ch") || has_suffix(b, "sh"))
            return {b + "es"};
        if (consonant_y) return {b.substr(0, n - 1) + "ies"};
        if (n >= 2 && b[n - 1] == 'o' && !is_vowel(b[n - 2])) return {b + "es", b + "s"};
        return {b + "s"};
    case Suffix::Ed:
        if (has_suffix(b, "e")) return {b + "d"};
        if (consonant_y) return {b.substr(0, n - 1) + "ied"};
        if (ends_cvc(b)) return doubling(b, "ed");
        return {b + "ed"};
    case Suffix::Ing:
        if (has_suffix(b, "ie")) return {b.substr(0, n - 2) + "ying"};
        if (has_suffix(b, "e") && !has_suffix(b, "ee") && !has_suffix(b, "ye") && !has_suffix(b, "oe") && n > 2)
            return {b.substr(0, n - 1) + "ing"};
        if (ends_cvc(b)) return doubling(b, "ing");
        return {b + "ing"};
    case Suffix::Er:
    case Suffix::Est: {
        const std::string ending = suffix == Suffix::Er ? "er" : "est";
        if (has_suffix(b, "e")) return {b + ending.substr(1)};
        if (consonant_y) return {b.substr(0, n - 1) + "i" + ending};
        if (ends_cvc(b) && vowel_groups(b) == 1) return {b + b.back() + ending};
        return {b + ending};
    }
    }
    return {};
}

bool RegularBase::takes(PartsOfSpeech pos) const {
    if (men_plural) return pos.noun;
    switch (suffix) {
    case Suffix::S: return pos.noun || pos.verb;
    case Suffix::Ed:
    case Suffix::Ing: return pos.verb;
    case Suffix::Er:
    case Suffix::Est: return pos.adjective;
    }
    return false;
}

std::vector<RegularBase> regular_bases(const std::string& w, PartsOfSpeech form_pos) {
    std::vector<RegularBase> out;
    // Keeps `base` when its regular spelling with `suffix` is the word.
    auto try_base = [&](const std::string& base, Suffix suffix) {
        if (base.size() < 2) return;
        const auto forms = regular_forms(base, suffix);
        if (std::find(forms.begin(), forms.end(), w) != forms.end()) out.push_back({base, suffix});
    };
    const std::size_t n = w.size();
    // -s, -es, -ies
    if (has_suffix(w, "s")) {
        try_base(w.substr(0, n - 1), Suffix::S);
        if (has_suffix(w, "es")) try_base(w.substr(0, n - 2), Suffix::S);
        if (has_suffix(w, "ies")) try_base(w.substr(0, n - 3) + "y", Suffix::S);
    }
    // An -ed or -ing form that is itself a verb (feed, need, bed, sing) is a base form.
    if (!form_pos.verb && has_suffix(w, "ed")) {
        try_base(w.substr(0, n - 1), Suffix::Ed);  // -d after e
        try_base(w.substr(0, n - 2), Suffix::Ed);
        if (n >= 4 && w[n - 3] == w[n - 4]) try_base(w.substr(0, n - 3), Suffix::Ed);  // doubled
        if (has_suffix(w, "ied")) try_base(w.substr(0, n - 3) + "y", Suffix::Ed);
    }
    if (!form_pos.verb && has_suffix(w, "ing")) {
        try_base(w.substr(0, n - 3), Suffix::Ing);
        try_base(w.substr(0, n - 3) + "e", Suffix::Ing);
        if (n >= 5 && w[n - 4] == w[n - 5]) try_base(w.substr(0, n - 4), Suffix::Ing);  // doubled
        if (has_suffix(w, "ying")) try_base(w.substr(0, n - 4) + "ie", Suffix::Ing);
    }
    // -er, -est (comparative, superlative)
    for (const auto& [ending, suffix] : {std::pair{std::string_view("er"), Suffix::Er}, {"est", Suffix::Est}}) {
        if (!has_suffix(w, ending)) continue;
        const std::string stem = w.substr(0, n - ending.size());
        try_base(stem, suffix);
        try_base(stem + "e", suffix);
        const std::size_t k = stem.size();
        if (k >= 2 && stem[k - 1] == stem[k - 2]) try_base(stem.substr(0, k - 1), suffix);  // doubled
        if (has_suffix(stem, "i")) try_base(stem.substr(0, k - 1) + "y", suffix);
    }
    // -men plurals of -man nouns (women, mailmen): WordNet makes them by a
    // detachment rule, so its exception lists lack them.
    if (n > 3 && has_suffix(w, "men")) out.push_back({w.substr(0, n - 3) + "man", Suffix::S, true});
    return out;
}

}  // namespace avsi
