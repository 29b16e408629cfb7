// Dictionary transcription of words through the voice's lexicon and
// letter-to-sound rules (transcription.h): Festival's lookups run in the
// Festival server (festival_server.cpp, request Transcribe), espeak-ng's in a
// child process of tts.cpp (espeak_tts.h).
#include "avsi/core/transcription.h"

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "espeak_tts.h"
#include "festival_tts.h"

namespace avsi {
namespace {

// Words per request, well under the request's text limit (64 KiB).
constexpr std::size_t k_batch_bytes = 32 * 1024;

// The project phones of one Festival word; throws naming the word and phone.
WordTranscription map_festival_word(const std::string& word, const detail::FestivalWord& festival,
                                    const std::string& voice) {
    const PhoneInventory& inventory = PhoneInventory::builtin();
    WordTranscription out{word, {}, festival.in_lexicon};
    const std::string where = fmt::format("word \"{}\" (Festival voice {})", word, voice);
    for (const auto& phone : festival.phones)
        for (auto& p : inventory.from_festival(phone.name, phone.stressed, where))
            if (p.symbol != "sil") out.phones.push_back(std::move(p));
    return out;
}

void check_radio_phone_set(const std::string& phone_set, const std::string& voice) {
    if (phone_set != "radio")
        throw InputError("tts", 0, 0, "voice",
                         fmt::format("Festival voice \"{}\" uses the phone set \"{}\"; the phone mapping "
                                     "(protocols/languages/en/phone_map.tsv) covers Festival's US English phone set \"radio\"",
                                     voice, phone_set));
}

// Throws unless every word is one word without spaces.
void check_words(const std::vector<std::string>& words) {
    for (const auto& word : words)
        if (word.empty() || word.find_first_of(" \t\r\n") != std::string::npos)
            throw InputError("tts", 0, 0, "word", fmt::format("expected one word without spaces, got \"{}\"", word));
}

}  // namespace

std::vector<WordTranscription> transcribe_words(const std::vector<std::string>& words, const TtsSettings& settings) {
    check_words(words);
    if (words.empty()) return {};
    if (settings.engine == TtsEngine::Espeak) return detail::espeak_transcribe(words, settings);
    std::vector<WordTranscription> out;
    out.reserve(words.size());
    std::size_t begin = 0;
    while (begin < words.size()) {
        std::size_t end = begin, bytes = 0;
        for (; end < words.size() && (end == begin || bytes + words[end].size() + 1 <= k_batch_bytes); ++end)
            bytes += words[end].size() + 1;
        const std::vector<std::string> batch(words.begin() + static_cast<long>(begin),
                                             words.begin() + static_cast<long>(end));
        const auto [phone_set, festival] = detail::festival_transcribe(batch, settings.voice);
        check_radio_phone_set(phone_set, settings.voice);
        for (std::size_t i = 0; i < batch.size(); ++i)
            out.push_back(map_festival_word(batch[i], festival[i], settings.voice));
        begin = end;
    }
    return out;
}

}  // namespace avsi
