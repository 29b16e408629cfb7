// Adaptive SRT sessions without a window (experiment/adaptive_session.h):
// the noise mixed at exactly the track's SNR under both level rules and both
// noise stages, the live
// score stepping the track, a resume that replays the stored presentations to
// the same next level, the interleaved design, the machine's repeat of a
// first sentence, and the store's schema migration to version 3.
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <cmath>

#include <fmt/format.h>

#include "avsi/core/corpus.h"
#include "avsi/core/error.h"
#include "avsi/core/protocol.h"
#include "avsi/experiment/adaptive_session.h"
#include "avsi/experiment/session.h"
#include "avsi/experiment/web_study.h"
#include "avsi/stimuli/builder.h"
#include "avsi/core/audio.h"
#include "avsi/core/files.h"
#include "avsi/vocoder/masking.h"
#include "avsi/vocoder/vocoder.h"
#include "support/temp_dir.h"

namespace avsi::experiment {
namespace {

namespace fs = std::filesystem;
using test::temp_dir;

const fs::path kProtocol = fs::path(AVSI_TEST_DATA_DIR) / "adaptive" / "protocol.toml";

// A speech-like test signal: a 150 Hz harmonic complex, syllable-modulated at
// 4 Hz, with pauses, 1.5 s at 16 kHz.
std::vector<float> speechlike(int rate) {
    std::vector<float> s(static_cast<std::size_t>(rate * 3 / 2));
    for (std::size_t i = 0; i < s.size(); ++i) {
        const double t = static_cast<double>(i) / rate;
        const double envelope = (t > 0.2 && t < 1.3) ? std::pow(std::sin(M_PI * 4 * t), 2) : 0.0;
        double v = 0;
        for (int h = 1; h <= 12; ++h) v += std::sin(2 * M_PI * 150 * h * t) / h;
        s[i] = static_cast<float>(0.08 * envelope * v);
    }
    return s;
}

// The SNR in a mixture whose stimulus span starts at `lead`: the speech part
// is gain·speech, the noise part what is left of the span.
double measured_snr_db(const std::vector<float>& mixed, std::size_t lead, const std::vector<float>& speech,
                       double speech_gain_db, int rate) {
    const double g = std::pow(10.0, speech_gain_db / 20.0);
    std::vector<double> s(speech.size());
    double nn = 0;
    for (std::size_t i = 0; i < speech.size(); ++i) {
        s[i] = g * speech[i];
        const double n = mixed[lead + i] - s[i];
        nn += n * n;
    }
    const double speech_rms = vocoder::speech_level_rms(s, rate, vocoder::SnrReference::ActiveFrames);
    return 20 * std::log10(speech_rms / std::sqrt(nn / speech.size()));
}

// The RMS in dBFS of x[from, to).
double rms_dbfs(const std::vector<float>& x, std::size_t from, std::size_t to) {
    double sum = 0;
    for (std::size_t i = from; i < to; ++i) sum += double(x[i]) * x[i];
    return 10 * std::log10(sum / double(to - from));
}

std::vector<PlannedTrial> plan_of(const Protocol& p, const Corpus& c, int subject) {
    return design_subject(p, assign_lists(c, p.design), subject);
}

}  // namespace

// Both noise stages under both level rules: the masker at exactly the
// track's SNR over the stimulus's span (at the vocoder's input when the noise
// goes before it, the output then the vocoder's of that input, sample for
// sample), running through the lead and the tail at its level.
TEST(AdaptiveSession, MixesTheNoiseAtExactlyTheTracksSnrUnderBothLevelRulesAndStages) {
    Protocol p = load_protocol(kProtocol);
    const Corpus corpus = read_corpus(p.corpus.sentences);
    const auto plan = plan_of(p, corpus, 1);
    const auto speech = speechlike(16000);
    const int rate = 16000;
    for (const std::string stage : {"before", "after"}) {
        for (const std::string rule : {"noise", "speech"}) {
            SCOPED_TRACE(stage + ", " + rule);
            ConfigValue v;
            v.string = rule;
            p.adaptive.set("level_rule", v);
            v.string = stage;
            p.adaptive.set("noise_stage", v);
            AdaptiveSession a(p, corpus, {}, "db");
            EXPECT_EQ(a.settings().noise_lead_s, 0.5);
            const std::size_t lead = 8000, tail = 8000;
            int presentations = 0;
            for (const auto& t : plan) {
                if (t.phase != Phase::Test) continue;
                const MixedPresentation m = a.mix(t, speech, rate);
                EXPECT_DOUBLE_EQ(m.level_db, a.level_db(t));
                EXPECT_DOUBLE_EQ(m.lead_s, 0.5);
                ASSERT_EQ(m.samples.size(), lead + speech.size() + tail);
                // The SNR where it is set: the vocoder's input (before the
                // vocoder's own limiter) or the output.
                const std::vector<float>& at = stage == "before" ? m.vocoder_input : m.samples;
                ASSERT_EQ(at.size(), m.samples.size());
                const double gain_db = m.speech_gain_db - (stage == "before" ? m.limit_gain_db : 0.0);
                EXPECT_NEAR(measured_snr_db(at, lead, speech, gain_db, rate), m.level_db, 0.01);
                // The masker runs before and after the stimulus at its level
                // (ramps left out; within 3 dB: the test signal's line spectrum
                // makes its speech-shaped noise narrowband, slowly fluctuating).
                const double noise_db = m.noise_gain_db - (stage == "before" ? m.limit_gain_db : 0.0);
                EXPECT_NEAR(rms_dbfs(at, 400, lead), noise_db, 3.0);
                EXPECT_NEAR(rms_dbfs(at, lead + speech.size(), at.size() - 400), noise_db, 3.0);
                EXPECT_EQ(at.front(), 0.0f);  // ramped in from silence
                if (rule == "speech" && m.limit_gain_db == 0.0) {
                    EXPECT_NEAR(m.noise_gain_db, p.corpus.level_dbfs, 1e-6);
                }
                if (stage == "before") {
                    vocoder::VocoderSettings vs = stimuli::protocol_vocoder_settings(p);
                    vs.seed = stimuli::sentence_vocoder_seed(vs, corpus.sentence(t.sentence).id);
                    Audio in;
                    in.sample_rate_hz = rate;
                    in.samples = m.vocoder_input;
                    EXPECT_EQ(vocoder::vocode(in, vs).audio.samples, m.samples);
                } else {
                    EXPECT_TRUE(m.vocoder_input.empty());
                }
                ++presentations;
                // Every keyword wrong: the tracks climb, so later mixtures are at other SNRs.
                a.record(t, m, "", std::vector<bool>(3, false), std::vector<bool>(3, false));
            }
            EXPECT_EQ(presentations, 20);
            EXPECT_GT(a.track("audio-only").level_db(), 0.0);
        }
    }
}

TEST(AdaptiveSession, TheLiveScoreStepsTheTrackAndAResumeReplaysToTheSameLevels) {
    const Protocol p = load_protocol(kProtocol);
    const Corpus corpus = read_corpus(p.corpus.sentences);
    const auto plan = plan_of(p, corpus, 3);
    const fs::path dir = temp_dir("adaptive_resume");
    Store store(dir / "s.sqlite");
    store.add_subject(3, plan);
    const int session = store.begin_session(3, 1, "");
    const auto speech = speechlike(16000);
    AdaptiveSession a(p, corpus, {}, "db");
    int answered = 0;
    for (const auto& t : plan) {
        if (answered == 9) break;  // "killed" in the middle of the tracks
        const Sentence& s = corpus.sentence(t.sentence);
        // Alternately the whole sentence and nothing.
        const std::string answer = answered % 2 == 0 ? s.text : "";
        for (;;) {
            const MixedPresentation m = a.mix(t, speech, 16000);
            const auto marks = a.score(t, answer);
            ASSERT_EQ(marks.size(), s.keywords.size());
            EXPECT_EQ(std::count(marks.begin(), marks.end(), true), answer.empty() ? 0 : static_cast<long>(marks.size()));
            const bool again = a.repeats(t, marks);
            const AdaptiveRecord r = a.record(t, m, answer, marks, marks);
            EXPECT_EQ(r.repeat, again);
            if (r.repeat) {
                store.commit_attempt(session, t, r);
                EXPECT_THROW(store.commit_attempt(session, t, r), std::exception);  // the same attempt twice
                continue;
            }
            store.commit_trial(session, t, Presentation{}, Response{answer, 0.0, answer.empty()}, r);
            break;
        }
        ++answered;
    }
    // The second track's first sentence was answered with nothing: presented
    // again, higher, until the repeat limit, every presentation stored.
    const auto stored = store.adaptive_trials(3);
    ASSERT_GT(stored.size(), 9u);
    AdaptiveSession resumed(p, corpus, stored, "db");
    for (const auto& c : p.conditions) {
        SCOPED_TRACE(c.name);
        EXPECT_DOUBLE_EQ(resumed.track(c.name).level_db(), a.track(c.name).level_db());
        EXPECT_EQ(resumed.track(c.name).steps().size(), a.track(c.name).steps().size());
    }
    // A stored level the rules do not give is refused (the protocol changed).
    auto tampered = stored;
    for (auto& row : tampered)
        if (!row.record.track.empty()) {
            row.record.level_db += 1.0;
            break;
        }
    EXPECT_THROW(AdaptiveSession(p, corpus, tampered, "db"), InputError);
    fs::remove_all(dir);
}

TEST(AdaptiveSession, BandCountTrackPlaysTheVariantOfItsLevelAndResumes) {
    const fs::path dir = temp_dir("adaptive_session_bands");
    const fs::path source = fs::path(AVSI_TEST_DATA_DIR) / "adaptive";
    fs::copy_file(source / "corpus.csv", dir / "corpus.csv");
    std::string text = read_text_file(source / "protocol.toml");
    text = text.substr(0, text.find("[adaptive]")) +
           "[adaptive]\nvariable = \"bands\"\nlevels = [2, 4, 8]\nstart_level = 4\nrepeat_first = false\n"
           "large_step_levels = 1\nsrt_from = 2\n";
    write_text_file(dir / "bands.toml", text);
    const Protocol p = load_protocol(dir / "bands.toml");
    const Corpus corpus = read_corpus(p.corpus.sentences);
    const auto plan = plan_of(p, corpus, 1);
    AdaptiveSession a(p, corpus, {}, "db");
    a.set_stimuli_dir(dir / "stimuli");
    try {
        a.check_variants(plan);
        FAIL() << "accepted a folder without variants";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(".bands-"), std::string::npos) << e.what();
    }
    // Each variant: a constant equal to its level / 100, so the samples say which one played.
    for (const auto& t : plan)
        for (const double level : a.settings().levels) {
            const fs::path path = dir / "stimuli" / stimuli::variant_audio_path(t.stimulus, "bands", level);
            fs::create_directories(path.parent_path());
            Audio v;
            v.sample_rate_hz = 16000;
            v.samples.assign(800, static_cast<float>(level / 100.0));
            write_audio(path, v, SampleFormat::Float32);
        }
    EXPECT_NO_THROW(a.check_variants(plan));
    const auto speech = speechlike(16000);
    std::vector<Store::AdaptiveRow> stored;
    std::map<std::string, int> per_track;
    int n = 0;
    for (const auto& t : plan) {
        if (n == 6) break;
        const double level = a.level_db(t);
        EXPECT_EQ(a.variant_path(t).filename().string(),
                  fs::path(t.stimulus).stem().string() + fmt::format(".bands-{}.wav", level));
        const MixedPresentation m = a.mix(t, speech, 16000);
        EXPECT_DOUBLE_EQ(m.level_db, level);
        ASSERT_EQ(m.samples.size(), 800u);
        EXPECT_FLOAT_EQ(m.samples.front(), static_cast<float>(level / 100.0));
        EXPECT_FLOAT_EQ(m.samples.back(), static_cast<float>(level / 100.0));
        EXPECT_EQ(m.noise_gain_db, kNoNoiseDbfs);
        if (t.phase != Phase::Test) {
            EXPECT_DOUBLE_EQ(level, 8.0);  // the practice level defaults to the top one
            continue;
        }
        // Each track alternately all right and all wrong: 4 → 2 → 4 → 2 … (one position a step).
        const int k = per_track[t.condition]++;
        const auto marks = a.score(t, k % 2 == 0 ? corpus.sentence(t.sentence).text : "");
        const AdaptiveRecord r = a.record(t, m, "", marks, marks);
        EXPECT_DOUBLE_EQ(r.level_db, level);
        EXPECT_DOUBLE_EQ(r.next_level_db, a.level_db(t));
        EXPECT_DOUBLE_EQ(r.step_db, r.next_level_db - r.level_db);
        EXPECT_TRUE(r.level_db == 2.0 || r.level_db == 4.0) << r.level_db;
        stored.push_back({1, t.position, 1, r});
        ++n;
    }
    // A variant at another sample rate than the video's audio is refused.
    const auto test_trial = std::find_if(plan.begin(), plan.end(), [](const PlannedTrial& t) { return t.phase == Phase::Test; });
    EXPECT_THROW(a.mix(*test_trial, speech, 48000), InputError);
    // Resume: the replay of the stored records gives the same next levels.
    AdaptiveSession resumed(p, corpus, stored, "db");
    for (const auto& c : p.conditions)
        EXPECT_DOUBLE_EQ(resumed.track(c.name).level_db(), a.track(c.name).level_db()) << c.name;
    auto tampered = stored;
    tampered.front().record.level_db = 8.0;
    EXPECT_THROW(AdaptiveSession(p, corpus, tampered, "db"), InputError);
    fs::remove_all(dir);
}

TEST(AdaptiveDesign, InterleavedTracksAlternateConditionsSentenceBySentence) {
    const Protocol p = load_protocol(kProtocol);
    const Corpus corpus = read_corpus(p.corpus.sentences);
    const auto plan = plan_of(p, corpus, 2);
    ASSERT_EQ(plan.size(), 22u);
    std::vector<PlannedTrial> test;
    for (const auto& t : plan)
        if (t.phase == Phase::Test) test.push_back(t);
    ASSERT_EQ(test.size(), 20u);
    for (std::size_t i = 0; i < test.size(); ++i) {
        EXPECT_EQ(test[i].position, static_cast<int>(i) + 3);
        EXPECT_EQ(test[i].block, 1);
        if (i > 0) {
            EXPECT_NE(test[i].condition, test[i - 1].condition) << i;
        }
    }
    // Blocked tracks keep the design's blocks.
    Protocol blocked = p;
    ConfigValue v;
    v.string = "blocked";
    blocked.adaptive.set("tracks", v);
    const auto b = plan_of(blocked, corpus, 2);
    EXPECT_EQ(b[2].condition, b[3].condition);
    EXPECT_EQ(b.back().block, 2);
}

TEST(AdaptiveDesign, TheMachinePresentsARepeatedTrialAgainWithoutAnsweringIt) {
    std::vector<PlannedTrial> plan(2);
    for (int i = 0; i < 2; ++i) {
        plan[static_cast<std::size_t>(i)].position = i + 1;
        plan[static_cast<std::size_t>(i)].subject = 1;
    }
    SessionSettings settings;
    settings.fixation_ms = 100;
    settings.response_delay_ms = 0;
    SessionMachine m(plan, {}, settings);
    int asked = 0;
    m.set_repeat_rule([&](int index, const Response& r) {
        ++asked;
        return index == 0 && r.text == "wrong";
    });
    double now = 0;
    m.continue_pressed(now);
    auto present_and_answer = [&](const std::string& text) {
        now += 0.2;
        m.tick(now);
        ASSERT_EQ(m.screen(), Screen::Stimulus);
        m.stimulus_finished(now);
        ASSERT_EQ(m.screen(), Screen::Response);
        m.submit(text, now);
    };
    present_and_answer("wrong");
    auto actions = m.take_actions();
    ASSERT_EQ(actions.size(), 2u);  // StartStimulus, CommitResponse(repeat)
    EXPECT_TRUE(actions[1].repeat);
    EXPECT_EQ(m.trial_index(), 0);
    EXPECT_EQ(m.answered_count(), 0);
    EXPECT_EQ(m.screen(), Screen::Fixation);
    present_and_answer("right");
    actions = m.take_actions();
    ASSERT_EQ(actions.size(), 2u);
    EXPECT_FALSE(actions[1].repeat);
    EXPECT_EQ(m.trial_index(), 1);
    EXPECT_EQ(m.answered_count(), 1);
    EXPECT_EQ(asked, 2);
}

TEST(AdaptiveDesign, TheWebStudyRefusesAdaptiveProtocols) {
    ExportWebSettings s;
    s.protocol = kProtocol;
    s.out_dir = temp_dir("adaptive_web") / "study";
    try {
        export_web(s);
        FAIL() << "exported";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("protocol.toml:35:1: error: adaptive: adaptive SRT tracks run in the lab runner"),
                  std::string::npos)
            << e.what();
    }
    EXPECT_FALSE(fs::exists(s.out_dir));
}

TEST(Store, MigratesAVersion2DatabaseToVersion3KeepingItsData) {
    const fs::path dir = temp_dir("store_v2");
    const fs::path db = dir / "v2.sqlite";
    PlannedTrial t;
    t.subject = 1;
    t.position = 1;
    t.condition = "a";
    t.sentence = "s1";
    t.stimulus = "s1/a.mp4";
    {
        Store store(db);
        store.add_subject(1, {t});
        store.commit_trial(store.begin_session(1, 1, ""), t, Presentation{}, Response{"hello", 12.0, false});
    }
    // Make it a version-2 database: no adaptive_trials table.
    {
        sqlite3* h = nullptr;
        ASSERT_EQ(sqlite3_open(db.c_str(), &h), SQLITE_OK);
        ASSERT_EQ(sqlite3_exec(h, "DROP TABLE adaptive_trials; PRAGMA user_version=2;", nullptr, nullptr, nullptr), SQLITE_OK);
        sqlite3_close(h);
    }
    Store store(db);
    EXPECT_EQ(store.schema_version(), 3);
    const auto responses = store.responses();
    ASSERT_EQ(responses.size(), 1u);
    EXPECT_EQ(responses[0].response.text, "hello");
    EXPECT_TRUE(store.adaptive_trials().empty());
    // The new table works after the migration.
    PlannedTrial t2 = t;
    t2.position = 2;
    {
        sqlite3* h = nullptr;
        ASSERT_EQ(sqlite3_open(db.c_str(), &h), SQLITE_OK);
        ASSERT_EQ(sqlite3_exec(h, "INSERT INTO planned_trials VALUES(1, 2, 'test', 1, '1', 'a', 's2', 's2/a.mp4')",
                               nullptr, nullptr, nullptr),
                  SQLITE_OK);
        sqlite3_close(h);
    }
    AdaptiveRecord r;
    r.track = "a";
    r.presentation = 1;
    r.level_db = -2.5;
    r.keywords = 3;
    r.correct = 2;
    r.marks = "110";
    store.commit_trial(1, t2, Presentation{}, Response{"x", 0.0, false}, r);
    const auto rows = store.adaptive_trials(1);
    ASSERT_EQ(rows.size(), 1u);
    r.answered_utc = rows[0].record.answered_utc;
    EXPECT_EQ(rows[0].record, r);
    fs::remove_all(dir);
}

}  // namespace avsi::experiment
