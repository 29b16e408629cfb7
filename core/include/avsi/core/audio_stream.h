// Audio files read and written block by block through libsndfile, so long
// recordings are processed in memory bounded by the block size rather than
// by the file's length. The samples are the ones read_audio and write_audio
// (audio.h) give and take: floats in [-1, 1], interleaved.
//
// Usage:
//   avsi::AudioFileReader in("long.wav");
//   avsi::AudioFileWriter out("copy.wav", in.sample_rate_hz(), in.channels());
//   std::vector<float> block(4096 * in.channels());
//   while (std::size_t n = in.read(block.data(), 4096)) out.write(block.data(), n);
//   out.commit();
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>

#include "avsi/core/audio.h"

namespace avsi {

// Where block-wise processing reads its input: interleaved float frames from
// any position, as often as a computation needs passes over them.
class AudioSource {
public:
    virtual ~AudioSource() = default;
    virtual int sample_rate_hz() const = 0;
    virtual int channels() const = 0;
    // The length in frames.
    virtual std::size_t frames() const = 0;
    // Reads up to `frames` frames (frames × channels floats) from the current
    // position into `out`; returns how many: fewer only at the end, 0 after it.
    virtual std::size_t read(float* out, std::size_t frames) = 0;
    // Moves to frame `frame` (at most frames()).
    virtual void seek(std::size_t frame) = 0;
    // Whether read_pcm16 gives 16-bit samples s whose read() floats are
    // s / 32768 exactly (a 16-bit PCM file), so that a caller may take
    // those and convert them itself (on the way to doubles, say).
    virtual bool gives_pcm16() const { return false; }
    // As read, into 16-bit samples; only when gives_pcm16().
    virtual std::size_t read_pcm16(std::int16_t* out, std::size_t frames);
};

// Where block-wise processing writes its output, in order.
class AudioSink {
public:
    virtual ~AudioSink() = default;
    // Appends `frames` interleaved frames.
    virtual void write(const float* samples, std::size_t frames) = 0;
    // Advice: start storing what has been written so far (a file: its disk
    // writes), so that the end waits for less. May be called from another
    // thread than write(), while it runs.
    virtual void start_writeback() {}
    // Whether the sink stores 16-bit samples and takes them ready made:
    // write_pcm16 of float_to_pcm16's samples then stores what write()
    // of the floats would (so the conversion can run on another thread).
    virtual bool takes_pcm16() const { return false; }
    // Appends `frames` interleaved frames of 16-bit samples; only when
    // takes_pcm16().
    virtual void write_pcm16(const std::int16_t* samples, std::size_t frames);
};

// Floats to 16-bit samples as libsndfile converts them when it writes a
// 16-bit file with clipping on (SFC_SET_CLIPPING, as AudioFileWriter sets
// it): scaled by 2^31, clipped to 32 bits, rounded to the nearest (ties to
// even), then the low 16 bits dropped (so rounded down); NaN gives -32768.
// Found by comparing with libsndfile 1.2.0 on 8.2 million values (every
// 16-bit step and half step, ±6 float steps around each, and 5 million
// uniform in [-1.2, 1.2]); AudioFileWriter checks it against the
// libsndfile it runs with before it takes 16-bit samples.
void float_to_pcm16(const float* in, std::size_t count, std::int16_t* out);

// An Audio buffer as a source (the buffer must outlive it).
class AudioBufferSource : public AudioSource {
public:
    explicit AudioBufferSource(const Audio& audio) : m_audio(audio) {}
    int sample_rate_hz() const override { return m_audio.sample_rate_hz; }
    int channels() const override { return m_audio.channels; }
    std::size_t frames() const override { return m_audio.frames(); }
    std::size_t read(float* out, std::size_t frames) override;
    void seek(std::size_t frame) override;

private:
    const Audio& m_audio;
    std::size_t m_position = 0;
};

// Appends to an Audio buffer (its rate and channels set by the caller).
class AudioBufferSink : public AudioSink {
public:
    explicit AudioBufferSink(Audio& audio) : m_audio(audio) {}
    void write(const float* samples, std::size_t frames) override;

private:
    Audio& m_audio;
};

// Reads a WAV or FLAC file (anything read_audio reads) block by block.
class AudioFileReader : public AudioSource {
public:
    // Opens the file; throws InputError naming it, with read_audio's messages.
    explicit AudioFileReader(const std::filesystem::path& path);
    ~AudioFileReader();
    AudioFileReader(const AudioFileReader&) = delete;
    AudioFileReader& operator=(const AudioFileReader&) = delete;

    const std::filesystem::path& path() const { return m_path; }
    int sample_rate_hz() const override { return m_rate_hz; }
    int channels() const override { return m_channels; }
    // The length the header gives, in frames.
    std::size_t frames() const override { return m_frames; }

    // As AudioSource::read; throws InputError when the file ends before the
    // length its header gives, or (float files) at a non-finite sample.
    std::size_t read(float* out, std::size_t frames) override;
    void seek(std::size_t frame) override;
    // A 16-bit PCM WAV: libsndfile's floats are its samples times 2^-15.
    bool gives_pcm16() const override { return m_pcm16; }
    std::size_t read_pcm16(std::int16_t* out, std::size_t frames) override;

private:
    struct File;
    // Checks that sf_readf_* gave `got` of the `wanted` frames.
    void expect_read(std::size_t wanted, long long got) const;
    std::filesystem::path m_path;
    std::unique_ptr<File> m_file;
    int m_rate_hz = 0;
    int m_channels = 0;
    std::size_t m_frames = 0;
    std::size_t m_position = 0;
    bool m_floats = false;  // float or double samples (which may be non-finite)
    bool m_pcm16 = false;   // see gives_pcm16
};

// Writes a WAV (.wav) or FLAC (.flac, PCM only) file block by block, into a
// temporary beside the target that commit() renames into place: an existing
// file is never left half-written, and without commit() (an exception on
// the way) the temporary is removed. Samples beyond ±1 are clipped, as
// write_audio clips them.
class AudioFileWriter : public AudioSink {
public:
    // Throws InputError for an unsupported extension or a file that cannot be created.
    AudioFileWriter(const std::filesystem::path& path, int sample_rate_hz, int channels,
                    SampleFormat format = SampleFormat::Pcm16);
    ~AudioFileWriter();
    AudioFileWriter(const AudioFileWriter&) = delete;
    AudioFileWriter& operator=(const AudioFileWriter&) = delete;

    void write(const float* samples, std::size_t frames) override;
    // sync_file_range(SYNC_FILE_RANGE_WRITE) of the temporary.
    void start_writeback() override;
    // A 16-bit WAV in this machine's byte order, with a libsndfile that
    // converts as float_to_pcm16 does.
    bool takes_pcm16() const override;
    void write_pcm16(const std::int16_t* samples, std::size_t frames) override;
    // Closes the file and renames it over the target.
    void commit();

private:
    struct File;
    std::filesystem::path m_path;
    std::unique_ptr<File> m_file;
    int m_channels = 0;
    bool m_native_pcm16 = false;  // a 16-bit WAV in this machine's byte order
};

}  // namespace avsi
