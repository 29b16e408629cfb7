// `avsi render` and `avsi contact-sheet` (see commands.h).
#include "avsi/stimuli/commands.h"

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/stimuli/image_io.h"
#include "avsi/synth/fap.h"

namespace avsi::stimuli {

void run_render(const RenderJobSettings& s) {
    if (s.trajectory_path.empty() == s.fap_path.empty())
        throw UsageError("give exactly one of --traj and --fap");
    if (s.out_path.empty()) throw UsageError("--out is required");
    const synth::Trajectory trajectory = s.fap_path.empty()
                                             ? synth::read_trajectory_csv(s.trajectory_path)
                                             : synth::decode_fap_file(s.fap_path);
    Audio audio;
    if (!s.audio_path.empty()) audio = read_audio(s.audio_path);
    const Head head = load_head(s.head.obj, s.head.rig);
    RenderSettings rs = s.render;
    rs.camera = camera_view_from_name(s.camera);
    OffscreenRenderer renderer(head, rs);
    const bool video = s.out_path.extension() == ".mp4";
    const bool folder = s.out_path.extension().empty();
    if (!video && !folder)
        throw InputError(s.out_path, "expected an .mp4 file or a folder for PNG frames, got extension '" +
                                         s.out_path.extension().string() + "'");
    if (video) {
        const auto n = render_video(renderer, trajectory, s.audio_path.empty() ? nullptr : &audio, s.out_path,
                                    s.blinks, s.video);
        log_info("wrote {} ({} frames at {} fps)", s.out_path.string(), n, trajectory.fps);
    } else {
        if (!s.audio_path.empty()) log_warning("--audio is not used for a PNG sequence");
        const auto n = render_png_sequence(renderer, trajectory, s.out_path, s.blinks);
        log_info("wrote {} PNG frames to {}", n, s.out_path.string());
    }
}

void run_contact_sheet(const ContactSheetJobSettings& s) {
    if (s.out_path.empty()) throw UsageError("--out is required");
    const Head head = load_head(s.head.obj, s.head.rig);
    ContactSheetSettings sheet = s.sheet;
    sheet.camera = camera_view_from_name(s.camera);
    write_png(s.out_path, render_contact_sheet(head, read_sheet_targets(s.targets_path), sheet));
    log_info("wrote {}", s.out_path.string());
}

}  // namespace avsi::stimuli
