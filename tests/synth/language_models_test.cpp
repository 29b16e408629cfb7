// Every model of a language (protocols/models/<lang>/) has an entry for every
// phone of that language's table, stressed and unstressed, so no sentence
// espeak-ng's voice can say stops a stimulus build (German YH0 did, in
// protocols/german-small.toml's corpus, before complete_language_models.py).
#include <filesystem>
#include <string>

#include <gtest/gtest.h>

#include "avsi/core/phones.h"
#include "avsi/synth/control_model.h"

namespace avsi::synth {
namespace {

const std::filesystem::path kModels = std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models";

// Every phone of the language's table, each vowel once stressed and once
// not, 80 ms apiece between pauses.
PhoneSequence every_phone(const std::string& language) {
    const PhoneInventory& inventory = PhoneInventory::builtin();
    PhoneSequence out{{"sil", 0.0, 0.2, false}};
    for (const auto& symbol : inventory.language_phones(language)) {
        if (symbol == "sil") continue;
        for (const bool stressed : {false, true}) {
            if (!stressed || inventory.is_vowel(symbol)) {
                const double t = out.back().end_s;
                out.push_back({symbol, t, t + 0.08, stressed});
            }
        }
    }
    out.push_back({"sil", out.back().end_s, out.back().end_s + 0.2, false});
    return out;
}

void expect_every_phone_synthesizes(const std::string& language, const std::vector<std::string>& files) {
    const PhoneSequence phones = every_phone(language);
    ASSERT_GT(phones.size(), 40u);
    for (const auto& file : files) {
        SCOPED_TRACE(language + "/" + file);
        const auto model = load_model(kModels / language / file);
        EXPECT_NO_THROW((void)model->synthesize(phones, 30.0));
    }
}

TEST(LanguageModels, SwedishModelsCoverEveryPhoneOfTheSwedishTable) {
    expect_every_phone_synthesizes("sv", {"cohen-massaro.json", "ohman.json", "ann1.json", "ann2.json", "rule.json",
                                          "mpeg4-cohen-massaro.json"});
}

TEST(LanguageModels, GermanModelsCoverEveryPhoneOfTheGermanTable) {
    expect_every_phone_synthesizes("de", {"cohen-massaro.json", "ohman.json", "rule.json", "mpeg4-cohen-massaro.json"});
}

}  // namespace
}  // namespace avsi::synth
