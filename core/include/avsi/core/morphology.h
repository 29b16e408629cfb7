// English inflectional morphology, once for the project: the regular
// spellings of a base with -s, -ed, -ing, -er and -est, and the other way
// round, the bases a word form is a regular inflection of. The corpus tools'
// word table (word_table.h: a keyword's lemma, for its frequency and parts of
// speech) and keyword scoring's inflection rule (analysis/inflection.h) both
// lemmatise with it, each with its own word list.
//
// The spelling rules (scripts/make-inflections mirrors them):
//   -s         -es after s, x, z, ch, sh; consonant + y -> -ies;
//              consonant + o -> -oes or -os
//   -ed        -d after e; consonant + y -> -ied
//   -ing       final e dropped except in -ee, -ye, -oe; -ie -> -ying
//   -er, -est  -r, -st after e; consonant + y -> -ier, -iest
//   after a single vowel + consonant (not w, x, y) the final consonant
//   doubles in one syllable (stop -> stopped, big -> bigger, never hat ->
//   hated); in longer words it may or may not before -ed and -ing, depending
//   on stress and variety (preferred, visited, travelled or traveled), and
//   does not before -er and -est (commoner).
// Irregular forms (children, went, better) follow no rule: they come from
// the callers' tables (WordNet's exception lists).
//
//   avsi::regular_forms("stop", avsi::Suffix::Ed);              // {"stopped"}
//   for (const auto& b : avsi::regular_bases("stopped", {}))   // {"stop", Ed}
//       if (b.takes(parts_of_speech_of(b.base))) …
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace avsi {

// The inflectional suffixes of English: plural and third person -s, past and
// participle -ed, -ing, comparative -er, superlative -est.
enum class Suffix { S, Ed, Ing, Er, Est };

// The parts of speech a word has (WordNet's; adverbs do not inflect).
struct PartsOfSpeech {
    bool noun = false;
    bool verb = false;
    bool adjective = false;
};

// WordNet's part-of-speech letters ("n", "nv", "nvar": noun, verb,
// adjective, adverb) as PartsOfSpeech; other letters are ignored.
PartsOfSpeech parts_of_speech(std::string_view wordnet_letters);

// The regular spellings of `base` + `suffix`: one, or two when the final
// consonant may be doubled or not, or -o may take -es or -s.
std::vector<std::string> regular_forms(const std::string& base, Suffix suffix);

// A base a word form is a regular inflection of.
struct RegularBase {
    std::string base;
    Suffix suffix = Suffix::S;
    // The -men plural of a -man noun (women -> woman, mailmen -> mailman):
    // WordNet's rule, not a spelling of -s (regular_forms spells "womans").
    bool men_plural = false;

    // Can a word of these parts of speech be this inflection's base? -s
    // takes a noun or a verb, -ed and -ing a verb, -er and -est an
    // adjective, -men a noun.
    bool takes(PartsOfSpeech base) const;
};

// Every base `form` (lower case) is a regular inflection of by the spelling
// rules above, whatever its parts of speech (RegularBase::takes says whether
// they fit), and a -men plural's -man singular; bases shorter than two
// letters are not. An -ed or -ing form that is itself a verb (`form_pos`:
// feed, need, bed, sing) is a base form, not a past or participle of
// anything, so it gets no -ed or -ing base. In a fixed order: -s, -ed, -ing,
// -er, -est, then -men; a base can come more than once (with two suffixes).
std::vector<RegularBase> regular_bases(const std::string& form, PartsOfSpeech form_pos);

}  // namespace avsi
