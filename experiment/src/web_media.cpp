// What a stimulus file holds, read through libavformat (see web_study.h), for
// the web export's browser check. Browsers play H.264 Constrained Baseline /
// Baseline 4:2:0 with AAC-LC in MP4 everywhere (the builder's x264
// "ultrafast" preset gives exactly that); other files are transcoded.
#include <memory>

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/pixdesc.h>
}

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/experiment/web_study.h"

namespace avsi::experiment {

bool MediaProbe::browser_ready() const {
    const bool mp4 = container.find("mp4") != std::string::npos;
    const bool video = video_codec == "h264" && (video_profile == "Constrained Baseline" || video_profile == "Baseline") &&
                       pixel_format == "yuv420p" && width % 2 == 0 && height % 2 == 0;
    const bool audio = audio_codec.empty() || (audio_codec == "aac" && audio_profile == "LC");
    return mp4 && video && audio;
}

std::string MediaProbe::describe() const {
    std::string out = fmt::format("video {} {} {} {}x{}", video_codec.empty() ? "none" : video_codec, video_profile,
                                  pixel_format, width, height);
    out += audio_codec.empty() ? ", no audio" : fmt::format(", audio {} {}", audio_codec, audio_profile);
    return out;
}

MediaProbe probe_media(const std::filesystem::path& path) {
    av_log_set_level(AV_LOG_ERROR);
    AVFormatContext* format = nullptr;
    if (avformat_open_input(&format, path.c_str(), nullptr, nullptr) < 0)
        throw InputError(path, "cannot open the media file (missing, or not a format FFmpeg reads)");
    std::unique_ptr<AVFormatContext, void (*)(AVFormatContext*)> guard(format, [](AVFormatContext* f) {
        avformat_close_input(&f);
    });
    if (avformat_find_stream_info(format, nullptr) < 0) throw InputError(path, "cannot read the media file's streams");
    MediaProbe probe;
    probe.container = format->iformat->name;
    for (unsigned i = 0; i < format->nb_streams; ++i) {
        const AVCodecParameters* p = format->streams[i]->codecpar;
        const char* profile = avcodec_profile_name(p->codec_id, p->profile);
        if (p->codec_type == AVMEDIA_TYPE_VIDEO && probe.video_codec.empty()) {
            probe.video_codec = avcodec_get_name(p->codec_id);
            probe.video_profile = profile ? profile : "";
            const char* pix = av_get_pix_fmt_name(static_cast<AVPixelFormat>(p->format));
            probe.pixel_format = pix ? pix : "";
            probe.width = p->width;
            probe.height = p->height;
        } else if (p->codec_type == AVMEDIA_TYPE_AUDIO && probe.audio_codec.empty()) {
            probe.audio_codec = avcodec_get_name(p->codec_id);
            probe.audio_profile = profile ? profile : "";
        }
    }
    if (probe.video_codec.empty()) throw InputError(path, "the stimulus has no video stream");
    return probe;
}

}  // namespace avsi::experiment
