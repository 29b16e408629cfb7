// The session runner's front end: GLFW window, Dear ImGui screens, frame
// pacing on the audio clock, durable commits (see runner.h). The flow itself
// lives in SessionMachine; this file only turns keys, time and the machine's
// actions into drawing, sound and database writes.
#include "avsi/experiment/runner.h"

#define GLFW_INCLUDE_NONE
#include <GL/gl.h>
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <imgui_stdlib.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <set>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "avsi/core/audio.h"
#include "avsi/core/checks.h"
#include "avsi/core/corpus.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "avsi/core/log.h"
#include "avsi/core/protocol.h"
#include "avsi/experiment/adaptive_session.h"
#include "avsi/experiment/design.h"
#include "avsi/experiment/session.h"
#include "avsi/experiment/store.h"
#include "avsi/stimuli/video.h"
#include "gl_functions.h"

namespace avsi::experiment {

namespace fs = std::filesystem;

std::vector<std::string> read_script(const fs::path& path) {
    const std::string text = read_text_file(path);
    std::vector<std::string> lines;
    std::size_t start = 0;
    while (start <= text.size()) {
        std::size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        std::string line = text.substr(start, end - start);
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (end == text.size() && line.empty()) break;
        start = end + 1;
        if (!line.empty() && line[0] == '#') continue;
        lines.push_back(line == "-" ? std::string() : line);
    }
    return lines;
}

namespace {

// A decoded stimulus video (the stimuli module's decoder) as a FrameSource.
class DecodedClip : public FrameSource {
public:
    DecodedClip(const fs::path& path, int expected_frames) : m_video(stimuli::decode_video(path, true)) {
        if (m_video.frames.empty() || m_video.fps <= 0)
            throw InputError(path, "the stimulus video has no frames");
        if (expected_frames > 0 && static_cast<int>(m_video.frames.size()) != expected_frames)
            throw InputError(path, 0, 0, "frames",
                             fmt::format("expected {} frames (manifest.json), decoded {}", expected_frames,
                                         m_video.frames.size()));
        if (m_video.has_audio) {
            m_rate = m_video.audio.sample_rate_hz;
            m_audio = m_video.audio.mono();
            // Align audio sample 0 with the first frame.
            const double shift_s = m_video.audio_start_s - m_video.video_start_s;
            const auto shift = static_cast<long>(std::lround(std::fabs(shift_s) * m_rate));
            if (shift_s > 0)
                m_audio.insert(m_audio.begin(), static_cast<std::size_t>(shift), 0.0f);
            else if (shift > 0)
                m_audio.erase(m_audio.begin(), m_audio.begin() + std::min<long>(shift, static_cast<long>(m_audio.size())));
        } else {
            // A silent stimulus still needs the audio clock: silence of the video's length.
            m_audio.assign(static_cast<std::size_t>(std::lround(m_video.video_duration_s * m_rate)), 0.0f);
        }
    }
    int width() const override { return m_video.width; }
    int height() const override { return m_video.height; }
    double fps() const override { return m_video.fps; }
    int frame_count() const override { return static_cast<int>(m_video.frames.size()); }
    const std::vector<float>& audio() const override { return m_audio; }
    int sample_rate() const override { return m_rate; }
    bool next_frame(VideoFrame& f) override {
        if (m_next >= frame_count()) return false;
        const stimuli::Image& image = m_video.frames[static_cast<std::size_t>(m_next)];
        f.width = image.width;
        f.height = image.height;
        f.index = m_next;
        f.pts_s = m_next / m_video.fps;
        f.rgba.resize(static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height) * 4);
        for (std::size_t i = 0, n = static_cast<std::size_t>(image.width) * image.height; i < n; ++i) {
            f.rgba[4 * i] = image.rgb[3 * i];
            f.rgba[4 * i + 1] = image.rgb[3 * i + 1];
            f.rgba[4 * i + 2] = image.rgb[3 * i + 2];
            f.rgba[4 * i + 3] = 255;
        }
        ++m_next;
        return true;
    }

private:
    stimuli::DecodedVideo m_video;
    std::vector<float> m_audio;
    int m_rate = 48000;
    int m_next = 0;
};

}  // namespace

StimulusManifest read_stimulus_manifest(const fs::path& dir) {
    const fs::path path = dir / "manifest.json";
    if (!fs::is_regular_file(path))
        throw InputError(path, "no stimulus manifest here; build the stimulus folder with `avsi build-stimuli "
                               "protocol.toml --out DIR`");
    const nlohmann::json j = read_json_file(path);
    if (!j.is_object() || json_string(j, "format") != "avsi-stimuli-manifest" || !j.contains("stimuli") ||
        !j["stimuli"].is_array())
        throw InputError(path, 0, 0, "format", "expected an avsi stimulus manifest (format \"avsi-stimuli-manifest\")");
    StimulusManifest m;
    m.experiment = json_string(j, "experiment");
    m.sha256 = sha256_file(path);
    DiagnosticList problems;
    std::size_t index = 0;
    for (const auto& item : j["stimuli"]) {
        const std::string field = fmt::format("stimuli[{}]", index++);
        try {
            ManifestEntry e;
            e.path = item.at("path").get<std::string>();
            const auto& frames = item.at("frames");
            // A stimulus lasts at most max_time_s at 1000 fps.
            if (!frames.is_number_integer() || frames.get<double>() < 1 || frames.get<double>() > max_time_s * 1000)
                problems.add(path.string(), 0, 0, field + ".frames",
                             fmt::format("expected an integer in [1, {}], got {}", max_time_s * 1000, frames.dump()));
            else
                e.frames = frames.get<int>();
            e.fps = require_in_range(item.at("fps").get<double>(), 1e-3, 1000.0, at(path.string(), 0, 0, field + ".fps"),
                                     "a frame rate");
            e.sha256 = item.at("sha256").get<std::string>();
            if (item.contains("variants") && !item["variants"].is_null())
                for (const auto& v : item["variants"].at("files"))
                    e.variants[v.at("wav").get<std::string>()] = v.at("sha256").get<std::string>();
            m.stimuli[e.path] = e;
        } catch (const nlohmann::json::exception& e) {
            problems.add(path.string(), 0, 0, field, fmt::format("expected path, frames, fps and sha256: {}", json_error_text(e)));
        } catch (const InputError& e) {
            problems.add(e.first());
        }
    }
    problems.throw_if_any();
    return m;
}

StimulusFolderOpener::StimulusFolderOpener(fs::path dir) : m_dir(std::move(dir)), m_manifest(read_stimulus_manifest(m_dir)) {}

void StimulusFolderOpener::verify(const std::vector<std::string>& stimuli) const {
    DiagnosticList problems;
    std::set<std::string> checked;
    for (const auto& stimulus : stimuli) {
        if (!checked.insert(stimulus).second) continue;
        const fs::path file = m_dir / stimulus;
        const auto entry = m_manifest.stimuli.find(stimulus);
        if (entry == m_manifest.stimuli.end())
            problems.add((m_dir / "manifest.json").string(), 0, 0, "stimuli",
                         fmt::format("{} is not in the manifest (rebuild with `avsi build-stimuli`)", stimulus));
        else if (!fs::is_regular_file(file))
            problems.add(file.string(), 0, 0, "", "missing stimulus (rebuild with `avsi build-stimuli`)");
        else if (const std::string sha = sha256_file(file); sha != entry->second.sha256)
            problems.add(file.string(), 0, 0, "sha256",
                         fmt::format("expected {} (manifest.json), got {}: the file changed after the build",
                                     entry->second.sha256, sha));
        if (entry == m_manifest.stimuli.end()) continue;
        for (const auto& [variant, expected] : entry->second.variants) {
            const fs::path wav = m_dir / variant;
            if (!fs::is_regular_file(wav))
                problems.add(wav.string(), 0, 0, "", "missing audio variant (rebuild with `avsi build-stimuli`)");
            else if (const std::string sha = sha256_file(wav); sha != expected)
                problems.add(wav.string(), 0, 0, "sha256",
                             fmt::format("expected {} (manifest.json), got {}: the file changed after the build",
                                         expected, sha));
        }
    }
    problems.throw_if_any();
}

std::unique_ptr<FrameSource> StimulusFolderOpener::open(const std::string& stimulus) {
    const auto entry = m_manifest.stimuli.find(stimulus);
    if (entry == m_manifest.stimuli.end())
        throw InputError(m_dir / "manifest.json", 0, 0, "stimuli", fmt::format("{} is not in the manifest", stimulus));
    return std::make_unique<DecodedClip>(m_dir / stimulus, entry->second.frames);
}

std::unique_ptr<StimulusOpener> make_stimulus_opener(const RunSettings& settings, double fps) {
    if (settings.test_pattern) {
        TestPatternSettings t;
        t.fps = fps;
        return std::make_unique<TestPatternOpener>(t);
    }
    if (settings.stimuli_dir.empty())
        throw UsageError("give the stimulus folder with --stimuli DIR (built by `avsi build-stimuli`), or "
                         "--test-pattern for a dry run with a generated clip");
    return std::make_unique<StimulusFolderOpener>(settings.stimuli_dir);
}

namespace {

// The GL entry points the runner calls itself (gl_functions.h).
detail::GlFunctions gl;

// GLFW + ImGui lifetime.
class Window {
public:
    Window(const RunSettings& s, bool fullscreen, int monitor_index, const std::string& title) {
        glfwSetErrorCallback([](int code, const char* text) { log_warning("GLFW error {}: {}", code, text); });
        if (!glfwInit())
            throw InputError("display", 0, 0, "", "cannot open a window (no display? run under xvfb-run for a headless session)");
        GLFWmonitor* monitor = nullptr;
        if (fullscreen) {
            int count = 0;
            GLFWmonitor** monitors = glfwGetMonitors(&count);
            if (monitor_index < 0 || monitor_index >= count) {
                glfwTerminate();
                throw InputError("display", 0, 0, "monitor",
                                 fmt::format("expected a monitor in [0, {}], got {}", count - 1, monitor_index));
            }
            monitor = monitors[monitor_index];
        }
        int width = s.window_width, height = s.window_height;
        if (monitor) {
            const GLFWvidmode* mode = glfwGetVideoMode(monitor);
            width = mode->width;
            height = mode->height;
            glfwWindowHint(GLFW_REFRESH_RATE, mode->refreshRate);
        }
        glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);
        m_window = glfwCreateWindow(width, height, title.c_str(), monitor, nullptr);
        if (!m_window) {
            glfwTerminate();
            throw InputError("display", 0, 0, "", "cannot create an OpenGL window");
        }
        glfwMakeContextCurrent(m_window);
        glfwSwapInterval(1);
        detail::load_gl_functions(gl, false);
        GLFWmonitor* reference = monitor ? monitor : glfwGetPrimaryMonitor();
        if (reference) m_refresh_hz = glfwGetVideoMode(reference)->refreshRate;
        if (m_refresh_hz <= 0) m_refresh_hz = 60.0;

        IMGUI_CHECKVERSION();
        ImGui::CreateContext();
        ImGuiIO& io = ImGui::GetIO();
        io.IniFilename = nullptr;
        const float size = std::max(16.0f, static_cast<float>(height) / 28.0f);
        const char* font = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
        if (fs::exists(font))
            io.Fonts->AddFontFromFileTTF(font, size);
        else
            io.FontGlobalScale = size / 13.0f;
        ImGui::StyleColorsDark();
        ImGui_ImplGlfw_InitForOpenGL(m_window, true);
        ImGui_ImplOpenGL3_Init("#version 130");
        gl.GenTextures(1, &m_texture);
        gl.BindTexture(GL_TEXTURE_2D, m_texture);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    }
    ~Window() {
        gl.DeleteTextures(1, &m_texture);
        ImGui_ImplOpenGL3_Shutdown();
        ImGui_ImplGlfw_Shutdown();
        ImGui::DestroyContext();
        glfwDestroyWindow(m_window);
        glfwTerminate();
    }
    GLFWwindow* handle() const { return m_window; }
    double refresh_hz() const { return m_refresh_hz; }
    GLuint texture() const { return m_texture; }
    // Replaces the texture's pixels with the frame (reallocating only when the size changes).
    void upload(const VideoFrame& f) {
        gl.BindTexture(GL_TEXTURE_2D, m_texture);
        gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
        if (f.width == m_texture_width && f.height == m_texture_height) {
            gl.TexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, f.width, f.height, GL_RGBA, GL_UNSIGNED_BYTE, f.rgba.data());
        } else {
            gl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA, f.width, f.height, 0, GL_RGBA, GL_UNSIGNED_BYTE, f.rgba.data());
            m_texture_width = f.width;
            m_texture_height = f.height;
        }
    }
    int texture_width() const { return m_texture_width; }
    int texture_height() const { return m_texture_height; }

    // Saves the back buffer (before the swap) as PNG.
    void screenshot(const fs::path& path) const {
        int w = 0, h = 0;
        glfwGetFramebufferSize(m_window, &w, &h);
        std::vector<unsigned char> pixels(static_cast<std::size_t>(w) * h * 3);
        gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
        gl.ReadBuffer(GL_BACK);
        gl.ReadPixels(0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, pixels.data());
        fs::create_directories(path.parent_path());
        auto out = OIIO::ImageOutput::create(path.string());
        if (!out) throw InputError(path, "cannot write a PNG here");
        OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::UINT8);
        // zlib level 1: a scripted run saves several screens per trial, and
        // the flat UI images compress nearly as well as at the default 6.
        spec.attribute("png:compressionLevel", 1);
        if (!out->open(path.string(), spec)) throw InputError(path, "cannot write: " + out->geterror());
        // GL rows run bottom to top: write with a negative stride.
        const auto stride = static_cast<OIIO::stride_t>(w) * 3;
        out->write_image(OIIO::TypeDesc::UINT8, pixels.data() + static_cast<std::size_t>(h - 1) * stride,
                         OIIO::AutoStride, -stride);
        out->close();
    }

private:
    GLFWwindow* m_window = nullptr;
    double m_refresh_hz = 60.0;
    GLuint m_texture = 0;
    int m_texture_width = 0;
    int m_texture_height = 0;
};

bool key_pressed(int glfw_key) { return ImGui::IsKeyPressed(glfw_key, false); }
bool named_key_pressed(ImGuiKey key) { return ImGui::IsKeyPressed(ImGui::GetKeyIndex(key), false); }

// Centered, wrapped text in the middle of the screen.
void centered_text(const std::string& text, float y_fraction = 0.4f) {
    const ImVec2 size = ImGui::GetIO().DisplaySize;
    const float wrap = size.x * 0.75f;
    const ImVec2 extent = ImGui::CalcTextSize(text.c_str(), nullptr, false, wrap);
    ImGui::SetCursorPos(ImVec2((size.x - extent.x) * 0.5f, size.y * y_fraction - extent.y * 0.5f));
    ImGui::PushTextWrapPos(ImGui::GetCursorPosX() + wrap);
    ImGui::TextUnformatted(text.c_str());
    ImGui::PopTextWrapPos();
}

void hint_text(const std::string& text) {
    const ImVec2 size = ImGui::GetIO().DisplaySize;
    const ImVec2 extent = ImGui::CalcTextSize(text.c_str());
    ImGui::SetCursorPos(ImVec2((size.x - extent.x) * 0.5f, size.y * 0.85f));
    ImGui::TextColored(ImVec4(0.75f, 0.75f, 0.75f, 1.0f), "%s", text.c_str());
}

// The buffer-swap period as measured on the audio clock: the median of the
// last swaps' intervals (the nominal refresh until enough are seen). With
// vsync it settles on the display's refresh; without vsync (a virtual
// display) on the loop's own pace, so the next flip is still predicted right.
class FlipPeriod {
public:
    explicit FlipPeriod(double nominal_s) : m_nominal_s(nominal_s) {}
    void flipped(double interval_s) {
        if (interval_s <= 0 || interval_s > 0.25) return;  // a stall (window creation, decoding) is not a refresh
        m_recent[m_next++ % m_recent.size()] = interval_s;
        m_count = std::min(m_count + 1, m_recent.size());
    }
    double seconds() const {
        if (m_count < 8) return m_nominal_s;
        std::array<double, 31> sorted = m_recent;
        std::sort(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(m_count));
        return sorted[m_count / 2];
    }

private:
    double m_nominal_s;
    std::array<double, 31> m_recent{};
    std::size_t m_next = 0;
    std::size_t m_count = 0;
};

// The current stimulus being presented.
struct Playback {
    std::unique_ptr<FrameSource> source;
    std::unique_ptr<FramePacer> pacer;
    VideoFrame frame;       // last decoded frame
    bool have_frame = false;
    int uploaded = -1;      // frame index in the window's texture
    bool started = false;   // pacer started (onset known)
    bool shown_any = false;
    std::optional<MixedPresentation> mixed;  // adaptive protocols: the audio as mixed and played
};

// A scripted answer: one line per planned trial; for adaptive protocols a
// line may hold the answers to successive presentations of a repeated trial,
// separated by " || " (the last one answers any further presentation), and
// each answer may end in " ## 101": the experimenter's keyword marks on the
// score check screen (confirm_scores).
std::string scripted_part(const std::string& line, int attempt) {
    std::vector<std::string> parts;
    std::size_t start = 0;
    while (true) {
        const std::size_t bar = line.find(" || ", start);
        parts.push_back(line.substr(start, bar == std::string::npos ? std::string::npos : bar - start));
        if (bar == std::string::npos) break;
        start = bar + 4;
    }
    return parts[static_cast<std::size_t>(std::clamp(attempt, 1, static_cast<int>(parts.size())) - 1)];
}

std::string scripted_answer(const std::string& line, int attempt) {
    std::string part = scripted_part(line, attempt);
    if (const std::size_t marks = part.find(" ## "); marks != std::string::npos) part.erase(marks);
    return part == "-" ? std::string() : part;
}

// The scripted experimenter's marks ("1"/"0" per keyword), if the answer has them.
std::optional<std::vector<bool>> scripted_marks(const std::string& line, int attempt, const std::string& script_path) {
    const std::string part = scripted_part(line, attempt);
    const std::size_t at = part.find(" ## ");
    if (at == std::string::npos) return std::nullopt;
    std::vector<bool> marks;
    for (char c : part.substr(at + 4)) {
        if (c != '0' && c != '1')
            throw InputError(script_path, 0, 0, "marks",
                             fmt::format("expected keyword marks of 0 and 1 after \" ## \", got \"{}\"", part.substr(at + 4)));
        marks.push_back(c == '1');
    }
    return marks;
}

}  // namespace

RunResult run_session(const RunSettings& settings) {
    if (settings.subject < 1) throw UsageError(fmt::format("--subject: expected a number ≥ 1, got {}", settings.subject));
    const Protocol protocol = load_protocol(settings.protocol);
    const Corpus corpus = read_corpus(protocol.corpus.sentences);
    const bool scripted = !settings.script.empty();
    std::vector<std::string> script;
    if (scripted) script = read_script(settings.script);
    auto opener = make_stimulus_opener(settings, protocol.render.fps);

    Store store(settings.database);
    // One runner per subject: a second one stops here, before any window or
    // write (the first one's sessions stay as they are).
    const std::string broken_lock = store.lock_subject(settings.subject);
    if (!broken_lock.empty()) log_warning("{}: subject {}: {}", settings.database.string(), settings.subject, broken_lock);
    if (const auto name = store.meta("experiment"); name && *name != protocol.name)
        throw InputError(settings.database, fmt::format("this database belongs to experiment \"{}\", the protocol "
                                                        "is \"{}\"; give another --db",
                                                        *name, protocol.name));
    store.set_meta("experiment", protocol.name);
    store.set_meta("protocol_sha256", sha256_file(settings.protocol));

    // The plan: stored on the subject's first session, reused on every resume.
    std::vector<PlannedTrial> plan = store.planned_trials(settings.subject);
    const std::vector<PlannedTrial> designed =
        design_subject(protocol, assign_lists(corpus, protocol.design), settings.subject);
    if (plan.empty()) {
        plan = designed;
        store.add_subject(settings.subject, plan);
    } else if (plan != designed) {
        log_warning("subject {}: the protocol or corpus changed since the first session; keeping the stored "
                    "trial list so the subject's lists stay the same",
                    settings.subject);
    }
    if (scripted && script.size() < plan.size())
        throw InputError(settings.script, fmt::format("the script has {} responses, subject {} has {} planned trials "
                                                      "(one line per trial in plan order)",
                                                      script.size(), settings.subject, plan.size()));

    // Every planned stimulus listed in the manifest, present and unchanged.
    std::string stimuli_note = "test pattern";
    if (auto* folder = dynamic_cast<StimulusFolderOpener*>(opener.get())) {
        if (!folder->manifest().experiment.empty() && folder->manifest().experiment != protocol.name)
            throw InputError(settings.stimuli_dir / "manifest.json", 0, 0, "experiment",
                             fmt::format("expected stimuli built for experiment \"{}\", got \"{}\"", protocol.name,
                                         folder->manifest().experiment));
        std::vector<std::string> stimuli;
        for (const auto& t : plan) stimuli.push_back(t.stimulus);
        folder->verify(stimuli);
        stimuli_note = fmt::format("{} (manifest.json sha256 {}, {} stimuli checked)", settings.stimuli_dir.string(),
                                   folder->manifest().sha256, std::set<std::string>(stimuli.begin(), stimuli.end()).size());
    }
    // Adaptive SRT tracks: replayed from the stored presentations.
    std::unique_ptr<AdaptiveSession> adaptive;
    if (protocol.adaptive.present()) {
        adaptive = std::make_unique<AdaptiveSession>(protocol, corpus, store.adaptive_trials(settings.subject),
                                                     settings.database.string());
        if (adaptive->settings().list_variable()) {
            // Band-count / cutoff tracks play the builder's audio variants.
            if (settings.stimuli_dir.empty())
                throw UsageError(fmt::format("--stimuli: a \"{}\" track plays the pre-rendered audio variants of the "
                                             "stimulus folder; give --stimuli DIR (with --test-pattern the video is "
                                             "the test clip, the audio the variants)",
                                             analysis::to_string(adaptive->settings().variable)));
            adaptive->set_stimuli_dir(settings.stimuli_dir);
            adaptive->check_variants(plan);
        } else if (!settings.stimuli_dir.empty()) {
            // Noise before vocoding reads each stimulus's unvocoded speech
            // (a test pattern without --stimuli: the pattern's own audio).
            adaptive->set_stimuli_dir(settings.stimuli_dir);
            adaptive->check_variants(plan);
        }
    }
    const std::vector<int> answered = store.answered_positions(settings.subject);
    if (answered.size() >= plan.size()) {
        // Every trial answered: a session left open was killed after its last
        // commit. Close it as completed rather than opening an empty session.
        for (const auto& open : store.open_sessions(settings.subject)) {
            store.end_session(open.session, "completed");
            store.add_event(open.session, settings.subject, "completed",
                            fmt::format("session {} ended without closing after the last trial was answered; "
                                        "closed as completed by the next run",
                                        open.session));
        }
        throw InputError(settings.database, fmt::format("subject {} has answered all {} planned trials; nothing to "
                                                        "run (give another --subject)",
                                                        settings.subject, plan.size()));
    }
    RunResult result;
    result.answered_before = static_cast<int>(answered.size());
    result.total = static_cast<int>(plan.size());
    SessionMachine machine(plan, answered, protocol.session);
    // Live scores of the answers not yet committed (trial index → keyword
    // marks as they count, and as the live scorer gave them).
    std::map<int, std::vector<bool>> live_marks, auto_marks;
    if (adaptive) {
        machine.set_confirm_scores(adaptive->settings().confirm_scores);
        machine.set_repeat_rule([&](int index, const Response& response) {
            const PlannedTrial& t = plan[static_cast<std::size_t>(index)];
            const auto checked = live_marks.find(index);
            std::vector<bool> marks = checked != live_marks.end() ? checked->second : adaptive->score(t, response.text);
            const bool again = adaptive->repeats(t, marks);
            live_marks[index] = std::move(marks);
            return again;
        });
    }
    auto script_line = [&](int index) {
        const std::string& line = script[static_cast<std::size_t>(index)];
        return adaptive ? scripted_answer(line, adaptive->next_attempt(plan[static_cast<std::size_t>(index)])) : line;
    };
    const int first_position = machine.trial() ? machine.trial()->position : 0;

    std::unique_ptr<AudioOutput> audio;
    if (settings.audio == "null")
        audio = std::make_unique<NullAudioOutput>();
    else if (settings.audio == "portaudio")
        audio = make_portaudio_output(settings.audio_device);
    else
        throw UsageError(fmt::format("--audio: expected \"portaudio\" or \"null\", got \"{}\"", settings.audio));
    result.audio_device = audio->name();

    const bool fullscreen = settings.fullscreen.value_or(protocol.session.fullscreen);
    const int monitor = settings.monitor.value_or(protocol.session.monitor);
    Window window(settings, fullscreen, monitor, fmt::format("avsi — {} — subject {}", protocol.name, settings.subject));
    const double refresh_hz = settings.audio == "null" ? settings.null_refresh_hz : window.refresh_hz();
    const double period_s = 1.0 / refresh_hz;
    // The simulated clock moves exactly one nominal period per swap; a real one is measured.
    FlipPeriod flip_period(period_s);
    const bool simulated = settings.audio == "null";

    for (const auto& open : store.open_sessions(settings.subject)) {
        store.mark_interrupted(open.session);
        store.add_event(open.session, settings.subject, "interrupted",
                        fmt::format("session {} ended without closing (crash, power loss or kill)", open.session));
    }
    const int session = store.begin_session(
        settings.subject, first_position,
        fmt::format("audio={}; refresh_hz={:.3f}; scripted={}; fullscreen={}; response_mode={}", audio->name(),
                    refresh_hz, scripted, fullscreen,
                    protocol.session.response_mode == ResponseMode::Experimenter ? "experimenter" : "subject"));
    result.session = session;
    store.add_event(session, settings.subject, result.answered_before > 0 ? "resume" : "start",
                    fmt::format("first trial {}, {} of {} answered before", first_position, result.answered_before,
                                result.total));
    store.add_event(session, settings.subject, "stimuli", stimuli_note);
    if (adaptive) {
        std::string levels;
        for (const auto& c : protocol.conditions) {
            const auto& track = adaptive->track(c.name);
            levels += fmt::format("{}{}: next {} dB after {} presentations", levels.empty() ? "" : "; ", c.name,
                                  track.level_db(), track.steps().size());
        }
        store.add_event(session, settings.subject, "adaptive-tracks", levels);
        log_info("adaptive tracks ({} scoring, {}): {}", analysis::to_string(adaptive->settings().track.procedure),
                 analysis::to_string(adaptive->settings().order), levels);
    }
    log_info("subject {}: session {} {} at trial {} of {} ({} answered before), audio {}", settings.subject, session,
             result.answered_before > 0 ? "resumes" : "starts", first_position, result.total,
             result.answered_before, audio->name());

    Playback playback;
    std::string answer;
    bool focus_answer = false;
    std::string last_screen_key;
    int screen_frames = 0;  // flips since the screen changed
    int screenshot_seq = 0;
    double last_flip_s = audio->now_s();
    const auto wall_start = std::chrono::steady_clock::now();
    const double clock_start = last_flip_s;
    double sum_offset = 0.0;
    int offset_count = 0;
    bool running = true;
    bool ended = false;

    while (running) {
        glfwPollEvents();
        const double next_flip_s = last_flip_s + (simulated ? period_s : flip_period.seconds());
        if (glfwWindowShouldClose(window.handle()) && !machine.finished()) {
            if (machine.screen() != Screen::Paused) machine.escape(next_flip_s);
            machine.quit();
        }

        ImGui_ImplOpenGL3_NewFrame();
        ImGui_ImplGlfw_NewFrame();
        ImGui::NewFrame();

        // Input: scripted, or keys.
        const Screen screen = machine.screen();
        // An answer waiting for the experimenter's check: scored live once.
        if (screen == Screen::ScoreCheck && !auto_marks.count(machine.trial_index())) {
            const int index = machine.trial_index();
            auto_marks[index] = adaptive->score(plan[static_cast<std::size_t>(index)], machine.pending_response().text);
            live_marks[index] = auto_marks[index];
        }
        const bool settled =
            fmt::format("{}-{}", to_string(screen), machine.trial_index()) == last_screen_key && screen_frames >= 1;
        if (scripted) {
            if (settled) {
                switch (screen) {
                    case Screen::Instructions:
                    case Screen::Break:
                    case Screen::Feedback: machine.continue_pressed(next_flip_s); break;
                    case Screen::Response:
                        machine.submit(script_line(machine.trial_index()), next_flip_s);
                        break;
                    case Screen::ConfirmEmpty: machine.confirm_empty(true, next_flip_s); break;
                    case Screen::ScoreCheck: {
                        const int index = machine.trial_index();
                        if (const auto marks = scripted_marks(script[static_cast<std::size_t>(index)],
                                                              adaptive->next_attempt(plan[static_cast<std::size_t>(index)]),
                                                              settings.script.string())) {
                            if (marks->size() != live_marks[index].size())
                                throw InputError(settings.script, 0, 0, "marks",
                                                 fmt::format("trial {}: expected {} keyword marks, got {}",
                                                             plan[static_cast<std::size_t>(index)].position,
                                                             live_marks[index].size(), marks->size()));
                            live_marks[index] = *marks;
                        }
                        machine.confirm_score(next_flip_s);
                        break;
                    }
                    case Screen::End: running = false; break;
                    default: break;
                }
            }
        } else {
            if (named_key_pressed(ImGuiKey_Escape)) {
                if (machine.screen() == Screen::End) running = false;
                else machine.escape(next_flip_s);
            } else if (screen == Screen::Paused && key_pressed(GLFW_KEY_Q)) {
                machine.quit();
            } else if (screen == Screen::Instructions || screen == Screen::Break || screen == Screen::Feedback) {
                if (named_key_pressed(ImGuiKey_Space) || named_key_pressed(ImGuiKey_Enter)) machine.continue_pressed(next_flip_s);
            } else if (screen == Screen::ScoreCheck) {
                auto& marks = live_marks[machine.trial_index()];
                for (std::size_t k = 0; k < marks.size() && k < 9; ++k)
                    if (key_pressed(GLFW_KEY_1 + static_cast<int>(k))) marks[k] = !marks[k];
                if (named_key_pressed(ImGuiKey_Enter)) machine.confirm_score(next_flip_s);
            } else if (screen == Screen::ConfirmEmpty) {
                if (key_pressed(GLFW_KEY_Y) || named_key_pressed(ImGuiKey_Enter)) machine.confirm_empty(true, next_flip_s);
                else if (key_pressed(GLFW_KEY_N)) machine.confirm_empty(false, next_flip_s);
            } else if (screen == Screen::End && screen_frames > 30 &&
                       (named_key_pressed(ImGuiKey_Enter) || named_key_pressed(ImGuiKey_Space))) {
                running = false;
            }
        }
        machine.tick(next_flip_s);

        // The machine's actions, in order; a commit finishes before anything else happens.
        for (auto& action : machine.take_actions()) {
            const PlannedTrial* t = action.trial_index >= 0 && action.trial_index < static_cast<int>(plan.size())
                                        ? &plan[static_cast<std::size_t>(action.trial_index)]
                                        : nullptr;
            switch (action.kind) {
                case SessionAction::Kind::StartStimulus: {
                    playback = Playback{};
                    playback.source = opener->open(t->stimulus);
                    playback.pacer = std::make_unique<FramePacer>(playback.source->fps(), playback.source->frame_count(),
                                                                  simulated ? refresh_hz : 1.0 / flip_period.seconds());
                    if (adaptive)
                        playback.mixed = adaptive->mix(*t, playback.source->audio(), playback.source->sample_rate());
                    const std::vector<float>& samples = playback.mixed ? playback.mixed->samples : playback.source->audio();
                    audio->play(samples, playback.source->sample_rate(), next_flip_s + audio->lead_s());
                    if (!settings.audio_capture.empty()) {
                        Audio sent;
                        sent.sample_rate_hz = playback.source->sample_rate();
                        sent.samples = samples;
                        fs::create_directories(settings.audio_capture);
                        const int attempt = playback.mixed ? playback.mixed->attempt : 1;
                        write_audio(settings.audio_capture / (attempt == 1 ? fmt::format("trial{:03}.wav", t->position)
                                                                           : fmt::format("trial{:03}_{}.wav", t->position, attempt)),
                                    sent, SampleFormat::Float32);
                    }
                    break;
                }
                case SessionAction::Kind::StopStimulus:
                    audio->stop();
                    store.add_event(session, settings.subject, "stimulus-interrupted",
                                    fmt::format("trial {} paused during the stimulus; shown again", t->position));
                    playback = Playback{};
                    break;
                case SessionAction::Kind::CommitResponse: {
                    Presentation p = playback.pacer ? playback.pacer->summary() : Presentation{};
                    if (adaptive) {
                        if (!playback.mixed) throw std::logic_error("adaptive: an answer without a mixed presentation");
                        auto cached = live_marks.find(action.trial_index);
                        const std::vector<bool> marks =
                            cached != live_marks.end() ? cached->second : adaptive->score(*t, action.response.text);
                        const auto live = auto_marks.find(action.trial_index);
                        const std::vector<bool> scored = live != auto_marks.end() ? live->second : marks;
                        live_marks.erase(action.trial_index);
                        auto_marks.erase(action.trial_index);
                        const AdaptiveRecord record =
                            adaptive->record(*t, *playback.mixed, action.response.text, scored, marks);
                        if (record.corrected)
                            store.add_event(session, settings.subject, "score-corrected",
                                            fmt::format("trial {} presentation {}: live score {} of {}, corrected to {} "
                                                        "({}) by the experimenter",
                                                        t->position, record.attempt, record.auto_correct,
                                                        record.keywords, record.correct, record.marks));
                        if (action.repeat) {
                            store.commit_attempt(session, *t, record);
                        } else {
                            store.commit_trial(session, *t, p, action.response, record);
                        }
                        log_info("trial {}{}: {} {:.2f} {}, {} of {} keywords{}", t->position,
                                 record.attempt > 1 ? fmt::format(" (presentation {})", record.attempt) : "",
                                 adaptive->settings().list_variable() ? std::string("level") : std::string("SNR"),
                                 record.level_db, adaptive->settings().unit(), record.correct, record.keywords,
                                 record.track.empty() ? std::string(" (no track)")
                                                      : fmt::format(", next {:.2f} {}{}", record.next_level_db,
                                                                    adaptive->settings().unit(),
                                                                    record.repeat ? " (the same sentence again)" : ""));
                        if (action.repeat) {
                            playback = Playback{};
                            break;
                        }
                    } else {
                        store.commit_trial(session, *t, p, action.response);
                    }
                    ++result.answered;
                    ++result.presentations;
                    result.dropped_frames += p.dropped_frames;
                    result.repeated_frames += p.repeated_frames;
                    result.max_abs_av_offset_ms = std::max(result.max_abs_av_offset_ms, p.max_abs_offset_ms);
                    if (!simulated)
                        log_info("trial {}: {} of {} frames shown, {} dropped, {} repeated; A/V offset mean {:.3f} ms, "
                                 "max |offset| {:.3f} ms (flip period {:.3f} ms)",
                                 t->position, p.frames_shown, p.frames_total, p.dropped_frames, p.repeated_frames,
                                 p.mean_offset_ms, p.max_abs_offset_ms, flip_period.seconds() * 1000.0);
                    for (const auto& f : p.flips) {
                        sum_offset += f.offset_ms;
                        ++offset_count;
                    }
                    playback = Playback{};
                    break;
                }
                case SessionAction::Kind::Finished:
                    if (!ended) {
                        store.end_session(session, "completed");
                        ended = true;
                    }
                    result.completed = true;
                    break;
                case SessionAction::Kind::Quit:
                    audio->stop();
                    store.end_session(session, "quit");
                    store.add_event(session, settings.subject, "quit",
                                    fmt::format("stopped at trial {}", t ? t->position : 0));
                    ended = true;
                    result.quit = true;
                    break;
            }
        }

        // Stimulus frame for the coming flip, chosen on the audio clock.
        int frame_to_show = -1;
        bool lead_frame = false;  // the first frame shown during the masker's lead
        if (machine.screen() == Screen::Stimulus && playback.source) {
            if (!playback.started) {
                if (const auto onset = audio->onset_s()) {
                    // The masker's lead plays before the video starts.
                    playback.pacer->start(*onset + (playback.mixed ? playback.mixed->lead_s : 0.0));
                    playback.started = true;
                    if (const std::string detail = audio->onset_detail(); !detail.empty())
                        log_info("trial {}: audio {}", machine.trial() ? machine.trial()->position : 0, detail);
                }
            }
            if (playback.started) {
                const int k = playback.pacer->frame_for(next_flip_s);
                if (k >= playback.pacer->frame_count()) {
                    if (!audio->playing()) machine.stimulus_finished(next_flip_s);
                } else if (k < 0 && !playback.shown_any) {
                    // The masker's lead: the first frame (the face at rest), outside the pacer's count.
                    if (!playback.have_frame) playback.have_frame = playback.source->next_frame(playback.frame);
                    if (playback.have_frame && playback.uploaded != playback.frame.index) {
                        window.upload(playback.frame);
                        playback.uploaded = playback.frame.index;
                    }
                    lead_frame = playback.have_frame;
                } else if (k >= 0) {
                    while ((!playback.have_frame || playback.frame.index < k) && playback.source->next_frame(playback.frame)) {
                        playback.have_frame = true;
                    }
                    if (playback.have_frame && playback.frame.index == k) {
                        // A frame held over several refreshes is uploaded once.
                        if (playback.uploaded != k) {
                            window.upload(playback.frame);
                            playback.uploaded = k;
                        }
                        frame_to_show = k;
                    }
                }
            }
        }

        // Draw the screen.
        const ImVec2 display = ImGui::GetIO().DisplaySize;
        ImGui::SetNextWindowPos(ImVec2(0, 0));
        ImGui::SetNextWindowSize(display);
        ImGui::Begin("screen", nullptr,
                     ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoSavedSettings |
                         ImGuiWindowFlags_NoBringToFrontOnFocus | ImGuiWindowFlags_NoBackground);
        const PlannedTrial* trial = machine.trial();
        const Screen shown = machine.screen();
        const std::string screen_key = fmt::format("{}-{}", to_string(shown), machine.trial_index());
        const bool new_screen = screen_key != last_screen_key;
        const std::string progress =
            protocol.session.show_progress && trial
                ? fmt::format("Sentence {} of {}", trial->position, machine.total_trials())
                : std::string();
        switch (shown) {
            case Screen::Instructions:
                centered_text(machine.message());
                hint_text("Press Space to begin");
                break;
            case Screen::Fixation: centered_text("+", 0.5f); break;
            case Screen::Stimulus:
                if (frame_to_show >= 0 || playback.shown_any || lead_frame) {
                    const float scale = std::min(display.x * 0.9f / window.texture_width(), display.y * 0.8f / window.texture_height());
                    const ImVec2 size(window.texture_width() * scale, window.texture_height() * scale);
                    // The video is opaque: drawn without blending (no read of
                    // the framebuffer under it), then ImGui's state is restored.
                    ImDrawList* background = ImGui::GetBackgroundDrawList();
                    background->AddCallback([](const ImDrawList*, const ImDrawCmd*) { gl.Disable(GL_BLEND); }, nullptr);
                    background->AddImage(
                        reinterpret_cast<ImTextureID>(static_cast<std::intptr_t>(window.texture())),
                        ImVec2((display.x - size.x) * 0.5f, (display.y - size.y) * 0.5f),
                        ImVec2((display.x + size.x) * 0.5f, (display.y + size.y) * 0.5f));
                    background->AddCallback(ImDrawCallback_ResetRenderState, nullptr);
                } else {
                    centered_text("+", 0.5f);
                }
                break;
            case Screen::Wait: break;
            case Screen::Response: {
                centered_text("What did you hear? Type every word, then press Enter.", 0.35f);
                ImGui::SetCursorPos(ImVec2(display.x * 0.15f, display.y * 0.5f));
                ImGui::PushItemWidth(display.x * 0.7f);
                if (scripted && trial) answer = script_line(machine.trial_index());
                if (!scripted && (new_screen || focus_answer)) {
                    ImGui::SetKeyboardFocusHere();
                    focus_answer = false;
                }
                if (new_screen && !scripted) answer.clear();
                if (ImGui::InputText("##answer", &answer, ImGuiInputTextFlags_EnterReturnsTrue) && !scripted) {
                    machine.submit(answer, next_flip_s);
                    focus_answer = true;
                }
                ImGui::PopItemWidth();
                hint_text("Enter: submit    Esc: pause");
                break;
            }
            case Screen::ScoreCheck: {
                std::string text = fmt::format("Score check: \"{}\"\n\n", machine.pending_response().text);
                if (trial) {
                    const Sentence& s = corpus.sentence(trial->sentence);
                    const auto& marks = live_marks[machine.trial_index()];
                    for (std::size_t k = 0; k < s.keywords.size() && k < marks.size(); ++k)
                        text += fmt::format("{}  [{}]  {}\n", k + 1, marks[k] ? "x" : " ", s.keywords[k].word);
                }
                centered_text(text);
                hint_text("1-9: toggle a keyword    Enter: accept the score");
                break;
            }
            case Screen::ConfirmEmpty:
                centered_text("You did not type anything. Submit an empty answer?");
                hint_text("Y or Enter: submit empty    N: go back and type");
                break;
            case Screen::Feedback: {
                std::string text;
                if (trial) text = "The sentence was:\n\n" + corpus.sentence(trial->sentence).text;
                centered_text(text);
                hint_text("Press Space to continue");
                break;
            }
            case Screen::Break:
                centered_text(machine.message());
                // The default break text already names the key.
                if (machine.message().find("Space") == std::string::npos) hint_text("Press Space to continue");
                break;
            case Screen::Paused:
                centered_text("Paused.");
                hint_text("Esc: continue    Q: stop the session (it can be resumed later)");
                break;
            case Screen::End: centered_text(machine.message()); break;
        }
        if (!progress.empty() && shown != Screen::Stimulus && shown != Screen::End && shown != Screen::Paused) {
            ImGui::SetCursorPos(ImVec2(display.x * 0.02f, display.y * 0.95f));
            ImGui::TextColored(ImVec4(0.75f, 0.75f, 0.75f, 1.0f), "%s", progress.c_str());
        }
        ImGui::End();
        ImGui::Render();
        int fb_w = 0, fb_h = 0;
        glfwGetFramebufferSize(window.handle(), &fb_w, &fb_h);
        gl.Viewport(0, 0, fb_w, fb_h);
        gl.ClearColor(0.25f, 0.25f, 0.25f, 1.0f);
        gl.Clear(GL_COLOR_BUFFER_BIT);
        ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());

        // One PNG per new screen (the trial screen once its first frame is up).
        if (!settings.screenshots.empty() && new_screen && (shown != Screen::Stimulus || frame_to_show >= 0)) {
            window.screenshot(settings.screenshots /
                              fmt::format("{:04}_{}_trial{:03}.png", ++screenshot_seq, to_string(shown),
                                          trial ? trial->position : 0));
            ++result.screenshots;
        }
        if (shown != Screen::Stimulus || frame_to_show >= 0 || !new_screen) {
            screen_frames = new_screen ? 0 : screen_frames + 1;
            last_screen_key = screen_key;
        }

        glfwSwapBuffers(window.handle());
        if (settings.audio != "null") gl.Finish();
        audio->after_flip(period_s);
        const double flip_s = audio->now_s();
        flip_period.flipped(flip_s - last_flip_s);
        last_flip_s = flip_s;
        if (frame_to_show >= 0) {
            playback.pacer->flipped(frame_to_show, playback.frame.pts_s, flip_s);
            playback.shown_any = true;
        }
        // The simulated clock never runs ahead of real time in an interactive dry run.
        if (settings.audio == "null" && !scripted) {
            const auto target = wall_start + std::chrono::duration<double>(flip_s - clock_start);
            std::this_thread::sleep_until(target);
        }
    }
    if (!ended) {
        store.end_session(session, "quit");
        result.quit = true;
    }
    result.mean_av_offset_ms = offset_count ? sum_offset / offset_count : 0.0;
    const auto answered_after = store.answered_positions(settings.subject);
    result.completed = answered_after.size() == plan.size();
    store.add_event(session, settings.subject, "timing-summary",
                    fmt::format("{} presentations, {} dropped frames, {} repeated frames, A/V offset mean {:.3f} ms, "
                                "max |offset| {:.3f} ms ({})",
                                result.presentations, result.dropped_frames, result.repeated_frames,
                                result.mean_av_offset_ms, result.max_abs_av_offset_ms, audio->name()));
    log_info("timing: {} presentations, {} dropped frames, {} repeated frames, A/V offset mean {:.3f} ms, "
             "max |offset| {:.3f} ms (clock: {})",
             result.presentations, result.dropped_frames, result.repeated_frames, result.mean_av_offset_ms,
             result.max_abs_av_offset_ms, audio->name());
    return result;
}

}  // namespace avsi::experiment
