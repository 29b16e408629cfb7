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
#include <thread>

#include "avsi/core/corpus.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/labels.h"
#include "avsi/core/onsets.h"

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
        TtsSettings s;
        s.voice = voice;
        TtsResult r;
        ASSERT_NO_THROW(r = synthesize_speech(text, s));
        EXPECT_NO_THROW(check_phone_sequence(r.phones, voice));
        EXPECT_GT(speech_labels(r.phones).size(), 150u);
        EXPECT_NEAR(r.phones.back().end_s, r.audio.duration_s(), 1e-9);
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
    s.voice = "de";
    EXPECT_THROW((void)synthesize_speech("hallo", s), InputError);  // not English
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
    const std::filesystem::path home =
        std::filesystem::temp_directory_path() / ("avsi_festivalrc_" + std::to_string(::getpid()));
    std::filesystem::create_directories(home);
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

// The offsets (acoustic onset − label, ms) of every stop and fricative after
// a vowel in the first `count` sentences of the default corpus.
std::vector<double> onset_offsets_ms(const TtsSettings& tts, std::size_t count, bool stops) {
    const Corpus corpus = read_corpus(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "corpus" / "sentences.csv");
    std::vector<double> out;
    for (std::size_t i = 0; i < count && i < corpus.sentences.size(); ++i) {
        const TtsResult r = synthesize_speech(corpus.sentences[i].text, tts);
        for (const auto& o : obstruent_onsets(r.audio, r.phones))
            if (o.stop == stops) out.push_back(1000.0 * o.offset_s());
    }
    std::sort(out.begin(), out.end());
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
}

// The Festival path keeps the audio and the phone times from one synthesis
// (HTS state durations give both), so they never drift apart. Measured on
// the default corpus (bench/tts_voices.cpp, README "Choosing the voice"), the
// acoustic closure or frication of a stop or fricative after a vowel comes a
// median 19 ms after its label with SLT (p5 +7.5, p95 +36 ms): HTS voices
// assign the vowel-to-consonant formant transition to the consonant. The
// issue's 10 ms criterion therefore does NOT hold (5 % of onsets are within
// 10 ms); what holds, and is checked here on 20 sentences, is that the face
// never lags the audio at these boundaries by more than 10 ms and the
// audio's onset lies inside the consonant's label, a median 10-30 ms in.
TEST(TtsFestival, ObstruentOnsetsFallInsideTheirLabelsJustAfterTheStart) {
    for (const bool stops : {true, false}) {
        SCOPED_TRACE(stops ? "stops" : "fricatives");
        const std::vector<double> v = onset_offsets_ms(festival(), 20, stops);
        ASSERT_GT(v.size(), 20u);
        const double median = v[v.size() / 2];
        EXPECT_GE(median, 10.0);
        EXPECT_LE(median, 30.0);
        EXPECT_GE(fraction_within(v, -10.0, 45.0), 0.9) << "min " << v.front() << " ms, max " << v.back() << " ms";
    }
}

}  // namespace
}  // namespace avsi
