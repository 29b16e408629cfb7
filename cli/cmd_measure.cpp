// `avsi measure`: geometric articulation measures (lip aperture, mouth width,
// lip protrusion, jaw opening, lower lip to upper incisors) of every frame of
// a trajectory, FAP stream or model output on a head, in millimetres; with
// phones, the phonetic constraints of the stimuli (lip closure in /p b m/,
// labiodental contact in /f v/, no interpenetration, rounding).
#include <memory>

#include <fmt/format.h>

#include "avsi/core/log.h"
#include "avsi/stimuli/commands.h"
#include "command.h"
#include "head_options.h"

namespace avsi::cli {
namespace {

const bool registered_measure = register_command({
    "measure",
    "Measure lip aperture, mouth width, protrusion and jaw opening per frame (mm) and check the articulation",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<stimuli::MeasureJobSettings>();
        auto check = std::make_shared<bool>(false);
        sub.footer(
            "Give exactly one source: --traj, --fap, or --model with --phones (or --text). With phones the\n"
            "constraints are checked and summarised: the lips close (central-third aperture <= 0.5 mm) at a\n"
            "sampled frame of every /p b m/ segment, the lower lip comes within 2 mm of the upper incisors in\n"
            "every /f v/, no frame has the lips passing through each other, and /uw w/ are narrower and more\n"
            "protruded than /iy/; in Swedish, /y:/ (YY) protrudes beyond /i:/ (IY) and /u-/ (UX) is narrower than\n"
            "/i:/ without /y:/'s protrusion. The head's rig must name the landmark vertices (its \"articulation\"\n"
            "section).");
        sub.add_option("--traj", o->trajectory_path, "Trajectory CSV (time_s,<param>…)");
        sub.add_option("--fap", o->fap_path, "MPEG-4 FAP v2.1 file");
        sub.add_option("--model", o->model_path, "Control model file (JSON), driven by --phones or --text");
        sub.add_option("--phones", o->phones_path,
                       "Timed phones (.tsv, .TextGrid, .lab): the model's input, or the labels of --traj/--fap for "
                       "the checks and the plot");
        sub.add_option("--text", o->text, "Text through the TTS front end (with --model)");
        sub.add_option("--tts", o->tts, "Synthesiser and voice of --text (espeak:sv, festival:<voice>)")
            ->capture_default_str();
        sub.add_option("--fps", o->fps, "Frame rate of the model's trajectory")->capture_default_str();
        sub.add_option("--out", o->out_path, "Measures CSV, one row per frame")->required();
        sub.add_option("--plot", o->plot_path, "SVG plot of the lip aperture over time with the phone labels");
        add_head_options(sub, o->head);
        sub.add_option("--closure-mm", o->limits.closure_mm, "Largest aperture that counts as closed")
            ->capture_default_str();
        sub.add_option("--labiodental-mm", o->limits.labiodental_mm,
                       "Largest lower-lip to upper-incisor distance that counts as contact")
            ->capture_default_str();
        sub.add_flag("--check", *check, "Exit with status 1 when a constraint is broken");
        return [o, check] {
            const auto r = stimuli::run_measure(*o);
            log_info("wrote {} ({} frames)", o->out_path.string(), r.frames);
            if (!r.checked) return 0;
            const auto& s = r.summary;
            fmt::print("bilabials closed {} of {}; labiodentals reached {} of {}; aperture {:.2f} to {:.2f} mm\n",
                       s.bilabials_closed, s.bilabials, s.labiodentals_reached, s.labiodentals, s.aperture_min_mm,
                       s.aperture_max_mm);
            if (s.rounding_checked)
                fmt::print("rounding: /uw w/ width {:.1f} mm, protrusion {:.2f} mm; /iy/ width {:.1f} mm, protrusion "
                           "{:.2f} mm\n",
                           s.width_rounded_mm, s.protrusion_rounded_mm, s.width_spread_mm, s.protrusion_spread_mm);
            if (s.close_front_checked)
                fmt::print("close front vowels: /iː/ width {:.1f} mm, protrusion {:.2f} mm; /yː/ width {:.1f} mm, "
                           "protrusion {:.2f} mm; /ʉː/ width {:.1f} mm, protrusion {:.2f} mm\n",
                           s.spread_iy.width_mm, s.spread_iy.protrusion_mm, s.outrounded_yy.width_mm,
                           s.outrounded_yy.protrusion_mm, s.inrounded_ux.width_mm, s.inrounded_ux.protrusion_mm);
            for (const auto& p : s.problems(o->limits)) fmt::print("problem: {}\n", p);
            return *check && s.violations() > 0 ? 1 : 0;
        };
    }});

}  // namespace
}  // namespace avsi::cli
