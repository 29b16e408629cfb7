// Alternates for keywords that a scorer may want to accept (`avsi corpus
// import` proposes them for review): the keyword's other number (canoe →
// canoes, planks → plank), its base form (slid → slide), its listed irregular
// forms (child → children) and its British/American spelling variants
// (colour → color), from the scoring rules' own tables (inflection.h,
// protocols/spelling_variants.csv), so a proposal is (nearly always) what the
// loose rule set would credit anyway. A generated plural is kept only if the
// word-frequency list knows it (woman → women, not "womans"; see propose()).
// Core's corpus import takes it as an
// avsi::AlternateProposer (core cannot depend on analysis).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "avsi/core/keyword_proposals.h"

namespace avsi::analysis {

class AlternateFinder {
public:
    // The shipped tables (protocols/inflections.csv, lemma_pos.tsv,
    // spelling_variants.csv). Throws InputError for a bad table.
    static std::shared_ptr<const AlternateFinder> load_default();

    // The proposals for a lower-case keyword, each once, in the order above.
    std::vector<AlternateProposal> propose(const std::string& keyword) const;
    // As an AlternateProposer for ImportSettings::alternates.
    AlternateProposer proposer() const;

private:
    struct Impl;
    std::shared_ptr<const Impl> m_impl;
};

}  // namespace avsi::analysis
