// PortAudio output with DAC-timestamped onsets (see media.h). The callback
// writes the pending clip starting at the sample whose DAC time is the
// requested onset, so the onset is known to the sample on the stream clock
// (Pa_GetStreamTime), the same clock the runner stamps its buffer swaps with.
#include <alsa/asoundlib.h>
#include <jack/jack.h>
#include <portaudio.h>

#include <cstdarg>
#include <cstdio>
#include <functional>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cmath>
#include <mutex>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/core/text.h"
#include "avsi/experiment/media.h"

namespace avsi::experiment {

namespace {

// ALSA and JACK print to stderr while PortAudio probes them (PCMs of cards
// that are absent, no JACK server); their messages go to the debug log.
void alsa_message(const char* file, int line, const char* function, int err, const char* format, ...) {
    char text[512];
    va_list args;
    va_start(args, format);
    std::vsnprintf(text, sizeof text, format, args);
    va_end(args);
    log_debug("ALSA {}:{} ({}): {}{}", file ? file : "?", line, function ? function : "?", text,
              err ? fmt::format(": {}", snd_strerror(err)) : std::string());
}

void jack_message(const char* text) { log_debug("JACK: {}", text ? text : ""); }

void initialise() {
    snd_lib_error_set_handler(&alsa_message);
    jack_set_error_function(&jack_message);
    jack_set_info_function(&jack_message);
    if (const PaError e = Pa_Initialize(); e != paNoError)
        throw InputError("portaudio", 0, 0, "", fmt::format("cannot initialise PortAudio: {}", Pa_GetErrorText(e)));
}

std::string describe(PaDeviceIndex i) {
    const PaDeviceInfo* d = Pa_GetDeviceInfo(i);
    const PaHostApiInfo* host = Pa_GetHostApiInfo(d->hostApi);
    return fmt::format("{}: {} ({}, {} output channels, {:.0f} Hz, low latency {:.1f} ms){}", i, d->name,
                       host ? host->name : "?", d->maxOutputChannels, d->defaultSampleRate,
                       d->defaultLowOutputLatency * 1000.0, i == Pa_GetDefaultOutputDevice() ? " [default]" : "");
}

std::vector<PaDeviceIndex> output_devices() {
    std::vector<PaDeviceIndex> out;
    for (PaDeviceIndex i = 0, n = Pa_GetDeviceCount(); i < n; ++i)
        if (Pa_GetDeviceInfo(i)->maxOutputChannels > 0) out.push_back(i);
    return out;
}

std::string device_list_text() {
    const auto devices = output_devices();
    if (devices.empty()) return "PortAudio finds no output device on this machine";
    std::string text = "the output devices are:";
    for (PaDeviceIndex i : devices) text += "\n  " + describe(i);
    return text;
}

// The device named by an index or a case-insensitive part of its name; the
// default output device for "". PortAudio must be initialised.
PaDeviceIndex find_device(const std::string& wanted) {
    if (wanted.empty()) {
        const PaDeviceIndex device = Pa_GetDefaultOutputDevice();
        if (device == paNoDevice)
            throw InputError("portaudio", 0, 0, "audio-device",
                             fmt::format("no default audio output device ({}); give --audio-device, or --audio null "
                                         "for a dry run",
                                         device_list_text()));
        return device;
    }
    const auto devices = output_devices();
    if (std::all_of(wanted.begin(), wanted.end(), [](char c) { return std::isdigit(static_cast<unsigned char>(c)); })) {
        const int index = std::stoi(wanted);
        if (std::find(devices.begin(), devices.end(), index) != devices.end()) return index;
        throw InputError("portaudio", 0, 0, "audio-device",
                         fmt::format("expected an output device index, got {} ({})", wanted, device_list_text()));
    }
    std::vector<PaDeviceIndex> matches;
    for (PaDeviceIndex i : devices) {
        const std::string name = ascii_lower(Pa_GetDeviceInfo(i)->name);
        if (name == ascii_lower(wanted)) return i;
        if (name.find(ascii_lower(wanted)) != std::string::npos) matches.push_back(i);
    }
    if (matches.size() == 1) return matches.front();
    throw InputError("portaudio", 0, 0, "audio-device",
                     fmt::format("expected one output device named like \"{}\", found {} ({})", wanted,
                                 matches.size(), device_list_text()));
}

// Opens and starts a mono float32 output stream at the device's low latency;
// throws InputError naming the device if it cannot.
PaStream* open_mono_stream(PaDeviceIndex device, int rate, PaStreamCallback* callback, void* user) {
    const PaDeviceInfo* info = Pa_GetDeviceInfo(device);
    PaStreamParameters out{};
    out.device = device;
    out.channelCount = 1;
    out.sampleFormat = paFloat32;
    out.suggestedLatency = info->defaultLowOutputLatency;
    PaStream* stream = nullptr;
    PaError e = Pa_OpenStream(&stream, nullptr, &out, rate, paFramesPerBufferUnspecified, paClipOff, callback, user);
    if (e == paNoError) e = Pa_StartStream(stream);
    if (e != paNoError) {
        if (stream) Pa_CloseStream(stream);
        throw InputError("portaudio", 0, 0, "audio-device",
                         fmt::format("cannot open audio output device \"{}\" at {} Hz: {}", info->name, rate,
                                     Pa_GetErrorText(e)));
    }
    return stream;
}

class PortAudioOutput : public AudioOutput {
public:
    explicit PortAudioOutput(const std::string& device) {
        initialise();
        m_initialised = true;
        try {
            m_device_index = find_device(device);
        } catch (...) {
            Pa_Terminate();
            m_initialised = false;
            throw;
        }
        m_device = Pa_GetDeviceInfo(m_device_index);
        // Open the stream now, so a device that cannot play fails before the
        // window opens and the clock runs from the start (a clip at another
        // rate reopens it).
        try {
            ensure_stream(48000);
        } catch (...) {
            Pa_Terminate();
            m_initialised = false;
            throw;
        }
    }
    ~PortAudioOutput() override {
        close();
        if (m_initialised) Pa_Terminate();
    }

    std::string name() const override {
        return fmt::format("portaudio: {} (latency {:.1f} ms)", m_device ? m_device->name : "?", m_latency_s * 1000.0);
    }
    double now_s() override {
        ensure_stream(m_rate ? m_rate : 48000);
        return Pa_GetStreamTime(m_stream);
    }
    double lead_s() const override { return m_latency_s + 0.010; }

    void play(const std::vector<float>& samples, int sample_rate, double at_s) override {
        ensure_stream(sample_rate);
        std::lock_guard lock(m_mutex);
        m_clip = samples;
        m_pos = 0;
        m_at_s = at_s;
        m_started = false;
        m_onset.store(-1.0);
        m_active = true;
    }
    std::optional<double> onset_s() override {
        const double v = m_onset.load();
        if (v < 0) return std::nullopt;
        return v;
    }
    std::string onset_detail() override {
        std::lock_guard lock(m_mutex);
        const double onset = m_onset.load();
        if (onset < 0) return "";
        return fmt::format("onset {:.6f} s on the DAC clock, {:+.3f} ms from the requested {:.6f} s; the callback saw "
                           "the DAC {:.3f} ms ahead",
                           onset, (onset - m_at_s) * 1000.0, m_at_s, m_dac_lead_s * 1000.0);
    }
    bool playing() override {
        std::lock_guard lock(m_mutex);
        return m_active;
    }
    void stop() override {
        std::lock_guard lock(m_mutex);
        m_active = false;
        m_clip.clear();
    }

private:
    void ensure_stream(int rate) {
        if (m_stream && rate == m_rate) return;
        close();
        m_stream = open_mono_stream(m_device_index, rate, &PortAudioOutput::callback, this);
        m_rate = rate;
        const PaStreamInfo* info = Pa_GetStreamInfo(m_stream);
        m_latency_s = info ? info->outputLatency : 0.0;
        log_info("audio: {}", name());
    }
    void close() {
        if (m_stream) {
            Pa_StopStream(m_stream);
            Pa_CloseStream(m_stream);
            m_stream = nullptr;
        }
    }

    static int callback(const void*, void* output, unsigned long frames, const PaStreamCallbackTimeInfo* time,
                        PaStreamCallbackFlags, void* user) {
        auto* self = static_cast<PortAudioOutput*>(user);
        auto* out = static_cast<float*>(output);
        std::fill(out, out + frames, 0.0f);
        std::unique_lock lock(self->m_mutex, std::try_to_lock);
        if (!lock.owns_lock() || !self->m_active) return paContinue;
        unsigned long first = 0;
        if (!self->m_started) {
            const double dac = time->outputBufferDacTime;
            const double wait = (self->m_at_s - dac) * self->m_rate;
            if (wait >= static_cast<double>(frames)) return paContinue;
            first = wait > 0 ? static_cast<unsigned long>(std::ceil(wait)) : 0;
            self->m_dac_lead_s = dac - time->currentTime;
            self->m_onset.store(dac + static_cast<double>(first) / self->m_rate);
            self->m_started = true;
        }
        for (unsigned long i = first; i < frames && self->m_pos < self->m_clip.size(); ++i)
            out[i] = self->m_clip[self->m_pos++];
        if (self->m_pos >= self->m_clip.size()) self->m_active = false;
        return paContinue;
    }

    bool m_initialised = false;
    const PaDeviceInfo* m_device = nullptr;
    PaDeviceIndex m_device_index = paNoDevice;
    PaStream* m_stream = nullptr;
    int m_rate = 0;
    double m_latency_s = 0.0;
    std::mutex m_mutex;
    std::vector<float> m_clip;
    std::size_t m_pos = 0;
    double m_at_s = 0.0;
    bool m_started = false;
    bool m_active = false;
    double m_dac_lead_s = 0.0;  // outputBufferDacTime − currentTime at the onset buffer
    std::atomic<double> m_onset{-1.0};
};

// A stream whose callback pulls every buffer from the caller (the player).
class PortAudioPullStream : public PullAudioStream {
public:
    PortAudioPullStream(const std::string& device, int rate, std::function<void(float*, std::size_t)> pull)
        : m_pull(std::move(pull)) {
        initialise();
        try {
            const PaDeviceIndex index = find_device(device);
            m_device = Pa_GetDeviceInfo(index);
            m_stream = open_mono_stream(index, rate, &PortAudioPullStream::callback, this);
            const PaStreamInfo* info = Pa_GetStreamInfo(m_stream);
            m_latency_s = info ? info->outputLatency : 0.0;
        } catch (...) {
            Pa_Terminate();
            throw;
        }
    }
    ~PortAudioPullStream() override {
        if (m_stream) {
            Pa_StopStream(m_stream);
            Pa_CloseStream(m_stream);
        }
        Pa_Terminate();
    }
    std::string name() const override {
        return fmt::format("portaudio: {} (latency {:.1f} ms)", m_device ? m_device->name : "?", m_latency_s * 1000.0);
    }
    double latency_s() const override { return m_latency_s; }

private:
    static int callback(const void*, void* output, unsigned long frames, const PaStreamCallbackTimeInfo*,
                        PaStreamCallbackFlags, void* user) {
        auto* self = static_cast<PortAudioPullStream*>(user);
        self->m_pull(static_cast<float*>(output), frames);
        return paContinue;
    }
    std::function<void(float*, std::size_t)> m_pull;
    const PaDeviceInfo* m_device = nullptr;
    PaStream* m_stream = nullptr;
    double m_latency_s = 0.0;
};

}  // namespace

std::unique_ptr<PullAudioStream> open_portaudio_pull_stream(const std::string& device, int sample_rate_hz,
                                                            std::function<void(float*, std::size_t)> pull) {
    return std::make_unique<PortAudioPullStream>(device, sample_rate_hz, std::move(pull));
}

std::unique_ptr<AudioOutput> make_portaudio_output(const std::string& device) {
    return std::make_unique<PortAudioOutput>(device);
}

std::vector<std::string> list_audio_devices() {
    initialise();
    std::vector<std::string> lines;
    for (PaDeviceIndex i : output_devices()) lines.push_back(describe(i));
    Pa_Terminate();
    return lines;
}

}  // namespace avsi::experiment
