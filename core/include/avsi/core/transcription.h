// Dictionary transcription of single words with a TTS front end's own
// lexicon and letter-to-sound rules: the phones a word has in the project
// phone set, untimed, and whether the lexicon holds the word or its phones
// come from letter-to-sound. Phoneme scoring (analysis/phoneme_scoring.h)
// transcribes the target sentences and the typed answers with it, so both
// go through the front end the stimuli were made with.
//
// - Festival (the default protocol's SLT voice): the voice's lexicon
//   (`lex.lookup_all` says whether it holds the word, `lex.lookup` gives the
//   entry, by the voice's letter-to-sound rules when it does not), stress
//   from the syllables; no post-lexical rules (the words are citation forms).
//   Phones mapped through the `festival` rows of protocols/languages/en/phone_map.tsv.
// - espeak-ng (the Swedish and German protocols' voices, any espeak-ng
//   voice with a phone table): espeak_TextToPhonemes gives the phones, with
//   stress, mapped as the synthesised stimuli's phoneme events are (the
//   language's table and sequence rules). Its phoneme trace says whether
//   the dictionary holds the word ("Found") or the language's rules spelled
//   it out ("Translate": compounds and inflections too, so in English most
//   words, whose dictionary espeak-ng keeps small, count as letter-to-sound).
//
//   auto words = avsi::transcribe_words({"garden", "blorf"}, settings);
//   // words[0].phones: G AA1 R D AH0 N, in_lexicon; words[1]: letter-to-sound
#pragma once

#include <string>
#include <vector>

#include "avsi/core/phones.h"
#include "avsi/core/tts.h"

namespace avsi {

struct WordTranscription {
    std::string word;
    PhoneSequence phones;    // untimed (start_s = end_s = 0); vowels carry their syllable's stress
    bool in_lexicon = true;  // false: the phones come from letter-to-sound
};

// One transcription per word, in order, with the voice of `settings`; words
// are lower-case orthographic words without spaces (normalize_words gives
// them). One request to the front end for all words. Throws InputError
// (field "tts") for a Festival voice whose phone set the mapping does not
// cover, (field "voice") for a voice not installed, and (field "word") for a
// word with spaces, an unmapped phone or no phones.
std::vector<WordTranscription> transcribe_words(const std::vector<std::string>& words, const TtsSettings& settings);

}  // namespace avsi
