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
#include "avsi/core/ui_strings.h"
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

// One run of a subject's session: the steps of run_session as members, the
// state they share as fields. Construction prepares everything that can be
// checked without a window (protocol, plan, stimuli, tracks); run() opens the
// devices and turns keys, time and the machine's actions into drawing, sound
// and database writes, one display refresh per loop.
class SessionRun {
public:
    explicit SessionRun(const RunSettings& settings)
        : m_settings(checked(settings)),
          m_protocol(load_protocol(settings.protocol)),
          m_corpus(read_corpus(m_protocol.corpus.sentences)),
          m_scripted(!settings.script.empty()),
          m_script(m_scripted ? read_script(settings.script) : std::vector<std::string>{}),
          m_opener(make_stimulus_opener(settings, m_protocol.render.fps)),
          m_store(settings.database) {
        claim_database();
        load_plan();
        check_stimuli();
        replay_tracks();
        refuse_if_complete();
        make_machine();
    }

    RunResult run() {
        open_devices();
        begin_session();
        while (m_running) {
            glfwPollEvents();
            const double next_flip_s = m_last_flip_s + (m_simulated ? m_period_s : m_flip_period->seconds());
            if (glfwWindowShouldClose(m_window->handle()) && !m_machine->finished()) {
                if (m_machine->screen() != Screen::Paused) m_machine->escape(next_flip_s);
                m_machine->quit();
            }
            ImGui_ImplOpenGL3_NewFrame();
            ImGui_ImplGlfw_NewFrame();
            ImGui::NewFrame();
            score_answer_to_check();
            if (m_scripted) scripted_input(next_flip_s);
            else key_input(next_flip_s);
            m_machine->tick(next_flip_s);
            // The machine's actions, in order; a commit finishes before anything else happens.
            for (auto& action : m_machine->take_actions()) perform(action, next_flip_s);
            const FrameChoice frame = choose_frame(next_flip_s);
            draw_screen(frame, next_flip_s);
            flip(frame);
        }
        return finish();
    }

private:
    // The stimulus frame for the coming flip: a frame of the clip, or the
    // first frame held during the masker's lead (outside the pacer's count).
    struct FrameChoice {
        int frame = -1;
        bool lead = false;
    };

    const PlannedTrial& planned(int index) const { return m_plan[static_cast<std::size_t>(index)]; }

    static const RunSettings& checked(const RunSettings& s) {
        if (s.subject < 1) throw UsageError(fmt::format("--subject: expected a number ≥ 1, got {}", s.subject));
        return s;
    }

    // One runner per subject: a second one stops here, before any window or
    // write (the first one's sessions stay as they are).
    void claim_database() {
        const std::string broken_lock = m_store.lock_subject(m_settings.subject);
        if (!broken_lock.empty())
            log_warning("{}: subject {}: {}", m_settings.database.string(), m_settings.subject, broken_lock);
        if (const auto name = m_store.meta("experiment"); name && *name != m_protocol.name)
            throw InputError(m_settings.database, fmt::format("this database belongs to experiment \"{}\", the protocol "
                                                              "is \"{}\"; give another --db",
                                                              *name, m_protocol.name));
        m_store.set_meta("experiment", m_protocol.name);
        m_store.set_meta("protocol_sha256", sha256_file(m_settings.protocol));
    }

    // The plan: stored on the subject's first session, reused on every resume.
    void load_plan() {
        m_plan = m_store.planned_trials(m_settings.subject);
        const std::vector<PlannedTrial> designed =
            design_subject(m_protocol, assign_lists(m_corpus, m_protocol.design), m_settings.subject);
        if (m_plan.empty()) {
            m_plan = designed;
            m_store.add_subject(m_settings.subject, m_plan);
        } else if (m_plan != designed) {
            log_warning("subject {}: the protocol or corpus changed since the first session; keeping the stored "
                        "trial list so the subject's lists stay the same",
                        m_settings.subject);
        }
        if (m_scripted && m_script.size() < m_plan.size())
            throw InputError(m_settings.script,
                             fmt::format("the script has {} responses, subject {} has {} planned trials "
                                         "(one line per trial in plan order)",
                                         m_script.size(), m_settings.subject, m_plan.size()));
    }

    // Every planned stimulus listed in the manifest, present and unchanged.
    void check_stimuli() {
        auto* folder = dynamic_cast<StimulusFolderOpener*>(m_opener.get());
        if (!folder) return;
        if (!folder->manifest().experiment.empty() && folder->manifest().experiment != m_protocol.name)
            throw InputError(m_settings.stimuli_dir / "manifest.json", 0, 0, "experiment",
                             fmt::format("expected stimuli built for experiment \"{}\", got \"{}\"", m_protocol.name,
                                         folder->manifest().experiment));
        std::vector<std::string> stimuli;
        for (const auto& t : m_plan) stimuli.push_back(t.stimulus);
        folder->verify(stimuli);
        m_stimuli_note = fmt::format("{} (manifest.json sha256 {}, {} stimuli checked)", m_settings.stimuli_dir.string(),
                                     folder->manifest().sha256,
                                     std::set<std::string>(stimuli.begin(), stimuli.end()).size());
    }

    // Adaptive SRT tracks: replayed from the stored presentations.
    void replay_tracks() {
        if (!m_protocol.adaptive.present()) return;
        m_adaptive = std::make_unique<AdaptiveSession>(m_protocol, m_corpus, m_store.adaptive_trials(m_settings.subject),
                                                       m_settings.database.string());
        if (m_adaptive->settings().list_variable()) {
            // Band-count / cutoff tracks play the builder's audio variants.
            if (m_settings.stimuli_dir.empty())
                throw UsageError(fmt::format("--stimuli: a \"{}\" track plays the pre-rendered audio variants of the "
                                             "stimulus folder; give --stimuli DIR (with --test-pattern the video is "
                                             "the test clip, the audio the variants)",
                                             analysis::to_string(m_adaptive->settings().variable)));
            m_adaptive->set_stimuli_dir(m_settings.stimuli_dir);
            m_adaptive->check_variants(m_plan);
        } else if (!m_settings.stimuli_dir.empty()) {
            // Noise before vocoding reads each stimulus's unvocoded speech
            // (a test pattern without --stimuli: the pattern's own audio).
            m_adaptive->set_stimuli_dir(m_settings.stimuli_dir);
            m_adaptive->check_variants(m_plan);
        }
    }

    // Every trial answered: a session left open was killed after its last
    // commit. Close it as completed rather than opening an empty session.
    void refuse_if_complete() {
        m_answered = m_store.answered_positions(m_settings.subject);
        if (m_answered.size() < m_plan.size()) return;
        for (const auto& open : m_store.open_sessions(m_settings.subject)) {
            m_store.end_session(open.session, "completed");
            m_store.add_event(open.session, m_settings.subject, "completed",
                              fmt::format("session {} ended without closing after the last trial was answered; "
                                          "closed as completed by the next run",
                                          open.session));
        }
        throw InputError(m_settings.database, fmt::format("subject {} has answered all {} planned trials; nothing to "
                                                          "run (give another --subject)",
                                                          m_settings.subject, m_plan.size()));
    }

    void make_machine() {
        m_result.answered_before = static_cast<int>(m_answered.size());
        m_result.total = static_cast<int>(m_plan.size());
        m_machine = std::make_unique<SessionMachine>(m_plan, m_answered, m_protocol.session);
        if (!m_adaptive) return;
        m_machine->set_confirm_scores(m_adaptive->settings().confirm_scores);
        m_machine->set_repeat_rule([this](int index, const Response& response) {
            const auto checked = m_live_marks.find(index);
            std::vector<bool> marks =
                checked != m_live_marks.end() ? checked->second : m_adaptive->score(planned(index), response.text);
            const bool again = m_adaptive->repeats(planned(index), marks);
            m_live_marks[index] = std::move(marks);
            return again;
        });
    }

    void open_devices() {
        if (m_settings.audio == "null")
            m_audio = std::make_unique<NullAudioOutput>();
        else if (m_settings.audio == "portaudio")
            m_audio = make_portaudio_output(m_settings.audio_device);
        else
            throw UsageError(fmt::format("--audio: expected \"portaudio\" or \"null\", got \"{}\"", m_settings.audio));
        m_result.audio_device = m_audio->name();
        m_fullscreen = m_settings.fullscreen.value_or(m_protocol.session.fullscreen);
        const int monitor = m_settings.monitor.value_or(m_protocol.session.monitor);
        m_window = std::make_unique<Window>(m_settings, m_fullscreen, monitor,
                                            fmt::format("avsi — {} — subject {}", m_protocol.name, m_settings.subject));
        m_simulated = m_settings.audio == "null";
        m_refresh_hz = m_simulated ? m_settings.null_refresh_hz : m_window->refresh_hz();
        m_period_s = 1.0 / m_refresh_hz;
        // The simulated clock moves exactly one nominal period per swap; a real one is measured.
        m_flip_period = std::make_unique<FlipPeriod>(m_period_s);
        m_last_flip_s = m_audio->now_s();
        m_clock_start = m_last_flip_s;
        m_wall_start = std::chrono::steady_clock::now();
    }

    // Sessions left open are marked interrupted; this one begins, with its
    // events (start or resume, the stimuli, the tracks' next levels).
    void begin_session() {
        for (const auto& open : m_store.open_sessions(m_settings.subject)) {
            m_store.mark_interrupted(open.session);
            m_store.add_event(open.session, m_settings.subject, "interrupted",
                              fmt::format("session {} ended without closing (crash, power loss or kill)", open.session));
        }
        const int first_position = m_machine->trial() ? m_machine->trial()->position : 0;
        m_session = m_store.begin_session(
            m_settings.subject, first_position,
            fmt::format("audio={}; refresh_hz={:.3f}; scripted={}; fullscreen={}; response_mode={}", m_audio->name(),
                        m_refresh_hz, m_scripted, m_fullscreen,
                        m_protocol.session.response_mode == ResponseMode::Experimenter ? "experimenter" : "subject"));
        m_result.session = m_session;
        m_store.add_event(m_session, m_settings.subject, m_result.answered_before > 0 ? "resume" : "start",
                          fmt::format("first trial {}, {} of {} answered before", first_position,
                                      m_result.answered_before, m_result.total));
        m_store.add_event(m_session, m_settings.subject, "stimuli", m_stimuli_note);
        if (m_adaptive) {
            std::string levels;
            for (const auto& c : m_protocol.conditions) {
                const auto& track = m_adaptive->track(c.name);
                levels += fmt::format("{}{}: next {} dB after {} presentations", levels.empty() ? "" : "; ", c.name,
                                      track.level_db(), track.steps().size());
            }
            m_store.add_event(m_session, m_settings.subject, "adaptive-tracks", levels);
            log_info("adaptive tracks ({} scoring, {}): {}", analysis::to_string(m_adaptive->settings().track.procedure),
                     analysis::to_string(m_adaptive->settings().order), levels);
        }
        log_info("subject {}: session {} {} at trial {} of {} ({} answered before), audio {}", m_settings.subject,
                 m_session, m_result.answered_before > 0 ? "resumes" : "starts", first_position, m_result.total,
                 m_result.answered_before, m_audio->name());
    }

    // The answer of a scripted line for the trial's next presentation.
    std::string script_line(int index) const {
        const std::string& line = m_script[static_cast<std::size_t>(index)];
        return m_adaptive ? scripted_answer(line, m_adaptive->next_attempt(planned(index))) : line;
    }

    // An answer waiting for the experimenter's check: scored live once.
    void score_answer_to_check() {
        if (m_machine->screen() != Screen::ScoreCheck || m_auto_marks.count(m_machine->trial_index())) return;
        const int index = m_machine->trial_index();
        m_auto_marks[index] = m_adaptive->score(planned(index), m_machine->pending_response().text);
        m_live_marks[index] = m_auto_marks[index];
    }

    // A scripted run answers each screen once it has been up for a flip.
    void scripted_input(double next_flip_s) {
        const Screen screen = m_machine->screen();
        const bool settled =
            fmt::format("{}-{}", to_string(screen), m_machine->trial_index()) == m_last_screen_key && m_screen_frames >= 1;
        if (!settled) return;
        switch (screen) {
            case Screen::Instructions:
            case Screen::Break:
            case Screen::Feedback: m_machine->continue_pressed(next_flip_s); break;
            case Screen::Response: m_machine->submit(script_line(m_machine->trial_index()), next_flip_s); break;
            case Screen::ConfirmEmpty: m_machine->confirm_empty(true, next_flip_s); break;
            case Screen::ScoreCheck: {
                const int index = m_machine->trial_index();
                if (const auto marks = scripted_marks(m_script[static_cast<std::size_t>(index)],
                                                      m_adaptive->next_attempt(planned(index)),
                                                      m_settings.script.string())) {
                    if (marks->size() != m_live_marks[index].size())
                        throw InputError(m_settings.script, 0, 0, "marks",
                                         fmt::format("trial {}: expected {} keyword marks, got {}",
                                                     planned(index).position, m_live_marks[index].size(), marks->size()));
                    m_live_marks[index] = *marks;
                }
                m_machine->confirm_score(next_flip_s);
                break;
            }
            case Screen::End: m_running = false; break;
            default: break;
        }
    }

    void key_input(double next_flip_s) {
        const Screen screen = m_machine->screen();
        if (named_key_pressed(ImGuiKey_Escape)) {
            if (screen == Screen::End) m_running = false;
            else m_machine->escape(next_flip_s);
        } else if (screen == Screen::Paused && key_pressed(GLFW_KEY_Q)) {
            m_machine->quit();
        } else if (screen == Screen::Instructions || screen == Screen::Break || screen == Screen::Feedback) {
            if (named_key_pressed(ImGuiKey_Space) || named_key_pressed(ImGuiKey_Enter))
                m_machine->continue_pressed(next_flip_s);
        } else if (screen == Screen::ScoreCheck) {
            auto& marks = m_live_marks[m_machine->trial_index()];
            for (std::size_t k = 0; k < marks.size() && k < 9; ++k)
                if (key_pressed(GLFW_KEY_1 + static_cast<int>(k))) marks[k] = !marks[k];
            if (named_key_pressed(ImGuiKey_Enter)) m_machine->confirm_score(next_flip_s);
        } else if (screen == Screen::ConfirmEmpty) {
            if (key_pressed(GLFW_KEY_Y) || named_key_pressed(ImGuiKey_Enter)) m_machine->confirm_empty(true, next_flip_s);
            else if (key_pressed(GLFW_KEY_N)) m_machine->confirm_empty(false, next_flip_s);
        } else if (screen == Screen::End && m_screen_frames > 30 &&
                   (named_key_pressed(ImGuiKey_Enter) || named_key_pressed(ImGuiKey_Space))) {
            m_running = false;
        }
    }

    void perform(const SessionAction& action, double next_flip_s) {
        const PlannedTrial* t = action.trial_index >= 0 && action.trial_index < static_cast<int>(m_plan.size())
                                    ? &planned(action.trial_index)
                                    : nullptr;
        switch (action.kind) {
            case SessionAction::Kind::StartStimulus: start_stimulus(*t, next_flip_s); break;
            case SessionAction::Kind::StopStimulus:
                m_audio->stop();
                m_store.add_event(m_session, m_settings.subject, "stimulus-interrupted",
                                  fmt::format("trial {} paused during the stimulus; shown again", t->position));
                m_playback = Playback{};
                break;
            case SessionAction::Kind::CommitResponse: commit_response(action, *t); break;
            case SessionAction::Kind::Finished:
                if (!m_ended) {
                    m_store.end_session(m_session, "completed");
                    m_ended = true;
                }
                m_result.completed = true;
                break;
            case SessionAction::Kind::Quit:
                m_audio->stop();
                m_store.end_session(m_session, "quit");
                m_store.add_event(m_session, m_settings.subject, "quit",
                                  fmt::format("stopped at trial {}", t ? t->position : 0));
                m_ended = true;
                m_result.quit = true;
                break;
        }
    }

    // Opens the trial's clip, mixes its audio (adaptive tracks) and schedules
    // it for the coming flip; with --audio-capture the samples sent are kept.
    void start_stimulus(const PlannedTrial& t, double next_flip_s) {
        m_playback = Playback{};
        m_playback.source = m_opener->open(t.stimulus);
        m_playback.pacer = std::make_unique<FramePacer>(m_playback.source->fps(), m_playback.source->frame_count(),
                                                        m_simulated ? m_refresh_hz : 1.0 / m_flip_period->seconds());
        if (m_adaptive)
            m_playback.mixed = m_adaptive->mix(t, m_playback.source->audio(), m_playback.source->sample_rate());
        const std::vector<float>& samples = m_playback.mixed ? m_playback.mixed->samples : m_playback.source->audio();
        m_audio->play(samples, m_playback.source->sample_rate(), next_flip_s + m_audio->lead_s());
        if (m_settings.audio_capture.empty()) return;
        Audio sent;
        sent.sample_rate_hz = m_playback.source->sample_rate();
        sent.samples = samples;
        fs::create_directories(m_settings.audio_capture);
        const int attempt = m_playback.mixed ? m_playback.mixed->attempt : 1;
        write_audio(m_settings.audio_capture / (attempt == 1 ? fmt::format("trial{:03}.wav", t.position)
                                                             : fmt::format("trial{:03}_{}.wav", t.position, attempt)),
                    sent, SampleFormat::Float32);
    }

    void commit_response(const SessionAction& action, const PlannedTrial& t) {
        const Presentation p = m_playback.pacer ? m_playback.pacer->summary() : Presentation{};
        if (m_adaptive) {
            const bool repeat = commit_adaptive(action, t, p);
            if (repeat) {
                m_playback = Playback{};
                return;
            }
        } else {
            m_store.commit_trial(m_session, t, p, action.response);
        }
        ++m_result.answered;
        ++m_result.presentations;
        m_result.dropped_frames += p.dropped_frames;
        m_result.repeated_frames += p.repeated_frames;
        m_result.max_abs_av_offset_ms = std::max(m_result.max_abs_av_offset_ms, p.max_abs_offset_ms);
        if (!m_simulated)
            log_info("trial {}: {} of {} frames shown, {} dropped, {} repeated; A/V offset mean {:.3f} ms, "
                     "max |offset| {:.3f} ms (flip period {:.3f} ms)",
                     t.position, p.frames_shown, p.frames_total, p.dropped_frames, p.repeated_frames, p.mean_offset_ms,
                     p.max_abs_offset_ms, m_flip_period->seconds() * 1000.0);
        for (const auto& f : p.flips) {
            m_sum_offset += f.offset_ms;
            ++m_offset_count;
        }
        m_playback = Playback{};
    }

    // An adaptive answer: scored (live, or as the experimenter corrected it),
    // stepped on its track and committed with the presentation's record.
    // Returns whether the trial is presented again (a repeat).
    bool commit_adaptive(const SessionAction& action, const PlannedTrial& t, const Presentation& p) {
        if (!m_playback.mixed) throw std::logic_error("adaptive: an answer without a mixed presentation");
        const auto cached = m_live_marks.find(action.trial_index);
        const std::vector<bool> marks =
            cached != m_live_marks.end() ? cached->second : m_adaptive->score(t, action.response.text);
        const auto live = m_auto_marks.find(action.trial_index);
        const std::vector<bool> scored = live != m_auto_marks.end() ? live->second : marks;
        m_live_marks.erase(action.trial_index);
        m_auto_marks.erase(action.trial_index);
        const AdaptiveRecord record = m_adaptive->record(t, *m_playback.mixed, action.response.text, scored, marks);
        if (record.corrected)
            m_store.add_event(m_session, m_settings.subject, "score-corrected",
                              fmt::format("trial {} presentation {}: live score {} of {}, corrected to {} ({}) by the "
                                          "experimenter",
                                          t.position, record.attempt, record.auto_correct, record.keywords,
                                          record.correct, record.marks));
        if (action.repeat) m_store.commit_attempt(m_session, t, record);
        else m_store.commit_trial(m_session, t, p, action.response, record);
        const std::string unit = m_adaptive->settings().unit();
        log_info("trial {}{}: {} {:.2f} {}, {} of {} keywords{}", t.position,
                 record.attempt > 1 ? fmt::format(" (presentation {})", record.attempt) : "",
                 m_adaptive->settings().list_variable() ? std::string("level") : std::string("SNR"), record.level_db,
                 unit, record.correct, record.keywords,
                 record.track.empty() ? std::string(" (no track)")
                                      : fmt::format(", next {:.2f} {}{}", record.next_level_db, unit,
                                                    record.repeat ? " (the same sentence again)" : ""));
        return action.repeat;
    }

    // The stimulus frame for the coming flip, chosen on the audio clock; the
    // pacer starts at the audio's onset plus the masker's lead.
    FrameChoice choose_frame(double next_flip_s) {
        FrameChoice choice;
        if (m_machine->screen() != Screen::Stimulus || !m_playback.source) return choice;
        Playback& pb = m_playback;
        if (!pb.started) {
            if (const auto onset = m_audio->onset_s()) {
                pb.pacer->start(*onset + (pb.mixed ? pb.mixed->lead_s : 0.0));
                pb.started = true;
                if (const std::string detail = m_audio->onset_detail(); !detail.empty())
                    log_info("trial {}: audio {}", m_machine->trial() ? m_machine->trial()->position : 0, detail);
            }
        }
        if (!pb.started) return choice;
        const int k = pb.pacer->frame_for(next_flip_s);
        if (k >= pb.pacer->frame_count()) {
            if (!m_audio->playing()) m_machine->stimulus_finished(next_flip_s);
        } else if (k < 0 && !pb.shown_any) {
            // The masker's lead: the first frame (the face at rest), outside the pacer's count.
            if (!pb.have_frame) pb.have_frame = pb.source->next_frame(pb.frame);
            if (pb.have_frame && pb.uploaded != pb.frame.index) {
                m_window->upload(pb.frame);
                pb.uploaded = pb.frame.index;
            }
            choice.lead = pb.have_frame;
        } else if (k >= 0) {
            while ((!pb.have_frame || pb.frame.index < k) && pb.source->next_frame(pb.frame)) pb.have_frame = true;
            if (pb.have_frame && pb.frame.index == k) {
                // A frame held over several refreshes is uploaded once.
                if (pb.uploaded != k) {
                    m_window->upload(pb.frame);
                    pb.uploaded = k;
                }
                choice.frame = k;
            }
        }
        return choice;
    }

    // The clip's texture, scaled to the display and drawn without blending
    // (the video is opaque), then ImGui's state restored.
    void draw_video(const ImVec2& display) {
        Window& w = *m_window;
        const float scale = std::min(display.x * 0.9f / w.texture_width(), display.y * 0.8f / w.texture_height());
        const ImVec2 size(w.texture_width() * scale, w.texture_height() * scale);
        ImDrawList* background = ImGui::GetBackgroundDrawList();
        background->AddCallback([](const ImDrawList*, const ImDrawCmd*) { gl.Disable(GL_BLEND); }, nullptr);
        background->AddImage(reinterpret_cast<ImTextureID>(static_cast<std::intptr_t>(w.texture())),
                             ImVec2((display.x - size.x) * 0.5f, (display.y - size.y) * 0.5f),
                             ImVec2((display.x + size.x) * 0.5f, (display.y + size.y) * 0.5f));
        background->AddCallback(ImDrawCallback_ResetRenderState, nullptr);
    }

    void draw_response(const ImVec2& display, bool new_screen, double next_flip_s) {
        centered_text(m_strings.text("runner", "answer_prompt"), 0.35f);
        ImGui::SetCursorPos(ImVec2(display.x * 0.15f, display.y * 0.5f));
        ImGui::PushItemWidth(display.x * 0.7f);
        if (m_scripted && m_machine->trial()) m_answer = script_line(m_machine->trial_index());
        if (!m_scripted && (new_screen || m_focus_answer)) {
            ImGui::SetKeyboardFocusHere();
            m_focus_answer = false;
        }
        if (new_screen && !m_scripted) m_answer.clear();
        if (ImGui::InputText("##answer", &m_answer, ImGuiInputTextFlags_EnterReturnsTrue) && !m_scripted) {
            m_machine->submit(m_answer, next_flip_s);
            m_focus_answer = true;
        }
        ImGui::PopItemWidth();
        hint_text(m_strings.text("runner", "answer_keys"));
    }

    void draw_score_check() {
        std::string text = fmt::format("Score check: \"{}\"\n\n", m_machine->pending_response().text);
        if (const PlannedTrial* trial = m_machine->trial()) {
            const Sentence& s = m_corpus.sentence(trial->sentence);
            const auto& marks = m_live_marks[m_machine->trial_index()];
            for (std::size_t k = 0; k < s.keywords.size() && k < marks.size(); ++k)
                text += fmt::format("{}  [{}]  {}\n", k + 1, marks[k] ? "x" : " ", s.keywords[k].word);
        }
        centered_text(text);
        hint_text("1-9: toggle a keyword    Enter: accept the score");
    }

    // Draws the machine's screen, renders it, and saves the screenshot of a
    // new screen (the trial screen once its first frame is up).
    void draw_screen(const FrameChoice& frame, double next_flip_s) {
        const ImVec2 display = ImGui::GetIO().DisplaySize;
        ImGui::SetNextWindowPos(ImVec2(0, 0));
        ImGui::SetNextWindowSize(display);
        ImGui::Begin("screen", nullptr,
                     ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoSavedSettings |
                         ImGuiWindowFlags_NoBringToFrontOnFocus | ImGuiWindowFlags_NoBackground);
        const PlannedTrial* trial = m_machine->trial();
        const Screen shown = m_machine->screen();
        const std::string screen_key = fmt::format("{}-{}", to_string(shown), m_machine->trial_index());
        const bool new_screen = screen_key != m_last_screen_key;
        switch (shown) {
            case Screen::Instructions:
                centered_text(m_machine->message());
                hint_text(m_strings.text("runner", "begin_hint"));
                break;
            case Screen::Fixation: centered_text("+", 0.5f); break;
            case Screen::Stimulus:
                if (frame.frame >= 0 || m_playback.shown_any || frame.lead) draw_video(display);
                else centered_text("+", 0.5f);
                break;
            case Screen::Wait: break;
            case Screen::Response: draw_response(display, new_screen, next_flip_s); break;
            case Screen::ScoreCheck: draw_score_check(); break;
            case Screen::ConfirmEmpty:
                centered_text(m_strings.text("runner", "empty_answer"));
                hint_text(m_strings.text("runner", "empty_answer_keys"));
                break;
            case Screen::Feedback:
                centered_text(trial ? m_strings.text("runner", "feedback") + "\n\n" + m_corpus.sentence(trial->sentence).text
                                    : std::string());
                hint_text(m_strings.text("runner", "continue_hint"));
                break;
            case Screen::Break:
                centered_text(m_machine->message());
                // The default break text already names the key (as does an English one naming Space).
                if (m_machine->message() != m_strings.text("session", "break_text") &&
                    m_machine->message().find("Space") == std::string::npos)
                    hint_text(m_strings.text("runner", "continue_hint"));
                break;
            case Screen::Paused:
                centered_text(m_strings.text("runner", "paused"));
                hint_text(m_strings.text("runner", "paused_keys"));
                break;
            case Screen::End: centered_text(m_machine->message()); break;
        }
        if (m_protocol.session.show_progress && trial && shown != Screen::Stimulus && shown != Screen::End &&
            shown != Screen::Paused) {
            const std::string progress = m_strings.fill(
                "runner", "progress",
                {{"position", std::to_string(trial->position)}, {"total", std::to_string(m_machine->total_trials())}});
            ImGui::SetCursorPos(ImVec2(display.x * 0.02f, display.y * 0.95f));
            ImGui::TextColored(ImVec4(0.75f, 0.75f, 0.75f, 1.0f), "%s", progress.c_str());
        }
        ImGui::End();
        ImGui::Render();
        int fb_w = 0, fb_h = 0;
        glfwGetFramebufferSize(m_window->handle(), &fb_w, &fb_h);
        gl.Viewport(0, 0, fb_w, fb_h);
        gl.ClearColor(0.25f, 0.25f, 0.25f, 1.0f);
        gl.Clear(GL_COLOR_BUFFER_BIT);
        ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
        if (!m_settings.screenshots.empty() && new_screen && (shown != Screen::Stimulus || frame.frame >= 0)) {
            m_window->screenshot(m_settings.screenshots / fmt::format("{:04}_{}_trial{:03}.png", ++m_screenshot_seq,
                                                                      to_string(shown), trial ? trial->position : 0));
            ++m_result.screenshots;
        }
        if (shown != Screen::Stimulus || frame.frame >= 0 || !new_screen) {
            m_screen_frames = new_screen ? 0 : m_screen_frames + 1;
            m_last_screen_key = screen_key;
        }
    }

    // Swaps, reads the flip time off the audio clock and tells the pacer
    // which frame reached the screen.
    void flip(const FrameChoice& frame) {
        glfwSwapBuffers(m_window->handle());
        if (m_settings.audio != "null") gl.Finish();
        m_audio->after_flip(m_period_s);
        const double flip_s = m_audio->now_s();
        m_flip_period->flipped(flip_s - m_last_flip_s);
        m_last_flip_s = flip_s;
        if (frame.frame >= 0) {
            m_playback.pacer->flipped(frame.frame, m_playback.frame.pts_s, flip_s);
            m_playback.shown_any = true;
        }
        // The simulated clock never runs ahead of real time in an interactive dry run.
        if (m_settings.audio == "null" && !m_scripted) {
            const auto target = m_wall_start + std::chrono::duration<double>(flip_s - m_clock_start);
            std::this_thread::sleep_until(target);
        }
    }

    // Closes the session (quit unless it completed) and logs the timing summary.
    RunResult finish() {
        if (!m_ended) {
            m_store.end_session(m_session, "quit");
            m_result.quit = true;
        }
        m_result.mean_av_offset_ms = m_offset_count ? m_sum_offset / m_offset_count : 0.0;
        m_result.completed = m_store.answered_positions(m_settings.subject).size() == m_plan.size();
        const std::string summary = fmt::format(
            "{} presentations, {} dropped frames, {} repeated frames, A/V offset mean {:.3f} ms, max |offset| {:.3f} ms",
            m_result.presentations, m_result.dropped_frames, m_result.repeated_frames, m_result.mean_av_offset_ms,
            m_result.max_abs_av_offset_ms);
        m_store.add_event(m_session, m_settings.subject, "timing-summary",
                          fmt::format("{} ({})", summary, m_audio->name()));
        log_info("timing: {} (clock: {})", summary, m_audio->name());
        return m_result;
    }

    const RunSettings& m_settings;
    const Protocol m_protocol;
    // What the subject reads, in the protocol's language (ui_strings.h).
    const UiStrings& m_strings = ui_strings(m_protocol.session.language);
    const Corpus m_corpus;
    const bool m_scripted;
    std::vector<std::string> m_script;
    std::unique_ptr<StimulusOpener> m_opener;
    Store m_store;
    std::vector<PlannedTrial> m_plan;
    std::vector<int> m_answered;  // positions answered before this run
    std::string m_stimuli_note = "test pattern";
    std::unique_ptr<AdaptiveSession> m_adaptive;
    std::unique_ptr<SessionMachine> m_machine;
    // Live scores of the answers not yet committed (trial index → keyword
    // marks as they count, and as the live scorer gave them).
    std::map<int, std::vector<bool>> m_live_marks, m_auto_marks;
    RunResult m_result;

    std::unique_ptr<AudioOutput> m_audio;
    std::unique_ptr<Window> m_window;
    bool m_fullscreen = false;
    bool m_simulated = false;
    double m_refresh_hz = 60.0;
    double m_period_s = 1.0 / 60.0;
    std::unique_ptr<FlipPeriod> m_flip_period;
    int m_session = 0;

    Playback m_playback;
    std::string m_answer;
    bool m_focus_answer = false;
    std::string m_last_screen_key;
    int m_screen_frames = 0;  // flips since the screen changed
    int m_screenshot_seq = 0;
    double m_last_flip_s = 0.0;
    std::chrono::steady_clock::time_point m_wall_start;
    double m_clock_start = 0.0;
    double m_sum_offset = 0.0;
    int m_offset_count = 0;
    bool m_running = true;
    bool m_ended = false;
};

}  // namespace

RunResult run_session(const RunSettings& settings) { return SessionRun(settings).run(); }

}  // namespace avsi::experiment
