// The TTS front end, espeak-ng and Festival: text -> audio + a contiguous
// phone sequence in the project phone set, covering the audio, with stress
// (espeak-ng's marks; Festival's syllable stress); the same speech in any
// order and from any thread.
#include "avsi/core/tts.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <thread>

#include "avsi/core/corpus.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/labels.h"
#include "avsi/core/onsets.h"
#include "support/run_avsi.h"
#include "support/temp_dir.h"

namespace avsi {
namespace {

std::vector<std::string> speech_labels(const PhoneSequence& phones) {
    std::vector<std::string> out;
    const auto& inventory = PhoneInventory::builtin();
    for (const auto& p : phones)
        if (p.symbol != "sil") out.push_back(phone_label(p, inventory.is_vowel(p.symbol)));
    return out;
}

double rms(const std::vector<float>& samples, std::size_t from, std::size_t to) {
    double sum = 0.0;
    for (std::size_t i = from; i < to; ++i) sum += double(samples[i]) * samples[i];
    return to > from ? std::sqrt(sum / double(to - from)) : 0.0;
}

TEST(Tts, ComeHereJohnGivesItsPhonesCoveringTheAudio) {
    const TtsResult r = synthesize_speech("Come here John.");
    EXPECT_EQ(r.audio.sample_rate_hz, 22050);
    EXPECT_EQ(r.audio.channels, 1);
    EXPECT_EQ(speech_labels(r.phones),
              (std::vector<std::string>{"K", "AH1", "M", "HH", "IH1", "R", "JH", "AA1", "N"}));
    ASSERT_FALSE(r.phones.empty());
    EXPECT_EQ(r.phones.front().symbol, "sil");
    EXPECT_EQ(r.phones.back().symbol, "sil");
    EXPECT_EQ(r.phones.front().start_s, 0.0);
    EXPECT_NEAR(r.phones.back().end_s, r.audio.duration_s(), 0.020);
    EXPECT_NO_THROW(check_phone_sequence(r.phones, "tts"));
    for (std::size_t i = 1; i < r.phones.size(); ++i) EXPECT_GT(r.phones[i].start_s, r.phones[i - 1].start_s);
    // Edge silences as set, and they are silent; the speech between is not.
    const TtsSettings defaults;
    EXPECT_NEAR(r.phones.front().end_s, defaults.lead_silence_s, 1.0 / 22050);
    EXPECT_NEAR(r.phones.back().duration_s(), defaults.trail_silence_s, 1.0 / 22050);
    const auto lead_end = static_cast<std::size_t>(r.phones.front().end_s * 22050);
    const auto trail_start = static_cast<std::size_t>(r.phones.back().start_s * 22050);
    EXPECT_LT(rms(r.audio.samples, 0, lead_end), 1e-4);
    EXPECT_GT(rms(r.audio.samples, lead_end, trail_start), 0.02);
    // Every phone lasts a plausible time.
    for (const auto& p : r.phones) EXPECT_GT(p.duration_s(), 0.01) << p.symbol;
}

TEST(Tts, VowelsTakeDurationAndEnergy) {
    const TtsResult r = synthesize_speech("Come here John.");
    for (const auto& p : r.phones) {
        if (!PhoneInventory::builtin().is_vowel(p.symbol)) continue;
        const auto a = static_cast<std::size_t>(p.start_s * 22050);
        const auto b = static_cast<std::size_t>(p.end_s * 22050);
        EXPECT_GT(rms(r.audio.samples, a, b), 0.03) << p.symbol << " at " << p.start_s;
    }
}

TEST(Tts, SettingsChangeRateAndSilences) {
    TtsSettings slow;
    slow.rate_wpm = 100;
    slow.lead_silence_s = 0.0;
    slow.trail_silence_s = 0.5;
    TtsSettings fast;
    fast.rate_wpm = 300;
    const TtsResult a = synthesize_speech("Come here John.", slow);
    const TtsResult b = synthesize_speech("Come here John.", fast);
    EXPECT_EQ(speech_labels(a.phones), speech_labels(b.phones));
    EXPECT_GT(a.audio.duration_s(), b.audio.duration_s() + 0.3);
    EXPECT_EQ(a.phones.front().symbol, "K");  // no leading silence asked for
    EXPECT_NEAR(a.phones.back().duration_s(), 0.5, 1.0 / 22050);
    EXPECT_NEAR(a.phones.back().end_s, a.audio.duration_s(), 1e-9);
}

TEST(Tts, NonRhoticVoiceUsesItsOwnVowels) {
    TtsSettings s;
    s.voice = "en";
    const TtsResult r = synthesize_speech("Come here John.", s);
    const auto labels = speech_labels(r.phones);
    EXPECT_EQ(labels, (std::vector<std::string>{"K", "AH1", "M", "HH", "IH1", "AH0", "JH", "AA1", "N"}));
}

// The speech of `text` in an espeak-ng voice, its phone sequence checked
// and covering the audio (a synthesis error propagates and fails the test).
TtsResult checked_speech(const std::string& text, const char* voice) {
    TtsSettings s;
    s.voice = voice;
    TtsResult r = synthesize_speech(text, s);
    EXPECT_NO_THROW(check_phone_sequence(r.phones, voice));
    EXPECT_NEAR(r.phones.back().end_s, r.audio.duration_s(), 1e-9);
    return r;
}

TEST(Tts, VariedEnglishTextMapsInEveryEnglishVoice) {
    // Words chosen to reach flaps, glottal stops, syllabic consonants,
    // r-coloured vowels, diphthongs and foreign fricatives.
    const std::string text =
        "Butter, the cat's water; button bottle ahead. Rhythm, poor tour, fire hour, Mary's cure. "
        "Uh-oh! Our onion vision: thing, sing, judge the church. Bach's loch, yes, wet genre. "
        "Huge idea, city, thought, cloth, bath, palm, face, goat, price, mouth, choice, near, square, "
        "start, north, force, nurse, letter, sudden, little, kitten.";
    for (const char* voice : {"en-us", "en", "en-gb-x-rp", "en-gb-scotland", "en-029", "en-us-nyc"}) {
        SCOPED_TRACE(voice);
        const TtsResult r = checked_speech(text, voice);
        EXPECT_GT(speech_labels(r.phones).size(), 150u);
    }
}

// espeak-ng's Swedish and German dictionaries give "has" and "the" to
// English: the stimulus's phones are still all the voice's language's
// (English's phones mapped to the nearest of its own), covering the audio.
TEST(Tts, WordsEspeakGivesToEnglishStayInTheVoicesPhoneSet) {
    for (const auto& [voice, text] : {std::pair{"sv", "Han has en bil."}, std::pair{"de", "Das ist the Haus."}}) {
        SCOPED_TRACE(voice);
        const TtsResult r = checked_speech(text, voice);
        const auto& own = PhoneInventory::builtin().language_phones(voice);
        for (const auto& p : r.phones) EXPECT_NE(std::find(own.begin(), own.end(), p.symbol), own.end()) << p.symbol;
    }
}

TEST(Tts, BadSettingsAreInputErrors) {
    TtsSettings s;
    s.voice = "en-usa";
    try {
        (void)synthesize_speech("hello", s);
        FAIL() << "unknown voice accepted";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().field, "voice");
        EXPECT_NE(std::string(e.what()).find("\"en-usa\""), std::string::npos) << e.what();
    }
    s.voice = "fr";
    EXPECT_THROW((void)synthesize_speech("bonjour", s), InputError);  // no phone table (protocols/languages/fr/)
    EXPECT_THROW((void)synthesize_speech("   "), InputError);
    TtsSettings rate;
    rate.rate_wpm = 10;
    EXPECT_THROW((void)synthesize_speech("hello", rate), InputError);
    // A failed call leaves espeak-ng usable.
    EXPECT_EQ(speech_labels(synthesize_speech("Come here John.").phones).size(), 9u);
}

TEST(Tts, ConcurrentCallsGiveTheSameSpeechAsSequentialOnes) {
    const TtsResult want = synthesize_speech("Come here John.");
    std::vector<TtsResult> got(4);
    std::vector<std::thread> threads;
    for (auto& g : got) threads.emplace_back([&g] { g = synthesize_speech("Come here John."); });
    for (auto& t : threads) t.join();
    for (const auto& g : got) {
        EXPECT_EQ(g.audio.samples, want.audio.samples);
        ASSERT_EQ(g.phones.size(), want.phones.size());
        for (std::size_t i = 0; i < want.phones.size(); ++i) {
            EXPECT_EQ(g.phones[i].symbol, want.phones[i].symbol);
            EXPECT_EQ(g.phones[i].stressed, want.phones[i].stressed);
            EXPECT_EQ(g.phones[i].end_s, want.phones[i].end_s);
        }
        EXPECT_NO_THROW(check_phone_sequence(g.phones, "thread"));
    }
}

// espeak-ng's wave generator keeps state between utterances; each utterance
// is synthesised from the same fresh state, so what was said before in the
// process does not change it by a single sample.
TEST(Tts, SpeechDoesNotDependOnWhatWasSpokenBefore) {
    const TtsResult first = synthesize_speech("The boy fell from the window.");
    (void)synthesize_speech("Okay, and now something else entirely, with a question?");
    TtsSettings slow;
    slow.rate_wpm = 120;
    (void)synthesize_speech("A slower sentence in between.", slow);
    const TtsResult again = synthesize_speech("The boy fell from the window.");
    EXPECT_EQ(again.audio.samples, first.audio.samples);
    ASSERT_EQ(again.phones.size(), first.phones.size());
    for (std::size_t i = 0; i < first.phones.size(); ++i) {
        EXPECT_EQ(again.phones[i].symbol, first.phones[i].symbol);
        EXPECT_EQ(again.phones[i].start_s, first.phones[i].start_s);
        EXPECT_EQ(again.phones[i].end_s, first.phones[i].end_s);
    }
}

// Zombie children of this process (State "Z" in /proc/<pid>/status).
int zombie_children() {
    int zombies = 0;
    for (const auto& entry : std::filesystem::directory_iterator("/proc")) {
        const std::string name = entry.path().filename().string();
        if (name.find_first_not_of("0123456789") != std::string::npos) continue;
        std::ifstream status(entry.path() / "status");
        std::string line, state;
        long parent = -1;
        while (std::getline(status, line)) {
            if (line.rfind("State:", 0) == 0) state = line.substr(6);
            if (line.rfind("PPid:", 0) == 0) parent = std::stol(line.substr(5));
        }
        if (parent == ::getpid() && state.find('Z') != std::string::npos) ++zombies;
    }
    return zombies;
}

// start_speech returns while the child speaks; several can be pending at
// once, taken in any order, each the same as synthesize_speech gives.
TEST(Tts, PendingSpeechGivesWhatSynthesizeSpeechGives) {
    const TtsResult want = synthesize_speech("The boy fell from the window.");
    TtsSettings slow;
    slow.rate_wpm = 120;
    const TtsResult want_slow = synthesize_speech("Come here John.", slow);
    PendingSpeech first = start_speech("The boy fell from the window.");
    PendingSpeech second = start_speech("Come here John.", slow);
    const TtsResult got_slow = second.get();
    const TtsResult got = first.get();
    EXPECT_EQ(got.audio.samples, want.audio.samples);
    EXPECT_EQ(got.phones, want.phones);
    EXPECT_EQ(got_slow.audio.samples, want_slow.audio.samples);
    EXPECT_EQ(got_slow.phones, want_slow.phones);
    EXPECT_THROW(first.get(), std::logic_error);
    // The child's errors come from get(): the voice is checked there.
    TtsSettings unknown;
    unknown.voice = "en-xx";
    PendingSpeech bad = start_speech("Hello.", unknown);
    EXPECT_THROW(bad.get(), InputError);
    // Empty text is refused at once.
    EXPECT_THROW(start_speech("  "), InputError);
}

// Speech started and never taken ends with its owner: the child is ended
// and reaped, not left running or as a zombie.
TEST(Tts, PendingSpeechNotTakenLeavesNoChild) {
    const int before = zombie_children();
    {
        PendingSpeech a = start_speech("An utterance nobody waits for.");
        PendingSpeech b = start_speech("Nor for this one.");
        PendingSpeech moved = std::move(b);
    }
    EXPECT_EQ(zombie_children(), before);
    // And the next utterance is unaffected.
    const TtsResult again = synthesize_speech("The boy fell from the window.");
    EXPECT_EQ(again.audio.samples, synthesize_speech("The boy fell from the window.").audio.samples);
}

// The first utterance of a process (its child reads espeak-ng's voice files
// itself) and a later one (the process listed the voices before forking)
// are the same speech, to the sample.
TEST(Tts, FirstUtteranceOfAProcessIsTheSameAsALaterOne) {
    if (!std::filesystem::exists(AVSI_CLI_PATH)) GTEST_SKIP() << "avsi executable not built";
    const std::string text = "She sells sea shells by the sea shore.";
    (void)synthesize_speech("One.");
    (void)synthesize_speech("Two.");
    const TtsResult later = synthesize_speech(text);
    const auto dir = test::temp_dir("tts_first");
    const test::CliResult r = test::run_avsi("phones --text " + test::shell_quote(text) + " --wav " +
                                             test::shell_quote((dir / "s.wav").string()) + " --out " +
                                             test::shell_quote((dir / "s.tsv").string()));
    ASSERT_EQ(r.exit_code, 0) << r.err;
    const Audio first = read_audio(dir / "s.wav");
    const PhoneSequence first_phones = read_phones(dir / "s.tsv");
    std::filesystem::remove_all(dir);
    ASSERT_EQ(first.samples.size(), later.audio.samples.size());
    for (std::size_t i = 0; i < first.samples.size(); ++i)
        ASSERT_NEAR(first.samples[i], later.audio.samples[i], 1.0 / 32768) << i;  // 16-bit WAV
    ASSERT_EQ(first_phones.size(), later.phones.size());
    for (std::size_t i = 0; i < first_phones.size(); ++i) EXPECT_EQ(first_phones[i].symbol, later.phones[i].symbol);
}

// --- Festival --------------------------------------------------------------

TtsSettings festival(const std::string& voice = "cmu_us_slt_arctic_hts") {
    TtsSettings s;
    set_tts_voice(s, "festival:" + voice);
    return s;
}

void expect_same_speech(const TtsResult& got, const TtsResult& want) {
    EXPECT_EQ(got.audio.sample_rate_hz, want.audio.sample_rate_hz);
    EXPECT_EQ(got.audio.samples, want.audio.samples);
    ASSERT_EQ(got.phones.size(), want.phones.size());
    for (std::size_t i = 0; i < want.phones.size(); ++i) EXPECT_EQ(got.phones[i], want.phones[i]) << i;
}

TEST(TtsVoiceSpec, ParsesEngineAndVoice) {
    TtsSettings s;
    set_tts_voice(s, "festival:kal_diphone");
    EXPECT_EQ(s.engine, TtsEngine::Festival);
    EXPECT_EQ(s.voice, "kal_diphone");
    EXPECT_EQ(tts_voice_spec(s), "festival:kal_diphone");
    set_tts_voice(s, "espeak:en-gb-x-rp");
    EXPECT_EQ(s.engine, TtsEngine::Espeak);
    EXPECT_EQ(s.voice, "en-gb-x-rp");
    EXPECT_EQ(tts_voice_spec(s), "espeak:en-gb-x-rp");
    for (const char* bad : {"en-us", "mary:slt", "festival:", ":en-us", "festival:a b", "festival:(quit)"}) {
        SCOPED_TRACE(bad);
        try {
            set_tts_voice(s, bad, "study.toml");
            ADD_FAILURE() << "accepted";
        } catch (const InputError& e) {
            EXPECT_EQ(e.first().path, "study.toml");
            EXPECT_EQ(e.first().field, "tts");
            EXPECT_NE(std::string(e.what()).find(bad), std::string::npos) << e.what();
        }
    }
    EXPECT_EQ(tts_voice_spec(s), "espeak:en-gb-x-rp");  // unchanged by the failures
    // A Festival voice given where an espeak-ng voice goes (`--voice festival:x`
    // becomes "espeak:festival:x") says what to give instead.
    try {
        set_tts_voice(s, "espeak:festival:kal_diphone", "--tts");
        ADD_FAILURE() << "accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("give \"festival:kal_diphone\" alone"), std::string::npos) << e.what();
    }
}

TEST(TtsFestival, ComeHereJohnGivesItsPhonesCoveringTheAudio) {
    const TtsResult r = synthesize_speech("Come here John.", festival());
    EXPECT_EQ(r.audio.sample_rate_hz, 32000);  // the SLT HTS voice's own rate
    EXPECT_EQ(r.audio.channels, 1);
    EXPECT_EQ(speech_labels(r.phones),
              (std::vector<std::string>{"K", "AH1", "M", "HH", "IH1", "R", "JH", "AA1", "N"}));
    ASSERT_FALSE(r.phones.empty());
    EXPECT_EQ(r.phones.front().symbol, "sil");
    EXPECT_EQ(r.phones.back().symbol, "sil");
    EXPECT_EQ(r.phones.front().start_s, 0.0);
    EXPECT_NEAR(r.phones.back().end_s, r.audio.duration_s(), 1e-9);
    EXPECT_NO_THROW(check_phone_sequence(r.phones, "tts"));
    const TtsSettings defaults;
    const double rate = r.audio.sample_rate_hz;
    EXPECT_NEAR(r.phones.front().end_s, defaults.lead_silence_s, 1.0 / rate);
    EXPECT_NEAR(r.phones.back().duration_s(), defaults.trail_silence_s, 1.0 / rate);
    const auto lead_end = static_cast<std::size_t>(r.phones.front().end_s * rate);
    const auto trail_start = static_cast<std::size_t>(r.phones.back().start_s * rate);
    EXPECT_LT(rms(r.audio.samples, 0, lead_end), 2e-3);  // HTS pauses are near-silent, not digital zero
    EXPECT_GT(rms(r.audio.samples, lead_end, trail_start), 0.02);
    for (const auto& p : r.phones) EXPECT_GT(p.duration_s(), 0.02) << p.symbol;
    // Vowels carry energy where the labels put them.
    for (const auto& p : r.phones) {
        if (!PhoneInventory::builtin().is_vowel(p.symbol)) continue;
        EXPECT_GT(rms(r.audio.samples, static_cast<std::size_t>(p.start_s * rate), static_cast<std::size_t>(p.end_s * rate)),
                  0.03)
            << p.symbol << " at " << p.start_s;
    }
}

TEST(TtsFestival, DiphoneVoiceAndReducedAndSyllabicPhonesMap) {
    // kal_diphone reduces vowels (ax) and writes syllabic consonants; both voices
    // speak at their own rate.
    const std::string text = "The button and the bottle, butter and rhythm, the university's water.";
    for (const char* voice : {"cmu_us_slt_arctic_hts", "kal_diphone"}) {
        SCOPED_TRACE(voice);
        const TtsResult r = synthesize_speech(text, festival(voice));
        EXPECT_EQ(r.audio.sample_rate_hz, std::string(voice) == "kal_diphone" ? 16000 : 32000);
        EXPECT_NO_THROW(check_phone_sequence(r.phones, voice));
        const auto labels = speech_labels(r.phones);
        EXPECT_GT(labels.size(), 40u);
        EXPECT_NE(std::find(labels.begin(), labels.end(), "AH0"), labels.end());  // ax, reduced
        EXPECT_NEAR(r.phones.back().end_s, r.audio.duration_s(), 1e-9);
    }
}

TEST(TtsFestival, SpeechDoesNotDependOnWhatWasSpokenBefore) {
    const TtsResult first = synthesize_speech("The boy fell from the window.", festival());
    (void)synthesize_speech("Okay, and now something else entirely, with a question?", festival());
    (void)synthesize_speech("A diphone voice in between.", festival("kal_diphone"));
    (void)synthesize_speech("And espeak-ng.", TtsSettings{});
    expect_same_speech(synthesize_speech("The boy fell from the window.", festival()), first);
}

TEST(TtsFestival, ConcurrentCallsGiveTheSameSpeechAsSequentialOnes) {
    const TtsResult want = synthesize_speech("Come here John.", festival());
    std::vector<TtsResult> got(4);
    std::vector<std::thread> threads;
    for (std::size_t i = 0; i < got.size(); ++i)
        threads.emplace_back([&got, i] {
            // Other voices and engines interleaved with the one compared.
            if (i % 2) (void)synthesize_speech("Something else.", i == 1 ? festival("kal_diphone") : TtsSettings{});
            got[i] = synthesize_speech("Come here John.", festival());
        });
    for (auto& t : threads) t.join();
    for (const auto& g : got) expect_same_speech(g, want);
}

// A user's ~/.festivalrc must not change the speech: this one would break
// the voice if Festival loaded it. (ctest runs each test in a process of its
// own, so the Festival server starts here, with this HOME.)
TEST(TtsFestival, IgnoresTheUsersFestivalrc) {
    const std::filesystem::path home = test::temp_dir("festivalrc");
    write_text_file(home / ".festivalrc", "(set! voice_cmu_us_slt_arctic_hts nil)\n(set! voice_kal_diphone nil)\n");
    const char* old_home = std::getenv("HOME");
    const std::string saved = old_home ? old_home : "";
    ::setenv("HOME", home.c_str(), 1);
    TtsResult r;
    EXPECT_NO_THROW(r = synthesize_speech("Come here John.", festival()));
    EXPECT_EQ(speech_labels(r.phones).size(), 9u);
    if (old_home) ::setenv("HOME", saved.c_str(), 1);
    else ::unsetenv("HOME");
    std::filesystem::remove_all(home);
}

TEST(TtsFestival, UnknownVoiceListsTheInstalledOnes) {
    try {
        (void)synthesize_speech("hello", festival("cmu_us_slt_arctic"));
        FAIL() << "unknown voice accepted";
    } catch (const InputError& e) {
        EXPECT_EQ(e.first().field, "voice");
        const std::string what = e.what();
        EXPECT_NE(what.find("unknown Festival voice \"cmu_us_slt_arctic\""), std::string::npos) << what;
        EXPECT_NE(what.find("did you mean \"cmu_us_slt_arctic_hts\""), std::string::npos) << what;
        EXPECT_NE(what.find("installed Festival voices: "), std::string::npos) << what;
        for (const auto& v : installed_tts_voices(TtsEngine::Festival))
            EXPECT_NE(what.find(v), std::string::npos) << v << " missing from: " << what;
    }
    EXPECT_THROW((void)describe_tts_voice(festival("no_such_voice")), InputError);
    const auto voices = installed_tts_voices(TtsEngine::Festival);
    EXPECT_NE(std::find(voices.begin(), voices.end(), "cmu_us_slt_arctic_hts"), voices.end());
    EXPECT_NE(std::find(voices.begin(), voices.end(), "kal_diphone"), voices.end());
    // espeak-ng settings do not apply to Festival voices.
    TtsSettings rate = festival();
    rate.rate_wpm = 120;
    EXPECT_THROW((void)synthesize_speech("hello", rate), InputError);
    // Text with nothing to say, and text too long for one request.
    EXPECT_THROW((void)synthesize_speech("...", festival()), InputError);
    EXPECT_THROW((void)synthesize_speech(std::string(70000, 'a'), festival()), InputError);
    // A failed call leaves Festival usable.
    EXPECT_EQ(speech_labels(synthesize_speech("Come here John.", festival()).phones).size(), 9u);
}

TEST(TtsFestival, DescribesEngineAndVoiceWithVersions) {
    const TtsVoiceInfo slt = describe_tts_voice(festival());
    EXPECT_EQ(slt.engine, "festival");
    EXPECT_EQ(slt.engine_version.rfind("2.", 0), 0u) << slt.engine_version;
    EXPECT_EQ(slt.voice, "cmu_us_slt_arctic_hts");
    EXPECT_EQ(slt.voice_sha256.size(), 64u);
    const TtsVoiceInfo kal = describe_tts_voice(festival("kal_diphone"));
    EXPECT_EQ(kal.voice_sha256.size(), 64u);
    EXPECT_NE(kal.voice_sha256, slt.voice_sha256);
    EXPECT_EQ(describe_tts_voice(festival()).voice_sha256, slt.voice_sha256);
    const TtsVoiceInfo espeak = describe_tts_voice(TtsSettings{});
    EXPECT_EQ(espeak.engine, "espeak-ng");
    EXPECT_EQ(espeak.voice, "en-us");
    EXPECT_FALSE(espeak.engine_version.empty());
    TtsSettings bad;
    bad.voice = "en-uss";
    EXPECT_THROW((void)describe_tts_voice(bad), InputError);
}

// --- Lip sync: acoustic onsets of stops and fricatives against their labels --

// A second measure of a consonant's acoustic onset, independent of the
// steepest-drop detector the front end aligns with (core/onsets.h): the
// short-time level (10 ms windows every 1 ms) crosses the midpoint, in dB,
// between the vowel's level (median over its middle half) and the
// consonant's (median over its middle half), searched from the vowel's
// centre. Only pairs whose levels differ by at least 6 dB have an energy
// landmark to measure; the others return nothing.
std::optional<double> midpoint_onset_s(const Audio& audio, const Phone& vowel, const Phone& consonant) {
    const double rate = audio.sample_rate_hz;
    const auto level_db = [&](double centre_s) {
        const long a = std::max(0L, std::lround((centre_s - 0.005) * rate));
        const long b = std::min(long(audio.samples.size()), std::lround((centre_s + 0.005) * rate));
        double sum = 0.0;
        for (long i = a; i < b; ++i) sum += double(audio.samples[std::size_t(i)]) * audio.samples[std::size_t(i)];
        return 10.0 * std::log10(sum / double(std::max(1L, b - a)) + 1e-12);
    };
    const auto median_level_db = [&](const Phone& p) {
        std::vector<double> v;
        for (double t = p.start_s + 0.25 * p.duration_s(); t <= p.end_s - 0.25 * p.duration_s(); t += 0.001)
            v.push_back(level_db(t));
        if (v.empty()) v.push_back(level_db(p.centre_s()));
        std::nth_element(v.begin(), v.begin() + long(v.size() / 2), v.end());
        return v[v.size() / 2];
    };
    const double high = median_level_db(vowel), low = median_level_db(consonant);
    if (high - low < 6.0) return std::nullopt;
    const double mid = 0.5 * (high + low);
    for (double t = vowel.centre_s(); t <= consonant.centre_s(); t += 0.001)
        if (level_db(t) < mid) return t;
    return std::nullopt;
}

struct OnsetOffsets {
    std::vector<double> ms;   // measured onset − label start, sorted
    std::size_t pairs = 0;    // stops or fricatives after a vowel
};

// The offsets of every stop (or fricative) after a vowel with an energy
// landmark in the first `count` sentences of the default corpus.
OnsetOffsets onset_offsets(const TtsSettings& tts, std::size_t count, bool stops) {
    const Corpus corpus = read_corpus(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "corpus" / "sentences.csv");
    const PhoneInventory& inventory = PhoneInventory::builtin();
    OnsetOffsets out;
    for (std::size_t i = 0; i < count && i < corpus.sentences.size(); ++i) {
        const TtsResult r = synthesize_speech(corpus.sentences[i].text, tts);
        for (std::size_t k = 1; k < r.phones.size(); ++k) {
            const Phone& p = r.phones[k];
            if (p.symbol == "sil" || !inventory.is_vowel(r.phones[k - 1].symbol)) continue;
            const FeatureVector f = inventory.features_of(p);
            const bool stop = f[std::size_t(Feature::Stop)] == 1.0f;
            if (stop != stops || (!stop && f[std::size_t(Feature::Fricative)] != 1.0f)) continue;
            ++out.pairs;
            if (const auto t = midpoint_onset_s(r.audio, r.phones[k - 1], p)) out.ms.push_back(1000.0 * (*t - p.start_s));
        }
    }
    std::sort(out.ms.begin(), out.ms.end());
    return out;
}

double fraction_within(const std::vector<double>& v, double low, double high) {
    return double(std::count_if(v.begin(), v.end(), [&](double x) { return x >= low && x <= high; })) / double(v.size());
}

TEST(Onsets, FindAnAbruptClosureWhereItIs) {
    // A synthetic vowel (a 150 Hz buzz) closed by silence at 0.300 s and
    // labelled 0.290 s: the onset is found at the closure, 10 ms after the label.
    Audio a;
    a.sample_rate_hz = 16000;
    for (int i = 0; i < 8000; ++i) a.samples.push_back(i >= 1600 && i < 4800 ? float(0.3 * std::sin(i * 0.0589)) : 0.0f);
    const PhoneSequence phones = {{"sil", 0.0, 0.1}, {"AA", 0.1, 0.29, true}, {"P", 0.29, 0.4}, {"sil", 0.4, 0.5}};
    const auto onsets = obstruent_onsets(a, phones);
    ASSERT_EQ(onsets.size(), 1u);
    EXPECT_EQ(onsets[0].symbol, "P");
    EXPECT_TRUE(onsets[0].stop);
    EXPECT_NEAR(onsets[0].acoustic_s, 0.300, 0.001);
    EXPECT_NEAR(onsets[0].offset_s(), 0.010, 0.001);
    EXPECT_GT(onsets[0].drop_db, 60.0);

    // Aligned, the vowel ends and the stop starts at the closure; a shift
    // beyond max_shift_s, or a drop below min_drop_db, leaves the labels.
    PhoneSequence aligned = phones;
    EXPECT_EQ(align_obstruent_onsets(a, aligned), 1u);
    EXPECT_NEAR(aligned[1].end_s, 0.300, 0.001);
    EXPECT_EQ(aligned[2].start_s, aligned[1].end_s);
    PhoneSequence kept = phones;
    EXPECT_EQ(align_obstruent_onsets(a, kept, {.max_shift_s = 0.005}), 0u);
    EXPECT_EQ(align_obstruent_onsets(a, kept, {.max_shift_s = 0.04, .min_drop_db = 200.0}), 0u);
    EXPECT_EQ(kept, phones);
}

// Lip sync with the default voice: the audio and the phone times come from
// one synthesis, and each stop's and fricative's start after a vowel is
// aligned to the audio's onset. Measured here by the midpoint crossing (a
// measure the alignment does not use) on 20 sentences of the default corpus:
// the median offset is within 5 ms and at least 85 % of the onsets with an
// energy landmark lie within 10 ms of their label (the two measures differ by
// a few ms where the level falls in two steps). Without the alignment, the
// SLT voice puts the label a median 20 ms before the onset (HTS gives the
// vowel-to-consonant transition to the consonant) and fewer than half of the
// stops are within 10 ms. (espeak-ng's vowels fade over 40-80 ms into a
// stop, so the two measures disagree by more than 10 ms there: docs/tts.md.)
TEST(TtsLipSync, ObstruentOnsetsLieWithin10MsOfTheirLabels) {
    for (const bool stops : {true, false}) {
        SCOPED_TRACE(stops ? "stops" : "fricatives");
        const OnsetOffsets o = onset_offsets(festival(), 20, stops);
        ASSERT_GT(o.ms.size(), 20u);
        EXPECT_GE(double(o.ms.size()), 0.7 * double(o.pairs)) << "too few landmarks to measure";
        const double median = o.ms[o.ms.size() / 2];
        EXPECT_LE(std::abs(median), 5.0);
        EXPECT_GE(fraction_within(o.ms, -10.0, 10.0), 0.85)
            << "min " << o.ms.front() << " ms, median " << median << " ms, max " << o.ms.back() << " ms";
    }
    TtsSettings raw = festival();
    raw.align_onsets = false;
    const OnsetOffsets o = onset_offsets(raw, 20, true);
    EXPECT_GE(o.ms[o.ms.size() / 2], 10.0);
    EXPECT_LT(fraction_within(o.ms, -10.0, 10.0), 0.5);
}

}  // namespace
}  // namespace avsi
