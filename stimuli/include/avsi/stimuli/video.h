// Stimulus video files through FFmpeg's libraries: MP4 with H.264 (libx264),
// yuv420p, constant frame rate, muxed with AAC audio, both streams starting
// at time 0. Encoding is deterministic (one x264 thread, bit-exact muxing
// flags), so the same frames and audio give a byte-identical file and the
// manifest can hash the file itself. The decoder reads frames and audio back
// (tests, the session runner).
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include "avsi/core/audio.h"
#include "avsi/stimuli/renderer.h"

namespace avsi::stimuli {

struct VideoSettings {
    double fps = 30.0;
    int crf = 18;                       // x264 constant rate factor (0 lossless … 51)
    const char* preset = "ultrafast";   // x264 preset (ultrafast: ~2x faster than veryfast, larger files)
    int audio_bitrate_bps = 128000;     // AAC
};

// Writes an MP4 frame by frame. The audio (if any) is padded with silence or
// cut to the video's duration (frame count / fps) so both streams end together.
class VideoWriter {
public:
    // `audio` may be nullptr for a silent video; `frame_count` is the number of
    // frames that will be written (needed to fit the audio).
    VideoWriter(const std::filesystem::path& path, int width, int height, std::size_t frame_count,
                const Audio* audio, const VideoSettings& settings = {});
    ~VideoWriter();
    VideoWriter(const VideoWriter&) = delete;
    VideoWriter& operator=(const VideoWriter&) = delete;

    // Appends one frame (same size as given to the constructor).
    void write(const Image& frame);
    // Appends the previous frame again without converting it (still pictures).
    void repeat_last();
    // Flushes the encoders and writes the trailer; the file is complete after this.
    void finish();

private:
    struct Impl;
    std::unique_ptr<Impl> m_impl;
};

struct DecodedVideo {
    int width = 0;
    int height = 0;
    double fps = 0.0;                 // the stream's frame rate (r_frame_rate)
    std::size_t frame_count = 0;      // decoded frames
    double video_start_s = 0.0;       // pts of the first frame
    double video_duration_s = 0.0;    // frame_count / fps
    std::vector<Image> frames;        // only when asked for
    bool has_audio = false;
    double audio_start_s = 0.0;       // pts of the first audio sample after priming
    Audio audio;                      // decoded samples (float, interleaved)
    const char* video_codec = "";
    const char* pixel_format = "";
};

// Decodes a video file; frames are kept as RGB only when `keep_frames`.
// Throws InputError naming the file if it cannot be read.
DecodedVideo decode_video(const std::filesystem::path& path, bool keep_frames = false);

}  // namespace avsi::stimuli
