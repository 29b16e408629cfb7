// `avsi render` and `avsi contact-sheet` (see commands.h).
#include "avsi/stimuli/commands.h"

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/labels.h"
#include "avsi/core/tts.h"
#include "avsi/core/log.h"
#include "avsi/core/rng.h"
#include "avsi/stimuli/gltf_head.h"
#include "avsi/stimuli/image_io.h"
#include "avsi/synth/control_model.h"
#include "avsi/synth/fap.h"

namespace avsi::stimuli {

Head load_head_files(const HeadFiles& files) {
    if (files.gltf.empty()) return load_head(files.obj, files.rig);
    return load_gltf_head(files.gltf, files.mapping.empty() ? default_blendshape_mapping() : files.mapping);
}

void run_export_head(const ExportHeadSettings& s) {
    if (s.out_path.empty()) throw UsageError("--out is required");
    if (s.out_path.extension() != ".glb" && s.out_path.extension() != ".gltf")
        throw UsageError("--out: expected a .glb or .gltf file, got '" + s.out_path.string() + "'");
    const Head head = load_head_files(s.head);
    export_gltf_head(head, s.out_path, s.head.mapping.empty() ? default_blendshape_mapping() : s.head.mapping);
    log_info("wrote {}", s.out_path.string());
}

void run_render(const RenderJobSettings& s) {
    if (s.trajectory_path.empty() == s.fap_path.empty())
        throw UsageError("give exactly one of --traj and --fap");
    if (s.out_path.empty()) throw UsageError("--out is required");
    const synth::Trajectory trajectory = s.fap_path.empty()
                                             ? synth::read_trajectory_csv(s.trajectory_path)
                                             : synth::decode_fap_file(s.fap_path);
    Audio audio;
    if (!s.audio_path.empty()) audio = read_audio(s.audio_path);
    const Head head = load_head_files(s.head);
    RenderSettings rs = s.render;
    rs.camera = camera_view_from_name(s.camera);
    OffscreenRenderer renderer(head, rs);
    if (const LodResult* lod = renderer.lod())
        log_info("level of detail ({}): {} of the head's {} triangles, {} kept at full detail; simplification error "
                 "{:.3f} mm",
                 lod->chosen_by == "max_triangles" ? "--max-triangles"
                 : lod->chosen_by == "auto"        ? fmt::format("auto, level {}", lod->level)
                                                   : fmt::format("level {}", lod->level),
                 lod->triangles, lod->full_triangles, lod->kept_triangles, lod->error_mm);
    PhoneSequence phones;
    if (!s.phones_path.empty()) phones = read_phones(s.phones_path);
    const PhoneSequence* tongue = s.phones_path.empty() ? nullptr : &phones;
    const bool video = s.out_path.extension() == ".mp4";
    const bool folder = s.out_path.extension().empty();
    if (!video && !folder)
        throw InputError(s.out_path, "expected an .mp4 file or a folder for PNG frames, got extension '" +
                                         s.out_path.extension().string() + "'");
    if (!s.layers_path.empty()) {
        LayerSettings layers = read_layer_settings(s.layers_path);
        // --no-blinks drops the blink layer; --blink-seed seeds it.
        if (!s.blinks.enabled)
            std::erase_if(layers.layers, [](const LayerSpec& l) { return l.kind == LayerKind::Blink; });
        LayerSeeds seeds;
        seeds.blink = s.blinks.seed;
        seeds.gaze = derive_seed(s.layer_seed, "gaze");
        seeds.head = derive_seed(s.layer_seed, "head-motion");
        const Animation animation = animate(head, trajectory, tongue, layers, seeds);
        for (const auto& w : animation.warnings) log_warning("{}: {}", s.layers_path.string(), w);
        const auto n = video ? render_pose_video(renderer, animation.poses, trajectory.fps,
                                                 s.audio_path.empty() ? nullptr : &audio, s.out_path, s.video)
                             : render_pose_png_sequence(renderer, animation.poses, s.out_path);
        log_info("wrote {} ({} frames at {} fps, layers {})", s.out_path.string(), n, trajectory.fps,
                 animation.record_json);
    } else if (video) {
        const auto n = render_video(renderer, trajectory, s.audio_path.empty() ? nullptr : &audio, s.out_path,
                                    s.blinks, s.video, tongue);
        log_info("wrote {} ({} frames at {} fps)", s.out_path.string(), n, trajectory.fps);
    } else {
        if (!s.audio_path.empty()) log_warning("--audio is not used for a PNG sequence");
        const auto n = render_png_sequence(renderer, trajectory, s.out_path, s.blinks, tongue);
        log_info("wrote {} PNG frames to {}", n, s.out_path.string());
    }
}

MeasureResult run_measure(const MeasureJobSettings& s) {
    const int sources = int(!s.trajectory_path.empty()) + int(!s.fap_path.empty()) + int(!s.model_path.empty());
    if (sources != 1) throw UsageError("give exactly one of --traj, --fap and --model");
    if (s.out_path.empty()) throw UsageError("--out is required");
    if (!s.model_path.empty() && s.phones_path.empty() == s.text.empty())
        throw UsageError("--model needs exactly one of --phones and --text");
    if (!s.text.empty() && s.model_path.empty()) throw UsageError("--text needs --model");
    if (!(s.fps > 0 && s.fps <= 1000)) throw UsageError("--fps: expected a frame rate in (0, 1000]");
    const Head head = load_head_files(s.head);
    const ArticulationMeter meter(head);  // fails early, naming missing landmarks

    PhoneSequence phones;
    if (!s.text.empty()) {
        TtsSettings tts;
        set_tts_voice(tts, s.tts, "--tts");
        phones = synthesize_speech(s.text, tts).phones;
    } else if (!s.phones_path.empty()) {
        phones = read_phones(s.phones_path);
    }
    synth::Trajectory trajectory;
    if (!s.model_path.empty()) trajectory = synth::load_model(s.model_path)->synthesize(phones, s.fps);
    else if (!s.fap_path.empty()) trajectory = synth::fap_to_trajectory(synth::read_fap(s.fap_path));
    else trajectory = synth::read_trajectory_csv(s.trajectory_path);

    MeasureResult result;
    const auto measures = meter.measure(trajectory);
    result.frames = measures.size();
    write_articulation_csv(s.out_path, measures);
    if (!phones.empty()) {
        result.checked = true;
        result.summary = check_articulation(phones, trajectory.fps, measures, s.limits);
    }
    if (!s.plot_path.empty())
        write_aperture_plot(s.plot_path, s.out_path.stem().string(), phones, measures, result.summary, s.limits);
    return result;
}

void run_contact_sheet(const ContactSheetJobSettings& s) {
    if (s.out_path.empty()) throw UsageError("--out is required");
    const Head head = load_head_files(s.head);
    ContactSheetSettings sheet = s.sheet;
    sheet.camera = camera_view_from_name(s.camera);
    write_png(s.out_path, render_contact_sheet(head, read_sheet_targets(s.targets_path), sheet));
    log_info("wrote {}", s.out_path.string());
}

}  // namespace avsi::stimuli
