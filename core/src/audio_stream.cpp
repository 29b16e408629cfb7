// Block-wise audio file reading and writing; see audio_stream.h.
#include "avsi/core/audio_stream.h"

#include <sndfile.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>
#include <vector>

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "sndfile_checks.h"

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

std::size_t AudioSource::read_pcm16(std::int16_t*, std::size_t) {
    AVSI_ASSERT(!"read_pcm16 on a source that does not give 16-bit samples");
    return 0;
}

void AudioSink::write_pcm16(const std::int16_t*, std::size_t) {
    AVSI_ASSERT(!"write_pcm16 on a sink that does not take 16-bit samples");
}

void float_to_pcm16(const float* in, std::size_t count, std::int16_t* out) {
    std::size_t i = 0;
#ifdef __SSE2__
    // Eight at a time: cvtps2dq rounds as lrintf does (to the nearest, ties
    // to even, in the default rounding mode, which nothing here changes)
    // and gives INT32_MIN for NaN and for what is out of range, which the
    // XOR with the ≥ 2^31 mask turns into INT32_MAX above.
    const __m128 two_31 = _mm_set1_ps(2147483648.0f);
    auto eight_bits = [&](const float* x) {
        const __m128 scaled = _mm_mul_ps(_mm_loadu_ps(x), two_31);
        const __m128i above = _mm_castps_si128(_mm_cmpge_ps(scaled, two_31));
        return _mm_srai_epi32(_mm_xor_si128(_mm_cvtps_epi32(scaled), above), 16);
    };
    for (; i + 8 <= count; i += 8)
        _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i), _mm_packs_epi32(eight_bits(in + i), eight_bits(in + i + 4)));
#endif
    for (; i < count; ++i) {
        const float scaled = in[i] * 2147483648.0f;  // exact: a power of two
        std::int32_t wide;
        if (scaled >= 2147483648.0f)
            wide = INT32_MAX;
        else if (scaled <= -2147483648.0f || std::isnan(scaled))
            wide = INT32_MIN;
        else
            wide = static_cast<std::int32_t>(std::lrintf(scaled));
        out[i] = static_cast<std::int16_t>(wide >> 16);
    }
}

namespace {

// Whether the libsndfile this process runs with writes 16-bit WAV samples
// as float_to_pcm16 makes them, on some 10,600 probe values through a WAV
// in memory (once per process, well under a millisecond): every eighth of
// a 16-bit step near zero; the edges and middles of every 61st step with a
// float step either side; the float steps next to ±1; the extremes,
// infinities and NaN. (A unit test compares 8 million values.)
bool libsndfile_writes_as_float_to_pcm16() {
    static const bool same = [] {
        std::vector<float> probe;
        for (int k = -2048; k <= 2048; ++k) probe.push_back(static_cast<float>(k) / (32768.0f * 8.0f));
        for (int step = -32768; step <= 32767; step += 61) {
            for (float x : {static_cast<float>(step) / 32768.0f, (static_cast<float>(step) + 0.5f) / 32768.0f}) {
                probe.push_back(x);
                probe.push_back(std::nextafter(x, 2.0f));
                probe.push_back(std::nextafter(x, -2.0f));
            }
        }
        for (float x : {1.0f, -1.0f}) {
            float up = x, down = x;
            for (int i = 0; i < 8; ++i) {
                probe.push_back(up = std::nextafter(up, 2.0f));
                probe.push_back(down = std::nextafter(down, -2.0f));
            }
        }
        for (float x : {0.0f, -0.0f, std::numeric_limits<float>::max(), -std::numeric_limits<float>::max(),
                        std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                        std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::denorm_min()})
            probe.push_back(x);
        const int fd = ::memfd_create("avsi-pcm16-probe", MFD_CLOEXEC);
        if (fd < 0) return false;
        SF_INFO info{};
        info.samplerate = 8000;
        info.channels = 1;
        info.format = SF_FORMAT_WAV | SF_FORMAT_PCM_16;
        bool ok = false;
        if (SNDFILE* out = sf_open_fd(fd, SFM_WRITE, &info, SF_FALSE)) {
            sf_command(out, SFC_SET_CLIPPING, nullptr, SF_TRUE);
            const auto n = static_cast<sf_count_t>(probe.size());
            ok = sf_writef_float(out, probe.data(), n) == n;
            ok = sf_close(out) == 0 && ok;
            SF_INFO read_info{};
            SNDFILE* in = ok && ::lseek(fd, 0, SEEK_SET) == 0 ? sf_open_fd(fd, SFM_READ, &read_info, SF_FALSE) : nullptr;
            std::vector<std::int16_t> stored(probe.size()), ours(probe.size());
            ok = in && sf_read_short(in, stored.data(), n) == n;
            if (in) sf_close(in);
            float_to_pcm16(probe.data(), probe.size(), ours.data());
            ok = ok && stored == ours;
        }
        ::close(fd);
        return ok;
    }();
    return same;
}

}  // namespace

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
    SF_INFO info;
    m_file->handle = open_audio_file(path, info);
    m_rate_hz = info.samplerate;
    m_channels = info.channels;
    m_frames = static_cast<std::size_t>(info.frames);
    const int container = info.format & SF_FORMAT_TYPEMASK;
    m_floats = has_float_samples(info);
    m_pcm16 = (info.format & SF_FORMAT_SUBMASK) == SF_FORMAT_PCM_16 &&
              (container == SF_FORMAT_WAV || container == SF_FORMAT_WAVEX);
}

AudioFileReader::~AudioFileReader() = default;

void AudioFileReader::expect_read(std::size_t wanted, long long got) const {
    if (got != static_cast<long long>(wanted))
        throw InputError(m_path, fmt::format("audio file is truncated: header says {} frames, read {}", m_frames,
                                             m_position + static_cast<std::size_t>(std::max<long long>(got, 0))));
}

std::size_t AudioFileReader::read_pcm16(std::int16_t* out, std::size_t frames) {
    AVSI_ASSERT(m_pcm16);
    const std::size_t wanted = std::min(frames, m_frames - m_position);
    if (wanted == 0) return 0;
    expect_read(wanted, sf_readf_short(m_file->handle, out, static_cast<sf_count_t>(wanted)));
    m_position += wanted;
    return wanted;
}

std::size_t AudioFileReader::read(float* out, std::size_t frames) {
    const std::size_t wanted = std::min(frames, m_frames - m_position);
    if (wanted == 0) return 0;
    expect_read(wanted, sf_readf_float(m_file->handle, out, static_cast<sf_count_t>(wanted)));
    if (m_floats)
        require_finite_samples(m_path, out, wanted * static_cast<std::size_t>(m_channels), m_channels, m_rate_hz,
                               m_position);
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
    m_native_pcm16 = major == SF_FORMAT_WAV && subtype == SF_FORMAT_PCM_16 &&
                     sf_command(m_file->handle, SFC_RAW_DATA_NEEDS_ENDSWAP, nullptr, 0) == SF_FALSE;
}

// The probe runs on the first ask only, so writers that never take 16-bit
// samples do not pay for it.
bool AudioFileWriter::takes_pcm16() const { return m_native_pcm16 && libsndfile_writes_as_float_to_pcm16(); }

AudioFileWriter::~AudioFileWriter() = default;

void AudioFileWriter::write(const float* samples, std::size_t frames) {
    AVSI_ASSERT(m_file && m_file->handle);
    const sf_count_t written = sf_writef_float(m_file->handle, samples, static_cast<sf_count_t>(frames));
    if (written != static_cast<sf_count_t>(frames))
        throw InputError(m_path, "cannot write audio file: short write (disk full?)");
}

void AudioFileWriter::write_pcm16(const std::int16_t* samples, std::size_t frames) {
    AVSI_ASSERT(m_file && m_file->handle && takes_pcm16());
    const auto bytes = static_cast<sf_count_t>(frames * static_cast<std::size_t>(m_channels) * sizeof(std::int16_t));
    if (sf_write_raw(m_file->handle, samples, bytes) != bytes)
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
