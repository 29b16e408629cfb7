// `avsi play` and the viseme-set editor in a GLFW window (see player.h and
// viseme_editor.h): the head drawn live by the renderer's HeadDrawer into a
// framebuffer texture shown with Dear ImGui, the audio through PortAudio (or
// the null device's simulated clock), scripted events, a per-refresh log and
// recording to MP4.
#include "avsi/experiment/player.h"

#define GLFW_INCLUDE_NONE
#include <GL/gl.h>
#include <GLFW/glfw3.h>
#include <imgui.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>

#include <fmt/format.h>

#include "avsi/core/audio.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/experiment/media.h"
#include "avsi/experiment/play_media.h"
#include "avsi/experiment/viseme_editor.h"
#include "avsi/stimuli/commands.h"
#include "avsi/stimuli/gltf_head.h"
#include "avsi/stimuli/image_io.h"
#include "avsi/stimuli/renderer.h"
#include "avsi/stimuli/video.h"
#include "avsi/synth/fap.h"
#include "gl_functions.h"

namespace avsi::experiment {

namespace fs = std::filesystem;

namespace {

void* glfw_loader(const char* name) { return reinterpret_cast<void*>(glfwGetProcAddress(name)); }

// The window, ImGui and the face: the head drawn by HeadDrawer into a
// framebuffer texture of the face's size.
class PlayerWindow {
public:
    PlayerWindow(int width, int height, const std::string& title, const stimuli::Head& head, int face_width,
                 int face_height)
        : m_head(head), m_face_width(face_width), m_face_height(face_height) {
        glfwSetErrorCallback([](int code, const char* text) { log_warning("GLFW error {}: {}", code, text); });
        if (!glfwInit())
            throw InputError("display", 0, 0, "",
                             "cannot open a window (no display? run under xvfb-run for a headless session)");
        glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
        glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 3);
        glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
        glfwWindowHint(GLFW_RESIZABLE, GLFW_FALSE);
        m_window = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
        if (!m_window) {
            glfwTerminate();
            throw InputError("display", 0, 0, "", "cannot create an OpenGL 3.3 core window");
        }
        glfwMakeContextCurrent(m_window);
        glfwSwapInterval(1);
        try {
            detail::load_gl_functions(m_gl, true);
            if (GLFWmonitor* monitor = glfwGetPrimaryMonitor())
                if (const GLFWvidmode* mode = glfwGetVideoMode(monitor); mode && mode->refreshRate > 0)
                    m_refresh_hz = mode->refreshRate;
            IMGUI_CHECKVERSION();
            ImGui::CreateContext();
            ImGuiIO& io = ImGui::GetIO();
            io.IniFilename = nullptr;
            const char* font = "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf";
            if (fs::exists(font)) io.Fonts->AddFontFromFileTTF(font, 15.0f);
            ImGui::StyleColorsDark();
            ImGui_ImplGlfw_InitForOpenGL(m_window, true);
            ImGui_ImplOpenGL3_Init("#version 330 core");
            m_imgui = true;
            // The face's framebuffer: colour texture + depth.
            m_gl.GenTextures(1, &m_face_texture);
            m_gl.BindTexture(GL_TEXTURE_2D, m_face_texture);
            m_gl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA, m_face_width, m_face_height, 0, GL_RGBA, GL_UNSIGNED_BYTE, nullptr);
            m_gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
            m_gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
            m_gl.GenRenderbuffers(1, &m_depth);
            m_gl.BindRenderbuffer(GL_RENDERBUFFER, m_depth);
            m_gl.RenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH_COMPONENT24, m_face_width, m_face_height);
            m_gl.GenFramebuffers(1, &m_fbo);
            m_gl.BindFramebuffer(GL_FRAMEBUFFER, m_fbo);
            m_gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, m_face_texture, 0);
            m_gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_RENDERBUFFER, m_depth);
            const GLenum status = m_gl.CheckFramebufferStatus(GL_FRAMEBUFFER);
            m_gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
            if (status != GL_FRAMEBUFFER_COMPLETE)
                throw InputError("display", 0, 0, "", fmt::format("cannot make the face's framebuffer (status {:#x})", status));
            m_drawer = std::make_unique<stimuli::HeadDrawer>(m_head, &glfw_loader);
        } catch (...) {
            release();
            throw;
        }
    }
    ~PlayerWindow() { release(); }
    PlayerWindow(const PlayerWindow&) = delete;
    PlayerWindow& operator=(const PlayerWindow&) = delete;

    GLFWwindow* handle() const { return m_window; }
    double refresh_hz() const { return m_refresh_hz; }
    ImTextureID face_texture() const { return reinterpret_cast<ImTextureID>(static_cast<std::intptr_t>(m_face_texture)); }
    int face_width() const { return m_face_width; }
    int face_height() const { return m_face_height; }

    // Draws the head in `pose` into the face texture.
    void draw_face(const stimuli::Pose& pose) {
        stimuli::pose_head(m_head, pose, m_posed);
        stimuli::apply_head_rotation(m_head, pose.head_rotation, m_posed);
        m_gl.BindFramebuffer(GL_FRAMEBUFFER, m_fbo);
        stimuli::RenderSettings settings;
        m_drawer->draw(m_posed, settings, m_face_width, m_face_height);
        m_gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
    }

    void begin_frame() {
        ImGui_ImplOpenGL3_NewFrame();
        ImGui_ImplGlfw_NewFrame();
        ImGui::NewFrame();
    }
    void end_frame() {
        ImGui::Render();
        int w = 0, h = 0;
        glfwGetFramebufferSize(m_window, &w, &h);
        m_gl.Viewport(0, 0, w, h);
        m_gl.ClearColor(0.12f, 0.12f, 0.13f, 1.0f);
        m_gl.Clear(GL_COLOR_BUFFER_BIT);
        ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
    }
    // The back buffer (before the swap), top row first.
    stimuli::Image read_window() const {
        int w = 0, h = 0;
        glfwGetFramebufferSize(m_window, &w, &h);
        stimuli::Image image;
        image.width = w;
        image.height = h;
        std::vector<std::uint8_t> pixels(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3);
        m_gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
        m_gl.ReadBuffer(GL_BACK);
        m_gl.ReadPixels(0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE, pixels.data());
        image.rgb.resize(pixels.size());
        const std::size_t row = static_cast<std::size_t>(w) * 3;
        for (int y = 0; y < h; ++y)
            std::copy_n(pixels.data() + static_cast<std::size_t>(h - 1 - y) * row, row,
                        image.rgb.data() + static_cast<std::size_t>(y) * row);
        return image;
    }
    void swap() { glfwSwapBuffers(m_window); }

private:
    void release() {
        m_drawer.reset();
        if (m_fbo) m_gl.DeleteFramebuffers(1, &m_fbo);
        if (m_depth) m_gl.DeleteRenderbuffers(1, &m_depth);
        if (m_face_texture) m_gl.DeleteTextures(1, &m_face_texture);
        m_fbo = m_depth = m_face_texture = 0;
        if (m_imgui) {
            ImGui_ImplOpenGL3_Shutdown();
            ImGui_ImplGlfw_Shutdown();
            ImGui::DestroyContext();
            m_imgui = false;
        }
        if (m_window) glfwDestroyWindow(m_window);
        m_window = nullptr;
        glfwTerminate();
    }

    const stimuli::Head& m_head;
    int m_face_width;
    int m_face_height;
    GLFWwindow* m_window = nullptr;
    detail::GlFunctions m_gl;
    double m_refresh_hz = 60.0;
    bool m_imgui = false;
    GLuint m_face_texture = 0, m_depth = 0, m_fbo = 0;
    std::unique_ptr<stimuli::HeadDrawer> m_drawer;
    stimuli::PosedMesh m_posed;
};

stimuli::Head load_play_head(const PlayMedia& media) {
    stimuli::HeadFiles files;
    if (!media.head_gltf.empty()) files.gltf = media.head_gltf;
    if (!media.head_obj.empty()) files.obj = media.head_obj;
    if (!media.head_rig.empty()) files.rig = media.head_rig;
    return stimuli::load_head_files(files);
}

bool key(int glfw_key) { return ImGui::IsKeyPressed(glfw_key, true); }

// Records the window at a fixed frame rate on the output clock: raw RGB
// frames go to a file beside the MP4 (memory stays flat however long the
// recording), encoded with the audio sent when the player closes.
class Recorder {
public:
    Recorder(fs::path path, double fps) : m_path(std::move(path)), m_fps(fps), m_raw(m_path.string() + ".frames.tmp") {
        if (m_path.has_parent_path()) fs::create_directories(m_path.parent_path());
        m_file.open(m_raw, std::ios::binary | std::ios::trunc);
        if (!m_file) throw InputError(m_raw, "cannot write the recording's frames here");
    }
    ~Recorder() {
        std::error_code ec;
        fs::remove(m_raw, ec);
    }
    // Adds the window image for every recording frame slot up to output time `t_s`.
    void capture(const PlayerWindow& window, double t_s) {
        const auto slot = static_cast<long long>(std::floor(t_s * m_fps + 1e-9));
        if (slot < m_frames) return;
        const stimuli::Image image = window.read_window();
        if (m_width == 0) {
            m_width = image.width & ~1;
            m_height = image.height & ~1;
        }
        for (; m_frames <= slot; ++m_frames)
            for (int y = 0; y < m_height; ++y)
                m_file.write(reinterpret_cast<const char*>(image.pixel(0, y)), static_cast<std::streamsize>(m_width) * 3);
    }
    // Encodes the frames with the audio sent; returns the frame count.
    int finish(const std::vector<float>& audio, int rate) {
        m_file.close();
        if (m_frames == 0) return 0;
        Audio a;
        a.sample_rate_hz = rate;
        a.samples = audio;
        stimuli::VideoSettings vs;
        vs.fps = m_fps;
        stimuli::VideoWriter writer(m_path, m_width, m_height, static_cast<std::size_t>(m_frames), &a, vs);
        std::ifstream in(m_raw, std::ios::binary);
        stimuli::Image frame;
        frame.width = m_width;
        frame.height = m_height;
        frame.rgb.resize(static_cast<std::size_t>(m_width) * static_cast<std::size_t>(m_height) * 3);
        for (long long k = 0; k < m_frames; ++k) {
            in.read(reinterpret_cast<char*>(frame.rgb.data()), static_cast<std::streamsize>(frame.rgb.size()));
            writer.write(frame);
        }
        writer.finish();
        return static_cast<int>(m_frames);
    }

private:
    fs::path m_path;
    double m_fps;
    fs::path m_raw;
    std::ofstream m_file;
    int m_width = 0, m_height = 0;
    long long m_frames = 0;
};

// The audio device: PortAudio pulling from the transport, or the null
// device whose clock moves rate/refresh_hz samples per screen refresh.
class Sink {
public:
    Sink(const PlaySettings& s, Transport& transport, int rate) : m_transport(transport), m_rate(rate) {
        if (s.audio == "null") {
            m_per_refresh = rate / s.null_refresh_hz;
            m_name = fmt::format("null (simulated clock, {:g} refreshes/s)", s.null_refresh_hz);
        } else if (s.audio == "portaudio") {
            m_stream = open_portaudio_pull_stream(s.audio_device, rate,
                                                  [&transport](float* out, std::size_t n) { transport.pull(out, n); });
            m_name = m_stream->name();
        } else {
            throw UsageError(fmt::format("--audio: expected \"portaudio\" or \"null\", got \"{}\"", s.audio));
        }
    }
    double latency_s() const { return m_stream ? m_stream->latency_s() : 0.0; }
    const std::string& name() const { return m_name; }
    // After each buffer swap: the null device consumes one refresh of samples.
    void after_flip() {
        if (m_stream) return;
        m_owed += m_per_refresh;
        const auto n = static_cast<std::size_t>(std::floor(m_owed));
        m_owed -= static_cast<double>(n);
        m_buffer.resize(n);
        if (n) m_transport.pull(m_buffer.data(), n);
    }

private:
    Transport& m_transport;
    int m_rate;
    std::unique_ptr<PullAudioStream> m_stream;
    std::string m_name;
    double m_per_refresh = 0.0;
    double m_owed = 0.0;
    std::vector<float> m_buffer;
};

constexpr std::array<double, 4> speed_steps{0.25, 0.5, 0.75, 1.0};

// The phone/viseme strip: the phones of a 2 s span around the play head (the
// whole utterance when shorter), phone above its viseme, the current one highlighted.
void draw_strip(const PlayMedia& media, double t_s, float width) {
    const ImVec2 origin = ImGui::GetCursorScreenPos();
    const float height = 46.0f;
    ImDrawList* draw = ImGui::GetWindowDrawList();
    const double duration = media.frame_count() / media.fps();
    const double span = std::min(duration, 2.0);
    const double t0 = std::clamp(t_s - span / 2.0, 0.0, duration - span);
    const auto x_of = [&](double t) { return origin.x + static_cast<float>((t - t0) / span) * width; };
    draw->AddRectFilled(origin, ImVec2(origin.x + width, origin.y + height), IM_COL32(40, 40, 44, 255));
    draw->PushClipRect(origin, ImVec2(origin.x + width, origin.y + height), true);
    for (std::size_t i = 0; i < media.phones.size(); ++i) {
        const auto& p = media.phones[i];
        if (p.end_s < t0 || p.start_s > t0 + span) continue;
        const float x0 = x_of(p.start_s), x1 = x_of(p.end_s);
        const bool current = t_s >= p.start_s && t_s < p.end_s;
        draw->AddRectFilled(ImVec2(x0, origin.y), ImVec2(x1, origin.y + height),
                            current ? IM_COL32(200, 140, 40, 255) : IM_COL32(70, 74, 84, 255));
        draw->AddRect(ImVec2(x0, origin.y), ImVec2(x1, origin.y + height), IM_COL32(20, 20, 20, 255));
        const std::string& viseme = i < media.visemes.size() ? media.visemes[i] : std::string();
        draw->PushClipRect(ImVec2(x0 + 1, origin.y), ImVec2(x1 - 1, origin.y + height), true);
        draw->AddText(ImVec2(x0 + 3, origin.y + 3), IM_COL32(255, 255, 255, 255), p.symbol.c_str());
        draw->AddText(ImVec2(x0 + 3, origin.y + 24), IM_COL32(200, 200, 210, 255), viseme.c_str());
        draw->PopClipRect();
    }
    const float xt = x_of(std::clamp(t_s, 0.0, duration));
    draw->AddLine(ImVec2(xt, origin.y), ImVec2(xt, origin.y + height), IM_COL32(255, 80, 60, 255), 2.0f);
    draw->PopClipRect();
    ImGui::Dummy(ImVec2(width, height + 4));
}

// The 10 articulatory parameters as bars over their documented ranges, the neutral value marked.
void draw_parameter_bars(const synth::Frame& params) {
    for (const auto& info : synth::params()) {
        const double v = params[synth::index(info.param)];
        const float fraction = static_cast<float>(std::clamp((v - info.min) / info.range(), 0.0, 1.0));
        const std::string label = fmt::format("{:+.2f}", v);
        ImGui::ProgressBar(fraction, ImVec2(140, 0), label.c_str());
        const ImVec2 min = ImGui::GetItemRectMin(), max = ImGui::GetItemRectMax();
        const float xn = min.x + static_cast<float>((info.neutral - info.min) / info.range()) * (max.x - min.x);
        ImGui::GetWindowDrawList()->AddLine(ImVec2(xn, min.y), ImVec2(xn, max.y), IM_COL32(255, 255, 255, 160));
        ImGui::SameLine();
        ImGui::TextUnformatted(std::string(info.name).c_str());
    }
}

void write_log_header(std::ofstream& log) {
    log << "refresh\twall_s\tframe\tsamples_sent\tsamples_played\tmedia_s\tspeed\toffset_ms\tplaying";
    for (const auto& info : synth::params()) log << '\t' << info.name;
    log << '\n';
}

double script_number(const ScriptEvent& e, std::size_t i) { return std::stod(e.args[i]); }

// What the player's controls set, from the script, the keys or the window.
struct PlayerControls {
    double offset_ms = 0.0;
    float speed_slider = 1.0f;
    bool quit = false;
    std::size_t next_event = 0;     // the next script event
    long long wait_refreshes = 0;   // refreshes the script still waits
    bool waiting_end = false;       // the script waits for the end of the media
    std::vector<fs::path> screenshots;  // to save after this refresh
};

// Runs the script's events until one waits (refreshes, or the end of the media).
void run_player_script(const std::vector<ScriptEvent>& script, Transport& transport, PlayerControls& c) {
    while (!c.quit && c.next_event < script.size()) {
        if (c.wait_refreshes > 0) {
            --c.wait_refreshes;
            break;
        }
        if (c.waiting_end) {
            if (!transport.at_end()) break;
            c.waiting_end = false;
        }
        const ScriptEvent& e = script[c.next_event++];
        if (e.command == "play") transport.play();
        else if (e.command == "pause") transport.pause();
        else if (e.command == "toggle") transport.playing() ? transport.pause() : transport.play();
        else if (e.command == "step") {
            transport.pause();
            transport.seek_frame(transport.frame(c.offset_ms, 0.0) + static_cast<int>(script_number(e, 0)), c.offset_ms);
        } else if (e.command == "seek") {
            transport.seek_frame(static_cast<int>(script_number(e, 0)), c.offset_ms);
        } else if (e.command == "speed") {
            transport.set_speed(script_number(e, 0));
            c.speed_slider = static_cast<float>(script_number(e, 0));
        } else if (e.command == "mute") transport.set_muted(e.args[0] == "on");
        else if (e.command == "offset") c.offset_ms = script_number(e, 0);
        else if (e.command == "wait") c.wait_refreshes = static_cast<long long>(script_number(e, 0));
        else if (e.command == "wait-end") c.waiting_end = true;
        else if (e.command == "screenshot") c.screenshots.emplace_back(e.args[0]);
        else if (e.command == "quit") c.quit = true;
    }
}

// The keys: space plays or pauses, arrows step frames or change the speed,
// Home and End seek, M mutes, [ and ] shift the A/V offset, Q or Esc quit.
void handle_player_keys(const PlayMedia& media, Transport& transport, PlayerControls& c) {
    const ImGuiIO& io = ImGui::GetIO();
    if (!io.WantTextInput) {
        if (key(GLFW_KEY_SPACE)) transport.playing() ? transport.pause() : transport.play();
        if (key(GLFW_KEY_RIGHT) || key(GLFW_KEY_LEFT)) {
            transport.pause();
            transport.seek_frame(transport.frame(c.offset_ms, 0.0) + (key(GLFW_KEY_RIGHT) ? 1 : -1), c.offset_ms);
        }
        if (key(GLFW_KEY_HOME)) transport.seek_frame(0, c.offset_ms);
        if (key(GLFW_KEY_END)) transport.seek_frame(media.frame_count() - 1, c.offset_ms);
        if (key(GLFW_KEY_UP) || key(GLFW_KEY_DOWN)) {
            const double now = transport.speed();
            double next = now;
            if (key(GLFW_KEY_UP)) {
                for (double v : speed_steps)
                    if (v > now + 1e-9) { next = v; break; }
            } else {
                for (auto it = speed_steps.rbegin(); it != speed_steps.rend(); ++it)
                    if (*it < now - 1e-9) { next = *it; break; }
            }
            transport.set_speed(next);
            c.speed_slider = static_cast<float>(next);
        }
        if (key(GLFW_KEY_M)) transport.set_muted(!transport.muted());
        if (key(GLFW_KEY_LEFT_BRACKET)) c.offset_ms = std::max(-500.0, c.offset_ms - 10.0);
        if (key(GLFW_KEY_RIGHT_BRACKET)) c.offset_ms = std::min(500.0, c.offset_ms + 10.0);
        if (key(GLFW_KEY_Q) || key(GLFW_KEY_ESCAPE)) c.quit = true;
    }
}

// The screen: face, strip, controls, parameter bars.
void draw_player_screen(PlayerWindow& window, const PlayMedia& media, Transport& transport, const Sink& sink, int frame,
                        double media_s, bool playing, const stimuli::Pose& drawn, PlayerControls& c) {
    const ImGuiIO& io = ImGui::GetIO();
    ImGui::SetNextWindowPos(ImVec2(0, 0));
    ImGui::SetNextWindowSize(io.DisplaySize);
    ImGui::Begin("player", nullptr,
                 ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoSavedSettings |
                     ImGuiWindowFlags_NoBringToFrontOnFocus);
    ImGui::BeginGroup();
    ImGui::Image(window.face_texture(), ImVec2(static_cast<float>(window.face_width()),
                                               static_cast<float>(window.face_height())),
                 ImVec2(0, 1), ImVec2(1, 0));
    draw_strip(media, media_s, static_cast<float>(window.face_width()));
    ImGui::EndGroup();
    ImGui::SameLine();
    ImGui::BeginGroup();
    ImGui::TextUnformatted(media.title.c_str());
    ImGui::Text("frame %d / %d   t = %.3f s", frame, media.frame_count() - 1, media_s);
    ImGui::Text("%s  %.2fx%s", playing ? "playing" : "paused", transport.speed(), transport.muted() ? "  muted" : "");
    for (std::size_t i = 0; i < media.phones.size(); ++i)
        if (media_s >= media.phones[i].start_s && media_s < media.phones[i].end_s)
            ImGui::Text("phone %s, viseme %s", media.phones[i].symbol.c_str(),
                        i < media.visemes.size() ? media.visemes[i].c_str() : "?");
    if (ImGui::Button(playing ? "Pause" : "Play")) playing ? transport.pause() : transport.play();
    ImGui::SameLine();
    if (ImGui::Button("< frame")) {
        transport.pause();
        transport.seek_frame(frame - 1, c.offset_ms);
    }
    ImGui::SameLine();
    if (ImGui::Button("frame >")) {
        transport.pause();
        transport.seek_frame(frame + 1, c.offset_ms);
    }
    ImGui::SetNextItemWidth(200);
    ImGui::SliderFloat("speed", &c.speed_slider, 0.25f, 1.0f, "%.2fx");
    if (ImGui::IsItemDeactivatedAfterEdit()) transport.set_speed(c.speed_slider);
    bool muted = transport.muted();
    if (ImGui::Checkbox("mute", &muted)) transport.set_muted(muted);
    float offset = static_cast<float>(c.offset_ms);
    ImGui::SetNextItemWidth(200);
    if (ImGui::SliderFloat("A/V offset (ms)", &offset, -500.0f, 500.0f, "%.0f")) c.offset_ms = offset;
    ImGui::Separator();
    draw_parameter_bars(drawn.params);
    ImGui::Separator();
    ImGui::TextWrapped("%s", sink.name().c_str());
    ImGui::EndGroup();
    ImGui::End();
}

// One line of the refresh log.
void log_refresh(std::ofstream& log, long long refresh, double wall_s, int frame, std::int64_t sent,
                 std::int64_t played, double media_s, double speed, double offset_ms, bool playing,
                 const stimuli::Pose& drawn) {
    log << refresh << '\t' << fmt::format("{:.6f}", wall_s) << '\t' << frame << '\t' << sent << '\t' << played << '\t'
        << fmt::format("{:.6f}", media_s) << '\t' << speed << '\t' << offset_ms << '\t' << (playing ? 1 : 0);
    for (double v : drawn.params) log << '\t' << fmt::format("{:.9g}", v);
    log << '\n';
}

PlayResult run_player(const PlaySettings& s) {
    PlayMedia media = load_play_media(s.source);
    if (!(s.speed >= 0.25 && s.speed <= 1.0))
        throw UsageError(fmt::format("--speed: expected a number in [0.25, 1], got {:g}", s.speed));
    if (!(s.offset_ms >= -500 && s.offset_ms <= 500))
        throw UsageError(fmt::format("--offset-ms: expected a number in [-500, 500], got {:g}", s.offset_ms));
    std::vector<ScriptEvent> script;
    if (!s.script.empty()) script = read_play_script(s.script, false);
    // The audio lasts as long as the video, as in the stimulus MP4 (VideoWriter pads or cuts it).
    media.audio.resize(static_cast<std::size_t>(std::llround(media.frame_count() / media.fps() * media.sample_rate_hz)), 0.0f);
    const stimuli::Head head = load_play_head(media);
    for (const std::string& w : animate_play_media(head, media)) log_warning("play: {}", w);

    Transport transport(media.audio, media.sample_rate_hz, media.fps(), media.frame_count());
    transport.set_speed(s.speed);
    transport.set_muted(s.muted);
    const bool keep = !s.audio_out.empty() || !s.record.empty();
    transport.keep_sent(keep);

    Sink sink(s, transport, media.sample_rate_hz);
    PlayerWindow window(s.window_width, s.window_height, "avsi play — " + media.title, head, s.face_width, s.face_height);
    log_info("play: {} ({} frames at {:g} fps, {:.2f} s), audio {}", media.title, media.frame_count(), media.fps(),
             media.frame_count() / media.fps(), sink.name());
    std::ofstream log;
    if (!s.log.empty()) {
        if (s.log.has_parent_path()) fs::create_directories(s.log.parent_path());
        log.open(s.log, std::ios::trunc);
        if (!log) throw InputError(s.log, "cannot write the log here");
        write_log_header(log);
    }
    std::optional<Recorder> recorder;
    if (!s.record.empty()) recorder.emplace(s.record, media.fps());

    PlayerControls c;
    c.offset_ms = s.offset_ms;
    c.speed_slider = static_cast<float>(s.speed);
    if (s.start_playing && script.empty()) transport.play();
    PlayResult result;
    int shown = -1;
    stimuli::Pose drawn;  // the pose on screen (logged)
    const auto start = std::chrono::steady_clock::now();

    while (!c.quit) {
        glfwPollEvents();
        if (glfwWindowShouldClose(window.handle())) break;
        c.screenshots.clear();
        run_player_script(script, transport, c);
        // A quitting refresh is still drawn (its screenshots saved), then the loop ends.
        window.begin_frame();
        handle_player_keys(media, transport, c);
        // The frame for the audio clock, read once for this refresh.
        const std::int64_t sent = transport.samples_sent();
        const std::int64_t played = transport.samples_played();
        const double media_s = transport.media_time_s(sink.latency_s());
        const int frame = transport.frame(c.offset_ms, sink.latency_s());
        const bool playing = transport.playing();
        if (frame != shown) {
            drawn = media.poses[static_cast<std::size_t>(frame)];
            window.draw_face(drawn);
            shown = frame;
            ++result.frames_shown;
        }
        draw_player_screen(window, media, transport, sink, frame, media_s, playing, drawn, c);
        window.end_frame();
        if (log.is_open())
            log_refresh(log, result.refreshes,
                        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), frame, sent,
                        played, media_s, transport.speed(), c.offset_ms, playing, drawn);
        for (const auto& path : c.screenshots) stimuli::write_png(path, window.read_window());
        if (recorder) recorder->capture(window, static_cast<double>(sent) / media.sample_rate_hz);
        window.swap();
        sink.after_flip();
        ++result.refreshes;
    }
    result.samples_sent = transport.samples_sent();
    if (keep) {
        const std::vector<float> sent = transport.sent();
        if (!s.audio_out.empty()) {
            Audio a;
            a.sample_rate_hz = media.sample_rate_hz;
            a.samples = sent;
            write_audio(s.audio_out, a);
        }
        if (recorder) result.recorded_frames = recorder->finish(sent, media.sample_rate_hz);
    }
    return result;
}

// The editor: the selected viseme's targets on the face, its contour and α,
// its FAP values, the phone mapping, undo, save and the diff with the file.

// What the editor's controls set, from the script, the keys or the window.
struct EditorControls {
    bool quit = false;
    std::size_t next_event = 0;     // the next script event
    long long wait_refreshes = 0;   // refreshes the script still waits
    std::vector<fs::path> screenshots;  // to save after this refresh
    bool changed = false;           // the set changed this refresh (the diff is redone)
    std::vector<std::string> diff;  // the set against the file on disk
    std::string status;             // the last save's outcome
    int phone_choice = 0;           // the phone the mapping combo shows
    bool saved = false;
};

// Saving from the window: a failure (read-only file, full disk) is shown
// and the edits stay in the editor, so nothing is lost.
void save_from_ui(VisemeEditor& editor, EditorControls& c) {
    try {
        editor.save();
        c.saved = true;
        c.status = "saved " + editor.path().string();
    } catch (const std::exception& e) {
        c.status = std::string("NOT saved: ") + e.what();
        log_warning("viseme editor: {}", c.status);
    }
    c.changed = true;
}

// Runs the script's events until one waits; a bad event is an InputError at its line.
void run_editor_script(const PlaySettings& s, const std::vector<ScriptEvent>& script, VisemeEditor& editor,
                       EditorControls& c) {
    while (!c.quit && c.next_event < script.size()) {
        if (c.wait_refreshes > 0) {
            --c.wait_refreshes;
            break;
        }
        const ScriptEvent& e = script[c.next_event++];
        try {
            if (e.command == "select") editor.select(e.args[0]);
            else if (e.command == "set") {
                editor.begin_edit();
                editor.set_target(*synth::param_from_name(e.args[0]), script_number(e, 1));
            } else if (e.command == "width") {
                editor.begin_edit();
                editor.set_width_mm(script_number(e, 0));
            } else if (e.command == "height") {
                editor.begin_edit();
                editor.set_height_mm(script_number(e, 0));
            } else if (e.command == "map") {
                const std::size_t v = editor.index_of(e.args[1]);
                editor.begin_edit();
                editor.map_phone(e.args[0], v);
            } else if (e.command == "undo") editor.undo();
            else if (e.command == "save") {
                editor.save(e.args.empty() ? fs::path() : fs::path(e.args[0]));
                c.saved = true;
            } else if (e.command == "wait") c.wait_refreshes = static_cast<long long>(script_number(e, 0));
            else if (e.command == "screenshot") c.screenshots.emplace_back(e.args[0]);
            else if (e.command == "quit") c.quit = true;
        } catch (const UsageError& error) {
            throw InputError(s.script.string(), e.line, 1, e.command, error.what());
        }
        c.changed = true;
    }
}

// The selected viseme on the face with its α and phones, the phone mapping,
// undo and save, and the differences from the file.
void draw_viseme_panel(PlayerWindow& window, VisemeEditor& editor, const synth::Viseme& viseme,
                       const std::vector<double>& alphas, const std::vector<std::string>& all_phones,
                       EditorControls& c) {
    ImGui::BeginGroup();
    ImGui::Image(window.face_texture(), ImVec2(static_cast<float>(window.face_width()),
                                               static_cast<float>(window.face_height())),
                 ImVec2(0, 1), ImVec2(1, 0));
    ImGui::Text("%s (id %d): alpha = %.3f from pi*w*h = %.0f mm^2", viseme.name.c_str(), viseme.id,
                alphas[editor.selected()], viseme.area_mm2());
    std::string phones;
    for (const auto& p : viseme.phones) phones += p + " ";
    ImGui::TextWrapped("phones: %s", phones.c_str());
    ImGui::SetNextItemWidth(90);
    if (ImGui::BeginCombo("##phone", all_phones[static_cast<std::size_t>(c.phone_choice)].c_str())) {
        for (std::size_t i = 0; i < all_phones.size(); ++i)
            if (ImGui::Selectable(all_phones[i].c_str(), static_cast<int>(i) == c.phone_choice))
                c.phone_choice = static_cast<int>(i);
        ImGui::EndCombo();
    }
    ImGui::SameLine();
    if (ImGui::Button("map to this viseme")) {
        editor.begin_edit();
        editor.map_phone(all_phones[static_cast<std::size_t>(c.phone_choice)], editor.selected());
        c.changed = true;
    }
    if (ImGui::Button("Undo")) c.changed |= editor.undo();
    ImGui::SameLine();
    if (ImGui::Button("Save")) save_from_ui(editor, c);
    ImGui::SameLine();
    ImGui::Text("%s  %s", editor.modified() ? "modified" : "unchanged", c.status.c_str());
    ImGui::Text("differences from %s on disk: %zu", editor.path().filename().string().c_str(), c.diff.size());
    ImGui::BeginChild("diff", ImVec2(static_cast<float>(window.face_width()), 0), true);
    for (const auto& line : c.diff) ImGui::BulletText("%s", line.c_str());
    ImGui::EndChild();
    ImGui::EndGroup();
}

// Sliders for the selected viseme's targets, contour and FAP values; a
// change of a FAP value is mapped back to the 10 parameters by the FAP
// decoder's least squares. One undo step per slider drag.
void draw_target_sliders(VisemeEditor& editor, const synth::Viseme& viseme, EditorControls& c) {
    const auto& mapped = synth::mapped_faps();
    ImGui::BeginGroup();
    // One undo step per slider drag: the set as it was before this refresh's changes.
    const synth::VisemeSet before = editor.set();
    const auto after_slider = [&] {
        if (ImGui::IsItemActivated()) editor.remember(before);
        if (ImGui::IsItemDeactivatedAfterEdit()) c.changed = true;
    };
    ImGui::TextUnformatted("articulatory targets");
    for (const auto& info : synth::params()) {
        float v = static_cast<float>(viseme.targets[synth::index(info.param)]);
        ImGui::SetNextItemWidth(160);
        const std::string name(info.name);
        if (ImGui::SliderFloat(name.c_str(), &v, static_cast<float>(info.min), static_cast<float>(info.max), "%.3f"))
            editor.set_target(info.param, std::clamp<double>(v, info.min, info.max));
        after_slider();
    }
    ImGui::TextUnformatted("outer-lip contour (mm)");
    float w = static_cast<float>(viseme.width_mm), h = static_cast<float>(viseme.height_mm);
    ImGui::SetNextItemWidth(160);
    if (ImGui::SliderFloat("width_mm", &w, 1.0f, 120.0f, "%.1f")) editor.set_width_mm(w);
    after_slider();
    ImGui::SetNextItemWidth(160);
    if (ImGui::SliderFloat("height_mm", &h, 1.0f, 80.0f, "%.1f")) editor.set_height_mm(h);
    after_slider();
    // The FAP values of the targets (MPEG-4, FAPU), editable: a change is
    // mapped back to the 10 parameters by the FAP decoder's least squares.
    ImGui::TextUnformatted("FAP values (FAPU)");
    ImGui::BeginChild("faps", ImVec2(0, 0), true);
    synth::Trajectory one;
    one.fps = 25.0;
    one.frames = {before.visemes[editor.selected()].targets};
    const synth::FapStream faps = synth::trajectory_to_fap(one);
    for (int fap : mapped) {
        int value = static_cast<int>(std::lround(faps.frames.front().values[static_cast<std::size_t>(fap - 1)]));
        ImGui::SetNextItemWidth(160);
        const std::string label = fmt::format("{} {}", fap, synth::fap_name(fap));
        if (ImGui::SliderInt(label.c_str(), &value, -1000, 1000)) {
            synth::FapStream edited = faps;
            edited.frames.front().values[static_cast<std::size_t>(fap - 1)] = value;
            const synth::Trajectory back = synth::fap_to_trajectory(edited);
            for (const auto& info : synth::params())
                editor.set_target(info.param,
                                  std::clamp(back.frames.front()[synth::index(info.param)], info.min, info.max));
        }
        after_slider();
    }
    ImGui::EndChild();
    ImGui::EndGroup();
}

PlayResult run_editor(const PlaySettings& s) {
    VisemeEditor editor(s.edit_visemes);
    std::vector<ScriptEvent> script;
    if (!s.script.empty()) script = read_play_script(s.script, true);
    const stimuli::Head head = stimuli::load_head_files({});
    PlayerWindow window(s.window_width, s.window_height, "avsi play — viseme editor: " + s.edit_visemes.string(), head,
                        s.face_width, s.face_height);
    PlayResult result;
    EditorControls c;
    std::optional<synth::Frame> shown;
    c.diff = editor.diff_with_disk();
    std::vector<std::string> all_phones;
    for (const auto& [phone, index] : editor.set().phone_to_viseme) all_phones.push_back(phone);

    while (!c.quit) {
        glfwPollEvents();
        if (glfwWindowShouldClose(window.handle())) break;
        c.screenshots.clear();
        c.changed = false;
        run_editor_script(s, script, editor, c);
        // A quitting refresh is still drawn (its screenshots saved), then the loop ends.
        window.begin_frame();
        const ImGuiIO& io = ImGui::GetIO();
        if (!io.WantTextInput) {
            if (key(GLFW_KEY_UP) && editor.selected() > 0) editor.select(editor.selected() - 1);
            if (key(GLFW_KEY_DOWN) && editor.selected() + 1 < editor.set().visemes.size()) editor.select(editor.selected() + 1);
            if (io.KeyCtrl && key(GLFW_KEY_Z)) c.changed |= editor.undo();
            if (io.KeyCtrl && key(GLFW_KEY_S)) save_from_ui(editor, c);
            if (key(GLFW_KEY_Q) || key(GLFW_KEY_ESCAPE)) c.quit = true;
        }
        const synth::Viseme viseme = editor.selected_viseme();
        if (!shown || *shown != viseme.targets) {
            stimuli::Pose pose;
            pose.params = viseme.targets;
            window.draw_face(pose);
            shown = viseme.targets;
        }

        ImGui::SetNextWindowPos(ImVec2(0, 0));
        ImGui::SetNextWindowSize(io.DisplaySize);
        ImGui::Begin("editor", nullptr,
                     ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoSavedSettings |
                         ImGuiWindowFlags_NoBringToFrontOnFocus);
        const std::vector<double> alphas = editor.alphas();
        // The visemes with their α.
        ImGui::BeginChild("visemes", ImVec2(170, 0), true);
        for (std::size_t i = 0; i < editor.set().visemes.size(); ++i) {
            const std::string label = fmt::format("{}  a={:.2f}", editor.set().visemes[i].name, alphas[i]);
            if (ImGui::Selectable(label.c_str(), i == editor.selected())) editor.select(i);
        }
        ImGui::EndChild();
        ImGui::SameLine();
        draw_viseme_panel(window, editor, viseme, alphas, all_phones, c);
        ImGui::SameLine();
        draw_target_sliders(editor, viseme, c);
        if (c.changed) c.diff = editor.diff_with_disk();
        ImGui::End();
        window.end_frame();
        for (const auto& path : c.screenshots) stimuli::write_png(path, window.read_window());
        window.swap();
        ++result.refreshes;
    }
    result.saved = c.saved;
    if (editor.modified()) log_warning("viseme editor: {} has unsaved changes (not saved)", editor.path().string());
    return result;
}

}  // namespace

PlayResult play(const PlaySettings& settings) {
    if (!settings.edit_visemes.empty()) return run_editor(settings);
    return run_player(settings);
}

}  // namespace avsi::experiment
