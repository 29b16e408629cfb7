// Phoneme-level scoring of typed answers (`avsi score --phonemes`), after
// the open-set phoneme scoring of sentence responses in lipreading studies
// (Bernstein, Demorest & Tucker 2000): every phone of the target sentence is
// marked correct, substituted (by which phone) or deleted; phones of the
// answer aligned to nothing are kept as insertions. docs/phoneme-analysis.md.
//
// 1. Words: the target sentence and the answer are split into spoken words
//    (spoken_words(): letters and apostrophes, digits read out) and each
//    word is transcribed by a pronunciation table (read_pronunciations()) or
//    the protocol's own TTS front end (core/transcription.h: lexicon, else
//    letter-to-sound, marked).
// 2. Word alignment: weighted edit distance over words; a word costs 0.5 to
//    delete or insert, and substituting answer word b for target word a
//    costs d(a, b) / (|a| + |b|) in [0, 1], d the phone distance of step 3
//    and |a| its phone count (0 for the same spelling).
// 3. Phone alignment within each pair of aligned words (a deleted word's
//    phones are all deleted, an inserted word's all inserted): weighted edit
//    distance, deletion and insertion 1, substitution of phone b for a
//        s(a, b) = 0 if a = b, else min(2, 0.5 + 0.25 · Σ_f |a_f − b_f|)
//    over the 16 phonetic features of protocols/languages/en/phones.tsv (the 17 of the
//    reference study without stress; the vowel features count 0.5 a step),
//    so /p/→/b/ costs 0.75, /p/→/k/ 1.0, and a phone far away in features
//    is no cheaper to substitute than to delete and insert. Phones compare
//    by base symbol (stress ignored).
// Ties in both alignments: the backtrace from the end takes a substitution
// (or match) before a deletion before an insertion. All costs are
// multiples of 1/8 in step 3, so ties are exact in floating point.
// tests/analysis/phoneme_reference.py is an independent (numpy) reference.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include "avsi/analysis/scoring.h"
#include "avsi/core/corpus.h"
#include "avsi/core/phones.h"
#include "avsi/core/transcription.h"
#include "avsi/core/tts.h"

namespace avsi::analysis {

// The words of a text as they are spoken, for transcription. English: Latin
// letters folded to ASCII, lower case, split at anything but letters,
// digits and apostrophes, apostrophes kept inside words ("don't") and
// dropped at the edges; numbers in digits read out ("7" -> "seven", "21st"
// -> "twenty first"; up to 999,999, larger ones kept as written). Swedish
// and German (text_normalize.h): the language's letters kept (läste, not
// laste), apostrophes dropped, digits kept for the language's front end to
// read ("5" -> fem).
std::vector<std::string> spoken_words(std::string_view text, std::string_view language = "en");

// Substitution cost s(a, b) of step 3 (a, b base symbols of the inventory).
double phone_substitution_cost(const PhoneInfo& a, const PhoneInfo& b);

// One step of an alignment: indices into the target and the answer, -1 on
// the side that has nothing (a deletion has response -1, an insertion target -1).
struct AlignedPair {
    long target = -1;
    long response = -1;
};
struct Alignment {
    std::vector<AlignedPair> pairs;  // in order
    double cost = 0.0;
};

// Weighted edit distance of n target and m answer items with the tie rule
// above; substitution(i, j) is the cost of answer item j for target item i.
Alignment align_weighted(std::size_t n, std::size_t m,
                         const std::function<double(std::size_t, std::size_t)>& substitution, double deletion,
                         double insertion);

// Phone alignment of step 3 (base symbols of the built-in inventory).
Alignment align_phones(const std::vector<std::string>& target, const std::vector<std::string>& response);

// Word -> transcription. A table read from a file or made by the front end.
using Pronunciations = std::map<std::string, WordTranscription, std::less<>>;

// Reads a pronunciation table: `word<TAB>phones` per line, phones as labels
// of the project phone set ("G AA1 R D AH0 N"), '#' comments. Its words take
// precedence over the front end and count as in the lexicon. Throws
// InputError naming file, line and field for an unknown phone, an empty or
// repeated word.
// `language` splits the words as spoken_words does.
Pronunciations read_pronunciations(const std::filesystem::path& path, std::string_view language = "en");

enum class PhoneOutcome { Correct, Substituted, Deleted, Inserted };
// "correct", "substituted", "deleted", "inserted".
const char* outcome_name(PhoneOutcome outcome);

// One row of phonemes.csv: one target phone, or one inserted answer phone.
struct PhonemeRow {
    std::string subject, session, trial, condition, sentence;
    std::size_t position = 0;      // 1-based target phone in the sentence; an insertion: the one before it (0: none)
    std::string target, response;  // base symbols; "" for the side that has none
    PhoneOutcome outcome = PhoneOutcome::Correct;
    std::size_t word = 0;  // 1-based target word (0 for a phone of an inserted word)
    std::string target_word, response_word;
    bool target_letter_to_sound = false, response_letter_to_sound = false;
};

// The alignment of one answer, for the audit.
struct AnswerAlignment {
    std::string subject, session, trial, condition, sentence, response;
    std::string target_tier, response_tier;  // aligned phones, '-' for a gap, '|' between words, padded to line up
    std::size_t correct = 0, substituted = 0, deleted = 0, inserted = 0;
    std::vector<std::string> letter_to_sound;  // words transcribed by letter-to-sound
    double cost = 0.0;                         // phone edit cost of the answer
};

struct PhonemeScoringResult {
    std::vector<PhonemeRow> rows;
    std::vector<AnswerAlignment> answers;
};

// The spoken words of every sentence of the corpus used by a test-phase
// response and of those responses, each once, in first-appearance order.
std::vector<std::string> words_to_transcribe(const Corpus& corpus, const std::vector<Response>& responses,
                                             std::string_view language = "en");

// Aligns every test-phase response with its sentence; every spoken word
// must be in `pronunciations`. Throws InputError for a sentence missing from
// the corpus (path "responses") and std::out_of_range for a word without a
// transcription.
PhonemeScoringResult score_phonemes(const Corpus& corpus, const std::vector<Response>& responses,
                                    const Pronunciations& pronunciations);

// The speech phones a recording's labels give, per sentence id (base
// symbols, in order, pauses left out).
using RecordedPhones = std::map<std::string, std::vector<std::string>, std::less<>>;

// The same with the target phones of the sentences in `recorded` taken from
// their recordings: what the talker said rather than the lexicon's citation
// form. The labels have no word boundaries, so the recorded phones are
// aligned (step 3's weighted edit distance) to the lexicon's phones of the
// sentence's words, and each recorded phone belongs to the word of the
// phone it is aligned with (a phone aligned to none, to the word of the
// phone before it; at the start, to the first word).
// `language` splits the words as spoken_words does.
PhonemeScoringResult score_phonemes(const Corpus& corpus, const std::vector<Response>& responses,
                                    const Pronunciations& pronunciations, const RecordedPhones& recorded,
                                    std::string_view language = "en");

// The recorded phones split into the words of `words` as above: one list per
// word (a word the talker elided gets none).
std::vector<std::vector<std::string>> recorded_phones_by_word(const std::vector<std::vector<std::string>>& words,
                                                              const std::vector<std::string>& recorded);

// The speech phones of every sentence of the corpus with label files
// (recorded speech: the corpus's labels column), read as build-stimuli reads
// them (labels.h).
RecordedPhones read_recorded_phones(const Corpus& corpus);

// phonemes.csv: subject,condition,sentence,position,target,response,outcome,
// word,target_word,response_word,target_letter_to_sound,
// response_letter_to_sound,session,trial.
void write_phonemes_csv(const std::filesystem::path& path, const std::vector<PhonemeRow>& rows);
// phoneme_alignment.csv: subject,session,trial,condition,sentence,response,
// target_phones,response_phones,correct,substituted,deleted,inserted,
// letter_to_sound,cost — one row per answer, the two tiers lined up.
void write_phoneme_alignment_csv(const std::filesystem::path& path, const std::vector<AnswerAlignment>& answers);

// `avsi score --phonemes`: reads corpus and responses, transcribes every
// word not in the pronunciation table with the front end (one request),
// takes the target phones of recorded sentences from their label files,
// scores and writes phonemes.csv and phoneme_alignment.csv into out_dir,
// then the confusion matrices and information transmitted per condition
// (phoneme_information.h): confusions.csv, information.csv,
// information_comparisons.csv.
struct PhonemeFilesSettings {
    std::filesystem::path corpus, responses, out_dir;
    std::filesystem::path pronunciations;  // optional table (read_pronunciations)
    TtsSettings tts;                       // the protocol's front end
    std::string language = "en";           // of the answers (spoken_words); the front end's
    // Target phones from the label files of the sentences that have them (a
    // protocol with audio = "recordings", or a bare corpus with labels); off
    // for a synthesised protocol, whose stimuli ignore the labels as
    // build-stimuli does.
    bool recorded_targets = true;
    std::size_t bootstrap = 2000;          // subject-bootstrap replicates of the RTI intervals
    std::uint64_t seed = 42;               // of the bootstrap
};
PhonemeScoringResult score_phoneme_files(const PhonemeFilesSettings& settings);

}  // namespace avsi::analysis
