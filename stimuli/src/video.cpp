// MP4 (H.264 + AAC) writing and decoding through libavformat/libavcodec/
// libswscale. Determinism: libx264 with one thread and no wall-clock data in
// the container (AVFMT_FLAG_BITEXACT, AV_CODEC_FLAG_BITEXACT).
//
// RGB → YUV 4:2:0 for the encoder is done here, not by libswscale, and only
// for the pixels that changed since the previous frame: a talking head's
// frames differ from the previous one only around the mouth and eyes, so
// this costs ~0.1 ms/frame where swscale's whole-frame conversion cost
// ~1.85 ms. swscale cannot do it: it converts whole-width slices in order
// and its chroma filter reads neighbouring pixels. The conversion here is
// local — each luma sample from its pixel, each chroma sample from the mean
// of its 2 × 2 block — so converting a changed span gives exactly what
// converting the whole frame would. Coefficients: ITU-R BT.601 in limited
// ("MPEG", 16–235/240) range, 8-bit integer form (as in ITU-R BT.601 and
// swscale's default); chroma sited at the block centre. Both are written into
// the stream (colorspace, range, chroma location) so decoders use the same.
#include "avsi/stimuli/video.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <utility>
#include <stdexcept>
#include <string>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/channel_layout.h>
#include <libavutil/opt.h>
#include <libavutil/pixdesc.h>
#include <libswscale/swscale.h>
}

#include "avsi/core/error.h"
#include "avsi/core/files.h"

namespace avsi::stimuli {

namespace {

std::string av_error(int code) {
    char buf[AV_ERROR_MAX_STRING_SIZE] = {0};
    av_strerror(code, buf, sizeof buf);
    return buf;
}

void check(int code, const char* what) {
    if (code < 0) throw std::runtime_error(std::string(what) + ": " + av_error(code));
}

}  // namespace

struct VideoWriter::Impl {
    std::filesystem::path path;
    std::unique_ptr<AtomicFile> file;
    AVFormatContext* format = nullptr;
    AVCodecContext* video = nullptr;
    AVCodecContext* audio = nullptr;
    AVStream* video_stream = nullptr;
    AVStream* audio_stream = nullptr;
    AVFrame* frame = nullptr;
    std::vector<std::uint8_t> previous_rgb;  // the last frame written, to find what changed
    bool have_previous = false;
    AVPacket* packet = nullptr;
    std::int64_t next_pts = 0;
    std::size_t expected = 0;
    int width = 0, height = 0;
    bool finished = false;

    void drain(AVCodecContext* codec, AVStream* stream) {
        while (true) {
            const int r = avcodec_receive_packet(codec, packet);
            if (r == AVERROR(EAGAIN) || r == AVERROR_EOF) return;
            check(r, "encoding");
            av_packet_rescale_ts(packet, codec->time_base, stream->time_base);
            packet->stream_index = stream->index;
            check(av_interleaved_write_frame(format, packet), "writing a packet");
        }
    }

    ~Impl() {
        av_frame_free(&frame);
        av_packet_free(&packet);
        avcodec_free_context(&video);
        avcodec_free_context(&audio);
        if (format) {
            if (format->pb) avio_closep(&format->pb);
            avformat_free_context(format);
        }
    }
};

VideoWriter::VideoWriter(const std::filesystem::path& path, int width, int height, std::size_t frame_count,
                         const Audio* audio, const VideoSettings& settings)
    : m_impl(std::make_unique<Impl>()) {
    auto& d = *m_impl;
    av_log_set_level(AV_LOG_ERROR);  // libraries never print: no x264/AAC statistics on stderr
    if (width % 2 || height % 2)
        throw InputError(path, "video size must be even for yuv420p, got " + std::to_string(width) + "x" +
                                   std::to_string(height));
    if (!(settings.fps > 0.0 && settings.fps <= 240.0))
        throw InputError(path, "expected a frame rate in (0, 240], got " + std::to_string(settings.fps));
    if (path.has_parent_path()) std::filesystem::create_directories(path.parent_path());
    d.path = path;
    d.file = std::make_unique<AtomicFile>(path);
    d.width = width;
    d.height = height;
    d.expected = frame_count;
    check(avformat_alloc_output_context2(&d.format, nullptr, "mp4", d.file->temp_path().c_str()), "mp4 muxer");
    d.format->flags |= AVFMT_FLAG_BITEXACT;
    d.packet = av_packet_alloc();
    d.frame = av_frame_alloc();

    // Video: H.264 through libx264, constant frame rate.
    const AVCodec* h264 = avcodec_find_encoder_by_name("libx264");
    if (!h264) throw std::runtime_error("libavcodec has no libx264 encoder");
    d.video = avcodec_alloc_context3(h264);
    const AVRational rate = av_d2q(settings.fps, 100000);
    d.video->width = width;
    d.video->height = height;
    d.video->pix_fmt = AV_PIX_FMT_YUV420P;
    d.video->time_base = av_inv_q(rate);
    d.video->framerate = rate;
    d.video->gop_size = static_cast<int>(std::lround(settings.fps));
    d.video->thread_count = 1;
    d.video->flags |= AV_CODEC_FLAG_BITEXACT;
    // What rgb_to_yuv420 produces (see the file comment).
    d.video->colorspace = AVCOL_SPC_SMPTE170M;
    d.video->color_range = AVCOL_RANGE_MPEG;
    d.video->chroma_sample_location = AVCHROMA_LOC_CENTER;
    if (d.format->oformat->flags & AVFMT_GLOBALHEADER) d.video->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
    av_opt_set(d.video->priv_data, "preset", settings.preset, 0);
    av_opt_set(d.video->priv_data, "crf", std::to_string(settings.crf).c_str(), 0);
    check(avcodec_open2(d.video, h264, nullptr), "opening libx264");
    d.video_stream = avformat_new_stream(d.format, nullptr);
    d.video_stream->time_base = d.video->time_base;
    d.video_stream->avg_frame_rate = rate;
    d.video_stream->r_frame_rate = rate;
    check(avcodec_parameters_from_context(d.video_stream->codecpar, d.video), "video parameters");

    // Audio: AAC, mono or the input's channels, at the input's rate.
    if (audio && audio->frames() > 0) {
        const AVCodec* aac = avcodec_find_encoder(AV_CODEC_ID_AAC);
        if (!aac) throw std::runtime_error("libavcodec has no AAC encoder");
        d.audio = avcodec_alloc_context3(aac);
        d.audio->sample_fmt = AV_SAMPLE_FMT_FLTP;
        d.audio->sample_rate = audio->sample_rate_hz;
        av_channel_layout_default(&d.audio->ch_layout, audio->channels);
        d.audio->bit_rate = settings.audio_bitrate_bps;
        d.audio->time_base = AVRational{1, audio->sample_rate_hz};
        d.audio->flags |= AV_CODEC_FLAG_BITEXACT;
        if (d.format->oformat->flags & AVFMT_GLOBALHEADER) d.audio->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
        check(avcodec_open2(d.audio, aac, nullptr), "opening the AAC encoder");
        d.audio_stream = avformat_new_stream(d.format, nullptr);
        d.audio_stream->time_base = d.audio->time_base;
        check(avcodec_parameters_from_context(d.audio_stream->codecpar, d.audio), "audio parameters");
    }

    check(avio_open(&d.format->pb, d.file->temp_path().c_str(), AVIO_FLAG_WRITE), "opening the output");
    check(avformat_write_header(d.format, nullptr), "writing the MP4 header");

    if (d.audio) {
        // The whole track up front, fitted to the video duration.
        const auto total = static_cast<std::size_t>(
            std::llround(static_cast<double>(frame_count) / settings.fps * audio->sample_rate_hz));
        const int channels = audio->channels;
        const int chunk = d.audio->frame_size > 0 ? d.audio->frame_size : 1024;
        for (std::size_t start = 0; start < total; start += static_cast<std::size_t>(chunk)) {
            const int n = static_cast<int>(std::min<std::size_t>(static_cast<std::size_t>(chunk), total - start));
            AVFrame* f = av_frame_alloc();
            f->nb_samples = n;
            f->format = AV_SAMPLE_FMT_FLTP;
            f->sample_rate = audio->sample_rate_hz;
            av_channel_layout_copy(&f->ch_layout, &d.audio->ch_layout);
            check(av_frame_get_buffer(f, 0), "audio frame");
            for (int c = 0; c < channels; ++c) {
                auto* dst = reinterpret_cast<float*>(f->data[c]);
                for (int i = 0; i < n; ++i) {
                    const std::size_t k = start + static_cast<std::size_t>(i);
                    dst[i] = k < audio->frames() ? audio->samples[k * static_cast<std::size_t>(channels) +
                                                                  static_cast<std::size_t>(c)]
                                                 : 0.0f;
                }
            }
            f->pts = static_cast<std::int64_t>(start);
            const int r = avcodec_send_frame(d.audio, f);
            av_frame_free(&f);
            check(r, "encoding audio");
            d.drain(d.audio, d.audio_stream);
        }
        check(avcodec_send_frame(d.audio, nullptr), "flushing audio");
        d.drain(d.audio, d.audio_stream);
    }

    d.frame->format = AV_PIX_FMT_YUV420P;
    d.frame->width = width;
    d.frame->height = height;
    check(av_frame_get_buffer(d.frame, 0), "video frame");
    d.previous_rgb.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 3);
}

VideoWriter::~VideoWriter() = default;

namespace {

// BT.601 limited range, 8-bit integer coefficients (×256).
inline std::uint8_t luma_601(int r, int g, int b) {
    return static_cast<std::uint8_t>(((66 * r + 129 * g + 25 * b + 128) >> 8) + 16);
}

// Converts pixels [x0, x1) (x0, x1 even) of the two RGB rows `top` and
// `bottom` (one row when bottom == top: an odd height's last row) into luma
// rows y_top / y_bottom and the chroma row u / v.
void rgb_to_yuv420_span(const std::uint8_t* top, const std::uint8_t* bottom, int x0, int x1, std::uint8_t* y_top,
                        std::uint8_t* y_bottom, std::uint8_t* u, std::uint8_t* v) {
    for (int x = x0; x < x1; x += 2) {
        const std::uint8_t* a = top + 3 * x;
        const std::uint8_t* b = bottom + 3 * x;
        y_top[x] = luma_601(a[0], a[1], a[2]);
        y_top[x + 1] = luma_601(a[3], a[4], a[5]);
        y_bottom[x] = luma_601(b[0], b[1], b[2]);
        y_bottom[x + 1] = luma_601(b[3], b[4], b[5]);
        // Chroma of the block mean: sums of four samples, so the ×256 scale becomes ×1024.
        const int r = a[0] + a[3] + b[0] + b[3], g = a[1] + a[4] + b[1] + b[4], bl = a[2] + a[5] + b[2] + b[5];
        u[x / 2] = static_cast<std::uint8_t>(((-38 * r - 74 * g + 112 * bl + 512) >> 10) + 128);
        v[x / 2] = static_cast<std::uint8_t>(((112 * r - 94 * g - 18 * bl + 512) >> 10) + 128);
    }
}

// The first and one-past-last byte where rows a and b (n bytes) differ; {n, n} when equal.
std::pair<std::size_t, std::size_t> differing_bytes(const std::uint8_t* a, const std::uint8_t* b, std::size_t n) {
    constexpr std::size_t block = 64;
    std::size_t first = 0;
    while (first < n && std::memcmp(a + first, b + first, std::min(block, n - first)) == 0) first += block;
    if (first >= n) return {n, n};
    while (a[first] == b[first]) ++first;
    std::size_t last = n;
    while (last - first > block && std::memcmp(a + last - block, b + last - block, block) == 0) last -= block;
    while (a[last - 1] == b[last - 1]) --last;
    return {first, last};
}

}  // namespace

void VideoWriter::write(const Image& image) {
    auto& d = *m_impl;
    AVSI_ASSERT(!d.finished && image.width == d.width && image.height == d.height &&
                image.rgb.size() == d.previous_rgb.size());
    // Keeps the data: the encoder may hold a reference, then this copies it.
    check(av_frame_make_writable(d.frame), "video frame");
    const std::size_t row_bytes = 3 * static_cast<std::size_t>(d.width);
    for (int y = 0; y < d.height; y += 2) {
        const int y2 = std::min(y + 1, d.height - 1);
        const std::uint8_t* top = image.pixel(0, y);
        const std::uint8_t* bottom = image.pixel(0, y2);
        std::uint8_t* prev_top = d.previous_rgb.data() + static_cast<std::size_t>(y) * row_bytes;
        std::uint8_t* prev_bottom = d.previous_rgb.data() + static_cast<std::size_t>(y2) * row_bytes;
        std::size_t first = 0, last = row_bytes;
        if (d.have_previous) {
            const auto [f0, l0] = differing_bytes(top, prev_top, row_bytes);
            const auto [f1, l1] = differing_bytes(bottom, prev_bottom, row_bytes);
            first = std::min(f0, f1);
            last = f0 == row_bytes ? l1 : f1 == row_bytes ? l0 : std::max(l0, l1);
            if (first >= last) continue;  // both rows unchanged
        }
        // Whole 2 × 2 blocks covering the changed bytes.
        const int x0 = static_cast<int>(first / 3) & ~1;
        const int x1 = std::min(d.width, (static_cast<int>((last + 2) / 3) + 1) & ~1);
        rgb_to_yuv420_span(top, bottom, x0, x1, d.frame->data[0] + static_cast<std::ptrdiff_t>(y) * d.frame->linesize[0],
                           d.frame->data[0] + static_cast<std::ptrdiff_t>(y2) * d.frame->linesize[0],
                           d.frame->data[1] + static_cast<std::ptrdiff_t>(y / 2) * d.frame->linesize[1],
                           d.frame->data[2] + static_cast<std::ptrdiff_t>(y / 2) * d.frame->linesize[2]);
        const std::size_t b0 = 3 * static_cast<std::size_t>(x0), b1 = 3 * static_cast<std::size_t>(x1);
        std::memcpy(prev_top + b0, top + b0, b1 - b0);
        if (y2 != y) std::memcpy(prev_bottom + b0, bottom + b0, b1 - b0);
    }
    d.have_previous = true;
    d.frame->pts = d.next_pts++;
    check(avcodec_send_frame(d.video, d.frame), "encoding video");
    d.drain(d.video, d.video_stream);
}

void VideoWriter::repeat_last() {
    auto& d = *m_impl;
    AVSI_ASSERT(!d.finished && d.next_pts > 0);
    // The encoder may still reference the frame's buffers: make them writable
    // (a copy when shared) before changing the timestamp.
    check(av_frame_make_writable(d.frame), "video frame");
    d.frame->pts = d.next_pts++;
    check(avcodec_send_frame(d.video, d.frame), "encoding video");
    d.drain(d.video, d.video_stream);
}

void VideoWriter::finish() {
    auto& d = *m_impl;
    if (d.finished) return;
    if (static_cast<std::size_t>(d.next_pts) != d.expected)
        throw std::runtime_error("VideoWriter: " + std::to_string(d.next_pts) + " frames written, " +
                                 std::to_string(d.expected) + " announced");
    check(avcodec_send_frame(d.video, nullptr), "flushing video");
    d.drain(d.video, d.video_stream);
    check(av_write_trailer(d.format), "writing the MP4 trailer");
    avio_closep(&d.format->pb);
    d.file->commit();
    d.finished = true;
}

DecodedVideo decode_video(const std::filesystem::path& path, bool keep_frames) {
    AVFormatContext* format = nullptr;
    if (avformat_open_input(&format, path.c_str(), nullptr, nullptr) < 0)
        throw InputError(path, "cannot open as a video file");
    struct Closer {
        AVFormatContext** f;
        ~Closer() { avformat_close_input(f); }
    } closer{&format};
    if (avformat_find_stream_info(format, nullptr) < 0) throw InputError(path, "cannot read stream information");
    const int vi = av_find_best_stream(format, AVMEDIA_TYPE_VIDEO, -1, -1, nullptr, 0);
    if (vi < 0) throw InputError(path, "no video stream");
    const int ai = av_find_best_stream(format, AVMEDIA_TYPE_AUDIO, -1, -1, nullptr, 0);

    auto open = [&](int index) {
        const AVCodecParameters* par = format->streams[index]->codecpar;
        const AVCodec* codec = avcodec_find_decoder(par->codec_id);
        if (!codec) throw InputError(path, "no decoder for stream " + std::to_string(index));
        AVCodecContext* ctx = avcodec_alloc_context3(codec);
        avcodec_parameters_to_context(ctx, par);
        ctx->thread_count = 1;
        ctx->pkt_timebase = format->streams[index]->time_base;
        if (avcodec_open2(ctx, codec, nullptr) < 0) throw InputError(path, "cannot open the decoder");
        return ctx;
    };
    DecodedVideo out;
    AVCodecContext* vdec = open(vi);
    AVCodecContext* adec = ai >= 0 ? open(ai) : nullptr;
    const AVStream* vs = format->streams[vi];
    out.width = vdec->width;
    out.height = vdec->height;
    out.fps = av_q2d(vs->r_frame_rate);
    out.video_codec = avcodec_get_name(vdec->codec_id);
    out.pixel_format = av_get_pix_fmt_name(vdec->pix_fmt) ? av_get_pix_fmt_name(vdec->pix_fmt) : "";
    if (adec) {
        out.has_audio = true;
        out.audio.sample_rate_hz = adec->sample_rate;
        out.audio.channels = adec->ch_layout.nb_channels;
    }
    SwsContext* sws = nullptr;
    AVPacket* packet = av_packet_alloc();
    AVFrame* frame = av_frame_alloc();
    bool first_video = true, first_audio = true;

    auto receive = [&](AVCodecContext* ctx, bool is_video) {
        while (avcodec_receive_frame(ctx, frame) == 0) {
            const AVStream* st = format->streams[is_video ? vi : ai];
            const std::int64_t pts = frame->best_effort_timestamp;
            if (is_video) {
                if (first_video) out.video_start_s = pts * av_q2d(st->time_base), first_video = false;
                ++out.frame_count;
                if (keep_frames) {
                    if (!sws)
                        sws = sws_getContext(frame->width, frame->height, static_cast<AVPixelFormat>(frame->format),
                                             frame->width, frame->height, AV_PIX_FMT_RGB24, SWS_BILINEAR, nullptr,
                                             nullptr, nullptr);
                    Image image;
                    image.width = frame->width;
                    image.height = frame->height;
                    image.rgb.resize(static_cast<std::size_t>(frame->width) * static_cast<std::size_t>(frame->height) * 3);
                    std::uint8_t* dst[1] = {image.rgb.data()};
                    const int stride[1] = {3 * frame->width};
                    sws_scale(sws, frame->data, frame->linesize, 0, frame->height, dst, stride);
                    out.frames.push_back(std::move(image));
                }
            } else {
                if (first_audio) out.audio_start_s = pts * av_q2d(st->time_base), first_audio = false;
                const int channels = frame->ch_layout.nb_channels;
                for (int i = 0; i < frame->nb_samples; ++i)
                    for (int c = 0; c < channels; ++c) {
                        float v = 0.0f;
                        if (frame->format == AV_SAMPLE_FMT_FLTP) v = reinterpret_cast<const float*>(frame->data[c])[i];
                        else if (frame->format == AV_SAMPLE_FMT_FLT)
                            v = reinterpret_cast<const float*>(frame->data[0])[i * channels + c];
                        else if (frame->format == AV_SAMPLE_FMT_S16)
                            v = reinterpret_cast<const std::int16_t*>(frame->data[0])[i * channels + c] / 32768.0f;
                        out.audio.samples.push_back(v);
                    }
            }
            av_frame_unref(frame);
        }
    };
    while (av_read_frame(format, packet) >= 0) {
        if (packet->stream_index == vi) {
            avcodec_send_packet(vdec, packet);
            receive(vdec, true);
        } else if (packet->stream_index == ai && adec) {
            avcodec_send_packet(adec, packet);
            receive(adec, false);
        }
        av_packet_unref(packet);
    }
    avcodec_send_packet(vdec, nullptr);
    receive(vdec, true);
    if (adec) {
        avcodec_send_packet(adec, nullptr);
        receive(adec, false);
    }
    if (adec) {
        // The last AAC frame is padded to 1024 samples; the track's declared
        // duration (the MP4 edit list) says how many samples are real.
        const AVStream* as = format->streams[ai];
        if (as->duration != AV_NOPTS_VALUE && out.audio.channels > 0) {
            const auto keep = static_cast<std::size_t>(std::llround(
                static_cast<double>(as->duration) * av_q2d(as->time_base) * out.audio.sample_rate_hz));
            if (keep < out.audio.frames())
                out.audio.samples.resize(keep * static_cast<std::size_t>(out.audio.channels));
        }
    }
    out.video_duration_s = out.fps > 0 ? static_cast<double>(out.frame_count) / out.fps : 0.0;
    if (sws) sws_freeContext(sws);
    av_frame_free(&frame);
    av_packet_free(&packet);
    avcodec_free_context(&vdec);
    avcodec_free_context(&adec);
    return out;
}

}  // namespace avsi::stimuli
