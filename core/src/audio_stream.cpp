// Block-wise audio file reading and writing; see audio_stream.h.
#include "avsi/core/audio_stream.h"

#include <sndfile.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <utility>

#include <fcntl.h>
#include <unistd.h>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi {

std::size_t AudioBufferSource::read(float* out, std::size_t frames) {
    const std::size_t n = std::min(frames, m_audio.frames() - m_position);
    const std::size_t channels = static_cast<std::size_t>(m_audio.channels);
    std::copy_n(m_audio.samples.data() + m_position * channels, n * channels, out);
    m_position += n;
    return n;
}

void AudioBufferSource::seek(std::size_t frame) {
    AVSI_ASSERT(frame <= m_audio.frames());
    m_position = frame;
}

void AudioBufferSink::write(const float* samples, std::size_t frames) {
    m_audio.samples.insert(m_audio.samples.end(), samples, samples + frames * static_cast<std::size_t>(m_audio.channels));
}

struct AudioFileReader::File {
    SNDFILE* handle = nullptr;
    ~File() {
        if (handle) sf_close(handle);
    }
};

AudioFileReader::AudioFileReader(const std::filesystem::path& path) : m_path(path), m_file(std::make_unique<File>()) {
    SF_INFO info{};
    m_file->handle = sf_open(path.c_str(), SFM_READ, &info);
    if (!m_file->handle) {
        if (!std::filesystem::exists(path)) throw InputError(path, "cannot open audio file: no such file");
        throw InputError(path, fmt::format("cannot read audio file: {} (supported: WAV and FLAC, "
                                           "PCM or float)", sf_strerror(nullptr)));
    }
    if (info.samplerate <= 0 || info.channels <= 0 || info.frames < 0)
        throw InputError(path, "audio file has no valid sample rate or channel count");
    if (info.frames == 0) throw InputError(path, "audio file has no samples");
    // Float reads of float files must not be rescaled; PCM maps to [-1, 1).
    sf_command(m_file->handle, SFC_SET_NORM_FLOAT, nullptr, SF_TRUE);
    m_rate_hz = info.samplerate;
    m_channels = info.channels;
    m_frames = static_cast<std::size_t>(info.frames);
}

AudioFileReader::~AudioFileReader() = default;

std::size_t AudioFileReader::read(float* out, std::size_t frames) {
    const std::size_t wanted = std::min(frames, m_frames - m_position);
    if (wanted == 0) return 0;
    const sf_count_t got = sf_readf_float(m_file->handle, out, static_cast<sf_count_t>(wanted));
    if (got != static_cast<sf_count_t>(wanted))
        throw InputError(m_path, fmt::format("audio file is truncated: header says {} frames, read {}", m_frames,
                                             m_position + static_cast<std::size_t>(std::max<sf_count_t>(got, 0))));
    m_position += wanted;
    return wanted;
}

void AudioFileReader::seek(std::size_t frame) {
    AVSI_ASSERT(frame <= m_frames);
    if (sf_seek(m_file->handle, static_cast<sf_count_t>(frame), SEEK_SET) != static_cast<sf_count_t>(frame))
        throw InputError(m_path, fmt::format("cannot read audio file from frame {}: {}", frame,
                                             sf_strerror(m_file->handle)));
    m_position = frame;
}

struct AudioFileWriter::File {
    explicit File(const std::filesystem::path& target) : atomic(target) {}
    AtomicFile atomic;
    SNDFILE* handle = nullptr;
    int fd = -1;  // the temporary's (libsndfile writes to it but does not close it)
    ~File() {
        if (handle) sf_close(handle);
        if (fd >= 0) ::close(fd);
    }
};

AudioFileWriter::AudioFileWriter(const std::filesystem::path& path, int rate_hz, int channels, SampleFormat format)
    : m_path(path), m_channels(channels) {
    AVSI_ASSERT(channels > 0 && rate_hz > 0);
    const std::string ext = path.extension().string();
    int major = 0;
    if (ext == ".wav" || ext == ".WAV") {
        major = SF_FORMAT_WAV;
    } else if (ext == ".flac" || ext == ".FLAC") {
        major = SF_FORMAT_FLAC;
        if (format == SampleFormat::Float32)
            throw InputError(path, "FLAC holds integer PCM only; use 16- or 24-bit, or write .wav");
    } else {
        throw InputError(path, fmt::format("unsupported audio file extension '{}'; supported "
                                           "extensions are '.wav' and '.flac'", ext));
    }
    int subtype = SF_FORMAT_PCM_16;
    if (format == SampleFormat::Pcm24) subtype = SF_FORMAT_PCM_24;
    if (format == SampleFormat::Float32) subtype = SF_FORMAT_FLOAT;
    m_file = std::make_unique<File>(path);
    SF_INFO info{};
    info.samplerate = rate_hz;
    info.channels = channels;
    info.format = major | subtype;
    // Opened here and handed to libsndfile, so that start_writeback has the descriptor.
    m_file->fd = ::open(m_file->atomic.temp_path().c_str(), O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (m_file->fd < 0) throw InputError(path, fmt::format("cannot write audio file: {}", std::strerror(errno)));
    m_file->handle = sf_open_fd(m_file->fd, SFM_WRITE, &info, SF_FALSE);
    if (!m_file->handle) throw InputError(path, fmt::format("cannot write audio file: {}", sf_strerror(nullptr)));
    // Clip integer output rather than wrapping around on overshoot.
    sf_command(m_file->handle, SFC_SET_CLIPPING, nullptr, SF_TRUE);
}

AudioFileWriter::~AudioFileWriter() = default;

void AudioFileWriter::write(const float* samples, std::size_t frames) {
    AVSI_ASSERT(m_file && m_file->handle);
    const sf_count_t written = sf_writef_float(m_file->handle, samples, static_cast<sf_count_t>(frames));
    if (written != static_cast<sf_count_t>(frames))
        throw InputError(m_path, "cannot write audio file: short write (disk full?)");
}

void AudioFileWriter::start_writeback() {
    AVSI_ASSERT(m_file && m_file->handle);
#ifdef SYNC_FILE_RANGE_WRITE
    ::sync_file_range(m_file->fd, 0, 0, SYNC_FILE_RANGE_WRITE);  // advice: failure changes nothing
#endif
}

void AudioFileWriter::commit() {
    AVSI_ASSERT(m_file && m_file->handle);
    const int status = sf_close(m_file->handle);
    m_file->handle = nullptr;
    const int closed = ::close(std::exchange(m_file->fd, -1));
    if (status != 0 || closed != 0)
        throw InputError(m_path, "cannot write audio file: short write (disk full?)");
    m_file->atomic.commit();
}

}  // namespace avsi
