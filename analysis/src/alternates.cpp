// Keyword alternates for review (alternates.h), from the scoring tables.
#include "avsi/analysis/alternates.h"

#include <algorithm>
#include <filesystem>

#include "avsi/analysis/inflection.h"
#include "avsi/analysis/scoring.h"
#include "avsi/core/morphology.h"
#include "avsi/core/word_table.h"

namespace avsi::analysis {

struct AlternateFinder::Impl {
    Inflections inflections;
    WordGroups variants;
};

std::shared_ptr<const AlternateFinder> AlternateFinder::load_default() {
    auto impl = std::make_shared<Impl>(
        Impl{Inflections::read_default(),
             WordGroups::read(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "spelling_variants.csv")});
    auto finder = std::make_shared<AlternateFinder>();
    finder->m_impl = std::move(impl);
    return finder;
}

std::vector<AlternateProposal> AlternateFinder::propose(const std::string& w) const {
    std::vector<AlternateProposal> out;
    auto add = [&](const std::string& form, const std::string& reason) {
        if (form == w || form.empty()) return;
        for (const auto& p : out)
            if (p.word == form) return;
        out.push_back({form, reason});
    };
    const Inflections& inf = m_impl->inflections;
    // The lemmas the keyword is a form of: its singular or base form.
    bool is_plural = false;  // w is the regular plural of a noun ("bowls")
    for (const auto& lemma : inf.lemmas(w)) {
        if (lemma == w) continue;
        const auto plurals = regular_forms(lemma, Suffix::S);
        const bool singular = inf.is_noun(lemma) && std::find(plurals.begin(), plurals.end(), w) != plurals.end();
        is_plural = is_plural || singular;
        add(lemma, singular ? "singular" : "base form");
    }
    // A noun's plural (not of a plural that is also a noun: bowls, not
    // "bowlses"). Of the regular spellings and, for a noun in -man, WordNet's
    // -men (woman → women, not "womans"), those the word-frequency list knows;
    // when it knows none (birches), the regular ones.
    if (inf.is_noun(w) && !is_plural) {
        std::vector<std::string> candidates;
        for (const auto& plural : regular_forms(w, Suffix::S))
            if (inf.same_lemma(w, plural)) candidates.push_back(plural);
        const std::vector<std::string> regular = candidates;
        if (w.size() > 3 && w.ends_with("man")) candidates.push_back(w.substr(0, w.size() - 3) + "men");
        std::vector<std::string> known;
        for (const auto& c : candidates)
            if (WordTable::builtin().zipf(c)) known.push_back(c);
        for (const auto& plural : known.empty() ? regular : known) add(plural, "plural");
    }
    // Listed irregular forms (children, mice; rang, rung).
    for (const auto& form : inf.irregular_forms_of(w)) add(form, "irregular form");
    // Spelling variants of the keyword and of what was proposed so far.
    for (const auto& v : m_impl->variants.partners(w)) add(v, "spelling variant");
    const std::size_t n = out.size();
    for (std::size_t i = 0; i < n; ++i)
        for (const auto& v : m_impl->variants.partners(out[i].word)) add(v, "spelling variant of " + out[i].word);
    return out;
}

AlternateProposer AlternateFinder::proposer() const {
    auto impl = m_impl;
    AlternateFinder copy;
    copy.m_impl = impl;
    return [copy](const std::string& keyword) { return copy.propose(keyword); };
}

}  // namespace avsi::analysis
