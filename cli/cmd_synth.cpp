// `avsi synth`: phones (a label file, or text through espeak-ng or Festival) → control
// model → articulatory trajectory (CSV or MPEG-4 FAP), optionally with an
// SVG plot of one parameter's dominance functions and trajectory.
#include <filesystem>
#include <memory>
#include <string>

#include "avsi/synth/synthesis.h"
#include "command.h"
#include "one_of.h"
#include "synth_choices.h"

namespace avsi::cli {
namespace {

const bool registered_synth = register_command({
    "synth",
    "Phones or text to articulatory parameter trajectories with a control model",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<synth::SynthesisSettings>();
        o->model_path = std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "cohen-massaro.json";
        sub.add_option("--model", o->model_path,
                       "Model file (JSON: rule, cohen-massaro, mpeg4-cohen-massaro or ohman)")
            ->capture_default_str();
        sub.add_option("--phones", o->phones_path, "Timed phones: .tsv, .TextGrid or .lab")->capture_default_str();
        sub.add_option("--text", o->text, "Text to synthesise (instead of --phones; see --tts)")
            ->capture_default_str();
        CLI::Option* tts = sub.add_option("--tts", o->tts,
                                          "Synthesiser and voice for --text: espeak:<voice> (en-us, en, en-gb-x-rp, "
                                          "...) or festival:<voice> (cmu_us_slt_arctic_hts, kal_diphone); avsi phones "
                                          "--list-voices shows the installed ones")
                               ->capture_default_str();
        auto voice = std::make_shared<std::string>();
        CLI::Option* voice_option =
            sub.add_option("--voice", *voice, "An espeak-ng voice for --text; the same as --tts espeak:<voice>");
        voice_option->excludes(tts);
        sub.add_option("--wav", o->wav_path, "Write the synthesised speech here (with --text)")
            ->capture_default_str();
        auto* fps = sub.add_option("--fps", o->fps, "Frame rate of the trajectory")->capture_default_str();
        sub.add_option("--out", o->out_path, "Output trajectory (.csv or .fap)")->required()->capture_default_str();
        sub.add_option("--format", o->format, "Output format: csv, fap, or auto (by --out extension)")
            ->capture_default_str()
            ->check(one_of({"csv", "fap", "auto"}));
        sub.add_option("--target", o->fap_target,
                       "FAP output for: mpeg4 (68 mask entries, Xface and MPEG-4 players) or greta (25 fps, "
                       "Greta's 69-entry masks; Greta plays every file at 25 fps)")
            ->capture_default_str()
            ->check(one_of({"mpeg4", "greta"}));
        sub.add_option("--plot", o->plot_path, "Write an SVG plot of one parameter here")->capture_default_str();
        sub.add_option("--param", o->plot_param, "Parameter to plot (snake_case name)")
            ->capture_default_str()
            ->check(one_of(param_names()));
        return [o, fps, voice] {
            o->fps_given = fps->count() > 0;
            if (!voice->empty()) o->tts = "espeak:" + *voice;
            synth::run_synthesis(*o);
            return 0;
        };
    }});

}  // namespace
}  // namespace avsi::cli
