// The player's window-free parts (player.h, play_media.h): loading what to
// play, its per-frame poses, the pitch-preserving time-stretch (SoundTouch's
// WSOLA), the transport and audio clock, and play scripts.
#include "avsi/experiment/play_media.h"

#include <soundtouch/SoundTouch.h>

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <map>
#include <optional>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "avsi/core/labels.h"
#include "avsi/core/text.h"
#include "avsi/stimuli/builder.h"
#include "avsi/synth/fap.h"
#include "avsi/synth/mpeg4_cohen_massaro.h"

namespace avsi::experiment {

namespace fs = std::filesystem;

std::vector<std::string> animate_play_media(const stimuli::Head& head, PlayMedia& media) {
    stimuli::Animation a = stimuli::animate(head, media.trajectory, media.phones.empty() ? nullptr : &media.phones,
                                            media.layers, media.layer_seeds);
    media.poses = std::move(a.poses);
    return std::move(a.warnings);
}

namespace {

fs::path default_viseme_set() { return fs::path(AVSI_PROTOCOLS_DIR) / "visemes" / "mpeg4_14.json"; }

// The manifest entry `stimulus` of a built folder: its sentence, condition,
// WAV (checked against its SHA-256) and frame count.
struct ManifestStimulus {
    std::string sentence;
    std::string condition;
    fs::path wav;
    std::size_t frames = 0;
};

ManifestStimulus manifest_stimulus(const fs::path& dir, const std::string& stimulus) {
    const fs::path path = dir / "manifest.json";
    if (!fs::is_regular_file(path))
        throw InputError(path, "no stimulus manifest here; build the folder with `avsi build-stimuli protocol.toml --out DIR`");
    const nlohmann::json j = read_json_file(path);
    if (!j.is_object() || json_string(j, "format") != "avsi-stimuli-manifest" || !j.contains("stimuli") ||
        !j["stimuli"].is_array())
        throw InputError(path, 0, 0, "format", "expected an avsi stimulus manifest (format \"avsi-stimuli-manifest\")");
    std::vector<std::string> paths;
    for (std::size_t i = 0; i < j["stimuli"].size(); ++i) {
        const auto& e = j["stimuli"][i];
        const std::string field = fmt::format("stimuli[{}]", i);
        try {
            const std::string p = e.at("path").get<std::string>();
            paths.push_back(p);
            if (p != stimulus) continue;
            ManifestStimulus m;
            m.sentence = e.at("sentence").get<std::string>();
            m.condition = e.at("condition").get<std::string>();
            m.wav = dir / e.at("wav").get<std::string>();
            m.frames = e.at("frames").get<std::size_t>();
            const std::string sha = e.at("wav_sha256").get<std::string>();
            if (!fs::is_regular_file(m.wav))
                throw InputError(m.wav, "missing stimulus audio (rebuild with `avsi build-stimuli`)");
            if (const std::string got = sha256_file(m.wav); got != sha)
                throw InputError(m.wav.string(), 0, 0, "wav_sha256",
                                 fmt::format("expected {} (manifest.json), got {}: the file changed after the build",
                                             sha, got));
            return m;
        } catch (const nlohmann::json::exception& ex) {
            throw InputError(path.string(), 0, 0, field,
                             fmt::format("expected path, sentence, condition, wav, wav_sha256 and frames: {}",
                                         json_error_text(ex)));
        }
    }
    const std::string close = closest_match(stimulus, paths);
    throw InputError(path.string(), 0, 0, "stimuli",
                     fmt::format("expected a stimulus path of the manifest{}, got \"{}\"",
                                 close.empty() ? std::string() : fmt::format(" (did you mean \"{}\"?)", close),
                                 stimulus));
}

}  // namespace

PlayMedia load_play_media(const PlaySource& s) {
    const int sources = int(!s.trajectory_path.empty()) + int(!s.fap_path.empty()) + int(!s.protocol_path.empty());
    if (sources != 1)
        throw UsageError("give exactly one of a trajectory (--traj), a FAP stream (--fap) or a stimulus definition "
                         "(--protocol with --sentence and --condition, or with --stimuli DIR --stimulus PATH)");
    const bool from_protocol = !s.protocol_path.empty();
    if (!from_protocol && (!s.sentence.empty() || !s.condition.empty() || !s.stimuli_dir.empty() || !s.stimulus.empty()))
        throw UsageError("--sentence, --condition, --stimuli and --stimulus name a stimulus of a protocol; they need --protocol");
    if (from_protocol && (!s.audio_path.empty() || !s.phones_path.empty()))
        throw UsageError("--audio-file and --phones go with --traj or --fap; a stimulus definition brings its own");

    PlayMedia m;
    if (from_protocol) {
        std::string sentence = s.sentence, condition = s.condition;
        std::optional<ManifestStimulus> built;
        if (!s.stimuli_dir.empty() || !s.stimulus.empty()) {
            if (s.stimuli_dir.empty() || s.stimulus.empty())
                throw UsageError("--stimuli DIR and --stimulus PATH go together (a manifest entry)");
            if (!sentence.empty() || !condition.empty())
                throw UsageError("give --stimulus PATH or --sentence and --condition, not both");
            built = manifest_stimulus(s.stimuli_dir, s.stimulus);
            sentence = built->sentence;
            condition = built->condition;
        } else if (sentence.empty() || condition.empty()) {
            throw UsageError("a stimulus definition needs --sentence and --condition (or --stimuli DIR --stimulus PATH)");
        }
        stimuli::StimulusDefinition d = stimuli::stimulus_definition(s.protocol_path, sentence, condition);
        if (built) {
            if (d.trajectory.size() != built->frames)
                throw InputError((s.stimuli_dir / "manifest.json").string(), 0, 0, "frames",
                                 fmt::format("{} was built with {} frames, the protocol now makes {}: rebuild it with "
                                             "`avsi build-stimuli`",
                                             s.stimulus, built->frames, d.trajectory.size()));
            d.audio = read_audio(built->wav);
        }
        m.title = built ? s.stimulus : sentence + " / " + condition;
        m.trajectory = std::move(d.trajectory);
        m.phones = std::move(d.phones);
        m.sample_rate_hz = d.audio.sample_rate_hz;
        m.audio = d.audio.mono();
        m.layers = std::move(d.layers);
        m.layer_seeds = d.layer_seeds;
        m.head_gltf = d.head_gltf;
        m.head_obj = d.head_mesh;
        m.head_rig = d.head_rig;
    } else {
        m.trajectory = s.fap_path.empty() ? synth::read_trajectory_csv(s.trajectory_path) : synth::decode_fap_file(s.fap_path);
        m.title = (s.fap_path.empty() ? s.trajectory_path : s.fap_path).filename().string();
        if (m.trajectory.size() == 0)
            throw InputError(s.fap_path.empty() ? s.trajectory_path : s.fap_path, "no frames to play");
        if (!s.phones_path.empty()) m.phones = read_phones(s.phones_path);
        if (!s.audio_path.empty()) {
            const Audio a = read_audio(s.audio_path);
            if (a.frames() == 0) throw InputError(s.audio_path, "the audio file has no samples");
            m.sample_rate_hz = a.sample_rate_hz;
            m.audio = a.mono();
        }
    }
    if (m.audio.empty())
        m.audio.assign(static_cast<std::size_t>(std::lround(m.trajectory.duration_s() * m.sample_rate_hz)), 0.0f);
    // The viseme of each phone, for the strip.
    const synth::VisemeSet set =
        synth::load_viseme_set(s.viseme_set_path.empty() ? default_viseme_set() : s.viseme_set_path);
    for (const auto& p : m.phones) {
        const auto it = set.phone_to_viseme.find(p.symbol);
        m.visemes.push_back(it == set.phone_to_viseme.end() ? std::string("?") : set.visemes[it->second].name);
    }
    return m;
}

std::vector<float> time_stretch(const std::vector<float>& audio, int sample_rate_hz, double speed) {
    AVSI_ASSERT(speed >= 0.25 - 1e-9 && speed <= 1.0 + 1e-9 && sample_rate_hz > 0);
    if (speed == 1.0) return audio;
    const auto wanted = static_cast<std::size_t>(std::llround(static_cast<double>(audio.size()) / speed));
    soundtouch::SoundTouch st;
    st.setSampleRate(static_cast<unsigned>(sample_rate_hz));
    st.setChannels(1);
    st.setTempo(speed);
    // Speech settings (shorter sequences than the music defaults): less echo on slowed speech.
    st.setSetting(SETTING_SEQUENCE_MS, 40);
    st.setSetting(SETTING_SEEKWINDOW_MS, 15);
    st.setSetting(SETTING_OVERLAP_MS, 8);
    std::vector<float> out;
    out.reserve(wanted + 4096);
    std::vector<float> block(4096);
    const auto drain = [&] {
        while (true) {
            const unsigned got = st.receiveSamples(block.data(), static_cast<unsigned>(block.size()));
            if (got == 0) break;
            out.insert(out.end(), block.begin(), block.begin() + got);
        }
    };
    constexpr std::size_t chunk = 8192;
    for (std::size_t i = 0; i < audio.size(); i += chunk) {
        st.putSamples(audio.data() + i, static_cast<unsigned>(std::min(chunk, audio.size() - i)));
        drain();
    }
    st.flush();
    drain();
    out.resize(wanted, 0.0f);  // exactly n / speed: the clock maps output samples to media time
    return out;
}

Transport::Transport(std::vector<float> audio, int sample_rate_hz, double fps, int frame_count)
    : m_source(std::move(audio)), m_stretched(m_source), m_rate(sample_rate_hz), m_fps(fps), m_frames(frame_count) {
    AVSI_ASSERT(m_rate > 0 && m_fps > 0 && m_frames > 0);
}

void Transport::pull(float* out, std::size_t n) {
    std::lock_guard lock(m_mutex);
    m_sent += static_cast<std::int64_t>(n);
    std::size_t copied = 0;
    if (m_playing) {
        const auto pos = static_cast<std::size_t>(m_pos);
        const std::size_t available = pos < m_stretched.size() ? m_stretched.size() - pos : 0;
        copied = std::min(n, available);
        if (!m_muted) std::copy_n(m_stretched.begin() + static_cast<std::ptrdiff_t>(pos), copied, out);
        else std::fill_n(out, copied, 0.0f);
        m_pos += static_cast<double>(copied);
        m_played += static_cast<std::int64_t>(copied);
        if (copied < n) {
            m_playing = false;
            m_at_end = true;
        }
    }
    std::fill(out + copied, out + n, 0.0f);
    if (m_keep) m_sent_samples.insert(m_sent_samples.end(), out, out + n);
}

void Transport::play() {
    std::lock_guard lock(m_mutex);
    if (m_at_end || m_pos >= static_cast<double>(m_stretched.size())) m_pos = 0.0;  // play again from the start
    m_at_end = false;
    m_playing = true;
}

void Transport::pause() {
    std::lock_guard lock(m_mutex);
    m_playing = false;
}

bool Transport::playing() const {
    std::lock_guard lock(m_mutex);
    return m_playing;
}

bool Transport::at_end() const {
    std::lock_guard lock(m_mutex);
    return m_at_end;
}

void Transport::set_speed(double speed) {
    AVSI_ASSERT(speed >= 0.25 - 1e-9 && speed <= 1.0 + 1e-9);
    {
        std::lock_guard lock(m_mutex);
        if (speed == m_speed) return;
    }
    // Stretched outside the lock (m_source never changes), so the device's
    // callback is not held up; then swapped in at the same media time.
    std::vector<float> stretched = time_stretch(m_source, m_rate, speed);
    std::lock_guard lock(m_mutex);
    const double media_s = m_pos * m_speed / m_rate;
    m_speed = speed;
    m_stretched = std::move(stretched);
    m_pos = std::min(media_s * m_rate / speed, static_cast<double>(m_stretched.size()));
}

double Transport::speed() const {
    std::lock_guard lock(m_mutex);
    return m_speed;
}

void Transport::set_muted(bool muted) {
    std::lock_guard lock(m_mutex);
    m_muted = muted;
}

bool Transport::muted() const {
    std::lock_guard lock(m_mutex);
    return m_muted;
}

void Transport::seek_frame(int frame, double offset_ms) {
    std::lock_guard lock(m_mutex);
    frame = std::clamp(frame, 0, m_frames - 1);
    const double media_s = (frame + 0.5) / m_fps + offset_ms / 1000.0;
    m_pos = std::clamp(media_s * m_rate / m_speed, 0.0, static_cast<double>(m_stretched.size()));
    m_at_end = false;
}

double Transport::media_time_s(double latency_s) const {
    std::lock_guard lock(m_mutex);
    // While playing, the samples still in the device's buffer are not heard yet.
    const double lag = m_playing ? latency_s * m_rate : 0.0;
    return std::max(0.0, m_pos - lag) * m_speed / m_rate;
}

int Transport::frame(double offset_ms, double latency_s) const {
    const double t = media_time_s(latency_s) - offset_ms / 1000.0;
    std::lock_guard lock(m_mutex);
    const auto k = static_cast<long long>(std::floor(t * m_fps));
    return static_cast<int>(std::clamp<long long>(k, 0, m_frames - 1));
}

std::int64_t Transport::samples_sent() const {
    std::lock_guard lock(m_mutex);
    return m_sent;
}

std::int64_t Transport::samples_played() const {
    std::lock_guard lock(m_mutex);
    return m_played;
}

std::vector<float> Transport::sent() const {
    std::lock_guard lock(m_mutex);
    return m_sent_samples;
}

void Transport::keep_sent(bool keep) {
    std::lock_guard lock(m_mutex);
    m_keep = keep;
}

namespace {

struct CommandSpec {
    int min_args;
    int max_args;
    bool editor;  // editor-only
    bool player;  // player-only
    const char* usage;
};

const std::map<std::string, CommandSpec, std::less<>>& script_commands() {
    static const std::map<std::string, CommandSpec, std::less<>> commands = {
        {"play", {0, 0, false, true, "play"}},
        {"pause", {0, 0, false, true, "pause"}},
        {"toggle", {0, 0, false, true, "toggle"}},
        {"step", {1, 1, false, true, "step N (frames, negative steps back)"}},
        {"seek", {1, 1, false, true, "seek FRAME"}},
        {"speed", {1, 1, false, true, "speed X (0.25 … 1)"}},
        {"mute", {1, 1, false, true, "mute on|off"}},
        {"offset", {1, 1, false, true, "offset MS (−500 … 500)"}},
        {"wait-end", {0, 0, false, true, "wait-end"}},
        {"wait", {1, 1, false, false, "wait N (screen refreshes)"}},
        {"screenshot", {1, 1, false, false, "screenshot PATH.png"}},
        {"quit", {0, 0, false, false, "quit"}},
        {"select", {1, 1, true, false, "select VISEME"}},
        {"set", {2, 2, true, false, "set PARAMETER VALUE"}},
        {"width", {1, 1, true, false, "width MM"}},
        {"height", {1, 1, true, false, "height MM"}},
        {"map", {2, 2, true, false, "map PHONE VISEME"}},
        {"undo", {0, 0, true, false, "undo"}},
        {"save", {0, 1, true, false, "save [PATH]"}},
    };
    return commands;
}

std::optional<double> parse_number(const std::string& s) {
    double v = 0.0;
    const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
    if (ec != std::errc() || end != s.data() + s.size() || !std::isfinite(v)) return std::nullopt;
    return v;
}

}  // namespace

std::vector<ScriptEvent> read_play_script(const fs::path& path, bool editor) {
    const std::string text = read_text_file(path);
    std::vector<ScriptEvent> events;
    DiagnosticList problems;
    int line_no = 0;
    std::size_t start = 0;
    std::vector<std::string> names;
    for (const auto& [name, spec] : script_commands())
        if (editor ? !spec.player : !spec.editor) names.push_back(name);
    while (start < text.size()) {
        std::size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        std::string line = text.substr(start, end - start);
        start = end + 1;
        ++line_no;
        if (const auto hash = line.find('#'); hash != std::string::npos) line.erase(hash);
        std::vector<std::string> words;
        for (std::size_t i = 0; i < line.size();) {
            while (i < line.size() && std::isspace(static_cast<unsigned char>(line[i]))) ++i;
            std::size_t j = i;
            while (j < line.size() && !std::isspace(static_cast<unsigned char>(line[j]))) ++j;
            if (j > i) words.push_back(line.substr(i, j - i));
            i = j;
        }
        if (words.empty()) continue;
        ScriptEvent e;
        e.line = line_no;
        e.command = words.front();
        e.args.assign(words.begin() + 1, words.end());
        const auto it = script_commands().find(e.command);
        if (it == script_commands().end() || (editor ? it->second.player : it->second.editor)) {
            const std::string close = closest_match(e.command, names);
            std::string all;
            for (const auto& n : names) all += (all.empty() ? "" : ", ") + n;
            problems.add(path.string(), line_no, 1, "command",
                         fmt::format("expected one of {}{}, got \"{}\"", all,
                                     close.empty() ? std::string() : fmt::format(" (did you mean \"{}\"?)", close),
                                     e.command));
            continue;
        }
        const CommandSpec& spec = it->second;
        const int n = static_cast<int>(e.args.size());
        if (n < spec.min_args || n > spec.max_args) {
            problems.add(path.string(), line_no, 1, e.command,
                         fmt::format("expected \"{}\", got {} argument(s)", spec.usage, n));
            continue;
        }
        // Numeric arguments and their ranges.
        const auto number_arg = [&](std::size_t i, double lo, double hi, bool integer) {
            const auto v = parse_number(e.args[i]);
            if (!v || *v < lo || *v > hi || (integer && *v != std::floor(*v)))
                problems.add(path.string(), line_no, 1, e.command,
                             fmt::format("expected \"{}\" with {} in [{:g}, {:g}], got \"{}\"", spec.usage,
                                         integer ? "an integer" : "a number", lo, hi, e.args[i]));
        };
        if (e.command == "step") number_arg(0, -1e6, 1e6, true);
        else if (e.command == "seek") number_arg(0, 0, 1e7, true);
        else if (e.command == "speed") number_arg(0, 0.25, 1.0, false);
        else if (e.command == "offset") number_arg(0, -500, 500, false);
        else if (e.command == "wait") number_arg(0, 0, 1e7, true);
        else if (e.command == "width" || e.command == "height") number_arg(0, 1e-9, 200, false);
        else if (e.command == "set") number_arg(1, -1e3, 1e3, false);
        else if (e.command == "mute" && e.args[0] != "on" && e.args[0] != "off")
            problems.add(path.string(), line_no, 1, "mute", fmt::format("expected on or off, got \"{}\"", e.args[0]));
        if (e.command == "set" && !synth::param_from_name(e.args[0])) {
            std::vector<std::string> params;
            for (const auto& info : synth::params()) params.emplace_back(info.name);
            const std::string close = closest_match(e.args[0], params);
            problems.add(path.string(), line_no, 1, "set",
                         fmt::format("expected an articulatory parameter{}, got \"{}\"",
                                     close.empty() ? std::string() : fmt::format(" (did you mean \"{}\"?)", close),
                                     e.args[0]));
        }
        events.push_back(std::move(e));
    }
    problems.throw_if_any();
    return events;
}

std::string play_help_text() {
    return R"(Keys (player):
  Space          play / pause (at the end: play again from the start)
  Left / Right   step one frame back / forward (pauses)
  Home / End     first / last frame
  Up / Down      speed up / down (0.25x, 0.5x, 0.75x, 1x)
  M              mute on / off (the clock keeps running)
  [ / ]          A/V offset -10 / +10 ms (video later with +)
  Q / Esc        quit
Keys (viseme editor, --edit-visemes):
  Up / Down      previous / next viseme
  Ctrl+Z         undo;   Ctrl+S  save
  Q / Esc        quit (unsaved changes are reported, not saved)
Script (--script FILE), one command a line, '#' comments:
  play | pause | toggle | step N | seek FRAME | speed X | mute on|off |
  offset MS | wait N (screen refreshes) | wait-end | screenshot PATH.png | quit
  editor: select VISEME | set PARAMETER VALUE | width MM | height MM |
          map PHONE VISEME | undo | save [PATH] | wait N | screenshot PATH | quit
Log (--log FILE.tsv): one row per screen refresh: refresh, wall_s, frame,
  samples_sent, samples_played, media_s, speed, offset_ms, playing, and the
  shown pose's 10 parameters.
The frame shown is floor((t_audio - offset) * fps), t_audio the media time of
the audio at the output: samples consumed x speed / rate (less the device
latency). With --audio null the clock is simulated: each refresh consumes
rate / null-refresh-hz samples, so a scripted run is deterministic.)";
}

}  // namespace avsi::experiment
