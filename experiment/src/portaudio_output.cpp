// PortAudio output with DAC-timestamped onsets (see media.h). The callback
// writes the pending clip starting at the sample whose DAC time is the
// requested onset, so the onset is known to the sample on the stream clock
// (Pa_GetStreamTime), the same clock the runner stamps its buffer swaps with.
#include <portaudio.h>

#include <atomic>
#include <cmath>
#include <mutex>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/experiment/media.h"

namespace avsi::experiment {

namespace {

class PortAudioOutput : public AudioOutput {
public:
    PortAudioOutput() {
        if (const PaError e = Pa_Initialize(); e != paNoError)
            throw InputError("portaudio", 0, 0, "", fmt::format("cannot initialise PortAudio: {}", Pa_GetErrorText(e)));
        m_initialised = true;
        const PaDeviceIndex device = Pa_GetDefaultOutputDevice();
        if (device == paNoDevice) {
            Pa_Terminate();
            throw InputError("portaudio", 0, 0, "", "no audio output device; use --audio null for a dry run");
        }
        m_device = Pa_GetDeviceInfo(device);
        m_device_index = device;
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
        PaStreamParameters out{};
        out.device = m_device_index;
        out.channelCount = 1;
        out.sampleFormat = paFloat32;
        out.suggestedLatency = m_device->defaultLowOutputLatency;
        PaError e = Pa_OpenStream(&m_stream, nullptr, &out, rate, paFramesPerBufferUnspecified, paClipOff,
                                  &PortAudioOutput::callback, this);
        if (e == paNoError) e = Pa_StartStream(m_stream);
        if (e != paNoError)
            throw InputError("portaudio", 0, 0, "",
                             fmt::format("cannot open the audio output at {} Hz: {}", rate, Pa_GetErrorText(e)));
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
    std::atomic<double> m_onset{-1.0};
};

}  // namespace

std::unique_ptr<AudioOutput> make_portaudio_output() { return std::make_unique<PortAudioOutput>(); }

}  // namespace avsi::experiment
