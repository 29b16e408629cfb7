// `avsi synth` / `avsi fap2traj` as library calls, and the SVG inspection
// plot (dominance functions and trajectory, as in Fig. 2 of the Beskow paper
// and Fig. 4–5 of the Charisma paper). The SVG is written as text.
#include "avsi/synth/synthesis.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include <fmt/format.h>

#include "avsi/core/audio.h"
#include "avsi/core/checks.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/labels.h"
#include "avsi/core/log.h"
#include "avsi/core/text.h"
#include "avsi/core/tts.h"
#include "avsi/synth/cohen_massaro.h"

namespace avsi::synth {

namespace {

std::string xml_escape(std::string_view s) {
    std::string out;
    for (char c : s) {
        switch (c) {
            case '<': out += "&lt;"; break;
            case '>': out += "&gt;"; break;
            case '&': out += "&amp;"; break;
            case '"': out += "&quot;"; break;
            default: out += c;
        }
    }
    return out;
}

const char* const palette[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                               "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};

double nice_step(double span, int target_ticks) {
    const double raw = span / target_ticks;
    const double mag = std::pow(10.0, std::floor(std::log10(raw)));
    for (double m : {1.0, 2.0, 5.0, 10.0})
        if (raw <= m * mag) return m * mag;
    return 10.0 * mag;
}

}  // namespace

std::string synthesis_plot_svg(const ControlModel& model, const PhoneSequence& phones, Param param, double fps,
                               const PlotSettings& settings) {
    check_phones_for_synthesis(phones);
    const ParamInfo& info = param_info(param);
    const double end_s = phones.back().end_s;
    const auto* dominance_model = dynamic_cast<const DominanceModel*>(&model);

    const double w = settings.width_px, h = settings.height_px;
    const double left = 70, right = 20, top = 40, bottom = 60, gap = 40;
    const double plot_w = w - left - right;
    const double avail = h - top - bottom;
    const double dom_h = dominance_model ? (avail - gap) * 0.45 : 0.0;
    const double traj_top = dominance_model ? top + dom_h + gap : top;
    const double traj_h = dominance_model ? avail - dom_h - gap : avail;
    auto x_of = [&](double t) { return left + plot_w * t / end_s; };

    std::string svg = fmt::format(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" viewBox=\"0 0 {0} {1}\" "
        "font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n",
        w, h);
    svg += fmt::format("<text x=\"{}\" y=\"22\" font-size=\"15\">{} model — {} at {} fps</text>\n", left,
                       xml_escape(model.kind()), xml_escape(info.name), fps);

    // Sample times for the curves.
    const std::size_t n_samples = std::max<std::size_t>(2, static_cast<std::size_t>(end_s * settings.sample_fps) + 1);
    std::vector<double> ts(n_samples);
    for (std::size_t k = 0; k < n_samples; ++k) ts[k] = end_s * static_cast<double>(k) / double(n_samples - 1);

    // Segment boundaries in both panels.
    auto boundaries = [&](double y0, double y1) {
        for (const auto& p : phones)
            svg += fmt::format("<line x1=\"{0:.2f}\" y1=\"{1:.2f}\" x2=\"{0:.2f}\" y2=\"{2:.2f}\" stroke=\"#bbb\" "
                               "stroke-dasharray=\"3,3\"/>\n",
                               x_of(p.start_s), y0, y1);
        svg += fmt::format("<line x1=\"{0:.2f}\" y1=\"{1:.2f}\" x2=\"{0:.2f}\" y2=\"{2:.2f}\" stroke=\"#bbb\" "
                           "stroke-dasharray=\"3,3\"/>\n",
                           x_of(end_s), y0, y1);
    };
    auto frame_rect = [&](double y0, double height, const std::string& label) {
        svg += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"black\"/>\n", left,
                           y0, plot_w, height);
        svg += fmt::format("<text transform=\"translate({:.1f},{:.1f}) rotate(-90)\" text-anchor=\"middle\">{}</text>\n",
                           18.0, y0 + height / 2, xml_escape(label));
    };

    if (dominance_model) {
        // Top panel: each segment's D_i(t).
        const auto segs = dominance_model->segments(phones, param);
        double peak = 0.0;
        for (const auto& s : segs) peak = std::max(peak, s.alpha);
        frame_rect(top, dom_h, "dominance D(t)");
        boundaries(top, top + dom_h);
        for (double v : {0.0, peak / 2, peak}) {
            const double y = top + dom_h * (1.0 - v / peak);
            svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"end\">{:.2g}</text>\n", left - 5, y + 4, v);
        }
        for (std::size_t i = 0; i < segs.size(); ++i) {
            std::string points;
            for (double t : ts)
                points += fmt::format("{:.2f},{:.2f} ", x_of(t), top + dom_h * (1.0 - dominance(segs[i], t) / peak));
            svg += fmt::format("<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\" points=\"{}\"/>\n",
                               palette[i % std::size(palette)], points);
        }
    }

    // Bottom panel: the trajectory (dense curve), frames at fps, targets.
    const double lo = info.min, hi = info.max;
    auto y_of = [&](double v) { return traj_top + traj_h * (1.0 - (v - lo) / (hi - lo)); };
    frame_rect(traj_top, traj_h, std::string(info.name));
    boundaries(traj_top, traj_top + traj_h);
    for (double v : {lo, info.neutral, hi})
        svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"end\">{:.2g}</text>\n", left - 5, y_of(v) + 4, v);
    svg += fmt::format("<line x1=\"{}\" y1=\"{:.2f}\" x2=\"{}\" y2=\"{:.2f}\" stroke=\"#ddd\"/>\n", left,
                       y_of(info.neutral), left + plot_w, y_of(info.neutral));
    std::vector<Frame> dense;
    model.evaluate(phones, ts, dense);
    std::string points;
    for (std::size_t k = 0; k < ts.size(); ++k)
        points += fmt::format("{:.2f},{:.2f} ", x_of(ts[k]), y_of(std::clamp(dense[k][index(param)], lo, hi)));
    svg += fmt::format("<polyline fill=\"none\" stroke=\"black\" stroke-width=\"1.5\" points=\"{}\"/>\n", points);
    const Trajectory sampled = model.synthesize(phones, fps);
    for (std::size_t k = 0; k < sampled.size(); ++k)
        svg += fmt::format("<circle cx=\"{:.2f}\" cy=\"{:.2f}\" r=\"1.8\" fill=\"#d62728\"/>\n", x_of(sampled.time_s(k)),
                           y_of(std::clamp(sampled.value(k, param), lo, hi)));
    if (dominance_model) {
        const auto segs = dominance_model->segments(phones, param);
        for (std::size_t i = 0; i < segs.size(); ++i) {
            const double x = x_of(segs[i].tau_s);
            svg += fmt::format("<line x1=\"{:.2f}\" y1=\"{:.2f}\" x2=\"{:.2f}\" y2=\"{:.2f}\" stroke=\"{}\" "
                               "stroke-width=\"3\"/>\n",
                               x - 6, y_of(segs[i].target), x + 6, y_of(segs[i].target),
                               palette[i % std::size(palette)]);
        }
    }

    // Time axis: phone labels at centres, ticks in seconds.
    const double axis_y = traj_top + traj_h;
    for (const auto& p : phones)
        svg += fmt::format("<text x=\"{:.2f}\" y=\"{:.1f}\" text-anchor=\"middle\" font-weight=\"bold\">{}</text>\n",
                           x_of(p.centre_s()), axis_y + 16, xml_escape(p.symbol));
    const double step = nice_step(end_s, 10);
    for (double t = 0.0; t <= end_s + 1e-9; t += step)
        svg += fmt::format("<text x=\"{:.2f}\" y=\"{:.1f}\" text-anchor=\"middle\" fill=\"#555\">{:g}</text>\n", x_of(t),
                           axis_y + 34, std::round(t / step) * step);
    svg += fmt::format("<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"middle\">time (s)</text>\n", left + plot_w / 2,
                       axis_y + 52);
    svg += "</svg>\n";
    return svg;
}

void run_synthesis(const SynthesisSettings& s) {
    const bool have_phones = !s.phones_path.empty(), have_text = !s.text.empty();
    if (have_phones == have_text)
        throw UsageError("give exactly one of --phones FILE and --text \"…\"");
    if (s.out_path.empty()) throw UsageError("--out is required");
    if (!s.wav_path.empty() && !have_text) throw UsageError("--wav needs --text (it writes the TTS audio)");
    std::string format = ascii_lower(s.format);
    if (format == "auto") format = ascii_lower(s.out_path.extension().string()) == ".fap" ? "fap" : "csv";
    if (format != "csv" && format != "fap")
        throw UsageError(fmt::format("--format: expected csv, fap or auto, got \"{}\"", s.format));
    if (s.fap_target != "mpeg4" && s.fap_target != "greta")
        throw UsageError(fmt::format("--target: expected mpeg4 or greta, got \"{}\"", s.fap_target));
    const bool greta = s.fap_target == "greta";
    if (greta && format != "fap") throw UsageError("--target greta writes a FAP file: give --out x.fap (or --format fap)");
    // Greta plays every FAP file at 25 fps: synthesise at 25.
    if (greta && s.fps_given && std::abs(s.fps - 25.0) > 1e-9)
        throw UsageError(fmt::format("--target greta: Greta plays FAP files at 25 fps, got --fps {}", s.fps));
    const double fps = greta ? 25.0 : s.fps;
    const auto plot_param = param_from_name(s.plot_param);
    if (!s.plot_path.empty() && !plot_param) {
        std::vector<std::string> names;
        for (const auto& info : params()) names.emplace_back(info.name);
        const std::string guess = closest_match(s.plot_param, names);
        throw UsageError(fmt::format("--param: unknown parameter \"{}\"{}", s.plot_param,
                                     guess.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", guess)));
    }

    // An espeak-ng voice speaks the text in its own process while the model
    // loads: most of what `synth --text` takes is espeak-ng's (its library,
    // its voice files, the child process). A Festival voice speaks in get().
    // A bad --tts or empty text is refused first; then a bad model, before
    // anything the utterance itself gets wrong (an unknown voice).
    std::optional<PendingSpeech> speaking;
    if (have_text) {
        TtsSettings tts;
        set_tts_voice(tts, s.tts, "--tts");
        speaking.emplace(start_speech(s.text, tts));
    }
    const auto model = load_model(s.model_path);
    PhoneSequence phones;
    if (have_phones) {
        phones = read_phones(s.phones_path);
    } else {
        TtsResult speech = speaking->get();
        phones = std::move(speech.phones);
        if (!s.wav_path.empty()) write_audio(s.wav_path, speech.audio);
    }
    if (phones.empty())
        throw InputError(have_phones ? s.phones_path.string() : std::string("--text"), 0, 0, "phones",
                         have_phones ? "expected timed phones, got none (an empty file or tier)"
                                     : "expected text with something to say, got no phones");
    Trajectory trajectory;
    try {
        trajectory = model->synthesize(phones, fps);
    } catch (const InputError& e) {
        // Name the phones' file in diagnostics about the phones.
        std::vector<Diagnostic> diagnostics = e.diagnostics();
        for (Diagnostic& d : diagnostics)
            if (d.path.empty()) d.path = have_phones ? s.phones_path.string() : "--text";
        throw InputError(std::move(diagnostics));
    }
    if (format == "fap")
        write_fap(s.out_path, trajectory_to_fap(trajectory, FapUnits{}, FapMapping{}, s.out_path.stem().string()),
                  greta ? FapTarget::Greta : FapTarget::Mpeg4);
    else
        write_trajectory_csv(s.out_path, trajectory);
    log_info("{}: {} frames at {} fps ({} model, {} phones)", s.out_path.string(), trajectory.size(), fps,
             model->kind(), phones.size());
    if (!s.plot_path.empty()) {
        write_text_file(s.plot_path, synthesis_plot_svg(*model, phones, *plot_param, fps));
        log_info("{}: plot of {}", s.plot_path.string(), s.plot_param);
    }
}

void run_fap_to_trajectory(const FapConversionSettings& s) {
    if (s.in_path.empty() || s.out_path.empty()) throw UsageError("an input .fap and --out are required");
    FapDecodeSettings decode;
    decode.clamp = s.clamp;
    const Trajectory trajectory = decode_fap_file(s.in_path, decode);
    write_trajectory_csv(s.out_path, trajectory);
    log_info("{}: {} frames at {} fps from {}", s.out_path.string(), trajectory.size(), trajectory.fps,
             s.in_path.string());
}

}  // namespace avsi::synth
