// Objective evaluation (Beskow §5, Table 2, Fig. 5): RMSE as % of range and
// Pearson ρ per parameter and frame subset; Markdown/CSV tables; SVG plot.
#include "avsi/learn/evaluation.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/synth/control_model.h"
#include "svg_plot.h"

namespace avsi::learn {

namespace fs = std::filesystem;

namespace {
constexpr double nan_v = std::numeric_limits<double>::quiet_NaN();
}

std::string_view subset_name(FrameSubset subset) {
    switch (subset) {
        case FrameSubset::AllNonSilence: return "all non-silence";
        case FrameSubset::Vowels: return "vowels";
        case FrameSubset::Consonants: return "consonants";
        case FrameSubset::Count: break;
    }
    return "?";
}

void EvaluationAccumulator::add(const PhoneSequence& phones, const ParamTrack& target,
                                const std::vector<Frame>& predicted) {
    AVSI_ASSERT(predicted.size() == target.size());
    const PhoneInventory& inventory = PhoneInventory::builtin();
    for (std::size_t k = 0; k < target.size(); ++k) {
        const auto i = phone_at(phones, target.time_s(k));
        if (!i || phones[*i].symbol == "sil") continue;
        const FrameSubset subset = inventory.is_vowel(phones[*i].symbol) ? FrameSubset::Vowels : FrameSubset::Consonants;
        for (std::size_t p = 0; p < param_count; ++p) {
            if (!target.present[p]) continue;
            const double y = target.frames[k][p], z = predicted[k][p];
            if (!std::isfinite(y) || !std::isfinite(z)) continue;
            for (FrameSubset s : {FrameSubset::AllNonSilence, subset}) {
                Sums& a = m_sums[static_cast<std::size_t>(s)][p];
                a.n += 1;
                a.sy += y;
                a.sz += z;
                a.syy += y * y;
                a.szz += z * z;
                a.syz += y * z;
                a.see += (z - y) * (z - y);
            }
        }
    }
}

ModelScores EvaluationAccumulator::scores(const std::string& name) const {
    ModelScores out;
    out.name = name;
    for (std::size_t s = 0; s < subset_count; ++s) {
        double rmse_sum = 0, rho_sum = 0;
        std::size_t rmse_n = 0, rho_n = 0, frames = 0;
        for (std::size_t p = 0; p < param_count; ++p) {
            const Sums& a = m_sums[s][p];
            Score& sc = out.per_param[s][p];
            sc.frames = static_cast<std::size_t>(a.n);
            if (a.n == 0) {
                sc.rmse_percent = nan_v;
                sc.pearson = nan_v;
                continue;
            }
            sc.rmse_percent = 100.0 * std::sqrt(a.see / a.n) / params()[p].range();
            const double vy = a.n * a.syy - a.sy * a.sy, vz = a.n * a.szz - a.sz * a.sz;
            sc.pearson = (vy > 1e-12 * a.n * a.n && vz > 1e-12 * a.n * a.n)
                             ? (a.n * a.syz - a.sy * a.sz) / std::sqrt(vy * vz)
                             : nan_v;
            rmse_sum += sc.rmse_percent;
            ++rmse_n;
            frames = std::max(frames, sc.frames);
            if (std::isfinite(sc.pearson)) {
                rho_sum += sc.pearson;
                ++rho_n;
            }
        }
        out.mean[s].rmse_percent = rmse_n ? rmse_sum / static_cast<double>(rmse_n) : nan_v;
        out.mean[s].pearson = rho_n ? rho_sum / static_cast<double>(rho_n) : nan_v;
        out.mean[s].frames = frames;
    }
    return out;
}

namespace {

// Sums for the phonetic columns of one model.
struct PhoneticSums {
    PhoneticScores scores;
    double aperture_sum = 0.0, incisor_sum = 0.0;
    std::size_t aperture_frames = 0, incisor_frames = 0;

    PhoneticScores finish() const {
        PhoneticScores s = scores;
        s.aperture_error_mm = aperture_frames ? aperture_sum / double(aperture_frames) : nan_v;
        s.lip_to_incisors_error_mm = incisor_frames ? incisor_sum / double(incisor_frames) : nan_v;
        return s;
    }
};

// The corpus track as a trajectory, or nothing when a parameter is missing
// anywhere (a head cannot be posed without it).
std::optional<Trajectory> complete_track(const ParamTrack& track) {
    Trajectory t;
    t.fps = track.fps;
    t.frames = track.frames;
    for (const auto& f : t.frames)
        for (double v : f)
            if (!std::isfinite(v)) return std::nullopt;
    return t;
}

// Adds one utterance: the model's checks, and its errors against the reference's measures.
void add_phonetic(PhoneticSums& sums, const std::string& utterance, const PhoneSequence& phones, double fps,
                  const std::vector<synth::ArticulationMeasures>& model,
                  const std::vector<synth::ArticulationMeasures>* reference) {
    const auto summary = synth::check_articulation(phones, fps, model);
    sums.scores.bilabials += summary.bilabials;
    sums.scores.bilabials_closed += summary.bilabials_closed;
    sums.scores.labiodentals += summary.labiodentals;
    sums.scores.labiodentals_reached += summary.labiodentals_reached;
    ++sums.scores.utterances;
    for (const auto& seg : summary.segments) {
        auto& worst = seg.kind == synth::SegmentClass::Bilabial ? sums.scores.worst_bilabials
                                                                : sums.scores.worst_labiodentals;
        worst.push_back({utterance, seg.phone, seg.start_s, seg.end_s, seg.best_mm});
        std::stable_sort(worst.begin(), worst.end(),
                         [](const PhoneticSegment& a, const PhoneticSegment& b) { return a.distance_mm > b.distance_mm; });
        if (worst.size() > PhoneticScores::worst_segments_kept) worst.pop_back();
    }
    if (!reference) return;
    for (const auto& seg : summary.segments)
        for (std::size_t k = 0; k < model.size() && k < reference->size(); ++k) {
            const double t = model[k].time_s;
            if (t < seg.start_s || t >= seg.end_s) continue;
            if (seg.kind == synth::SegmentClass::Bilabial) {
                sums.aperture_sum += std::abs(model[k].aperture_mid_mm - (*reference)[k].aperture_mid_mm);
                ++sums.aperture_frames;
            } else {
                sums.incisor_sum += std::abs(model[k].lip_to_incisors_mm - (*reference)[k].lip_to_incisors_mm);
                ++sums.incisor_frames;
            }
        }
}

}  // namespace

std::vector<ModelScores> evaluate_predictors(const std::vector<CorpusUtterance>& utterances,
                                             const std::vector<NamedPredictor>& predictors,
                                             const ArticulationFunction& articulation) {
    // The reference tracks' measures, once for every model.
    std::vector<std::optional<std::vector<synth::ArticulationMeasures>>> reference(utterances.size());
    if (articulation)
        for (std::size_t i = 0; i < utterances.size(); ++i)
            if (const auto track = complete_track(utterances[i].track)) reference[i] = articulation(*track);
    std::vector<ModelScores> out;
    for (const auto& predictor : predictors) {
        EvaluationAccumulator acc;
        PhoneticSums phonetic;
        std::vector<double> times;
        std::vector<Frame> frames;
        for (std::size_t i = 0; i < utterances.size(); ++i) {
            const auto& u = utterances[i];
            times.resize(u.track.size());
            for (std::size_t k = 0; k < times.size(); ++k) times[k] = u.track.time_s(k);
            frames.clear();
            predictor.predict(u.phones, times, frames);
            AVSI_ASSERT(frames.size() == times.size());
            acc.add(u.phones, u.track, frames);
            if (articulation) {
                Trajectory predicted;
                predicted.fps = u.track.fps;
                predicted.frames = frames;
                add_phonetic(phonetic, u.id, u.phones, u.track.fps, articulation(predicted),
                             reference[i] ? &*reference[i] : nullptr);
            }
        }
        out.push_back(acc.scores(predictor.name));
        if (articulation) out.back().phonetic = phonetic.finish();
    }
    return out;
}

PhoneticScores reference_phonetic_scores(const std::vector<CorpusUtterance>& utterances,
                                         const ArticulationFunction& articulation) {
    PhoneticSums sums;
    for (const auto& u : utterances)
        if (const auto track = complete_track(u.track)) {
            const auto m = articulation(*track);
            add_phonetic(sums, u.id, u.phones, track->fps, m, &m);
        }
    return sums.finish();
}

namespace {

std::string num(double v, int decimals) { return std::isfinite(v) ? fmt::format("{:.{}f}", v, decimals) : "–"; }

}  // namespace

std::string scores_markdown(const std::vector<ModelScores>& scores, const std::string& caption) {
    std::string md = fmt::format("{}\n\n| frames |", caption);
    std::string rule = "| --- |";
    for (const auto& m : scores) {
        md += fmt::format(" {} RMSE (%) | {} ρ |", m.name, m.name);
        rule += " ---: | ---: |";
    }
    md += "\n" + rule + "\n";
    for (std::size_t s = 0; s < subset_count; ++s) {
        md += fmt::format("| {} |", subset_name(static_cast<FrameSubset>(s)));
        for (const auto& m : scores) md += fmt::format(" {} | {} |", num(m.mean[s].rmse_percent, 2), num(m.mean[s].pearson, 4));
        md += "\n";
    }
    for (std::size_t s = 0; s < subset_count; ++s) {
        md += fmt::format("\nPer parameter, {} frames:\n\n| parameter |", subset_name(static_cast<FrameSubset>(s)));
        for (const auto& m : scores) md += fmt::format(" {} RMSE (%) | {} ρ |", m.name, m.name);
        md += "\n" + rule + "\n";
        for (std::size_t p = 0; p < param_count; ++p) {
            if (scores.empty() || scores.front().per_param[s][p].frames == 0) continue;
            md += fmt::format("| {} |", params()[p].name);
            for (const auto& m : scores)
                md += fmt::format(" {} | {} |", num(m.per_param[s][p].rmse_percent, 2), num(m.per_param[s][p].pearson, 4));
            md += "\n";
        }
    }
    return md;
}

std::string scores_csv(const std::vector<ModelScores>& scores) {
    std::string csv = "model,subset,parameter,rmse_percent,pearson,frames\n";
    for (const auto& m : scores)
        for (std::size_t s = 0; s < subset_count; ++s) {
            const std::string subset(subset_name(static_cast<FrameSubset>(s)));
            csv += csv_line({m.name, subset, "mean", num(m.mean[s].rmse_percent, 4), num(m.mean[s].pearson, 6),
                             fmt::format("{}", m.mean[s].frames)});
            for (std::size_t p = 0; p < param_count; ++p) {
                const Score& sc = m.per_param[s][p];
                if (sc.frames == 0) continue;
                csv += csv_line({m.name, subset, std::string(params()[p].name), num(sc.rmse_percent, 4),
                                 num(sc.pearson, 6), fmt::format("{}", sc.frames)});
            }
        }
    return csv;
}

namespace {

// One row of the phonetic table: label, then the columns.
std::string phonetic_row(const std::string& name, const PhoneticScores& p) {
    return fmt::format("| {} | {}/{} ({}) | {}/{} ({}) | {} | {} |\n", name, p.bilabials_closed, p.bilabials,
                       fmt::format("{:.1f} %", 100.0 * p.closure_rate()), p.labiodentals_reached, p.labiodentals,
                       fmt::format("{:.1f} %", 100.0 * p.contact_rate()), num(p.aperture_error_mm, 2),
                       num(p.lip_to_incisors_error_mm, 2));
}

std::string phonetic_csv_row(const std::string& name, const PhoneticScores& p) {
    return csv_line({name, fmt::format("{}", p.bilabials), fmt::format("{}", p.bilabials_closed),
                     num(p.closure_rate(), 4), fmt::format("{}", p.labiodentals),
                     fmt::format("{}", p.labiodentals_reached), num(p.contact_rate(), 4), num(p.aperture_error_mm, 4),
                     num(p.lip_to_incisors_error_mm, 4)});
}

}  // namespace

std::string phonetic_markdown(const PhoneticScores& reference, const std::vector<ModelScores>& scores) {
    std::string md =
        "| model | bilabials closed | labiodentals reached | aperture error at /p b m/ (mm) | lower lip to incisors "
        "error at /f v/ (mm) |\n| --- | ---: | ---: | ---: | ---: |\n";
    md += phonetic_row("reference data", reference);
    for (const auto& m : scores)
        if (m.phonetic) md += phonetic_row(m.name, *m.phonetic);
    return md;
}

std::string worst_segments_markdown(const std::vector<ModelScores>& scores) {
    std::string md = "| model | segment | utterance | phone | time (s) | distance (mm) |\n| --- | --- | --- | --- | ---: | ---: |\n";
    for (const auto& m : scores) {
        if (!m.phonetic) continue;
        for (const auto* list : {&m.phonetic->worst_bilabials, &m.phonetic->worst_labiodentals})
            for (const auto& w : *list)
                md += fmt::format("| {} | {} | {} | {} | {:.3f} – {:.3f} | {:.2f} |\n", m.name,
                                  list == &m.phonetic->worst_bilabials ? "lip aperture" : "lower lip to incisors",
                                  w.utterance, w.phone, w.start_s, w.end_s, w.distance_mm);
    }
    return md;
}

std::string phonetic_csv(const PhoneticScores& reference, const std::vector<ModelScores>& scores) {
    std::string csv = "model,bilabials,bilabials_closed,closure_rate,labiodentals,labiodentals_reached,contact_rate,"
                      "aperture_error_mm,lip_to_incisors_error_mm\n";
    csv += phonetic_csv_row("reference", reference);
    for (const auto& m : scores)
        if (m.phonetic) csv += phonetic_csv_row(m.name, *m.phonetic);
    return csv;
}

void write_trajectory_plot_svg(const fs::path& path, const CorpusUtterance& u, Param param,
                               const std::vector<std::pair<std::string, std::vector<double>>>& curves) {
    const detail::PlotBox box{1000, 420, 70, 180, 30, 70};
    const double width = box.width, height = box.height, left = box.left, right = box.right, top = box.top,
                 bottom = box.bottom;
    const std::size_t n = u.track.size();
    AVSI_ASSERT(n >= 2);
    const double t0 = u.track.time_s(0), t1 = u.track.time_s(n - 1);
    detail::ValueRange range;
    for (std::size_t k = 0; k < n; ++k) range.extend(u.track.frames[k][index(param)]);
    for (const auto& c : curves)
        for (double v : c.second) range.extend(v);
    const auto [lo, hi] = range.padded(0.05);

    detail::SvgPage page(path, box);
    auto X = [&](double t) { return page.x_of(t, t0, t1); };
    auto Y = [&](double v) { return page.y_of(v, lo, hi); };
    cairo_t* cr = page.cr();

    // Phone boundaries and labels.
    cairo_set_line_width(cr, 0.5);
    for (const auto& ph : u.phones) {
        if (ph.end_s < t0 || ph.start_s > t1) continue;
        cairo_set_source_rgb(cr, 0.85, 0.85, 0.85);
        cairo_move_to(cr, X(std::max(ph.start_s, t0)), top);
        cairo_line_to(cr, X(std::max(ph.start_s, t0)), height - bottom);
        cairo_stroke(cr);
        cairo_set_source_rgb(cr, 0.2, 0.2, 0.2);
        const std::string label = ph.symbol == "sil" ? "" : ph.symbol;
        cairo_text_extents_t ext;
        cairo_text_extents(cr, label.c_str(), &ext);
        page.text(X(std::clamp(ph.centre_s(), t0, t1)) - ext.width / 2, height - bottom + 16, label);
    }
    // Axes.
    page.frame_with_value_labels(lo, hi, 45);
    const double step = (t1 - t0) > 4 ? 1.0 : 0.5;
    for (double t = std::ceil(t0 / step) * step; t <= t1 + 1e-9; t += step)
        page.text(X(t) - 8, height - bottom + 34, fmt::format("{:.1f}", t));
    page.text(left, 18, fmt::format("{} — {} (time in s)", u.id, params()[index(param)].name));

    // Curves: target in black, models in colours; legend at the right.
    static const double colours[][3] = {{0.85, 0.15, 0.15}, {0.1, 0.4, 0.85}, {0.1, 0.6, 0.2},
                                        {0.8, 0.5, 0.0},    {0.6, 0.2, 0.7},  {0.3, 0.6, 0.7}};
    auto draw = [&](const std::vector<double>& values, const double* rgb, double line, const std::string& name,
                    std::size_t row) {
        cairo_set_source_rgb(cr, rgb[0], rgb[1], rgb[2]);
        cairo_set_line_width(cr, line);
        page.polyline(
            std::min(values.size(), n), [&](std::size_t k) { return X(u.track.time_s(k)); },
            [&](std::size_t k) { return Y(values[k]); });
        const double ly = top + 14 + 18.0 * static_cast<double>(row);
        cairo_move_to(cr, width - right + 12, ly - 4);
        cairo_line_to(cr, width - right + 36, ly - 4);
        cairo_stroke(cr);
        page.text(width - right + 42, ly, name);
    };
    std::vector<double> target(n);
    for (std::size_t k = 0; k < n; ++k) target[k] = u.track.frames[k][index(param)];
    const double black[3] = {0, 0, 0};
    draw(target, black, 2.0, "target", 0);
    for (std::size_t c = 0; c < curves.size(); ++c) draw(curves[c].second, colours[c % 6], 1.2, curves[c].first, c + 1);

    page.finish();
}

EvaluationResult run_evaluation(const EvaluationSettings& settings) {
    if (settings.models.empty()) throw InputError("", 0, 0, "--models", "expected at least one model file");
    if (settings.out.empty()) throw InputError("", 0, 0, "--out", "expected an output path prefix");
    const auto plot_param = param_from_name(settings.plot_param);
    if (!plot_param) {
        std::vector<std::string> names;
        for (const auto& info : params()) names.emplace_back(info.name);
        const std::string hint = closest_match(settings.plot_param, names);
        throw InputError("", 0, 0, "--plot-param",
                         fmt::format("unknown parameter \"{}\"{}", settings.plot_param,
                                     hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
    }
    const ArticulatoryCorpus corpus = load_articulatory_corpus(settings.corpus);
    const CorpusSplit split = split_corpus(corpus, {settings.split_seed, settings.test_fraction});
    std::vector<std::string> ids;
    if (settings.subset == "test")
        ids = split.test_ids;
    else if (settings.subset == "train")
        ids = split.train_ids;
    else if (settings.subset == "all")
        for (const auto& e : corpus.entries) ids.push_back(e.id);
    else
        throw InputError("", 0, 0, "--subset", fmt::format("expected test, train or all, got \"{}\"", settings.subset));
    if (ids.empty()) throw InputError(corpus.manifest, fmt::format("the {} split is empty", settings.subset));

    std::vector<std::shared_ptr<const ControlModel>> models;
    std::vector<NamedPredictor> predictors;
    auto add = [&](std::shared_ptr<const ControlModel> model, std::string name) {
        models.push_back(std::move(model));
        const ControlModel* m = models.back().get();
        predictors.push_back({std::move(name), [m](const PhoneSequence& phones, std::span<const double> times,
                                                   std::vector<Frame>& out) { m->evaluate(phones, times, out); }});
    };
    if (settings.closure_hold && !settings.lip_tasks)
        throw InputError("", 0, 0, "--closure-hold",
                         "the closure constraint measures the lips on a head: leave out --no-phonetic");
    for (const auto& path : settings.models) {
        std::shared_ptr<const ControlModel> model = load_model(path);
        add(model, path.stem().string());
        if (settings.closure_hold)
            add(std::make_shared<ClosureConstrainedModel>(model, settings.lip_tasks, ClosureSettings{}),
                path.stem().string() + "+hold");
    }
    log_info("evaluating {} model(s) on {} {} utterances of {}", models.size(), ids.size(), settings.subset,
             corpus.name);
    const std::vector<CorpusUtterance> utterances = load_corpus_utterances(corpus, ids);

    EvaluationResult result;
    result.utterances = utterances.size();
    result.scores = evaluate_predictors(utterances, predictors, settings.articulation);
    const std::string caption = fmt::format(
        "Table 2 layout: RMSE (% of each parameter's full range) and Pearson ρ between target and predicted "
        "trajectories, averaged over parameters; corpus {} (hash {}), {} split ({} utterances, split seed {}, "
        "test fraction {}).",
        corpus.name, corpus.hash.substr(0, 12), settings.subset, utterances.size(), split.seed, split.test_fraction);
    result.markdown = scores_markdown(result.scores, caption);
    if (corpus.synthetic)
        result.markdown +=
            "\nThis corpus is synthetic (its manifest says \"synthetic\": true): the table checks the training "
            "pipeline — how well each model learns a speaker whose mechanism none of them shares — and is not a "
            "replication of Table 2 of the reference study, which needs real articulography (docs/articulography.md).\n";
    const fs::path base = settings.out;
    if (settings.articulation) {
        result.reference = reference_phonetic_scores(utterances, settings.articulation);
        result.markdown += fmt::format(
            "\nPhonetic columns: what the face shows, measured on {} (avsi measure): a bilabial is closed when a "
            "sampled frame inside it has a central-third lip aperture ≤ 0.5 mm, a labiodental reached when one has "
            "the lower lip within 2 mm of the upper incisors; errors are mean absolute differences from the "
            "reference track's measures over the segments' frames.\n\n{}",
            settings.articulation_head.empty() ? std::string("the head") : settings.articulation_head,
            phonetic_markdown(*result.reference, result.scores));
        result.markdown += fmt::format(
            "\nFor a trained model these are results, not constraints: how often it closes the lips for /p b m/ and "
            "brings the lower lip to the upper incisors for /f v/ in running speech. The worst segments of each "
            "model:\n\n{}",
            worst_segments_markdown(result.scores));
        write_text_file(fs::path(base.string() + "_phonetic.csv"), phonetic_csv(*result.reference, result.scores));
    }
    write_text_file(fs::path(base.string() + ".md"), result.markdown);
    write_text_file(fs::path(base.string() + ".csv"), scores_csv(result.scores));

    // Fig. 5: one utterance, one parameter, target and every model.
    const std::string plot_id = settings.plot_utterance.empty() ? utterances.front().id : settings.plot_utterance;
    const auto it = std::find_if(utterances.begin(), utterances.end(), [&](const auto& u) { return u.id == plot_id; });
    CorpusUtterance plotted;
    if (it != utterances.end())
        plotted = *it;
    else
        plotted = load_corpus_utterances(corpus, {plot_id}).front();
    std::vector<double> times(plotted.track.size());
    for (std::size_t k = 0; k < times.size(); ++k) times[k] = plotted.track.time_s(k);
    std::vector<std::pair<std::string, std::vector<double>>> curves;
    for (std::size_t m = 0; m < models.size(); ++m) {
        std::vector<Frame> frames;
        models[m]->evaluate(plotted.phones, times, frames);
        std::vector<double> values(frames.size());
        for (std::size_t k = 0; k < frames.size(); ++k) values[k] = frames[k][index(*plot_param)];
        curves.emplace_back(predictors[m].name, std::move(values));
    }
    write_trajectory_plot_svg(fs::path(base.string() + ".svg"), plotted, *plot_param, curves);
    return result;
}

}  // namespace avsi::learn
