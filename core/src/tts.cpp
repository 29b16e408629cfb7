// Text-to-speech front end. espeak-ng: audio from the synth callback, phone
// timing from espeakEVENT_PHONEME events, stress from espeak_TextToPhonemes.
// Festival (festival_tts.cpp): audio and the Segment relation with syllable
// stress. Both are mapped into the project phone set through
// protocols/languages/en/phone_map.tsv and padded to the same edge silences. Each utterance
// is synthesised in a forked child from a freshly initialised engine, so the
// output never depends on what was spoken before (docs/tts.md). Then the
// obstruent onsets are aligned to the audio (onsets.h).
#include "avsi/core/tts.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <tuple>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/onsets.h"
#include "espeak_library.h"
#include "espeak_tts.h"
#include "festival_tts.h"
#include "wire.h"

namespace avsi {

namespace {

struct EspeakEvent {
    std::string mnemonic;  // phoneme events only
    long sample = 0;       // audio position in samples
    int word = 0;          // index of the word the phoneme belongs to (0 before the first)
};

// What the synth callback collects for one synthesize_speech call.
struct Collector {
    std::vector<short> samples;
    std::vector<EspeakEvent> phonemes;
    long end_sample = -1;
    int word = 0;
};

// espeak-ng's functions (loaded on first use: espeak_library.h).
const detail::EspeakLibrary& espeak() { return detail::espeak_library(); }

std::mutex g_espeak_mutex;  // espeak-ng's state is global and not thread-safe
Collector* g_collector = nullptr;
int g_sample_rate_hz = 0;
int g_children_forked = 0;  // by start_espeak

int synth_callback(short* wav, int count, espeak_EVENT* events) {
    if (!g_collector) return 1;
    if (wav && count > 0) g_collector->samples.insert(g_collector->samples.end(), wav, wav + count);
    for (espeak_EVENT* e = events; e && e->type != espeakEVENT_LIST_TERMINATED; ++e) {
        if (e->type == espeakEVENT_WORD) {
            ++g_collector->word;
        } else if (e->type == espeakEVENT_PHONEME) {
            char name[sizeof(e->id.string) + 1] = {};
            std::memcpy(name, e->id.string, sizeof(e->id.string));
            g_collector->phonemes.push_back({name, static_cast<long>(e->sample), g_collector->word});
        } else if (e->type == espeakEVENT_END || e->type == espeakEVENT_MSG_TERMINATED) {
            g_collector->end_sample = std::max(g_collector->end_sample, static_cast<long>(e->sample));
        }
    }
    return 0;
}

// Initialises espeak-ng once (caller holds the mutex).
void ensure_initialized() {
    if (g_sample_rate_hz > 0) return;
    const int rate = espeak().Initialize(AUDIO_OUTPUT_SYNCHRONOUS, 0, nullptr,
                                         espeakINITIALIZE_PHONEME_EVENTS | espeakINITIALIZE_DONT_EXIT);
    if (rate <= 0)
        throw std::runtime_error("espeak-ng could not be initialised (is espeak-ng-data installed?)");
    g_sample_rate_hz = rate;
    espeak().SetSynthCallback(synth_callback);
}

// The languages with a phone table (protocols/languages/<code>/), sorted.
const std::vector<std::string>& table_languages() {
    static const std::vector<std::string> codes = [] {
        std::vector<std::string> out;
        std::error_code ec;
        for (const auto& e : std::filesystem::directory_iterator(std::filesystem::path(AVSI_PROTOCOLS_DIR) / "languages", ec))
            if (e.is_directory()) out.push_back(e.path().filename().string());
        std::sort(out.begin(), out.end());
        return out;
    }();
    return codes;
}

// The phone table of an espeak-ng language code ("en-gb-x-rp" -> "en",
// "sv" -> "sv"), or "" when there is none.
std::string table_of_language(const std::string& language) {
    const std::string base = language.substr(0, language.find('-'));
    const auto& codes = table_languages();
    return std::find(codes.begin(), codes.end(), base) != codes.end() ? base : std::string();
}

// The language codes of the installed voices the phone tables cover
// ("de", "en-us", "en-gb-x-rp", "sv", …).
std::vector<std::string> english_voice_languages() {
    std::vector<std::string> out;
    for (const espeak_VOICE** v = espeak().ListVoices(nullptr); v && *v; ++v) {
        // `languages`: repeated [priority byte][language\0], ending with a 0 byte.
        for (const char* p = (*v)->languages; p && *p; p += std::strlen(p + 1) + 2) {
            const std::string language(p + 1);
            if (!table_of_language(language).empty() &&
                std::find(out.begin(), out.end(), language) == out.end())
                out.push_back(language);
        }
    }
    std::sort(out.begin(), out.end());
    return out;
}

// The covered voices as a list for an error message.
std::string english_voice_list() {
    std::string list;
    for (const auto& l : english_voice_languages()) list += (list.empty() ? "" : ", ") + l;
    return list;
}

// Selects the voice; returns the phone-map variant ("" for en-us tables, "en"
// for the non-rhotic English tables, the language's code for another
// language's table: "sv", "de"). Caller holds the mutex. The installed
// voices are listed only for an error: espeak_SetVoiceByName lists them
// itself unless this process already has (start_espeak).
std::string select_voice(const std::string& voice) {
    if (voice.empty() || espeak().SetVoiceByName(voice.c_str()) != EE_OK) {
        const std::string close = closest_match(voice, english_voice_languages());
        throw InputError("tts", 0, 0, "voice",
                         fmt::format("unknown espeak-ng voice \"{}\"{}; voices with a phone table: {}", voice,
                                     close.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", close),
                                     english_voice_list()));
    }
    const espeak_VOICE* current = espeak().GetCurrentVoice();
    const std::string language = current && current->languages ? std::string(current->languages + 1) : "";
    const std::string identifier = current && current->identifier ? current->identifier : "";
    const std::string table = table_of_language(language);
    if (table.empty())
        throw InputError("tts", 0, 0, "voice",
                         fmt::format("voice \"{}\" speaks \"{}\", which has no phone table "
                                     "(protocols/languages/{}/); voices with a phone table: {}",
                                     voice, language, language.substr(0, language.find('-')), english_voice_list()));
    if (table != "en") return table;
    std::string id_lower = identifier;
    for (char& c : id_lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return id_lower.find("en-us") != std::string::npos ? "" : "en";
}

struct StressToken {
    std::string base;
    std::optional<bool> stress;
};

// espeak_TextToPhonemes output for the whole text, one string per clause
// ('|' between phonemes). Caller holds the mutex.
std::vector<std::string> phoneme_clauses(const std::string& text) {
    std::vector<std::string> clauses;
    const void* pointer = text.c_str();
    const int mode = static_cast<int>('|') << 8;  // ASCII names, '|' between phonemes
    while (pointer) {
        const char* out = espeak().TextToPhonemes(&pointer, espeakCHARS_UTF8, mode);
        if (!out) break;
        clauses.emplace_back(out);
    }
    return clauses;
}

// The clauses split into mnemonics with their stress marks separated.
std::vector<StressToken> stress_tokens(const std::vector<std::string>& clauses, const PhoneInventory& inventory,
                                       const std::string& variant) {
    std::vector<StressToken> tokens;
    for (const std::string& clause : clauses) {
        std::size_t i = 0;
        while (i < clause.size()) {
            std::size_t j = i;
            while (j < clause.size() && clause[j] != '|' && clause[j] != ' ') ++j;
            if (j > i) {
                auto [base, stress] = inventory.split_espeak_stress(std::string_view(clause).substr(i, j - i), variant);
                tokens.push_back({std::move(base), stress});
            }
            i = j + 1;
        }
    }
    return tokens;
}

// For each event, the stress of the matching TextToPhonemes token (Levenshtein
// alignment over mnemonics; substitutions also carry stress across).
std::vector<bool> align_stress(const std::vector<EspeakEvent>& events, const std::vector<StressToken>& tokens) {
    const std::size_t n = events.size(), m = tokens.size();
    std::vector<std::vector<int>> cost(n + 1, std::vector<int>(m + 1, 0));
    for (std::size_t i = 0; i <= n; ++i) cost[i][0] = static_cast<int>(i);
    for (std::size_t j = 0; j <= m; ++j) cost[0][j] = static_cast<int>(j);
    for (std::size_t i = 1; i <= n; ++i)
        for (std::size_t j = 1; j <= m; ++j) {
            const int sub = events[i - 1].mnemonic == tokens[j - 1].base ? 0 : 1;
            cost[i][j] = std::min({cost[i - 1][j - 1] + sub, cost[i - 1][j] + 1, cost[i][j - 1] + 1});
        }
    std::vector<bool> stressed(n, false);
    std::size_t i = n, j = m;
    while (i > 0 && j > 0) {
        const int sub = events[i - 1].mnemonic == tokens[j - 1].base ? 0 : 1;
        if (cost[i][j] == cost[i - 1][j - 1] + sub) {
            stressed[i - 1] = tokens[j - 1].stress.value_or(false);
            --i;
            --j;
        } else if (cost[i][j] == cost[i - 1][j] + 1) {
            --i;
        } else {
            --j;
        }
    }
    return stressed;
}

// --- Synthesis in a forked child -------------------------------------------
//
// espeak-ng keeps wave-generator state between utterances: the same text
// comes out a few samples longer or shorter depending on what was spoken
// before in the process. So this process never synthesises. It initialises
// espeak-ng once and forks a child per utterance; the child starts from that
// same freshly initialised state, synthesises, sends the result through a
// pipe and exits. Every utterance is then identical whatever came before,
// in any order, in any process. (The child uses only espeak-ng, malloc and
// write(), which are safe after fork().)

struct Synthesis {
    Collector collector;
    std::vector<std::string> clauses;  // espeak_TextToPhonemes, for the stress marks
    std::string variant;
};

enum : std::int64_t { kOk = 0, kInputError = 1, kFailure = 2 };

// Serialises the child's error in place of its answer.
void write_error(detail::WireWriter& w, const std::exception& e) {
    w.clear();
    if (const auto* input = dynamic_cast<const InputError*>(&e)) {
        w.i64(kInputError);
        w.str(input->first().field);
        w.str(input->first().message);
    } else {
        w.i64(kFailure);
        w.str(e.what());
    }
}

// In the child: the whole synthesis, serialised.
std::string child_synthesis(const std::string& text, const TtsSettings& settings) {
    detail::WireWriter w;
    try {
        Synthesis r;
        r.variant = select_voice(settings.voice);
        espeak().SetParameter(espeakRATE, settings.rate_wpm, 0);
        espeak().SetParameter(espeakPITCH, settings.pitch, 0);
        r.clauses = phoneme_clauses(text);
        g_collector = &r.collector;
        const espeak_ERROR status = espeak().Synth(text.c_str(), text.size() + 1, 0, POS_CHARACTER, 0,
                                                   espeakCHARS_UTF8, nullptr, nullptr);
        espeak().Synchronize();
        g_collector = nullptr;
        if (status != EE_OK) throw std::runtime_error(fmt::format("espeak-ng failed to synthesise (error {})", int(status)));
        w.i64(kOk);
        w.str(r.variant);
        w.i64(static_cast<std::int64_t>(r.clauses.size()));
        for (const auto& c : r.clauses) w.str(c);
        w.i64(static_cast<std::int64_t>(r.collector.phonemes.size()));
        for (const auto& e : r.collector.phonemes) {
            w.str(e.mnemonic);
            w.i64(e.sample);
            w.i64(e.word);
        }
        w.i64(r.collector.end_sample);
        w.i64(static_cast<std::int64_t>(r.collector.samples.size()));
        w.bytes(r.collector.samples.data(), r.collector.samples.size() * sizeof(short));
    } catch (const std::exception& e) {
        write_error(w, e);
    }
    return w.data();
}

}  // namespace

namespace detail {
// A child synthesising one utterance: its process and the read end of the
// pipe its answer comes through (PendingSpeech::State holds one).
struct EspeakChild {
    pid_t pid = -1;
    int fd = -1;
    int rate_hz = 0;
};
}  // namespace detail

namespace {

using detail::EspeakChild;

// Forks a child that runs `work` (its answer: a serialised message that
// starts with kOk, kInputError or kFailure). Caller holds the mutex and has initialised
// espeak-ng. Both pipe ends are close-on-exec and the parent's write end is
// closed before the mutex is released, so no other child (all are forked
// under the mutex) or executed program holds it: the answer ends at the
// child's exit.
EspeakChild fork_child(const std::function<std::string()>& work) {
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) throw std::runtime_error(fmt::format("tts: pipe failed: {}", std::strerror(errno)));
    const pid_t pid = ::fork();
    if (pid < 0) {
        ::close(fds[0]);
        ::close(fds[1]);
        throw std::runtime_error(fmt::format("tts: fork failed: {}", std::strerror(errno)));
    }
    if (pid == 0) {  // child
        ::close(fds[0]);
        const std::string message = work();
        std::size_t done = 0;
        while (done < message.size()) {
            const ssize_t n = ::write(fds[1], message.data() + done, message.size() - done);
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) ::_exit(3);
            done += static_cast<std::size_t>(n);
        }
        ::_exit(0);  // no destructors or atexit handlers of the parent's state
    }
    ::close(fds[1]);
    return {pid, fds[0], g_sample_rate_hz};
}

// Ends a child whose answer will not be read.
void abandon_child(EspeakChild& child) {
    if (child.fd >= 0) ::close(child.fd);
    if (child.pid > 0) {
        ::kill(child.pid, SIGKILL);
        while (::waitpid(child.pid, nullptr, 0) < 0 && errno == EINTR) {
        }
    }
    child = {};
}

// Reads the child's answer and reaps it; throws the child's error.
std::string read_child(EspeakChild& child) {
    std::string message;
    char buffer[1 << 16];
    for (;;) {
        const ssize_t n = ::read(child.fd, buffer, sizeof buffer);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) break;
        message.append(buffer, static_cast<std::size_t>(n));
    }
    ::close(child.fd);
    child.fd = -1;
    int wstatus = 0;
    while (::waitpid(child.pid, &wstatus, 0) < 0 && errno == EINTR) {
    }
    child.pid = -1;
    if (!WIFEXITED(wstatus) || WEXITSTATUS(wstatus) != 0 || message.empty())
        throw std::runtime_error(fmt::format("tts: the espeak-ng child process failed (status {})", wstatus));
    return message;
}

// Reads the answer's kind; throws the child's error.
void check_answer(detail::WireReader& r) {
    const std::int64_t kind = r.i64();
    if (kind == kInputError) {
        std::string field = r.str();
        std::string what = r.str();
        throw InputError("tts", 0, 0, std::move(field), std::move(what));
    }
    if (kind != kOk) throw std::runtime_error(r.str());
}

Synthesis collect_child(EspeakChild& child) {
    const std::string message = read_child(child);
    detail::WireReader r(message, "espeak-ng child");
    check_answer(r);
    Synthesis out;
    out.variant = r.str();
    out.clauses.resize(r.count(sizeof(std::int64_t)));
    for (auto& c : out.clauses) c = r.str();
    out.collector.phonemes.resize(r.count(3 * sizeof(std::int64_t)));
    for (auto& e : out.collector.phonemes) {
        e.mnemonic = r.str();
        e.sample = static_cast<long>(r.i64());
        e.word = static_cast<int>(r.i64());
    }
    out.collector.end_sample = static_cast<long>(r.i64());
    out.collector.samples.resize(r.count(sizeof(short)));
    r.bytes(out.collector.samples.data(), out.collector.samples.size() * sizeof(short));
    return out;
}

// A phone with times in samples, and the word it came from.
struct SamplePhone {
    Phone phone;
    long start = 0;
    long end = 0;
    int word = 0;
};

// Appends `p` unless it is empty; a silence after a silence extends it.
void append_phone(std::vector<SamplePhone>& phones, SamplePhone p) {
    if (p.end <= p.start) return;
    if (!phones.empty() && p.phone.symbol == "sil" && phones.back().phone.symbol == "sil") {
        phones.back().end = p.end;
        return;
    }
    phones.push_back(std::move(p));
}

// The result from the engine's phones (contiguous, in samples of `samples`):
// the leading and trailing silence cut or padded to the settings.
TtsResult pad_edges(std::vector<SamplePhone> phones, std::vector<short> samples, int rate_hz,
                    const TtsSettings& settings, const std::string& where, const char* engine) {
    if (!phones.empty() && phones.back().phone.symbol == "sil") phones.pop_back();
    if (!phones.empty() && phones.front().phone.symbol == "sil") phones.erase(phones.begin());
    if (phones.empty()) throw InputError(where, 0, 0, "text", fmt::format("{} produced only silence for this text", engine));
    const long speech_start = phones.front().start;
    const long speech_end = phones.back().end;
    const long lead = std::lround(settings.lead_silence_s * rate_hz);
    const long trail = std::lround(settings.trail_silence_s * rate_hz);
    const long shift = lead - speech_start;
    if (shift > 0) samples.insert(samples.begin(), static_cast<std::size_t>(shift), short{0});
    else samples.erase(samples.begin(), samples.begin() + (-shift));
    const long total_out = speech_end + shift + trail;
    samples.resize(static_cast<std::size_t>(total_out), short{0});

    TtsResult result;
    result.audio.sample_rate_hz = rate_hz;
    result.audio.channels = 1;
    result.audio.samples.reserve(samples.size());
    for (short s : samples) result.audio.samples.push_back(static_cast<float>(s) / 32768.0f);
    auto seconds = [rate_hz](long sample) { return static_cast<double>(sample) / rate_hz; };
    if (lead > 0) result.phones.push_back({"sil", 0.0, seconds(lead), false});
    for (const auto& p : phones)
        result.phones.push_back({p.phone.symbol, seconds(p.start + shift), seconds(p.end + shift), p.phone.stressed});
    if (trail > 0) result.phones.push_back({"sil", seconds(speech_end + shift), seconds(total_out), false});
    return result;
}

// Two phones of one word that a sequence rule joins become its result over
// both segments (the first's stress kept).
std::vector<SamplePhone> apply_sequence_rules(std::vector<SamplePhone> phones,
                                              const std::vector<PhoneInventory::SequenceRule>& rules) {
    if (rules.empty()) return phones;
    std::vector<SamplePhone> out;
    for (auto& p : phones) {
        if (!out.empty() && out.back().word == p.word && out.back().word > 0) {
            const auto rule = std::find_if(rules.begin(), rules.end(), [&](const PhoneInventory::SequenceRule& r) {
                return r.first == out.back().phone.symbol && r.second == p.phone.symbol;
            });
            if (rule != rules.end()) {
                out.back().phone.symbol = rule->result;
                out.back().phone.stressed = false;
                out.back().end = p.end;
                continue;
            }
        }
        out.push_back(std::move(p));
    }
    return out;
}

// Within each word: an R after R or ER is the r-colouring already written
// (en-us "our" = aU 3 r- -> AW ER R) and joins the phone before; then the
// language's sequence rules (Swedish r + t -> ʈ) make their pairs one phone
// over both segments.
std::vector<SamplePhone> join_within_words(std::vector<SamplePhone> phones, const PhoneInventory& inventory,
                                           const std::string& variant) {
    std::vector<SamplePhone> merged;
    for (auto& p : phones) {
        if (!merged.empty() && p.phone.symbol == "R" && merged.back().word == p.word &&
            (merged.back().phone.symbol == "R" || merged.back().phone.symbol == "ER")) {
            merged.back().end = p.end;
            continue;
        }
        merged.push_back(std::move(p));
    }
    return apply_sequence_rules(std::move(merged), inventory.sequence_rules(variant));
}

// The language speaking at each phoneme. espeak-ng's dictionary gives some
// words to another language, and its phonemes then say so ("(en)h'az(sv)":
// Swedish "has" is English, German "the" too): the phonemes between the
// markers are mapped with that language's table and each phone replaced by
// the nearest phone of the voice's own language by features, so a stimulus
// or an answer with such a word stays in the study's phone set.
class SpokenLanguage {
public:
    SpokenLanguage(const PhoneInventory& inventory, const std::string& variant, const std::string& where)
        : m_inventory(inventory),
          m_variant(variant),
          m_current(variant),
          m_language(variant.empty() ? "en" : variant),
          m_own(inventory.language_phones(m_language)),
          m_where(where) {}

    // True for a language marker ("(en)"), which switches the table.
    bool switch_at(const std::string& mnemonic) {
        if (mnemonic.size() <= 2 || mnemonic.front() != '(' || mnemonic.back() != ')') return false;
        const std::string code = mnemonic.substr(1, mnemonic.size() - 2);
        if (code == m_language) {
            m_current = m_variant;
            return true;
        }
        // English's non-rhotic table for espeak-ng's "en"; another language's own.
        m_current = code == "en" ? "en" : table_of_language(code) == code ? code : std::string();
        if (m_current.empty())
            throw InputError("tts", 0, 0, "text",
                             fmt::format("espeak-ng speaks part of the {} in \"{}\", which has no phone table "
                                         "(protocols/languages/)",
                                         m_where, code));
        m_switched = true;
        return true;
    }

    // The phones of one mnemonic in the language speaking now, as the voice's
    // language's phones. TextToPhonemes writes the length mark ':' (a phoneme
    // of its own, mapped to nothing) onto the phoneme before it: Swedish "ck"
    // is "k:", whose phoneme event is "k".
    std::vector<Phone> phones(const std::string& mnemonic) const {
        std::vector<Phone> out;
        try {
            out = m_inventory.from_espeak(mnemonic, m_where, m_current);
        } catch (const InputError&) {
            if (mnemonic.size() < 2 || mnemonic.back() != ':') throw;
            out = m_inventory.from_espeak(mnemonic.substr(0, mnemonic.size() - 1), m_where, m_current);
        }
        const auto own = [this](const std::string& symbol) {
            return std::find(m_own.begin(), m_own.end(), symbol) != m_own.end();
        };
        for (auto& p : out)
            if (!own(p.symbol)) p.symbol = m_inventory.nearest_by_features(p.symbol, own);
        return out;
    }

    bool switched() const { return m_switched; }

private:
    const PhoneInventory& m_inventory;
    std::string m_variant, m_current, m_language;
    const std::vector<std::string>& m_own;
    std::string m_where;
    bool m_switched = false;
};

// Step 1: checks the settings and starts the utterance in a child process
// (see fork_child).
EspeakChild start_espeak(const std::string& text, const TtsSettings& settings) {
    if (settings.rate_wpm < espeakRATE_MINIMUM || settings.rate_wpm > espeakRATE_MAXIMUM)
        throw InputError("tts", 0, 0, "rate_wpm",
                         fmt::format("expected words per minute in [{}, {}], got {}", espeakRATE_MINIMUM,
                                     espeakRATE_MAXIMUM, settings.rate_wpm));
    if (settings.pitch < 0 || settings.pitch > 99)
        throw InputError("tts", 0, 0, "pitch", fmt::format("expected a pitch in [0, 99], got {}", settings.pitch));
    std::lock_guard lock(g_espeak_mutex);
    ensure_initialized();
    // Finding a voice by name reads every installed voice file (190 of them,
    // about 3.5 ms) unless the voices are listed already. The first child
    // lists them itself while this process goes on; before the second, this
    // process lists them once, and every later child finds the list made.
    if (g_children_forked++ == 1) espeak().ListVoices(nullptr);
    return fork_child([&] { return child_synthesis(text, settings); });
}

// Steps 2 to 4: the child's samples, events and stress as phones.
TtsResult finish_espeak(EspeakChild& child, const std::string& text, const TtsSettings& settings) {
    const PhoneInventory& inventory = PhoneInventory::builtin();  // read while the child speaks
    const int rate_hz = child.rate_hz;
    Synthesis synthesis = collect_child(child);
    Collector& collector = synthesis.collector;
    const std::string& variant = synthesis.variant;
    const std::vector<StressToken> tokens = stress_tokens(synthesis.clauses, inventory, variant);
    const std::string where = fmt::format("text \"{}\" (espeak-ng voice {})", text, settings.voice);
    if (collector.phonemes.empty() || collector.samples.empty())
        throw InputError(where, 0, 0, "text", "espeak-ng produced no speech for this text");
    log_debug("espeak-ng: {} phoneme events, {} samples at {} Hz", collector.phonemes.size(),
              collector.samples.size(), rate_hz);

    // Step 2: phones in samples. Each phoneme ends where the next begins.
    const auto stressed = align_stress(collector.phonemes, tokens);
    SpokenLanguage language(inventory, variant, where);
    const long total = static_cast<long>(collector.samples.size());
    std::vector<SamplePhone> phones;
    append_phone(phones, {{"sil"}, 0, std::clamp(collector.phonemes.front().sample, 0L, total), 0});
    for (std::size_t k = 0; k < collector.phonemes.size(); ++k) {
        const EspeakEvent& event = collector.phonemes[k];
        const long start = std::clamp(std::max(event.sample, phones.empty() ? 0L : phones.back().end), 0L, total);
        const long next = k + 1 < collector.phonemes.size() ? collector.phonemes[k + 1].sample : total;
        const long end = std::clamp(std::max(next, start), start, total);
        const std::string mnemonic = (stressed[k] ? "'" : "") + event.mnemonic;
        const auto mapped = language.switch_at(event.mnemonic) ? std::vector<Phone>{} : language.phones(mnemonic);
        if (mapped.empty()) {  // an internal or language marker: its time joins the previous phone
            if (!phones.empty()) phones.back().end = end;
            else append_phone(phones, {{"sil"}, start, end, event.word});
            continue;
        }
        const double step = double(end - start) / double(mapped.size());
        for (std::size_t m = 0; m < mapped.size(); ++m) {
            const long s = start + std::lround(step * double(m));
            const long e = m + 1 == mapped.size() ? end : start + std::lround(step * double(m + 1));
            append_phone(phones, {mapped[m], s, e, event.word});
        }
    }
    if (phones.back().end < total) append_phone(phones, {{"sil"}, phones.back().end, total, phones.back().word});

    // Steps 3 and 4: the r-colouring already written joins the phone before,
    // and the language's sequence rules join their pairs.
    std::vector<SamplePhone> merged = join_within_words(std::move(phones), inventory, variant);

    // Step 5: lead and trail silence cut or padded to the settings.
    return pad_edges(std::move(merged), std::move(collector.samples), rate_hz, settings, where, "espeak-ng");
}

// --- Dictionary transcription of single words --------------------------------
//
// espeak_TextToPhonemes gives a word's phonemes; the phoneme trace it writes
// meanwhile (espeak_SetPhonemeTrace) says where they came from: "Found:
// 'och' [Ok]" for a dictionary entry (numbers too: "Found: '_5'"),
// "Translate 'bilnyckel'" followed by the rules it matched for a word spelled
// out by the language's rules (a compound, an inflection, an unknown word).
// A word is in the dictionary when its trace has no "Translate" line.

// In the child: per word, the TextToPhonemes clauses and whether the trace
// found it, serialised.
std::string child_transcription(const std::vector<std::string>& words, const TtsSettings& settings) {
    detail::WireWriter w;
    char* trace_text = nullptr;
    std::size_t trace_size = 0;
    FILE* trace = nullptr;
    try {
        const std::string variant = select_voice(settings.voice);
        trace = ::open_memstream(&trace_text, &trace_size);
        if (!trace) throw std::runtime_error(fmt::format("tts: open_memstream failed: {}", std::strerror(errno)));
        espeak().SetPhonemeTrace(espeakPHONEMES_TRACE, trace);
        w.i64(kOk);
        w.str(variant);
        w.i64(static_cast<std::int64_t>(words.size()));
        for (const std::string& word : words) {
            std::fflush(trace);
            const std::size_t before = trace_size;
            const std::vector<std::string> clauses = phoneme_clauses(word);
            std::fflush(trace);
            const std::string log(trace_text + before, trace_size - before);
            const bool translated = log.rfind("Translate '", 0) == 0 || log.find("\nTranslate '") != std::string::npos;
            w.i64(static_cast<std::int64_t>(clauses.size()));
            for (const auto& c : clauses) w.str(c);
            w.i64(translated ? 0 : 1);
        }
        espeak().SetPhonemeTrace(0, nullptr);
    } catch (const std::exception& e) {
        write_error(w, e);
    }
    if (trace) std::fclose(trace);
    std::free(trace_text);
    return w.data();
}

// One word's phones mapped as a synthesised word's phoneme events are
// (finish_espeak, steps 2 to 4), and whether espeak-ng switched language
// for it.
struct WordPhones {
    PhoneSequence phones;
    bool switched = false;
};

// The phones of a word's TextToPhonemes clauses.
WordPhones word_phones(const std::vector<std::string>& clauses, const PhoneInventory& inventory,
                       const std::string& variant, const std::string& where) {
    SpokenLanguage language(inventory, variant, where);
    std::vector<SamplePhone> phones;
    for (const StressToken& token : stress_tokens(clauses, inventory, variant)) {
        if (language.switch_at(token.base)) continue;
        for (auto& p : language.phones((token.stress.value_or(false) ? "'" : "") + token.base))
            if (p.symbol != "sil") phones.push_back({std::move(p), 0, 0, 1});
    }
    WordPhones out;
    for (auto& p : join_within_words(std::move(phones), inventory, variant)) out.phones.push_back(std::move(p.phone));
    out.switched = language.switched();
    return out;
}

// Festival: the Segment relation gives each phone's end; it starts where the
// previous one ends. Phones are mapped through the `festival` rows of
// protocols/languages/en/phone_map.tsv, so the voice must use the US English phone set.
TtsResult synthesize_festival(const std::string& text, const TtsSettings& settings) {
    const TtsSettings defaults;
    for (const auto& [field, value, fixed] : {std::tuple{"rate_wpm", settings.rate_wpm, defaults.rate_wpm},
                                              std::tuple{"pitch", settings.pitch, defaults.pitch}})
        if (value != fixed)
            throw InputError("tts", 0, 0, field,
                             fmt::format("applies to espeak-ng voices only; Festival voice {} speaks at its own "
                                         "rate and pitch (expected the default {}, got {})",
                                         settings.voice, fixed, value));
    const PhoneInventory& inventory = PhoneInventory::builtin();
    detail::FestivalUtterance u = detail::festival_synthesize(text, settings.voice);
    const std::string where = fmt::format("text \"{}\" (Festival voice {})", text, settings.voice);
    if (u.phone_set != "radio")
        throw InputError("tts", 0, 0, "voice",
                         fmt::format("Festival voice \"{}\" uses the phone set \"{}\"; the phone mapping "
                                     "(protocols/languages/en/phone_map.tsv) covers Festival's US English phone set \"radio\" "
                                     "(voices cmu_us_slt_arctic_hts, kal_diphone, ...)",
                                     settings.voice, u.phone_set));
    if (u.segments.empty() || u.samples.empty())
        throw InputError(where, 0, 0, "text", "Festival produced no speech for this text");
    const int rate_hz = u.sample_rate_hz;
    log_debug("festival: {} segments, {} samples at {} Hz", u.segments.size(), u.samples.size(), rate_hz);

    const long total = static_cast<long>(u.samples.size());
    std::vector<SamplePhone> phones;
    long start = 0;
    for (const auto& seg : u.segments) {
        const long end = std::clamp(std::lround(seg.end_s * rate_hz), start, total);
        const auto mapped = inventory.from_festival(seg.name, seg.stressed, where);
        const double step = double(end - start) / double(mapped.size());
        for (std::size_t m = 0; m < mapped.size(); ++m) {
            const long s = start + std::lround(step * double(m));
            const long e = m + 1 == mapped.size() ? end : start + std::lround(step * double(m + 1));
            append_phone(phones, {mapped[m], s, e, 0});
        }
        start = end;
    }
    if (start < total) append_phone(phones, {{"sil"}, start, total, 0});
    std::vector<short> samples(u.samples.begin(), u.samples.end());
    return pad_edges(std::move(phones), std::move(samples), rate_hz, settings, where, "Festival");
}

// SHA-256 over the files under `dir` (relative paths and contents, sorted).
std::string directory_sha256(const std::filesystem::path& dir) {
    std::vector<std::pair<std::string, std::string>> files;
    std::error_code ec;
    for (auto it = std::filesystem::recursive_directory_iterator(dir, ec);
         !ec && it != std::filesystem::recursive_directory_iterator(); it.increment(ec))
        if (it->is_regular_file())
            files.emplace_back(std::filesystem::relative(it->path(), dir).generic_string(), sha256_file(it->path()));
    if (ec || files.empty()) return {};
    std::sort(files.begin(), files.end());
    std::string all;
    for (const auto& [path, hash] : files) all += path + '\t' + hash + '\n';
    return sha256_hex(all);
}

}  // namespace

std::vector<WordTranscription> detail::espeak_transcribe(const std::vector<std::string>& words,
                                                         const TtsSettings& settings) {
    EspeakChild child;
    {
        std::lock_guard lock(g_espeak_mutex);
        ensure_initialized();
        child = fork_child([&] { return child_transcription(words, settings); });
    }
    const PhoneInventory& inventory = PhoneInventory::builtin();
    const std::string message = read_child(child);
    detail::WireReader r(message, "espeak-ng child");
    check_answer(r);
    const std::string variant = r.str();
    if (r.count(sizeof(std::int64_t)) != words.size()) throw std::runtime_error("espeak-ng child: malformed message");
    std::vector<WordTranscription> out;
    out.reserve(words.size());
    for (const std::string& word : words) {
        std::vector<std::string> clauses(r.count(sizeof(std::int64_t)));
        for (auto& c : clauses) c = r.str();
        const bool in_dictionary = r.i64() != 0;
        const std::string where = fmt::format("word \"{}\" (espeak-ng voice {})", word, settings.voice);
        WordPhones phones = word_phones(clauses, inventory, variant, where);
        if (phones.phones.empty())
            throw InputError("tts", 0, 0, "word", fmt::format("espeak-ng gives no phones for the {}", where));
        // A word of another language is marked as the rules' words are: its
        // phones are not the language's dictionary's.
        out.push_back({word, std::move(phones.phones), in_dictionary && !phones.switched});
    }
    return out;
}

void set_tts_voice(TtsSettings& settings, std::string_view spec, std::string_view where) {
    const auto colon = spec.find(':');
    const std::string_view engine = colon == std::string_view::npos ? std::string_view() : spec.substr(0, colon);
    const std::string_view voice = colon == std::string_view::npos ? std::string_view() : spec.substr(colon + 1);
    if (engine != "espeak" && engine != "festival")
        throw InputError(std::string(where), 0, 0, "tts",
                         fmt::format("expected \"espeak:<voice>\" or \"festival:<voice>\" (e.g. \"espeak:en-us\", "
                                     "\"festival:cmu_us_slt_arctic_hts\"), got \"{}\"",
                                     spec));
    if (voice.rfind("espeak:", 0) == 0 || voice.rfind("festival:", 0) == 0)  // "espeak:" + --voice festival:x
        throw InputError(std::string(where), 0, 0, "tts",
                         fmt::format("\"{}\" names an engine twice; for this voice give \"{}\" alone (as --tts, "
                                     "not --voice, which takes an espeak-ng voice)",
                                     spec, voice));
    if (voice.empty() || voice.find_first_of(" \t\n\"'()") != std::string_view::npos)
        throw InputError(std::string(where), 0, 0, "tts",
                         fmt::format("expected a voice name after \"{}:\", got \"{}\"", engine, spec));
    settings.engine = engine == "festival" ? TtsEngine::Festival : TtsEngine::Espeak;
    settings.voice = std::string(voice);
}

std::string tts_voice_spec(const TtsSettings& settings) {
    return (settings.engine == TtsEngine::Festival ? "festival:" : "espeak:") + settings.voice;
}

std::string tts_voice_language(const TtsSettings& settings) {
    if (settings.engine == TtsEngine::Festival) return "en";
    std::string name = settings.voice.substr(settings.voice.rfind('/') == std::string::npos ? 0 : settings.voice.rfind('/') + 1);
    name = name.substr(0, name.find('+'));  // a variant: "sv+m3" speaks sv
    for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return table_of_language(name);
}

TtsVoiceInfo describe_tts_voice(const TtsSettings& settings) {
    TtsVoiceInfo info;
    info.voice = settings.voice;
    if (settings.engine == TtsEngine::Festival) {
        const detail::FestivalVoiceInfo f = detail::festival_voice_info(settings.voice);
        info.engine = "festival";
        info.engine_version = f.festival_version;
        info.voice_sha256 = directory_sha256(f.directory);
        return info;
    }
    info.engine = "espeak-ng";
    std::lock_guard lock(g_espeak_mutex);
    ensure_initialized();
    const auto english = english_voice_languages();
    if (std::find(english.begin(), english.end(), settings.voice) == english.end()) {
        // Names espeak-ng accepts beyond the language codes are checked when
        // the voice is selected; an unknown one fails there with the list.
        bool known = false;
        for (const espeak_VOICE** v = espeak().ListVoices(nullptr); v && *v && !known; ++v)
            known = ((*v)->name && settings.voice == (*v)->name) ||
                    ((*v)->identifier && settings.voice == (*v)->identifier);
        if (!known) {
            std::string list;
            for (const auto& l : english) list += (list.empty() ? "" : ", ") + l;
            const std::string close = closest_match(settings.voice, english);
            throw InputError("tts", 0, 0, "voice",
                             fmt::format("unknown espeak-ng voice \"{}\" or one without a phone table{}; voices with a phone table: {}",
                                         settings.voice, close.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", close), list));
        }
    }
    info.engine_version = espeak().Info(nullptr);
    return info;
}

std::vector<std::string> installed_tts_voices(TtsEngine engine) {
    if (engine == TtsEngine::Festival) return detail::festival_voices();
    std::lock_guard lock(g_espeak_mutex);
    ensure_initialized();
    return english_voice_languages();
}

struct PendingSpeech::State {
    std::string text;
    TtsSettings settings;
    EspeakChild child;  // espeak-ng: the child speaking it; Festival: none (spoken in get)

    State(std::string t, TtsSettings s) : text(std::move(t)), settings(std::move(s)) {}
    State(const State&) = delete;
    State& operator=(const State&) = delete;
    ~State() { abandon_child(child); }
};

PendingSpeech::PendingSpeech(std::unique_ptr<State> state) : m_state(std::move(state)) {}
PendingSpeech::PendingSpeech(PendingSpeech&&) noexcept = default;
PendingSpeech& PendingSpeech::operator=(PendingSpeech&&) noexcept = default;
PendingSpeech::~PendingSpeech() = default;

TtsResult PendingSpeech::get() {
    if (!m_state) throw std::logic_error("PendingSpeech::get: the speech was already taken");
    const std::unique_ptr<State> state = std::move(m_state);
    TtsResult result = state->settings.engine == TtsEngine::Festival
                           ? synthesize_festival(state->text, state->settings)
                           : finish_espeak(state->child, state->text, state->settings);
    if (state->settings.align_onsets) align_obstruent_onsets(result.audio, result.phones);
    return result;
}

PendingSpeech start_speech(const std::string& text, const TtsSettings& settings) {
    if (text.find_first_not_of(" \t\r\n") == std::string::npos)
        throw InputError("tts", 0, 0, "text", "expected some text to speak, got an empty string");
    for (const auto& [name, value] : {std::pair{"lead_silence_s", settings.lead_silence_s},
                                      std::pair{"trail_silence_s", settings.trail_silence_s}})
        if (!(value >= 0.0 && value <= 60.0))
            throw InputError("tts", 0, 0, name, fmt::format("expected seconds in [0, 60], got {}", value));
    auto state = std::make_unique<PendingSpeech::State>(text, settings);
    if (settings.engine == TtsEngine::Espeak) state->child = start_espeak(text, settings);
    return PendingSpeech(std::move(state));
}

TtsResult synthesize_speech(const std::string& text, const TtsSettings& settings) {
    return start_speech(text, settings).get();
}

}  // namespace avsi
