// `avsi render`: a trajectory (CSV) or FAP stream → the talking head → MP4
// (muxed with optional audio) or a folder of PNG frames.
#include <memory>
#include <string>

#include "avsi/stimuli/commands.h"
#include "command.h"
#include "head_options.h"
#include "lod_options.h"
#include "one_of.h"

namespace avsi::cli {
namespace {

const bool registered_render = register_command({
    "render",
    "Render the talking head from a trajectory or FAP file to MP4 or PNG frames",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<stimuli::RenderJobSettings>();
        sub.add_option("--traj", o->trajectory_path, "Trajectory CSV (time_s,<param>…)")->capture_default_str();
        sub.add_option("--fap", o->fap_path, "MPEG-4 FAP v2.1 file (instead of --traj)")->capture_default_str();
        sub.add_option("--audio", o->audio_path, "Audio (WAV/FLAC) muxed into the MP4")->capture_default_str();
        sub.add_option("--out", o->out_path, "Output: x.mp4, or a folder for PNG frames")->required();
        sub.add_option("--phones", o->phones_path,
                       "Timed phones (.tsv/.TextGrid/.lab): the tongue tip rises for /θ ð t d n l/");
        add_head_options(sub, o->head);
        sub.add_option("--width", o->render.width, "Frame width in pixels")->capture_default_str();
        sub.add_option("--height", o->render.height, "Frame height in pixels")->capture_default_str();
        sub.add_option("--camera", o->camera, "Camera: front or three-quarter")
            ->capture_default_str()
            ->check(one_of({"front", "three-quarter"}));
        sub.add_option("--samples", o->render.samples, "MSAA samples per pixel (1 = off; 4 costs many times a frame on llvmpipe)")
            ->capture_default_str();
        sub.add_flag("!--no-fxaa", o->render.fxaa, "Do not anti-alias with FXAA");
        sub.add_flag("--per-pixel-lighting", o->render.per_pixel_lighting,
                     "Light per pixel instead of per vertex (~1.6x per frame)")
            ->capture_default_str();
        const auto parse_lod = add_lod_options(sub, o->render.lod);
        sub.add_option("--crf", o->video.crf, "x264 constant rate factor")->capture_default_str();
        sub.add_option("--blink-seed", o->blinks.seed, "Seed of the blink times")->capture_default_str();
        sub.add_flag("!--no-blinks", o->blinks.enabled, "Do not blink");
        sub.add_option("--layers", o->layers_path,
                       "Animation layers: a TOML file with a [layers] table (gaze, head motion, expressions, FAP "
                       "streams; docs/animation-layers.md)");
        sub.add_option("--layer-seed", o->layer_seed, "Seed of the gaze and idle head-motion layers")->capture_default_str();
        return [o, parse_lod] {
            parse_lod();
            stimuli::run_render(*o);
            return 0;
        };
    }});

}  // namespace
}  // namespace avsi::cli
