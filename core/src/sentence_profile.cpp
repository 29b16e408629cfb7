// The balance measures of a sentence (sentence_profile.h): syllables and
// keyword phones from the espeak-ng rendering, keyword frequencies from the
// word table, keyword phones by visual class.
#include "avsi/core/sentence_profile.h"

#include <algorithm>
#include <numeric>

#include "avsi/core/text.h"
#include "avsi/core/tts.h"

namespace avsi {

namespace {

const PhoneInfo* phone_info(const Phone& p) {
    const auto& inv = PhoneInventory::builtin();
    if (p.symbol == "sil" || !inv.contains(p.symbol)) return nullptr;
    return &inv.info(p.symbol);
}

// The mean of `v`, 0 when empty.
double mean_or_zero(const std::vector<double>& v) {
    return v.empty() ? 0.0 : std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

}  // namespace

const char* to_string(VisemeClass c) {
    switch (c) {
        case VisemeClass::Bilabial: return "bilabial";
        case VisemeClass::Labiodental: return "labiodental";
        case VisemeClass::Dental: return "dental";
        case VisemeClass::Rounded: return "rounded";
        case VisemeClass::OpenVowel: return "open vowel";
        case VisemeClass::SpreadVowel: return "spread vowel";
        case VisemeClass::Lingual: return "lingual";
        case VisemeClass::Count: break;
    }
    return "?";
}

VisemeClass viseme_class(const PhoneInfo& phone) {
    const auto f = [&](Feature k) { return phone.features[static_cast<std::size_t>(k)]; };
    const bool vowel = phone.phone_class == PhoneClass::Vowel;
    const bool rounded = f(Feature::Rounded) >= 0.5f || f(Feature::Protruded) >= 0.5f;
    if (!vowel && f(Feature::Labiodental) > 0.5f) return VisemeClass::Labiodental;
    if (!vowel && f(Feature::Dental) > 0.5f) return VisemeClass::Dental;
    if (!vowel && f(Feature::Bilabial) > 0.5f && !rounded) return VisemeClass::Bilabial;
    if (rounded) return VisemeClass::Rounded;
    if (vowel) return f(Feature::Open) >= 1.0f ? VisemeClass::OpenVowel : VisemeClass::SpreadVowel;
    return VisemeClass::Lingual;
}

double SentenceProfile::mean_log_frequency() const { return mean_or_zero(keyword_log_frequency); }

int SentenceProfile::keyword_phones() const { return std::accumulate(keyword_visemes.begin(), keyword_visemes.end(), 0); }

int count_syllables(const std::string& text, const std::string& voice) {
    TtsSettings tts;
    tts.voice = voice;
    const TtsResult r = synthesize_speech(text, tts);
    const auto& inv = PhoneInventory::builtin();
    return static_cast<int>(std::count_if(r.phones.begin(), r.phones.end(),
                                          [&](const Phone& p) { return inv.is_vowel(p.symbol); }));
}

SentenceProfile profile_sentence(const Sentence& sentence, const WordTable& words, const ProfileSettings& settings) {
    SentenceProfile p;
    p.id = sentence.id;
    p.syllables = count_syllables(sentence.text, settings.voice);
    TtsSettings tts;
    tts.voice = settings.voice;
    for (const auto& k : sentence.keywords) {
        // A multi-word keyword: the mean over its words.
        const auto parts = text_words(k.word);
        std::vector<double> f;
        if (settings.keyword_frequency)
            for (const auto& w : parts) f.push_back(words.log_frequency(w));
        p.keyword_log_frequency.push_back(mean_or_zero(f));
        for (const Phone& ph : synthesize_speech(k.word, tts).phones)
            if (const PhoneInfo* info = phone_info(ph))
                ++p.keyword_visemes[static_cast<std::size_t>(viseme_class(*info))];
    }
    return p;
}

}  // namespace avsi
