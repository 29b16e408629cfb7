// English inflectional morphology (core/morphology.h): the regular spellings
// of -s, -ed, -ing, -er and -est, and the bases a form comes from, as the
// corpus tools' word table and keyword scoring's inflection rule use them.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "avsi/core/morphology.h"

namespace avsi {
namespace {

using V = std::vector<std::string>;

TEST(Morphology, RegularSpellingRules) {
    EXPECT_EQ(regular_forms("boy", Suffix::S), V{"boys"});
    EXPECT_EQ(regular_forms("box", Suffix::S), V{"boxes"});
    EXPECT_EQ(regular_forms("baby", Suffix::S), V{"babies"});
    EXPECT_EQ(regular_forms("potato", Suffix::S), (V{"potatoes", "potatos"}));
    EXPECT_EQ(regular_forms("bake", Suffix::Ed), V{"baked"});
    EXPECT_EQ(regular_forms("carry", Suffix::Ed), V{"carried"});
    EXPECT_EQ(regular_forms("stop", Suffix::Ed), V{"stopped"});   // one syllable: doubled
    EXPECT_EQ(regular_forms("hat", Suffix::Ed), V{"hatted"});     // so hated is not hat + ed
    EXPECT_EQ(regular_forms("travel", Suffix::Ed), (V{"travelled", "traveled"}));
    EXPECT_EQ(regular_forms("help", Suffix::Ed), V{"helped"});
    EXPECT_EQ(regular_forms("bake", Suffix::Ing), V{"baking"});
    EXPECT_EQ(regular_forms("see", Suffix::Ing), V{"seeing"});
    EXPECT_EQ(regular_forms("die", Suffix::Ing), V{"dying"});
    EXPECT_EQ(regular_forms("run", Suffix::Ing), V{"running"});
    EXPECT_EQ(regular_forms("visit", Suffix::Ing), (V{"visitting", "visiting"}));
}

TEST(Morphology, ComparativeAndSuperlativeSpellings) {
    EXPECT_EQ(regular_forms("big", Suffix::Er), V{"bigger"});     // one syllable: doubled
    EXPECT_EQ(regular_forms("big", Suffix::Est), V{"biggest"});
    EXPECT_EQ(regular_forms("nice", Suffix::Er), V{"nicer"});
    EXPECT_EQ(regular_forms("happy", Suffix::Est), V{"happiest"});
    EXPECT_EQ(regular_forms("common", Suffix::Er), V{"commoner"});  // longer: not doubled
    EXPECT_EQ(regular_forms("green", Suffix::Er), V{"greener"});
}

// Is `base` + `suffix` among the bases of `form`?
bool has_base(const std::string& form, const std::string& base, Suffix suffix, PartsOfSpeech form_pos = {}) {
    const auto all = regular_bases(form, form_pos);
    return std::any_of(all.begin(), all.end(),
                       [&](const RegularBase& b) { return b.base == base && b.suffix == suffix && !b.men_plural; });
}

TEST(Morphology, BasesAreTheOnesWhoseRegularSpellingIsTheForm) {
    EXPECT_TRUE(has_base("dogs", "dog", Suffix::S));
    EXPECT_TRUE(has_base("boxes", "box", Suffix::S));
    EXPECT_TRUE(has_base("babies", "baby", Suffix::S));
    EXPECT_FALSE(has_base("babies", "babi", Suffix::S));     // babi + s is "babis"
    EXPECT_TRUE(has_base("potatoes", "potato", Suffix::S));
    EXPECT_TRUE(has_base("hated", "hate", Suffix::Ed));
    EXPECT_FALSE(has_base("hated", "hat", Suffix::Ed));      // hat + ed is "hatted"
    EXPECT_TRUE(has_base("stopped", "stop", Suffix::Ed));
    EXPECT_TRUE(has_base("carried", "carry", Suffix::Ed));
    EXPECT_TRUE(has_base("dying", "die", Suffix::Ing));
    EXPECT_TRUE(has_base("baking", "bake", Suffix::Ing));
    EXPECT_FALSE(has_base("baking", "bak", Suffix::Ing));    // bak + ing is "bakking"
    EXPECT_TRUE(has_base("bigger", "big", Suffix::Er));
    EXPECT_TRUE(has_base("nicer", "nice", Suffix::Er));
    EXPECT_TRUE(has_base("happiest", "happy", Suffix::Est));
    EXPECT_TRUE(regular_bases("dog", {}).empty());
    EXPECT_TRUE(regular_bases("as", {}).empty());           // no base shorter than two letters
    // Every base found spells the form back.
    for (const std::string form : {"stopped", "travelling", "boxes", "cries", "bigger", "hoped", "seeing"})
        for (const auto& b : regular_bases(form, {})) {
            const auto forms = regular_forms(b.base, b.suffix);
            EXPECT_NE(std::find(forms.begin(), forms.end(), form), forms.end()) << form << " from " << b.base;
        }
}

TEST(Morphology, APastOrParticipleThatIsAVerbItselfIsABaseForm) {
    EXPECT_TRUE(has_base("bed", "be", Suffix::Ed));
    EXPECT_FALSE(has_base("bed", "be", Suffix::Ed, {.noun = true, .verb = true}));
    EXPECT_TRUE(has_base("feed", "fee", Suffix::Ed));
    EXPECT_FALSE(has_base("feed", "fee", Suffix::Ed, {.verb = true}));
    EXPECT_TRUE(has_base("feeds", "feed", Suffix::S, {.verb = true}));  // -s still applies
}

TEST(Morphology, MenPluralsNeedANounAndEachSuffixItsPartOfSpeech) {
    const auto women = regular_bases("mailmen", {});
    ASSERT_EQ(women.size(), 1u);
    EXPECT_EQ(women[0].base, "mailman");
    EXPECT_TRUE(women[0].men_plural);
    EXPECT_TRUE(women[0].takes({.noun = true}));
    EXPECT_FALSE(women[0].takes({.verb = true}));
    const RegularBase plural{"dog", Suffix::S}, past{"bark", Suffix::Ed}, comparative{"big", Suffix::Er};
    EXPECT_TRUE(plural.takes({.verb = true}));
    EXPECT_FALSE(plural.takes({.adjective = true}));
    EXPECT_FALSE(past.takes({.noun = true}));
    EXPECT_TRUE(comparative.takes(parts_of_speech("nar")));
    EXPECT_FALSE(comparative.takes(parts_of_speech("nvr")));
}

}  // namespace
}  // namespace avsi
