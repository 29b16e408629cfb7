// The adaptive SRT analysis and its report (see adaptive_report.h), and the
// files of `avsi simulate-srt` (adaptive.h).
#include "avsi/analysis/adaptive_report.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>

#include <fmt/format.h>

#include "adaptive_plot.h"
#include "avsi/analysis/pairwise.h"
#include "avsi/analysis/rm_anova.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/protocol.h"
#include "avsi/core/text.h"
#include "report_html.h"

namespace avsi::analysis {

namespace fs = std::filesystem;

namespace {

std::string full(double v) { return fmt::format("{}", v); }
std::string fixed2(double v) { return fmt::format("{:.2f}", v); }

// Levels of pooled psychometric points are rounded to this grid (dB).
constexpr double kPoolGridDb = 0.1;

}  // namespace

bool is_adaptive_trials_file(const fs::path& path) {
    try {
        const CsvTable t = read_csv(path);
        return t.column("level_db") && t.column("presentation");
    } catch (const InputError&) {
        return false;
    }
}

std::vector<AdaptiveTrialRow> read_adaptive_trials(const fs::path& path) {
    const CsvTable t = read_csv(path);
    const std::size_t c_subject = t.require_column("subject"), c_condition = t.require_column("condition"),
                      c_presentation = t.require_column("presentation"), c_level = t.require_column("level_db"),
                      c_keywords = t.require_column("keywords"), c_correct = t.require_column("correct");
    const auto c_sentence = t.column("sentence_index");
    const auto c_attempt = t.column("attempt");
    const auto c_next = t.column("next_level_db");
    const auto c_phase = t.column("phase");
    DiagnosticList problems;
    std::vector<AdaptiveTrialRow> rows;
    for (const auto& r : t.rows) {
        auto field = [&](std::size_t c) -> const std::string& { return r.fields[c]; };
        if (c_phase && field(*c_phase) != "test") continue;  // warm-up and practice have no track
        AdaptiveTrialRow row;
        row.line = r.line;
        row.level_column = static_cast<int>(c_level) + 1;
        row.subject = field(c_subject);
        row.condition = field(c_condition);
        auto integer = [&](std::size_t c, const char* name, long long lo, long long hi, int& out) {
            const auto v = parse_int(field(c));
            if (!v || *v < lo || *v > hi)
                problems.add(t.path, r.line, static_cast<int>(c) + 1, name,
                             fmt::format("expected an integer in [{}, {}], got \"{}\"", lo, hi, field(c)));
            else
                out = static_cast<int>(*v);
        };
        auto number = [&](std::size_t c, const char* name, double& out) {
            const auto v = parse_double(field(c));
            if (!v || std::fabs(*v) > 100000.0)
                problems.add(t.path, r.line, static_cast<int>(c) + 1, name,
                             fmt::format("expected a level in [-100000, 100000] (dB, bands or Hz), got \"{}\"",
                                         field(c)));
            else
                out = *v;
        };
        if (row.subject.empty()) problems.add(t.path, r.line, static_cast<int>(c_subject) + 1, "subject", "expected a subject, got \"\"");
        if (row.condition.empty())
            problems.add(t.path, r.line, static_cast<int>(c_condition) + 1, "condition", "expected a condition, got \"\"");
        integer(c_presentation, "presentation", 1, 100000, row.presentation);
        number(c_level, "level_db", row.level_db);
        integer(c_keywords, "keywords", 1, 100, row.keywords);
        integer(c_correct, "correct", 0, 100, row.correct);
        if (row.correct > row.keywords)
            problems.add(t.path, r.line, static_cast<int>(c_correct) + 1, "correct",
                         fmt::format("expected at most keywords ({}), got {}", row.keywords, row.correct));
        if (c_sentence) integer(*c_sentence, "sentence_index", 1, 100000, row.sentence_index);
        if (c_attempt) integer(*c_attempt, "attempt", 1, 1000, row.attempt);
        if (c_next) number(*c_next, "next_level_db", row.next_level_db);
        rows.push_back(std::move(row));
    }
    problems.throw_if_any();
    if (rows.empty()) throw InputError(path, "no test-phase trials of adaptive tracks in this file");
    return rows;
}

namespace {

// The ceiling of a condition ([adaptive] ceilings; 1 without).
double condition_ceiling(const AdaptiveProtocol* protocol, const std::string& condition) {
    if (!protocol) return 1.0;
    const auto it = protocol->ceilings.find(condition);
    return it == protocol->ceilings.end() ? 1.0 : it->second;
}

// The analysis scale of a track's steps: dB as they are, list levels as log2.
std::vector<TrackStep> on_analysis_scale(const SrtAnalysis& a, std::vector<TrackStep> steps) {
    if (!a.log2_scale) return steps;
    for (auto& st : steps) {
        st.level_db = std::log2(st.level_db);
        st.next_level_db = std::log2(st.next_level_db);
        st.step_db = st.next_level_db - st.level_db;
    }
    return steps;
}

// The rows by track, subjects in first-appearance order.
struct TrackRows {
    std::vector<std::string> subjects;
    std::map<std::pair<std::string, std::string>, std::vector<const AdaptiveTrialRow*>> by_track;
};

// Groups the rows by track and sets the conditions the report shows (the
// protocol's order, those without tracks left out and noted) and the
// reference; a condition outside the protocol's is an InputError.
TrackRows group_tracks(SrtAnalysis& a, const std::vector<AdaptiveTrialRow>& rows,
                       const std::vector<std::string>& conditions, const std::string& reference,
                       const std::string& source) {
    TrackRows t;
    std::vector<std::string> seen_conditions;
    for (const auto& r : rows) {
        if (std::find(t.subjects.begin(), t.subjects.end(), r.subject) == t.subjects.end()) t.subjects.push_back(r.subject);
        if (std::find(seen_conditions.begin(), seen_conditions.end(), r.condition) == seen_conditions.end())
            seen_conditions.push_back(r.condition);
        t.by_track[{r.subject, r.condition}].push_back(&r);
    }
    a.conditions = conditions.empty() ? seen_conditions : conditions;
    for (const auto& c : seen_conditions)
        if (std::find(a.conditions.begin(), a.conditions.end(), c) == a.conditions.end())
            throw InputError(source, 0, 0, "condition",
                             fmt::format("expected one of the protocol's conditions ({}), got \"{}\"",
                                         fmt::join(a.conditions, ", "), c));
    std::vector<std::string> present;
    for (const auto& c : a.conditions)
        if (std::find(seen_conditions.begin(), seen_conditions.end(), c) != seen_conditions.end())
            present.push_back(c);
        else
            a.notes.push_back(fmt::format("condition {} has no adaptive trials", c));
    a.conditions = present;
    a.reference = reference.empty() ? a.conditions.front() : reference;
    if (std::find(a.conditions.begin(), a.conditions.end(), a.reference) == a.conditions.end())
        throw InputError(source, 0, 0, "reference",
                         fmt::format("expected a condition with tracks ({}), got \"{}\"", fmt::join(a.conditions, ", "),
                                     a.reference));
    return t;
}

// Replays one track under the rules (the stored levels must be theirs) and
// estimates its SRT; none, with a problem added, when the rows disagree.
std::optional<TrackResult> replay_track(const SrtAnalysis& a, std::vector<const AdaptiveTrialRow*> trials,
                                        const std::string& subject, const std::string& condition,
                                        const AdaptiveProtocol* protocol, const std::string& source,
                                        DiagnosticList& problems) {
    const TrackSettings& settings = a.settings;
    const AdaptiveProtocol* list = protocol && protocol->list_variable() ? protocol : nullptr;
    const auto value_of = [&](double track_level) { return list ? list->value_of(track_level) : track_level; };
    std::stable_sort(trials.begin(), trials.end(),
                     [](const auto* x, const auto* y) { return x->presentation < y->presentation; });
    TrackResult tr;
    tr.subject = subject;
    tr.condition = condition;
    AdaptiveTrack track(settings);
    bool ok = true;
    for (std::size_t i = 0; i < trials.size() && ok; ++i) {
        const AdaptiveTrialRow& r = *trials[i];
        if (r.presentation != static_cast<int>(i) + 1) {
            problems.add(source, r.line, 0, "presentation",
                         fmt::format("expected presentation {} of subject {}'s {} track, got {}", i + 1,
                                     subject, condition, r.presentation));
            ok = false;
            break;
        }
        if (std::fabs(value_of(track.level_db()) - r.level_db) > 1e-6) {
            problems.add(source, r.line, r.level_column, "level_db",
                         fmt::format("expected {} (the [adaptive] rules replayed on the stored scores of "
                                     "subject {}, {}), got {}",
                                     value_of(track.level_db()), subject, condition, r.level_db));
            ok = false;
            break;
        }
        track.record(r.keywords, r.correct);
    }
    if (!ok) return std::nullopt;
    tr.steps = list ? in_units(*list, track.steps()) : track.steps();
    const std::vector<TrackStep> scaled = on_analysis_scale(a, tr.steps);
    tr.srt = estimate_srt(settings, scaled);
    tr.ml = estimate_srt(settings, scaled, SrtEstimator::MaximumLikelihood, condition_ceiling(protocol, condition));
    tr.convergence = track_convergence(settings, track.steps());
    return tr;
}

// Subject × condition SRTs (the Scores layout, dB in `percent`).
void srt_scores(SrtAnalysis& a, const std::string& source) {
    for (const auto& t : a.tracks) {
        ScoreCell cell;
        cell.subject = t.subject;
        cell.condition = t.condition;
        cell.keywords = static_cast<int>(t.steps.size());
        if (t.excluded) {
            // Left out: not converged (named in a.excluded).
        } else if (t.srt.valid) {
            cell.percent = t.srt.srt_db;
        } else {
            a.notes.push_back(fmt::format("subject {}, {}: no SRT ({})", t.subject, t.condition, t.srt.note));
        }
        a.srts.cells.push_back(cell);
    }
    a.srts = select_conditions(a.srts, a.conditions, source);
}

// Visual benefit: reference SRT − condition SRT, paired over subjects with
// both; the k − 1 benefits are one family of tests: Holm over them, as
// pairwise.csv does over all pairs.
void visual_benefits(SrtAnalysis& a, const std::vector<std::string>& subjects, double confidence) {
    std::map<std::pair<std::string, std::string>, double> srt;
    for (const auto& c : a.srts.cells)
        if (c.percent) srt[{c.subject, c.condition}] = *c.percent;
    for (const auto& condition : a.conditions) {
        if (condition == a.reference) continue;
        VisualBenefit b;
        b.condition = condition;
        b.reference = a.reference;
        std::vector<double> d;
        for (const auto& s : subjects) {
            const auto r = srt.find({s, a.reference});
            const auto c = srt.find({s, condition});
            if (r != srt.end() && c != srt.end()) d.push_back(r->second - c->second);
        }
        b.n = d.size();
        if (b.n >= 1) b.mean_db = std::accumulate(d.begin(), d.end(), 0.0) / b.n;
        if (b.n >= 2) {
            double ss = 0.0;
            for (double v : d) ss += (v - b.mean_db) * (v - b.mean_db);
            b.sd_db = std::sqrt(ss / (b.n - 1));
            b.se_db = b.sd_db / std::sqrt(static_cast<double>(b.n));
            b.df = static_cast<double>(b.n - 1);
            const double q = t_quantile_upper(1.0 - confidence, b.df);
            b.ci_low_db = b.mean_db - q * b.se_db;
            b.ci_high_db = b.mean_db + q * b.se_db;
            if (b.se_db > 0) {
                b.t = b.mean_db / b.se_db;
                b.p_value = t_two_sided_p(*b.t, b.df);
            }
        } else {
            a.notes.push_back(fmt::format("visual benefit of {}: {} subject(s) with both SRTs, no interval", condition, b.n));
        }
        a.benefits.push_back(b);
    }
    std::vector<std::optional<double>> benefit_p;
    for (const auto& b : a.benefits) benefit_p.push_back(b.p_value);
    const auto holm = holm_adjust(benefit_p);
    for (std::size_t i = 0; i < a.benefits.size(); ++i) a.benefits[i].p_holm = holm[i];
}

// The pooled psychometric function of each condition.
void pooled_fits(SrtAnalysis& a, const AdaptiveProtocol* protocol) {
    for (const auto& condition : a.conditions) {
        std::map<long long, PsychometricPoint> pooled;
        for (const auto& t : a.tracks) {
            if (t.condition != condition) continue;
            for (const auto& s : on_analysis_scale(a, t.steps)) {
                const long long key = std::llround(s.level_db / kPoolGridDb);
                PsychometricPoint& p = pooled[key];
                p.level_db = key * kPoolGridDb;
                p.trials += s.keywords;
                p.correct += s.correct;
            }
        }
        ConditionFit f;
        f.condition = condition;
        for (const auto& [key, p] : pooled) f.points.push_back(p);
        f.fit = fit_psychometric(f.points, std::nullopt, condition_ceiling(protocol, condition));
        if (!f.fit.converged) a.notes.push_back(fmt::format("psychometric function of {}: {}", condition, f.fit.note));
        a.fits.push_back(std::move(f));
    }
}

}  // namespace

SrtAnalysis analyze_srt(const std::vector<AdaptiveTrialRow>& rows, const TrackSettings& settings,
                        const std::vector<std::string>& conditions, const std::string& reference,
                        const std::string& source, double confidence, const AdaptiveProtocol* protocol,
                        bool include_unconverged) {
    validate(settings, source);
    SrtAnalysis a;
    a.settings = settings;
    a.include_unconverged = include_unconverged;
    if (protocol && protocol->list_variable()) {
        a.unit = protocol->unit();
        a.log2_scale = true;
        a.scale = fmt::format("log2({})", a.unit);
        a.level_label = protocol->variable == AdaptiveVariable::Bands ? "vocoder bands" : "envelope cutoff (Hz)";
        a.threshold_label =
            protocol->variable == AdaptiveVariable::Bands ? "log2 vocoder bands" : "log2 Hz envelope cutoff";
    }
    const TrackRows tracks = group_tracks(a, rows, conditions, reference, source);
    DiagnosticList problems;
    for (const auto& subject : tracks.subjects)
        for (const auto& condition : a.conditions) {
            const auto it = tracks.by_track.find({subject, condition});
            if (it == tracks.by_track.end()) continue;
            if (auto tr = replay_track(a, it->second, subject, condition, protocol, source, problems)) {
                if (!tr->convergence.converged) {
                    ++a.excluded_tracks;
                    tr->excluded = !include_unconverged;
                    a.excluded.push_back(fmt::format("subject {}, {}: {}", subject, condition, tr->convergence.reason));
                }
                a.tracks.push_back(std::move(*tr));
            }
        }
    problems.throw_if_any();
    srt_scores(a, source);
    // The ANOVA on SRTs in dB, when there is an error term.
    if (a.conditions.size() >= 2) {
        try {
            a.anova = analyze(make_within_data(a.srts, source), confidence);
        } catch (const InputError& e) {
            a.notes.push_back(fmt::format("no ANOVA: {}", e.what()));
        }
    }
    visual_benefits(a, tracks.subjects, confidence);
    pooled_fits(a, protocol);
    return a;
}

namespace {

std::string opt_text(const std::optional<double>& v, const char* format = "{:.4f}") {
    return v ? fmt::format(fmt::runtime(format), *v) : "NA";
}

// The target of the pooled fit the procedure estimates (sentence: all keywords).
double fit_target(const SrtAnalysis& a) {
    int keywords = 1;
    for (const auto& t : a.tracks)
        for (const auto& s : t.steps) keywords = std::max(keywords, s.keywords);
    return a.settings.procedure == AdaptiveProcedure::Sentence ? std::pow(0.5, 1.0 / keywords) : a.settings.target;
}

void write_png(const fs::path& path, const detail::XyPlot& plot, int width = 800, int height = 500) {
    AtomicFile file(path);
    detail::write_xy_plot_png(file.temp_path(), plot, width, height);
    file.commit();
}

}  // namespace

namespace {

// srt.csv: srt_db, se_db and the ML columns are on the analysis scale
// (`scale`: dB, or log2 of bands / Hz); srt_units is the threshold in the
// variable's units (2^srt for a log2 scale).
std::string srt_csv_text(const SrtAnalysis& a) {
    std::string srt_csv = csv_line({"subject", "condition", "srt_db", "se_db", "scale", "srt_units", "estimator",
                                    "levels", "presentations", "reversals", "converged", "excluded", "ml_srt_db",
                                    "ml_se_db", "ml_slope_per_db", "note"});
    for (const auto& t : a.tracks)
        srt_csv += csv_line({t.subject, t.condition, t.srt.valid ? full(t.srt.srt_db) : "NA",
                             t.srt.valid ? full(t.srt.se_db) : "NA", a.scale,
                             t.srt.valid ? full(a.log2_scale ? std::exp2(t.srt.srt_db) : t.srt.srt_db) : "NA",
                             to_string(t.srt.estimator), std::to_string(t.srt.levels), std::to_string(t.steps.size()),
                             std::to_string(t.steps.empty() ? 0 : t.steps.back().reversals),
                             t.convergence.converged ? "1" : "0", t.excluded ? "1" : "0",
                             t.ml.valid ? full(t.ml.srt_db) : "NA", t.ml.valid ? full(t.ml.se_db) : "NA",
                             t.ml.fit && t.ml.fit->converged ? full(t.ml.fit->slope_per_db) : "NA",
                             !t.convergence.converged ? t.convergence.reason
                             : t.srt.valid            ? (t.ml.valid ? "" : t.ml.note)
                                                      : t.srt.note});
    return srt_csv;
}

// benefit.csv: each condition's visual benefit and its test.
std::string benefit_csv_text(const SrtAnalysis& a, const SrtReportSettings& settings) {
    std::string benefit_csv = csv_line({"condition", "reference", "n", "benefit_db", "sd_db", "se_db", "ci_low_db",
                                        "ci_high_db", "t", "df", "p", "p_holm", "confidence"});
    for (const auto& b : a.benefits)
        benefit_csv += csv_line({b.condition, b.reference, std::to_string(b.n), full(b.mean_db), full(b.sd_db),
                                 full(b.se_db), full(b.ci_low_db), full(b.ci_high_db), b.t ? full(*b.t) : "NA",
                                 full(b.df), b.p_value ? full(*b.p_value) : "NA", b.p_holm ? full(*b.p_holm) : "NA",
                                 full(settings.confidence)});
    return benefit_csv;
}

// psychometric.csv: each condition's pooled fit and its level at the target.
std::string psychometric_csv_text(const SrtAnalysis& a, double target) {
    std::string psy_csv = csv_line({"condition", "converged", "l50_db", "se_l50_db", "slope_per_db", "se_slope",
                                    "target", "level_at_target_db", "se_level_at_target_db", "levels", "keywords", "note"});
    for (const auto& f : a.fits)
        psy_csv += csv_line({f.condition, f.fit.converged ? "1" : "0", f.fit.converged ? full(f.fit.l50_db) : "NA",
                             f.fit.converged ? full(f.fit.se_l50_db) : "NA",
                             f.fit.converged ? full(f.fit.slope_per_db) : "NA",
                             f.fit.converged ? full(f.fit.se_slope) : "NA", full(target),
                             f.fit.converged && target < f.fit.ceiling ? full(f.fit.level_at(target)) : "NA",
                             f.fit.converged && target < f.fit.ceiling ? full(f.fit.se_level_at(target)) : "NA",
                             std::to_string(f.points.size()),
                             std::to_string(f.fit.trials), f.fit.note});
    return psy_csv;
}

// anova.json and pairwise.csv (the percent report's machinery, on dB), when there is an ANOVA.
void write_srt_anova(const SrtAnalysis& a, const SrtReportSettings& settings) {
    ReportSettings rs;
    rs.out_dir = settings.out_dir;
    rs.source = settings.source;
    rs.title = settings.title;
    rs.confidence = settings.confidence;
    if (a.anova) {
        write_text_file(settings.out_dir / "anova.json", anova_json(*a.anova, rs));
        std::string pw = csv_line({"a", "b", "mean_difference_db", "sd_difference_db", "t", "df", "p", "p_holm",
                                   "ci_low_db", "ci_high_db", "d_z"});
        for (const auto& c : a.anova->pairwise)
            pw += csv_line({c.a, c.b, full(c.mean_difference), full(c.sd_difference), c.t ? full(*c.t) : "NA",
                            full(c.df), c.p_value ? full(*c.p_value) : "NA", c.p_holm ? full(*c.p_holm) : "NA",
                            full(c.ci_low), full(c.ci_high), c.d_z ? full(*c.d_z) : "NA"});
        write_text_file(settings.out_dir / "pairwise.csv", pw);
    }
}

// A report figure: its caption and its file (relative to the report folder).
using Figure = std::pair<std::string, fs::path>;

// srt.png: the mean SRT per condition with within-subject intervals.
void srt_figure(const SrtAnalysis& a, const SrtReportSettings& settings, std::vector<Figure>& figures) {
    if (!a.anova) return;
    detail::XyPlot p;
    p.title = settings.title;
    p.y_label = fmt::format("SRT ({})", a.threshold_label);
    p.x_categories = a.conditions;
    detail::XySeries s;
    s.line = false;
    for (std::size_t j = 0; j < a.anova->descriptives.size(); ++j) {
        const auto& d = a.anova->descriptives[j];
        s.x.push_back(static_cast<double>(j));
        s.y.push_back(d.mean);
        s.low.push_back(d.ci_low);
        s.high.push_back(d.ci_high);
    }
    p.series.push_back(s);
    p.caption = fmt::format("n = {} subjects; error bars: {:.0f} % within-subject CI (Cousineau-Morey); lower is "
                            "better. {}",
                            a.anova->anova.n, 100 * settings.confidence, apa_anova(a.anova->anova));
    write_png(settings.out_dir / "srt.png", p);
    figures.push_back({"SRT by condition", "srt.png"});
}

// psychometric.png: the pooled proportions and the fits.
void psychometric_figure(const SrtAnalysis& a, const SrtReportSettings& settings, std::vector<Figure>& figures) {
    detail::XyPlot p;
    p.title = "Psychometric functions (keywords, pooled over subjects)";
    p.x_label = a.log2_scale ? fmt::format("log2 {}", a.level_label) : a.level_label;
    p.y_label = "Keywords correct (proportion)";
    p.caption = fmt::format("points: pooled proportions per {:.1f} {} level; lines: ML logistic fits", kPoolGridDb, a.scale);
    p.y_from_zero = true;
    int color = 0;
    for (const auto& f : a.fits) {
        detail::XySeries pts;
        pts.name = f.condition;
        pts.line = false;
        pts.color = color;
        for (const auto& q : f.points) {
            pts.x.push_back(q.level_db);
            pts.y.push_back(static_cast<double>(q.correct) / q.trials);
        }
        if (f.fit.converged && !f.points.empty()) {
            detail::XySeries curve;
            curve.name = f.condition + " fit";
            curve.markers = false;
            curve.color = color;
            const double lo = f.points.front().level_db, hi = f.points.back().level_db;
            for (int i = 0; i <= 100; ++i) {
                const double x = lo + (hi - lo) * i / 100.0;
                curve.x.push_back(x);
                curve.y.push_back(f.fit.p(x));
            }
            p.series.push_back(curve);
        }
        p.series.push_back(pts);
        ++color;
    }
    write_png(settings.out_dir / "psychometric.png", p);
    figures.push_back({"Psychometric functions", "psychometric.png"});
}

// tracks/subject_<id>.png: each subject's tracks.
std::vector<Figure> track_figures(const SrtAnalysis& a, const SrtReportSettings& settings) {
    std::vector<std::string> subjects;
    for (const auto& t : a.tracks)
        if (std::find(subjects.begin(), subjects.end(), t.subject) == subjects.end()) subjects.push_back(t.subject);
    std::vector<Figure> track_figures;
    for (const auto& subject : subjects) {
        detail::XyPlot p;
        p.title = fmt::format("Subject {}: adaptive tracks", subject);
        p.x_label = "Presentation";
        p.y_label = a.level_label;
        p.caption = "filled: every keyword right; open: not; ringed: reversal (the step after it changes direction)";
        for (const auto& t : a.tracks) {
            if (t.subject != subject) continue;
            detail::XySeries s;
            s.name = t.condition +
                     (t.srt.valid ? fmt::format(" ({:.1f} {})", a.log2_scale ? std::exp2(t.srt.srt_db) : t.srt.srt_db, a.unit)
                                  : "") +
                     (t.convergence.converged ? "" : " (not converged)");
            s.color = static_cast<int>(std::find(a.conditions.begin(), a.conditions.end(), t.condition) -
                                       a.conditions.begin());
            for (const auto& st : t.steps) {
                s.x.push_back(st.presentation);
                s.y.push_back(st.level_db);
                s.filled.push_back(st.sentence_correct);
                s.ringed.push_back(st.reversal);
            }
            p.series.push_back(s);
        }
        const fs::path rel = fs::path("tracks") / fmt::format("subject_{}.png", subject);
        write_png(settings.out_dir / rel, p, 800, 400);
        track_figures.push_back({fmt::format("Subject {}", subject), rel});
    }
    return track_figures;
}

// The procedure in one sentence, for the report's header.
std::string procedure_text(const SrtAnalysis& a) {
    return
        a.unit != "dB"
            ? fmt::format("sentence scoring, 1-up/1-down on all keywords correct on a list of levels ({}; steps of {} "
                          "levels after sentences 1-{}, then {}{}); threshold = mean of the log2 levels from sentence "
                          "{}{} (a geometric mean in {}); thresholds, fits, ANOVA and benefit on the {} scale",
                          a.level_label, a.settings.large_step_db, a.settings.large_steps, a.settings.small_step_db,
                          a.settings.repeat_first ? "; first sentence repeated upward until correct" : "",
                          a.settings.srt_from, a.settings.srt_include_next ? " plus the next level" : "", a.unit,
                          a.scale)
        : a.settings.procedure == AdaptiveProcedure::Sentence
            ? fmt::format("sentence scoring, 1-up/1-down on all keywords correct ({} dB steps after sentences 1-{}, "
                          "then {} dB{}); SRT = mean of the levels from sentence {}{}",
                          a.settings.large_step_db, a.settings.large_steps, a.settings.small_step_db,
                          a.settings.repeat_first ? "; first sentence repeated upward until correct" : "",
                          a.settings.srt_from, a.settings.srt_include_next ? " plus the next level" : "")
            : fmt::format("word scoring after Brand & Kollmeier (2002), target {:.2f}, assumed slope {:.3f}/dB, f(i) = "
                          "max({}, {}·{}^-i); SRT by {}",
                          a.settings.target, a.settings.slope_per_db, a.settings.f_min, a.settings.f_start,
                          a.settings.f_ratio,
                          a.settings.estimator == SrtEstimator::MeanOfLevels
                              ? fmt::format("the mean of the levels from sentence {}", a.settings.srt_from)
                              : std::string("the ML fit of the psychometric function"));
}

// The report as Markdown and as HTML, section by section.
struct ReportText {
    std::string md, html;
};

// SRT means per condition and the ANOVA.
void report_srt_means(const SrtAnalysis& a, ReportText& r) {
    r.md += fmt::format("## SRT by condition ({}; lower is better)\n\n", a.threshold_label);
    r.html += fmt::format("<h2>SRT by condition ({}; lower is better)</h2>\n", a.threshold_label);
    if (a.anova) {
        r.md += "| condition | n | mean SRT | SD | within-subject CI |\n| --- | ---: | ---: | ---: | --- |\n";
        r.html += fmt::format("<table><tr><th>condition</th><th>n</th><th>mean SRT ({})</th><th>SD</th><th>within-subject "
                              "CI</th></tr>\n", a.scale);
        for (const auto& d : a.anova->descriptives) {
            r.md += fmt::format("| {} | {} | {:.2f} | {:.2f} | [{:.2f}, {:.2f}] |\n", d.condition, d.n, d.mean, d.sd,
                                d.ci_low, d.ci_high);
            r.html += fmt::format("<tr><td>{}</td><td>{}</td><td>{:.2f}</td><td>{:.2f}</td><td>[{:.2f}, {:.2f}]</td></tr>\n",
                                  xml_escape(d.condition), d.n, d.mean, d.sd, d.ci_low, d.ci_high);
        }
        r.html += "</table>\n";
        const std::string apa = apa_anova(a.anova->anova);
        r.md += fmt::format("\nRepeated-measures ANOVA on the SRTs: {} (n = {}).\n\n", apa, a.anova->anova.n);
        r.html += fmt::format("<p>Repeated-measures ANOVA on the SRTs: {} (n = {}).</p>\n", xml_escape(apa),
                              a.anova->anova.n);
        r.md += sphericity_markdown(*a.anova) + "\n";
        r.html += sphericity_html(*a.anova);
    } else {
        r.md += "Too few complete subjects for an ANOVA (see the notes).\n\n";
        r.html += "<p>Too few complete subjects for an ANOVA (see the notes).</p>\n";
    }
}

// The visual benefits and their tests.
void report_benefits(const SrtAnalysis& a, const SrtReportSettings& settings, ReportText& r) {
    r.md += fmt::format("## Visual benefit (SRT of {} minus SRT of the condition; positive: the face helps)\n\n", a.reference);
    r.html += fmt::format("<h2>Visual benefit (SRT of {} minus SRT of the condition; positive: the face helps)</h2>\n",
                          xml_escape(a.reference));
    r.md += fmt::format("| condition | n | benefit ({}) | {:.0f} % CI | t | df | p | p (Holm) |\n| --- | ---: | ---: | --- | "
                        "---: | ---: | ---: | ---: |\n",
                        a.scale, 100 * settings.confidence);
    r.html += fmt::format("<table><tr><th>condition</th><th>n</th><th>benefit ({})</th><th>{:.0f} % CI</th><th>t</th>"
                          "<th>df</th><th>p</th><th>p (Holm)</th></tr>\n",
                          a.scale, 100 * settings.confidence);
    for (const auto& b : a.benefits) {
        const std::string p = b.p_value ? table_p(*b.p_value) : "NA";
        const std::string p_holm = b.p_holm ? table_p(*b.p_holm) : "NA";
        r.md += fmt::format("| {} | {} | {:.2f} | [{:.2f}, {:.2f}] | {} | {:.0f} | {} | {} |\n", b.condition, b.n,
                            b.mean_db, b.ci_low_db, b.ci_high_db, opt_text(b.t, "{:.2f}"), b.df, p, p_holm);
        r.html += fmt::format("<tr><td>{}</td><td>{}</td><td>{:.2f}</td><td>[{:.2f}, {:.2f}]</td><td>{}</td><td>{:.0f}</td>"
                              "<td>{}</td><td>{}</td></tr>\n",
                              xml_escape(b.condition), b.n, b.mean_db, b.ci_low_db, b.ci_high_db,
                              opt_text(b.t, "{:.2f}"), b.df, p, p_holm);
    }
    r.html += "</table>\n";
    r.md += fmt::format("\nUncorrected paired t-tests (df = n − 1) and Holm's adjustment over the {} benefit(s) "
                        "against {}.\n\n",
                        a.benefits.size(), a.reference);
    r.html += fmt::format("<p>Uncorrected paired t-tests (df = n − 1) and Holm's adjustment over the {} benefit(s) "
                          "against {}.</p>\n",
                          a.benefits.size(), xml_escape(a.reference));
}

// The tracks left out of the statistics, and warnings.
void report_convergence(const SrtAnalysis& a, ReportText& r) {
    std::string text;
    if (a.excluded_tracks == 0)
        text = "Every track converged (no level at a bound from the averaged sentences on, at least " +
               std::to_string(a.settings.min_reversals) + " reversals).";
    else
        text = fmt::format("{} of {} tracks did not converge (a level at a bound from sentence {} on, or fewer than "
                           "{} reversals) and {}: {}.",
                           a.excluded_tracks, a.tracks.size(), a.settings.srt_from, a.settings.min_reversals,
                           a.include_unconverged ? "are kept in the ANOVA and the benefit (--include-unconverged)"
                                                 : "are left out of the ANOVA and the benefit (a subject without a "
                                                   "threshold in every condition is dropped from the ANOVA)",
                           fmt::join(a.excluded, "; "));
    r.md += "## Convergence\n\n" + text + "\n\n";
    r.html += "<h2>Convergence</h2>\n<p>" + xml_escape(text) + "</p>\n";
    for (const auto& w : a.warnings) {
        r.md += "Warning: " + w + ".\n\n";
        r.html += "<p>Warning: " + xml_escape(w) + ".</p>\n";
    }
}

// Each subject's SRT per condition.
void report_subject_srts(const SrtAnalysis& a, ReportText& r) {
    const std::string units_head = a.log2_scale ? fmt::format(" | SRT ({})", a.unit) : "";
    r.md += fmt::format("\n## SRT per subject and condition\n\n| subject | condition | SRT ({}){} | SE | ML SRT | ML SE | "
                        "presentations | reversals | converged |\n| --- | --- | ---: |{} ---: | ---: | ---: | ---: | ---: | --- |\n",
                        a.scale, units_head, a.log2_scale ? " ---: |" : "");
    r.html += fmt::format("<h2>SRT per subject and condition</h2>\n<table><tr><th>subject</th><th>condition</th><th>SRT "
                          "({})</th>{}<th>SE</th><th>ML SRT</th><th>ML SE</th><th>presentations</th><th>reversals</th>"
                          "<th>converged</th></tr>\n",
                          a.scale, a.log2_scale ? fmt::format("<th>SRT ({})</th>", a.unit) : "");
    for (const auto& t : a.tracks) {
        const std::string srt = t.srt.valid ? fixed2(t.srt.srt_db) : "NA", se = t.srt.valid ? fixed2(t.srt.se_db) : "NA";
        const std::string ml = t.ml.valid ? fixed2(t.ml.srt_db) : "NA", mlse = t.ml.valid ? fixed2(t.ml.se_db) : "NA";
        const std::string units = t.srt.valid ? fixed2(std::exp2(t.srt.srt_db)) : "NA";
        const std::string converged = t.convergence.converged ? "yes" : (t.excluded ? "no (left out)" : "no (kept)");
        const int reversals = t.steps.empty() ? 0 : t.steps.back().reversals;
        r.md += fmt::format("| {} | {} | {}{} | {} | {} | {} | {} | {} | {} |\n", t.subject, t.condition, srt,
                            a.log2_scale ? " | " + units : "", se, ml, mlse, t.steps.size(), reversals, converged);
        r.html += fmt::format("<tr><td>{}</td><td>{}</td><td>{}</td>{}<td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>"
                              "<td>{}</td></tr>\n",
                              xml_escape(t.subject), xml_escape(t.condition), srt,
                              a.log2_scale ? "<td>" + units + "</td>" : "", se, ml, mlse, t.steps.size(), reversals,
                              converged);
    }
    r.html += "</table>\n";
    r.md += "\nSE of the mean of levels: SD/√n of the averaged levels, which are serially correlated, so it is optimistic; "
            "ML SE: from the Fisher information of the track's own fit.\n\n";
}

// The pooled psychometric functions.
void report_fits(const SrtAnalysis& a, double target, ReportText& r) {
    r.md += fmt::format("## Psychometric functions (pooled over subjects)\n\n| condition | L50 ({0}) | slope (/{0}) | level "
                        "at target | keywords |\n| --- | ---: | ---: | ---: | ---: |\n",
                        a.scale);
    r.html += fmt::format("<h2>Psychometric functions (pooled over subjects)</h2>\n<table><tr><th>condition</th><th>L50 "
                          "({0})</th><th>slope (/{0})</th><th>level at target</th><th>keywords</th></tr>\n",
                          a.scale);
    for (const auto& f : a.fits) {
        const std::string l50 = f.fit.converged ? fixed2(f.fit.l50_db) : "NA";
        const std::string slope = f.fit.converged ? fmt::format("{:.3f}", f.fit.slope_per_db) : "NA";
        const std::string at = f.fit.converged && target < f.fit.ceiling ? fixed2(f.fit.level_at(target)) : "NA";
        r.md += fmt::format("| {} | {} | {} | {} | {} |\n", f.condition, l50, slope, at, f.fit.trials);
        r.html += fmt::format("<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>\n",
                              xml_escape(f.condition), l50, slope, at, f.fit.trials);
    }
    r.html += "</table>\n";
    r.md += fmt::format("\nTarget {:.3f} per keyword ({}). Pooling subjects with different SRTs flattens the slope.\n\n",
                        target,
                        a.settings.procedure == AdaptiveProcedure::Sentence ? "every keyword of a sentence right half the time"
                                                                            : "the word procedure's target");
}

// The figures (inlined into the HTML) and the notes.
void report_figures_and_notes(const SrtAnalysis& a, const SrtReportSettings& settings, const std::vector<Figure>& figures,
                              const std::vector<Figure>& track_figures, ReportText& r) {
    for (const auto& [caption, file] : figures) {
        r.md += fmt::format("![{}]({})\n\n", caption, file.string());
        r.html += fmt::format("<figure><img alt=\"{0}\" src=\"data:image/png;base64,{1}\"><figcaption>{0}</figcaption></figure>\n",
                              xml_escape(caption), detail::base64(read_text_file(settings.out_dir / file)));
    }
    r.md += "## Tracks\n\n";
    r.html += "<h2>Tracks</h2>\n";
    for (const auto& [caption, file] : track_figures) {
        r.md += fmt::format("![{}]({})\n\n", caption, file.string());
        r.html += fmt::format("<figure><img alt=\"{0}\" src=\"data:image/png;base64,{1}\"></figure>\n",
                              xml_escape(caption), detail::base64(read_text_file(settings.out_dir / file)));
    }
    if (!a.notes.empty()) {
        r.md += "## Notes\n\n";
        r.html += "<h2>Notes</h2>\n<ul>\n";
        for (const auto& n : a.notes) {
            r.md += "- " + n + "\n";
            r.html += "<li>" + xml_escape(n) + "</li>\n";
        }
        r.html += "</ul>\n";
    }
}

}  // namespace

void write_srt_report(const SrtAnalysis& a, const SrtReportSettings& settings) {
    fs::create_directories(settings.out_dir / "tracks");
    const double target = fit_target(a);
    write_text_file(settings.out_dir / "srt.csv", srt_csv_text(a));
    write_text_file(settings.out_dir / "benefit.csv", benefit_csv_text(a, settings));
    write_text_file(settings.out_dir / "psychometric.csv", psychometric_csv_text(a, target));
    write_srt_anova(a, settings);
    std::vector<Figure> figures;
    srt_figure(a, settings, figures);
    psychometric_figure(a, settings, figures);
    const std::vector<Figure> tracks = track_figures(a, settings);
    const std::string procedure = procedure_text(a);
    ReportText r;
    r.md = fmt::format("# {}\n\nData: `{}`{}. Procedure: {}.\n\n", settings.title, settings.source.string(),
                                 settings.protocol.empty() ? "" : fmt::format(", protocol `{}`", settings.protocol.string()),
                                 procedure);
    r.html = fmt::format(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{0}</title><style>body{{font-family:sans-serif;"
        "max-width:60rem;margin:2rem auto;padding:0 1rem}}table{{border-collapse:collapse}}td,th{{border:1px solid "
        "#ccc;padding:.2rem .5rem;text-align:right}}th{{background:#f3f3f3}}</style></head><body>\n<h1>{0}</h1>\n"
        "<p>Data: <code>{1}</code>. Procedure: {2}.</p>\n",
        xml_escape(settings.title), xml_escape(settings.source.string()), xml_escape(procedure));
    if (!a.masker.empty()) {
        r.md += a.masker + "\n\n";
        r.html += "<p>" + xml_escape(a.masker) + "</p>\n";
    }
    report_srt_means(a, r);
    report_benefits(a, settings, r);
    report_convergence(a, r);
    report_subject_srts(a, r);
    report_fits(a, target, r);
    report_figures_and_notes(a, settings, figures, tracks, r);
    r.html += "</body></html>\n";
    write_text_file(settings.out_dir / "report.md", r.md);
    write_text_file(settings.out_dir / "index.html", r.html);
}

SrtAnalysis analyze_adaptive_file(const AdaptiveAnalyzeSettings& s) {
    if (s.protocol.empty())
        throw UsageError("--protocol: the adaptive analysis needs the protocol whose [adaptive] rules made the tracks");
    const Protocol protocol = load_protocol(s.protocol);
    const AdaptiveProtocol adaptive = adaptive_protocol(protocol);
    if (!adaptive.enabled)
        throw InputError(s.protocol, 0, 0, "adaptive", "expected an [adaptive] section: the protocol runs no adaptive tracks");
    const auto rows = read_adaptive_trials(s.input);
    SrtAnalysis a = analyze_srt(rows, adaptive.track, protocol.condition_names(), adaptive.reference, s.input.string(),
                                s.confidence, &adaptive, s.include_unconverged);
    int keywords = 1;
    for (const auto& r : rows) keywords = std::max(keywords, r.keywords);
    a.warnings = adaptive_design_warnings(adaptive, keywords);
    a.masker = masker_description(adaptive);
    for (const auto& w : a.warnings) log_warning("{}", w);
    SrtReportSettings rs;
    rs.out_dir = s.out_dir;
    rs.source = s.input;
    rs.protocol = s.protocol;
    rs.title = s.title;
    rs.confidence = s.confidence;
    write_srt_report(a, rs);
    log_info("SRT report written to {}", s.out_dir.string());
    return a;
}

void write_srt_simulation(const fs::path& out_dir, const SrtSimulationResult& r) {
    fs::create_directories(out_dir);
    std::string csv = csv_line({"method", "procedure", "estimator", "sentences", "listeners", "valid", "unconverged",
                                "included_unconverged", "l50_db", "slope_per_db", "ceiling", "assumed_slope_per_db",
                                "keywords", "true_db", "mean_db", "bias_db", "sd_db", "rmse_db", "mean_presentations",
                                "seed"});
    const auto na = [](double v) { return std::isfinite(v) ? full(v) : std::string("NA"); };
    for (const auto& row : r.rows)
        csv += csv_line({"simulation", to_string(r.settings.track.procedure), row.estimator, std::to_string(row.sentences),
                         std::to_string(r.settings.listeners), std::to_string(row.estimates),
                         std::to_string(row.unconverged), r.settings.include_unconverged ? "1" : "0",
                         full(r.settings.listener.l50_db), full(r.settings.listener.slope_per_db),
                         full(r.settings.listener.ceiling), full(r.settings.track.slope_per_db),
                         std::to_string(r.settings.listener.keywords), na(row.true_db), full(row.mean_db),
                         na(row.bias_db), full(row.sd_db), na(row.rmse_db), full(row.mean_presentations),
                         std::to_string(r.settings.seed)});
    write_text_file(out_dir / "srt_simulation.csv", csv);
    detail::XyPlot p;
    p.title = "SRT by simulation: spread and bias by track length";
    p.x_label = "Sentences per track";
    p.y_label = "dB";
    p.y_from_zero = true;
    p.caption = fmt::format("filled: SD, open: bias; {} simulated listeners per point (L50 {} dB, slope {}/dB, {} keywords), seed {}",
                            r.settings.listeners, r.settings.listener.l50_db, r.settings.listener.slope_per_db,
                            r.settings.listener.keywords, r.settings.seed);
    int color = 0;
    for (const std::string estimator : {"mean", "ml"}) {
        detail::XySeries sd, bias;
        sd.name = "SD, " + estimator;
        bias.name = "bias, " + estimator;
        sd.color = bias.color = color++;
        bias.filled.clear();
        for (const auto& row : r.rows) {
            if (row.estimator != estimator || row.estimates == 0) continue;
            sd.x.push_back(row.sentences);
            sd.y.push_back(row.sd_db);
            bias.x.push_back(row.sentences);
            bias.y.push_back(row.bias_db);
            bias.filled.push_back(false);
        }
        p.series.push_back(sd);
        p.series.push_back(bias);
    }
    write_png(out_dir / "srt_simulation.png", p);
}

}  // namespace avsi::analysis
