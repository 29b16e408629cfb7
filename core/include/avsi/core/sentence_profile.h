// The measures a test list is balanced on (list_balance.h), per sentence:
//   syllables        vowel phones of the espeak-ng rendering of the text (tts.h);
//                    syllabic consonants count, since the phone map writes them AH0 + C.
//   keyword log frequency  log10(1 + n), n = SemCor sense-tagged count of the
//                    keyword's lemma (WordNet 3.0 cntlist.rev, derived into
//                    protocols/corpus/word-frequency.tsv by scripts/make-word-frequency;
//                    word_table.h).
//                    English only (ProfileSettings::keyword_frequency).
//   keyword visemes  the keywords' phones (each keyword spoken alone) counted
//                    per visual class of VisemeClass, from the phone features
//                    of the voice's language table (protocols/languages/<lang>/phones.tsv).
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "avsi/core/corpus.h"
#include "avsi/core/phones.h"
#include "avsi/core/word_table.h"

namespace avsi {

// Visual classes of phones for balancing viseme content, by lip shape first:
// the first that applies wins.
enum class VisemeClass : int {
    Bilabial = 0,  // lips closed: P B M
    Labiodental,   // lower lip to teeth: F V
    Dental,        // tongue between teeth: TH DH
    Rounded,       // rounded or protruded lips (rounded or protruded ≥ 0.5): W R SH ZH CH JH, OW UW UH AO OY AW ER
    OpenVowel,     // open (jaw-lowered) vowels: AA AE AY
    SpreadVowel,   // other vowels: AH EH EY IH IY
    Lingual,       // consonants with neutral lips: T D N S Z L K G NG HH Y
    Count
};
inline constexpr std::size_t viseme_class_count = static_cast<std::size_t>(VisemeClass::Count);
// "bilabial", "labiodental", "dental", "rounded", "open vowel", "spread vowel", "lingual".
const char* to_string(VisemeClass c);
// The class of a speech phone from its features (not for `sil`).
VisemeClass viseme_class(const PhoneInfo& phone);

// The balance measures of one sentence.
struct SentenceProfile {
    std::string id;
    int syllables = 0;
    std::vector<double> keyword_log_frequency;  // one per keyword (0 without keyword_frequency)
    std::array<int, viseme_class_count> keyword_visemes{};  // keyword phones per class

    // Mean keyword log frequency (0 without keywords).
    double mean_log_frequency() const;
    int keyword_phones() const;
};

struct ProfileSettings {
    std::string voice = "en-us";   // espeak-ng voice for syllables and keyword phones
    // Keyword frequency from the word table (English's SemCor counts); false
    // for another language, whose keywords get no frequency (an English
    // count of a Swedish "hand" or "bok" would be wrong).
    bool keyword_frequency = true;
};

// Vowel phones in the espeak-ng rendering of `text`.
int count_syllables(const std::string& text, const std::string& voice = "en-us");
// Syllables, keyword frequencies and keyword visemes of a sentence.
SentenceProfile profile_sentence(const Sentence& sentence, const WordTable& words,
                                 const ProfileSettings& settings = {});

}  // namespace avsi
