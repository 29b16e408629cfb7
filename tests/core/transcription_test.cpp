// Dictionary transcription of single words (transcription.h) through
// espeak-ng: a word gets the phones its synthesis gives (the stimuli's
// phones), in English, Swedish and German, and the phoneme trace marks the
// words the language's rules spelled out.
#include "avsi/core/transcription.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <string>
#include <vector>

#include "avsi/core/corpus.h"
#include "avsi/core/error.h"
#include "avsi/core/labels.h"

namespace avsi {
namespace {

TtsSettings espeak_voice(const char* voice) {
    TtsSettings s;
    s.engine = TtsEngine::Espeak;
    s.voice = voice;
    return s;
}

std::string labels(const PhoneSequence& phones) {
    const auto& inventory = PhoneInventory::builtin();
    std::string out;
    for (const auto& p : phones)
        if (p.symbol != "sil") out += (out.empty() ? "" : " ") + phone_label(p, inventory.is_vowel(p.symbol));
    return out;
}

struct VoiceWords {
    const char* voice;
    std::vector<std::string> words;
};

// Words of each language with its own phones: Swedish retroflexes from r +
// dental (kort, barn), front rounded vowels, sj- and tj-sounds; German
// umlauts, ich- and ach-sounds, affricates; English flaps and r-colouring.
const std::vector<VoiceWords> k_words = {
    {"sv", {"och", "jag", "kort", "barn", "sjuksköterska", "tjugo", "bilnyckel", "pojken", "fönster", "hus", "sju",
            "människor", "köpte", "has"}},
    {"de", {"und", "die", "fünf", "haustür", "nass", "brötchen", "ich", "nacht", "zeit", "pferd", "schön", "über", "the"}},
    {"en-us", {"the", "garden", "butter", "our", "church", "thought", "judge", "blorf"}},
};

TEST(EspeakTranscription, WordsGetThePhonesTheirSynthesisGives) {
    for (const auto& [voice, words] : k_words) {
        const TtsSettings s = espeak_voice(voice);
        const std::vector<WordTranscription> got = transcribe_words(words, s);
        ASSERT_EQ(got.size(), words.size()) << voice;
        for (std::size_t i = 0; i < words.size(); ++i) {
            SCOPED_TRACE(std::string(voice) + " " + words[i]);
            EXPECT_EQ(got[i].word, words[i]);
            EXPECT_EQ(labels(got[i].phones), labels(synthesize_speech(words[i], s).phones));
            for (const auto& p : got[i].phones) EXPECT_EQ(p.start_s, 0.0);
        }
    }
}

// The words of a corpus: runs of letters (any non-ASCII byte counts as one,
// so å, ä, ö, ü and ß stay inside words), ASCII lower-cased.
std::vector<std::string> corpus_words(const char* corpus) {
    std::set<std::string> words;
    for (const auto& sentence : read_corpus(std::filesystem::path(AVSI_PROTOCOLS_DIR) / corpus).sentences) {
        std::string word;
        for (const char c : sentence.text + " ") {
            const auto u = static_cast<unsigned char>(c);
            if (std::isalpha(u) || u >= 0x80) {
                word += static_cast<char>(std::tolower(u));
            } else if (!word.empty()) {
                words.insert(word);
                word.clear();
            }
        }
    }
    return {words.begin(), words.end()};
}

// Every word of the shipped Swedish and German corpora, as the phoneme
// scoring of their studies transcribes them.
TEST(EspeakTranscription, EveryWordOfTheShippedCorporaGetsItsSynthesisPhones) {
    for (const auto& [voice, corpus] : {std::pair{"sv", "languages/sv/sentences/sentences.csv"},
                                        std::pair{"de", "languages/de/sentences/sentences.csv"}}) {
        const std::vector<std::string> words = corpus_words(corpus);
        ASSERT_GT(words.size(), 50u) << corpus;
        const TtsSettings s = espeak_voice(voice);
        const std::vector<WordTranscription> got = transcribe_words(words, s);
        std::size_t rules = 0;
        for (std::size_t i = 0; i < words.size(); ++i) {
            EXPECT_EQ(labels(got[i].phones), labels(synthesize_speech(words[i], s).phones)) << voice << " " << words[i];
            rules += got[i].in_lexicon ? 0 : 1;
        }
        EXPECT_GT(rules, 0u) << voice;  // compounds and inflections are spelled out by the rules
        EXPECT_LT(rules, words.size()) << voice;
    }
}

TEST(EspeakTranscription, SwedishPhonesAreTheLanguagesOwn) {
    const auto got = transcribe_words({"barn", "fönster", "sju", "bilnyckel"}, espeak_voice("sv"));
    EXPECT_EQ(labels(got[0].phones), "B AA1 RN");  // r + n is one retroflex nasal
    EXPECT_NE(labels(got[1].phones).find("OE"), std::string::npos) << labels(got[1].phones);
    EXPECT_EQ(got[2].phones.front().symbol, "SJ");
    EXPECT_EQ(labels(got[3].phones), "B IH1 L N YH0 K AH0 L");  // "ck" is a long k: one K
}

TEST(EspeakTranscription, TheTraceMarksWordsTheRulesSpelledOut) {
    const auto in_dictionary = [](const char* voice, const std::vector<std::string>& words) {
        std::vector<bool> out;
        for (const auto& w : transcribe_words(words, espeak_voice(voice))) out.push_back(w.in_lexicon);
        return out;
    };
    // Dictionary entries (Swedish and German function words, a number);
    // then compounds, inflections and unknown words the rules spell out.
    EXPECT_EQ(in_dictionary("sv", {"och", "jag", "en", "fem", "bilnyckel", "sjuksköterska", "pojken"}),
              (std::vector<bool>{true, true, true, true, false, false, false}));
    EXPECT_EQ(in_dictionary("de", {"und", "die", "haustür", "nass", "brötchen"}),
              (std::vector<bool>{true, true, false, false, false}));
    EXPECT_EQ(in_dictionary("en-us", {"the", "blorf"}), (std::vector<bool>{true, false}));
}

// espeak-ng's Swedish dictionary gives "has" to English ("(en)h'az(sv)"):
// English's phones, each the nearest Swedish one by features, marked
// (/z/ has no Swedish phone; /s/ and /l/ are equally near, one feature off).
TEST(EspeakTranscription, AWordOfAnotherLanguageGetsTheNearestOwnPhones) {
    const auto got = transcribe_words({"has", "hus"}, espeak_voice("sv"));
    EXPECT_EQ(labels(got[0].phones).substr(0, 7), "HH AE1 ");
    ASSERT_EQ(got[0].phones.size(), 3u);
    EXPECT_TRUE(got[0].phones[2].symbol == "S" || got[0].phones[2].symbol == "L") << got[0].phones[2].symbol;
    EXPECT_FALSE(got[0].in_lexicon);
    const auto& swedish = PhoneInventory::builtin().language_phones("sv");
    for (const auto& p : got[0].phones)
        EXPECT_NE(std::find(swedish.begin(), swedish.end(), p.symbol), swedish.end()) << p.symbol;
    EXPECT_EQ(labels(got[1].phones), "HH UX1 S");
    const auto german = transcribe_words({"the"}, espeak_voice("de"));  // German espeak-ng's "the" is English too
    EXPECT_EQ(labels(german[0].phones), "DH AH0");
    EXPECT_FALSE(german[0].in_lexicon);
}

TEST(EspeakTranscription, BadWordsAndVoicesNameTheField) {
    const auto field_of = [](const std::vector<std::string>& words, const char* voice) {
        try {
            transcribe_words(words, espeak_voice(voice));
        } catch (const InputError& e) {
            return e.first().field + ": " + e.first().message;
        }
        return std::string("no error");
    };
    EXPECT_EQ(field_of({"two words"}, "sv").rfind("word: expected one word without spaces", 0), 0u);
    EXPECT_EQ(field_of({"hus"}, "sv-nowhere").rfind("voice: unknown espeak-ng voice \"sv-nowhere\"", 0), 0u);
    EXPECT_EQ(field_of({"..."}, "sv").rfind("word: espeak-ng gives no phones", 0), 0u);
    EXPECT_TRUE(transcribe_words({}, espeak_voice("sv")).empty());
}

}  // namespace
}  // namespace avsi
