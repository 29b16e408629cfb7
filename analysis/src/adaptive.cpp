// Adaptive SRT tracks, estimates, the psychometric fit and simulated
// listeners (see adaptive.h: MacLeod & Summerfield 1990, HINT, Brand &
// Kollmeier 2002).
#include "avsi/analysis/adaptive.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/protocol.h"
#include "avsi/core/rng.h"
#include "simulation_shards.h"

namespace avsi::analysis {

namespace {

double srt_logit(double p) { return std::log(p / (1.0 - p)); }
double srt_logistic(double x) { return 1.0 / (1.0 + std::exp(-x)); }

}  // namespace

std::vector<TrackStep> in_units(const AdaptiveProtocol& adaptive, const std::vector<TrackStep>& steps) {
    std::vector<TrackStep> out = steps;
    for (auto& s : out) {
        s.level_db = adaptive.value_of(s.level_db);
        s.next_level_db = adaptive.value_of(s.next_level_db);
        s.step_db = s.next_level_db - s.level_db;
    }
    return out;
}

void validate(const TrackSettings& s, const std::string& source) {
    DiagnosticList problems;
    auto bad = [&](const char* field, const std::string& what) {
        problems.add(source, 0, 0, fmt::format("adaptive.{}", field), what);
    };
    if (!std::isfinite(s.min_db) || !std::isfinite(s.max_db) || s.min_db >= s.max_db)
        bad("min_snr_db", fmt::format("expected min_snr_db < max_snr_db, got {} and {}", s.min_db, s.max_db));
    else if (!(s.start_db >= s.min_db && s.start_db <= s.max_db))
        bad("start_snr_db", fmt::format("expected a level in [{}, {}], got {}", s.min_db, s.max_db, s.start_db));
    if (!(s.large_step_db > 0 && s.large_step_db <= 20))
        bad("large_step_db", fmt::format("expected a step in (0, 20] dB, got {}", s.large_step_db));
    if (!(s.small_step_db > 0 && s.small_step_db <= 20))
        bad("small_step_db", fmt::format("expected a step in (0, 20] dB, got {}", s.small_step_db));
    if (s.large_steps < 0 || s.large_steps > 1000)
        bad("large_steps", fmt::format("expected an integer in [0, 1000], got {}", s.large_steps));
    if (s.max_first_repeats < 0 || s.max_first_repeats > 100)
        bad("max_first_repeats", fmt::format("expected an integer in [0, 100], got {}", s.max_first_repeats));
    if (!(s.target > 0 && s.target < 1)) bad("target", fmt::format("expected a proportion in (0, 1), got {}", s.target));
    if (!(s.slope_per_db > 0 && s.slope_per_db <= 1))
        bad("slope_per_db", fmt::format("expected a slope in (0, 1] per dB, got {}", s.slope_per_db));
    if (!(s.f_start > 0 && s.f_start <= 10)) bad("f_start", fmt::format("expected a factor in (0, 10], got {}", s.f_start));
    if (!(s.f_ratio >= 1 && s.f_ratio <= 10)) bad("f_ratio", fmt::format("expected a ratio in [1, 10], got {}", s.f_ratio));
    if (!(s.f_min > 0 && s.f_min <= s.f_start))
        bad("f_min", fmt::format("expected a factor in (0, f_start = {}], got {}", s.f_start, s.f_min));
    if (s.srt_from < 1 || s.srt_from > 1000)
        bad("srt_from", fmt::format("expected a sentence number in [1, 1000], got {}", s.srt_from));
    if (s.min_reversals < 0 || s.min_reversals > 1000)
        bad("min_reversals", fmt::format("expected an integer in [0, 1000], got {}", s.min_reversals));
    problems.throw_if_any();
}

AdaptiveTrack::AdaptiveTrack(TrackSettings settings) : m_settings(std::move(settings)) {
    validate(m_settings);
    m_level_db = m_settings.start_db;
}

int AdaptiveTrack::sentences() const {
    if (m_steps.empty()) return 0;
    return m_steps.back().repeat ? m_steps.back().sentence - 1 : m_steps.back().sentence;
}

double bk_step_factor(const TrackSettings& s, int reversals) {
    return std::max(s.f_min, s.f_start * std::pow(s.f_ratio, -static_cast<double>(reversals)));
}

const TrackStep& AdaptiveTrack::record(int keywords, int correct) {
    if (keywords < 1 || correct < 0 || correct > keywords)
        throw InputError("adaptive track", 0, 0, "score",
                         fmt::format("expected 0 ≤ correct ≤ keywords and keywords ≥ 1, got {} of {}", correct, keywords));
    const TrackSettings& s = m_settings;
    TrackStep step;
    step.presentation = static_cast<int>(m_steps.size()) + 1;
    if (m_repeat) {
        step.sentence = m_steps.back().sentence;
        step.attempt = m_steps.back().attempt + 1;
    } else {
        step.sentence = m_steps.empty() ? 1 : m_steps.back().sentence + 1;
        step.attempt = 1;
    }
    step.level_db = m_level_db;
    step.keywords = keywords;
    step.correct = correct;
    step.sentence_correct = correct == keywords;

    double wanted = 0.0;  // the signed step before the bounds
    step.repeat = false;
    if (s.procedure == AdaptiveProcedure::Sentence) {
        const bool first = step.sentence == 1;
        if (first && s.repeat_first && !step.sentence_correct && step.attempt <= s.max_first_repeats) {
            // First sentence, still wrong: the same sentence again, higher.
            wanted = s.large_step_db;
            step.repeat = true;
        } else {
            const double size = step.sentence <= s.large_steps ? s.large_step_db : s.small_step_db;
            wanted = step.sentence_correct ? -size : size;
        }
    } else {
        const double prop = static_cast<double>(correct) / keywords;
        wanted = -bk_step_factor(s, m_reversals) * (prop - s.target) / s.slope_per_db;
    }
    double next = m_level_db + wanted;
    if (next > s.max_db || next < s.min_db) {
        next = std::clamp(next, s.min_db, s.max_db);
        step.at_bound = true;
    }
    step.next_level_db = next;
    step.step_db = next - m_level_db;
    // Reversals follow the direction of the rule's step (the bound may make it zero).
    const int direction = wanted > 0 ? 1 : (wanted < 0 ? -1 : 0);
    // The upward repeats of the first sentence are the track's approach, not
    // part of its up-down sequence: they set the direction without reversing.
    if (direction != 0) {
        if (m_last_direction != 0 && direction != m_last_direction) {
            step.reversal = true;
            ++m_reversals;
        }
        m_last_direction = direction;
    }
    step.reversals = m_reversals;
    m_level_db = next;
    m_repeat = step.repeat;
    m_steps.push_back(step);
    return m_steps.back();
}

std::vector<double> srt_levels(const TrackSettings& settings, const std::vector<TrackStep>& steps) {
    std::vector<double> levels;
    for (std::size_t i = 0; i < steps.size(); ++i) {
        const TrackStep& st = steps[i];
        if (st.repeat) continue;  // not the sentence's last presentation
        if (st.sentence >= settings.srt_from) levels.push_back(st.level_db);
    }
    if (settings.srt_include_next && !steps.empty() && !steps.back().repeat &&
        steps.back().sentence + 1 >= settings.srt_from)
        levels.push_back(steps.back().next_level_db);
    return levels;
}

double PsychometricFit::p(double level_db) const {
    return ceiling * srt_logistic(4.0 * slope_per_db * (level_db - l50_db));
}

double PsychometricFit::level_at(double target) const {
    if (!(target < ceiling)) return std::numeric_limits<double>::quiet_NaN();
    return l50_db + srt_logit(target / ceiling) / (4.0 * slope_per_db);
}

double PsychometricFit::se_level_at(double target) const {
    if (!(target < ceiling)) return std::numeric_limits<double>::quiet_NaN();
    // L_t = (logit(t/c) − a) / b with a = −b·L50, b = 4s.
    const double b = 4.0 * slope_per_db;
    const double a = -b * l50_db;
    const double da = -1.0 / b;
    const double db = -(srt_logit(target / ceiling) - a) / (b * b);
    const double var = da * da * var_a + 2 * da * db * cov_a_b + db * db * var_b;
    return std::sqrt(std::max(0.0, var));
}

namespace {

// The level that separates the responses perfectly (every trial below it
// wrong, every trial above it right, any at it), if one does: the
// likelihood then keeps rising as the slope grows.
std::optional<double> separating_level(const std::vector<PsychometricPoint>& points) {
    for (const auto& cut : points) {
        bool separated = true;
        for (const auto& pt : points) {
            if (pt.trials == 0) continue;
            if (pt.level_db < cut.level_db && pt.correct != 0) separated = false;
            if (pt.level_db > cut.level_db && pt.correct != pt.trials) separated = false;
        }
        if (separated) return cut.level_db;
    }
    return std::nullopt;
}

// The log-likelihood of the points under p = c·σ(a + b·(L − center)).
double psychometric_log_likelihood(const std::vector<PsychometricPoint>& points, double center, double ceiling,
                                   double a, double b) {
    const double log_c = std::log(ceiling);
    double ll = 0.0;
    for (const auto& pt : points) {
        if (pt.trials == 0) continue;
        const double eta = a + b * (pt.level_db - center);
        // log σ = −log(1 + e^−η), log(1 − σ) = −log(1 + e^η), both stable;
        // with a ceiling, log p = log c + log σ and 1 − p = (1 − σ) + (1 − c)·σ.
        const double log_s = -std::log1p(std::exp(-std::fabs(eta))) - std::max(0.0, -eta);
        const double log_q1 = -std::log1p(std::exp(-std::fabs(eta))) - std::max(0.0, eta);
        const double log_q = ceiling == 1.0 ? log_q1 : std::log1p(-ceiling * std::exp(log_s));
        ll += pt.correct * (log_c + log_s) + (pt.trials - pt.correct) * log_q;
    }
    return ll;
}

// Fisher scoring: per point the weight n·(dp/dη)²/(p(1 − p)) and the score
// residual (y − n·p)·(dp/dη)/(p(1 − p)), dp/dη = c·σ(1 − σ); for c = 1
// these are n·p(1 − p) and y − n·p (Newton–Raphson).
void fisher_weight_residual(const PsychometricPoint& pt, double eta, double ceiling, double& w, double& r) {
    const double sg = srt_logistic(eta);
    const double p = ceiling * sg;
    const double dp = ceiling * sg * (1 - sg);
    const double v = p * (1 - p);
    if (!(v > 0)) {
        w = 0.0;
        r = 0.0;
        return;
    }
    w = pt.trials * dp * dp / v;
    r = (pt.correct - pt.trials * p) * dp / v;
}

// The covariance {var a, var b, cov a b} of the centred (a, b) from the
// Fisher information at the fit (var b = cov = 0 with a fixed slope).
std::array<double, 3> fisher_covariance(const std::vector<PsychometricPoint>& points, double center, double ceiling,
                                        double a, double b, bool fixed_slope) {
    double haa = 0, hab = 0, hbb = 0;
    for (const auto& pt : points) {
        if (pt.trials == 0) continue;
        const double x = pt.level_db - center;
        double w = 0.0, r = 0.0;
        fisher_weight_residual(pt, a + b * x, ceiling, w, r);
        haa += w;
        hab += w * x;
        hbb += w * x * x;
    }
    double var_a = 0, var_b = 0, cov = 0;
    if (fixed_slope) {
        var_a = 1.0 / haa;
    } else {
        const double det = haa * hbb - hab * hab;
        var_a = hbb / det;
        var_b = haa / det;
        cov = -hab / det;
    }
    return {var_a, var_b, cov};
}

}  // namespace

PsychometricFit fit_psychometric(const std::vector<PsychometricPoint>& points, std::optional<double> fixed_slope,
                                 double ceiling) {
    if (!(ceiling > 0.0 && ceiling <= 1.0))
        throw InputError("psychometric fit", 0, 0, "ceiling", fmt::format("expected a proportion in (0, 1], got {}", ceiling));
    PsychometricFit fit;
    fit.ceiling = ceiling;
    fit.slope_fixed = fixed_slope.has_value();
    int total = 0, correct = 0;
    double sum_level = 0.0;
    for (const auto& pt : points) {
        if (pt.trials < 0 || pt.correct < 0 || pt.correct > pt.trials || !std::isfinite(pt.level_db))
            throw InputError("psychometric fit", 0, 0, "points",
                             fmt::format("expected 0 ≤ correct ≤ trials at a finite level, got {} of {} at {}",
                                         pt.correct, pt.trials, pt.level_db));
        if (pt.trials == 0) continue;
        ++fit.points;
        total += pt.trials;
        correct += pt.correct;
        sum_level += pt.level_db * pt.trials;
    }
    fit.trials = total;
    if (total == 0 || correct == 0 || correct == total) {
        fit.note = total == 0 ? "no trials" : (correct == 0 ? "every trial wrong: no finite threshold"
                                                            : "every trial right: no finite threshold");
        return fit;
    }
    if (fixed_slope && !(*fixed_slope > 0)) throw InputError("psychometric fit", 0, 0, "slope", "expected a slope > 0");
    // (Quasi-)complete separation: every trial below some level wrong, every
    // trial above it right (any at that level): the likelihood keeps rising
    // as the slope grows, so there is no finite free-slope estimate.
    if (!fixed_slope)
        if (const auto cut = separating_level(points)) {
            fit.note = fmt::format("the responses separate perfectly by level (all wrong below {} dB, all right "
                                   "above): no finite slope",
                                   *cut);
            return fit;
        }
    const double center = sum_level / total;  // centring keeps the Hessian well conditioned

    auto loglik = [&](double a, double b) { return psychometric_log_likelihood(points, center, ceiling, a, b); };
    auto weight_residual = [&](const PsychometricPoint& pt, double eta, double& w, double& r) {
        fisher_weight_residual(pt, eta, ceiling, w, r);
    };
    // Start: the pooled logit at the centre (below the ceiling), a moderate slope.
    double a = srt_logit(std::min(0.95, static_cast<double>(correct) / total / ceiling));
    double b = fixed_slope ? 4.0 * *fixed_slope : 0.4;
    double ll = loglik(a, b);
    bool done = false;
    for (int it = 1; it <= 200 && !done; ++it) {
        fit.iterations = it;
        double ga = 0, gb = 0, haa = 0, hab = 0, hbb = 0;
        for (const auto& pt : points) {
            if (pt.trials == 0) continue;
            const double x = pt.level_db - center;
            double w = 0.0, r = 0.0;
            weight_residual(pt, a + b * x, w, r);
            ga += r;
            gb += r * x;
            haa += w;
            hab += w * x;
            hbb += w * x * x;
        }
        double da = 0, db = 0;
        if (fixed_slope) {
            if (haa <= 0) break;
            da = ga / haa;
        } else {
            const double det = haa * hbb - hab * hab;
            if (!(det > 0)) break;
            da = (hbb * ga - hab * gb) / det;
            db = (haa * gb - hab * ga) / det;
        }
        // Step halving until the likelihood does not fall.
        double t = 1.0;
        double na = a + da, nb = b + db, nll = loglik(na, nb);
        while (nll < ll - 1e-12 && t > 1e-6) {
            t *= 0.5;
            na = a + t * da;
            nb = b + t * db;
            nll = loglik(na, nb);
        }
        const bool small = std::fabs(na - a) < 1e-10 && std::fabs(nb - b) < 1e-10;
        a = na;
        b = nb;
        ll = nll;
        if (small || (std::fabs(t * da) < 1e-9 && std::fabs(t * db) < 1e-9)) done = true;
        if (std::fabs(b) > 200.0) break;  // running off to a step function
    }
    if (!done) {
        fit.note = std::fabs(b) > 200.0 ? "the responses separate perfectly by level: no finite slope"
                                        : "the fit did not converge";
        return fit;
    }
    if (!(b > 0)) {
        fit.note = fmt::format("the fitted slope is not positive ({:.4f} per dB): performance does not rise with level",
                               b / 4.0);
        return fit;
    }
    const auto [var_a, var_b, cov] = fisher_covariance(points, center, ceiling, a, b, fixed_slope.has_value());
    fit.converged = true;
    fit.slope_per_db = b / 4.0;
    fit.l50_db = center - a / b;
    fit.log_likelihood = ll;
    // Back to the uncentred intercept A = a − b·center for the public covariance.
    fit.var_a = var_a + center * center * var_b - 2 * center * cov;
    fit.var_b = var_b;
    fit.cov_a_b = cov - center * var_b;
    fit.se_slope = std::sqrt(var_b) / 4.0;
    fit.se_l50_db = fit.se_level_at(0.5);
    return fit;
}

std::vector<PsychometricPoint> track_points(const std::vector<TrackStep>& steps) {
    std::vector<PsychometricPoint> out;
    out.reserve(steps.size());
    for (const auto& s : steps) out.push_back({s.level_db, s.keywords, s.correct});
    return out;
}

double tracked_proportion(const TrackSettings& s, int keywords) {
    return s.procedure == AdaptiveProcedure::Sentence ? std::pow(0.5, 1.0 / std::max(1, keywords)) : s.target;
}

double procedure_threshold_db(const TrackSettings& s, double l50_db, double slope_per_db, int keywords) {
    return l50_db + srt_logit(tracked_proportion(s, keywords)) / (4.0 * slope_per_db);
}

double listener_p(const SimulatedListener& listener, double level_db) {
    return listener.ceiling * srt_logistic(4.0 * listener.slope_per_db * (level_db - listener.l50_db));
}

std::optional<double> procedure_threshold_db(const TrackSettings& s, const SimulatedListener& listener) {
    const double p = tracked_proportion(s, listener.keywords);
    if (!(p < listener.ceiling)) return std::nullopt;
    return listener.l50_db + srt_logit(p / listener.ceiling) / (4.0 * listener.slope_per_db);
}

TrackConvergence track_convergence(const TrackSettings& s, const std::vector<TrackStep>& steps) {
    TrackConvergence c;
    c.reversals = steps.empty() ? 0 : steps.back().reversals;
    for (const auto& st : steps) {
        if (!st.at_bound || st.sentence < s.srt_from) continue;
        // The rule's direction: up after a wrong sentence (or below the word target).
        const bool up = s.procedure == AdaptiveProcedure::Sentence
                            ? !st.sentence_correct
                            : static_cast<double>(st.correct) / st.keywords < s.target;
        c.at_bound = true;
        c.converged = false;
        c.reason = fmt::format("at the {} bound from sentence {}", up ? "upper" : "lower", st.sentence);
        break;
    }
    if (s.min_reversals > 0 && c.reversals < s.min_reversals) {
        c.converged = false;
        c.reason += fmt::format("{}{} reversal(s), fewer than {}", c.reason.empty() ? "" : "; ", c.reversals,
                                s.min_reversals);
    }
    return c;
}

SrtEstimate estimate_srt(const TrackSettings& settings, const std::vector<TrackStep>& steps) {
    return estimate_srt(settings, steps,
                        settings.procedure == AdaptiveProcedure::Sentence ? SrtEstimator::MeanOfLevels
                                                                          : settings.estimator);
}

SrtEstimate estimate_srt(const TrackSettings& settings, const std::vector<TrackStep>& steps, SrtEstimator estimator,
                         double ceiling) {
    SrtEstimate e;
    e.estimator = estimator;
    if (estimator == SrtEstimator::MeanOfLevels) {
        const std::vector<double> levels = srt_levels(settings, steps);
        e.levels = static_cast<int>(levels.size());
        if (levels.size() < 2) {
            e.note = fmt::format("{} level(s) from sentence {} on: the track is too short for the mean of levels",
                                 levels.size(), settings.srt_from);
            return e;
        }
        const double mean = std::accumulate(levels.begin(), levels.end(), 0.0) / levels.size();
        double ss = 0.0;
        for (double l : levels) ss += (l - mean) * (l - mean);
        e.srt_db = mean;
        e.se_db = std::sqrt(ss / (levels.size() - 1)) / std::sqrt(static_cast<double>(levels.size()));
        e.valid = true;
        return e;
    }
    const PsychometricFit fit = fit_psychometric(track_points(steps), std::nullopt, ceiling);
    e.fit = fit;
    if (!fit.converged) {
        e.note = fit.note;
        return e;
    }
    int keywords = 1;
    for (const auto& s : steps) keywords = std::max(keywords, s.keywords);
    const double target = tracked_proportion(settings, keywords);
    if (!(target < ceiling)) {
        e.note = fmt::format("the tracked proportion {:.3f} is at or above the ceiling {:.3f}: no threshold", target,
                             ceiling);
        return e;
    }
    e.srt_db = fit.level_at(target);
    e.se_db = fit.se_level_at(target);
    // A threshold further outside the levels the track presented than their
    // own span is an extrapolation of a nearly flat fit (a track that never
    // came near its target, e.g. against a ceiling), not an estimate.
    double lowest = steps.front().level_db, highest = lowest;
    for (const auto& s : steps) {
        lowest = std::min(lowest, s.level_db);
        highest = std::max(highest, s.level_db);
    }
    const double span = highest - lowest;
    if (e.srt_db < lowest - span || e.srt_db > highest + span) {
        e.note = fmt::format("the fitted threshold ({:.3g}) lies far outside the levels the track presented ([{}, {}])",
                             e.srt_db, lowest, highest);
        return e;
    }
    e.valid = true;
    return e;
}

int simulate_response(const SimulatedListener& listener, double level_db, Rng& rng) {
    const double p = listener_p(listener, level_db);
    int correct = 0;
    for (int k = 0; k < listener.keywords; ++k)
        if (rng.uniform() < p) ++correct;
    return correct;
}

namespace {

// The checks of simulate_srt's settings (InputError naming the option, all at once).
void validate_simulation(const SrtSimulationSettings& settings) {
    validate(settings.track, "simulate-srt");
    DiagnosticList problems;
    if (settings.listener.keywords < 1 || settings.listener.keywords > 20)
        problems.add("simulate-srt", 0, 0, "--keywords",
                     fmt::format("expected an integer in [1, 20], got {}", settings.listener.keywords));
    if (!(settings.listener.slope_per_db > 0 && settings.listener.slope_per_db <= 1))
        problems.add("simulate-srt", 0, 0, "--slope",
                     fmt::format("expected a slope in (0, 1] per dB, got {}", settings.listener.slope_per_db));
    if (settings.listeners < 2 || settings.listeners > 1000000)
        problems.add("simulate-srt", 0, 0, "--listeners",
                     fmt::format("expected an integer in [2, 1000000], got {}", settings.listeners));
    if (settings.sentence_counts.empty())
        problems.add("simulate-srt", 0, 0, "--sentences", "expected at least one sentence count");
    for (int n : settings.sentence_counts)
        if (n < settings.track.srt_from + 1 || n > 1000)
            problems.add("simulate-srt", 0, 0, "--sentences",
                         fmt::format("expected sentence counts in [{} (srt_from + 1), 1000], got {}",
                                     settings.track.srt_from + 1, n));
    if (!(settings.listener.ceiling > 0 && settings.listener.ceiling <= 1))
        problems.add("simulate-srt", 0, 0, "--ceiling",
                     fmt::format("expected a proportion in (0, 1], got {}", settings.listener.ceiling));
    if (!(settings.start_offset_sd_db >= 0 && settings.start_offset_sd_db <= 30))
        problems.add("simulate-srt", 0, 0, "--start-sd",
                     fmt::format("expected an SD in [0, 30] dB, got {}", settings.start_offset_sd_db));
    problems.throw_if_any();
}

const std::array<SrtEstimator, 2> simulation_estimators = {SrtEstimator::MeanOfLevels, SrtEstimator::MaximumLikelihood};

// One simulated listener's track of n sentences: its presentations, whether
// it converged, and each estimator's estimate (none when not valid, or when
// an unconverged track is left out).
struct ListenerOutcome {
    int presentations = 0;
    bool converged = true;
    std::array<std::optional<double>, 2> estimates;
};

ListenerOutcome simulate_listener(const SrtSimulationSettings& settings, int n, int listener) {
    // One stream per (length, listener): a row does not depend on the other rows.
    Rng rng(derive_seed(settings.seed, fmt::format("n{}/listener{}", n, listener)));
    TrackSettings track = settings.track;
    if (settings.start_offset_sd_db > 0)
        track.start_db = std::clamp(track.start_db + rng.normal(0.0, settings.start_offset_sd_db), track.min_db,
                                    track.max_db);
    AdaptiveTrack t(track);
    while (t.sentences() < n) t.record(settings.listener.keywords, simulate_response(settings.listener, t.level_db(), rng));
    ListenerOutcome o;
    o.presentations = static_cast<int>(t.steps().size());
    o.converged = track_convergence(track, t.steps()).converged;
    if (!o.converged && !settings.include_unconverged) return o;
    for (std::size_t e = 0; e < simulation_estimators.size(); ++e) {
        const SrtEstimate est = estimate_srt(track, t.steps(), simulation_estimators[e]);
        if (est.valid) o.estimates[e] = est.srt_db;
    }
    return o;
}

// The rows of track length n (one per estimator) from every listener's outcome, in order.
void add_simulation_rows(const SrtSimulationSettings& settings, double truth, int n,
                         const std::vector<ListenerOutcome>& outcomes, SrtSimulationResult& result) {
    std::vector<std::vector<double>> values(simulation_estimators.size());
    double presentations = 0.0;
    int unconverged = 0;
    for (const auto& o : outcomes) {
        presentations += static_cast<double>(o.presentations);
        if (!o.converged) ++unconverged;
        for (std::size_t e = 0; e < simulation_estimators.size(); ++e)
            if (o.estimates[e]) values[e].push_back(*o.estimates[e]);
    }
    for (std::size_t e = 0; e < simulation_estimators.size(); ++e) {
        SrtSimulationRow row;
        row.sentences = n;
        row.estimator = to_string(simulation_estimators[e]);
        row.true_db = truth;
        row.estimates = static_cast<int>(values[e].size());
        row.unconverged = unconverged;
        row.mean_presentations = presentations / settings.listeners;
        if (!values[e].empty()) {
            const double m = std::accumulate(values[e].begin(), values[e].end(), 0.0) / values[e].size();
            double ss = 0.0, sq = 0.0;
            for (double v : values[e]) {
                ss += (v - m) * (v - m);
                sq += (v - truth) * (v - truth);
            }
            row.mean_db = m;
            row.bias_db = m - truth;
            row.sd_db = values[e].size() > 1 ? std::sqrt(ss / (values[e].size() - 1)) : 0.0;
            row.rmse_db = std::sqrt(sq / values[e].size());
        }
        result.rows.push_back(row);
    }
}

double simulation_truth(const SrtSimulationSettings& settings) {
    return procedure_threshold_db(settings.track, settings.listener).value_or(std::numeric_limits<double>::quiet_NaN());
}

// The settings a shard file records and the merge compares: all of them.
nlohmann::json simulation_settings_json(const SrtSimulationSettings& s) {
    const TrackSettings& t = s.track;
    return {{"track", {{"procedure", to_string(t.procedure)}, {"start_db", t.start_db}, {"min_db", t.min_db},
                       {"max_db", t.max_db}, {"large_step_db", t.large_step_db}, {"large_steps", t.large_steps},
                       {"small_step_db", t.small_step_db}, {"repeat_first", t.repeat_first},
                       {"max_first_repeats", t.max_first_repeats}, {"target", t.target},
                       {"slope_per_db", t.slope_per_db}, {"f_start", t.f_start}, {"f_ratio", t.f_ratio},
                       {"f_min", t.f_min}, {"srt_from", t.srt_from}, {"min_reversals", t.min_reversals},
                       {"srt_include_next", t.srt_include_next}, {"estimator", to_string(t.estimator)}}},
            {"listener", {{"l50_db", s.listener.l50_db}, {"slope_per_db", s.listener.slope_per_db},
                          {"keywords", s.listener.keywords}, {"ceiling", s.listener.ceiling}}},
            {"sentence_counts", s.sentence_counts},
            {"listeners", s.listeners},
            {"seed", s.seed},
            {"start_offset_sd_db", s.start_offset_sd_db},
            {"include_unconverged", s.include_unconverged}};
}

const detail::ShardKind& srt_shard_kind() {
    static const detail::ShardKind kind{
        "avsi-simulate-srt-shard", "srt_simulation",
        {"sentences", "listener", "presentations", "converged", "mean_db", "ml_db"}, "avsi simulate-srt … --out DIR"};
    return kind;
}

}  // namespace

SrtSimulationResult simulate_srt(const SrtSimulationSettings& settings) {
    validate_simulation(settings);
    SrtSimulationResult result;
    result.settings = settings;
    const double truth = simulation_truth(settings);
    for (int n : settings.sentence_counts) {
        std::vector<ListenerOutcome> outcomes;
        for (int listener = 0; listener < settings.listeners; ++listener)
            outcomes.push_back(simulate_listener(settings, n, listener));
        add_simulation_rows(settings, truth, n, outcomes, result);
    }
    return result;
}

void simulate_srt_shard(const SrtSimulationSettings& settings, ShardSpec shard, const std::filesystem::path& out_dir) {
    validate_simulation(settings);
    const auto [first, last] = shard_range(static_cast<std::size_t>(settings.listeners), shard);
    const auto number = [](const std::optional<double>& v) { return v ? fmt::format("{}", *v) : std::string("NA"); };
    std::string rows;
    for (int n : settings.sentence_counts)
        for (std::size_t listener = first; listener < last; ++listener) {
            const ListenerOutcome o = simulate_listener(settings, n, static_cast<int>(listener));
            rows += fmt::format("{},{},{},{:d},{},{}\n", n, listener, o.presentations, o.converged,
                                number(o.estimates[0]), number(o.estimates[1]));
        }
    detail::write_shard_file(out_dir, srt_shard_kind(), shard, simulation_settings_json(settings), rows);
    log_info("simulate-srt: shard {} wrote {} of the {} listeners of each track length to {}", shard.text(),
             first < last ? fmt::format("listeners {}..{}", first, last - 1) : std::string("none"), settings.listeners,
             detail::shard_file_path(out_dir, srt_shard_kind(), shard).string());
}

SrtSimulationResult merge_srt_shards(const SrtSimulationSettings& settings, const std::filesystem::path& out_dir) {
    validate_simulation(settings);
    const std::size_t total = static_cast<std::size_t>(settings.listeners);
    const auto& counts = settings.sentence_counts;
    std::vector<std::vector<ListenerOutcome>> outcomes(counts.size());
    std::size_t at = 0, listener = 0;  // the next row expected: track length `at`, listener `listener`
    const auto row = [&](ShardSpec shard, const detail::ShardRow& r) {
        const auto [first, last] = shard_range(total, shard);
        if (at >= counts.size() || first == last)
            r.fail(0, fmt::format("expected the end of shard {}, got another row", shard.text()));
        const long long n = r.integer(0), i = r.integer(1);
        if (n != counts[at] || i != static_cast<long long>(listener))
            r.fail(n != counts[at] ? 0 : 1,
                   fmt::format("expected sentences {} listener {} (shard {} holds listeners {}..{} of each track "
                               "length), got sentences {} listener {}",
                               counts[at], listener, shard.text(), first, last - 1, n, i));
        ListenerOutcome o;
        const long long p = r.integer(2), c = r.integer(3);
        if (p < n || p > 100000) r.fail(2, fmt::format("expected a count of presentations in [{}, 100000], got {}", n, p));
        if (c != 0 && c != 1) r.fail(3, fmt::format("expected 0 or 1, got {}", c));
        o.presentations = static_cast<int>(p);
        o.converged = c == 1;
        for (std::size_t e = 0; e < 2; ++e)
            if (!r.is_na(4 + e)) o.estimates[e] = r.number(4 + e);
        outcomes[at].push_back(o);
        if (++listener == last) listener = first, ++at;
    };
    const auto end = [&](ShardSpec shard, const std::function<void(const std::string&)>& fail) {
        const auto [first, last] = shard_range(total, shard);
        if (at < counts.size() && first < last)
            fail(fmt::format("cut short: shard {} ends before sentences {} listener {} (it holds listeners {}..{} "
                             "for each track length: {})",
                             shard.text(), counts[at], listener, first, last - 1, fmt::join(counts, ", ")));
        at = 0;
        listener = shard_range(total, ShardSpec{shard.index + 1, shard.count}).first;
    };
    const std::size_t shards =
        detail::read_shard_files(out_dir, srt_shard_kind(), simulation_settings_json(settings), row, end);
    SrtSimulationResult result;
    result.settings = settings;
    const double truth = simulation_truth(settings);
    for (std::size_t j = 0; j < counts.size(); ++j) add_simulation_rows(settings, truth, counts[j], outcomes[j], result);
    log_info("simulate-srt: merged {} shards in {}", shards, out_dir.string());
    return result;
}

std::string srt_simulation_table(const SrtSimulationResult& r) {
    const auto& s = r.settings;
    const auto db = [](double v, int width) {
        return std::isfinite(v) ? fmt::format("{:>{}.2f}", v, width) : fmt::format("{:>{}}", "NA", width);
    };
    const double truth = r.rows.empty() ? 0.0 : r.rows.front().true_db;
    std::string out = fmt::format(
        "SRT by simulation ({} simulated listeners per row, seed {}): {} scoring{}, listener L50 {:.2f} dB, slope "
        "{:.3f}/dB, ceiling {:.3f}, {} keywords per sentence; {}\n",
        s.listeners, s.seed, to_string(s.track.procedure),
        s.track.procedure == AdaptiveProcedure::Word ? fmt::format(" (assumed slope {:.3f}/dB)", s.track.slope_per_db)
                                                     : std::string(),
        s.listener.l50_db, s.listener.slope_per_db, s.listener.ceiling, s.listener.keywords,
        std::isfinite(truth)
            ? fmt::format("the procedure targets {:.2f} dB", truth)
            : fmt::format("the procedure's target ({:.3f} per keyword) is at or above the ceiling: no threshold exists",
                          tracked_proportion(s.track, s.listener.keywords)));
    out += fmt::format("Tracks that hit a bound from sentence {} on or reversed fewer than {} times are {}.\n",
                       s.track.srt_from, s.track.min_reversals,
                       s.include_unconverged ? "counted and kept (--include-unconverged)" : "counted and left out");
    out += fmt::format("{:>9}  {:>9}  {:>9}  {:>11}  {:>9}  {:>8}  {:>8}  {:>8}  {:>13}\n", "sentences", "estimator",
                       "valid", "unconverged", "mean dB", "bias dB", "SD dB", "RMSE dB", "presentations");
    for (const auto& row : r.rows)
        out += fmt::format("{:>9}  {:>9}  {:>9}  {:>11}  {}  {}  {:>8.2f}  {}  {:>13.1f}\n", row.sentences,
                           row.estimator, row.estimates, row.unconverged, db(row.mean_db, 9), db(row.bias_db, 8),
                           row.sd_db, db(row.rmse_db, 8), row.mean_presentations);
    return out;
}

std::vector<std::string> adaptive_design_warnings(const AdaptiveProtocol& a, int keywords) {
    std::vector<std::string> out;
    if (!a.enabled) return out;
    const double tracked = tracked_proportion(a.track, keywords);
    for (const auto& [condition, ceiling] : a.ceilings)
        if (!(tracked < ceiling))
            out.push_back(fmt::format(
                "adaptive: condition \"{}\" has a ceiling of {:.3f} keywords right, at or below the {:.3f} per keyword "
                "the {} track aims at ({}): its tracks cannot converge and climb towards the bound; those that reach "
                "it are flagged and left out of the ANOVA and the benefit, the others are biased upwards",
                condition, ceiling, tracked, to_string(a.track.procedure),
                a.track.procedure == AdaptiveProcedure::Sentence
                    ? fmt::format("all {} keywords right half the time", keywords)
                    : fmt::format("target {:.2f}", a.track.target)));
    return out;
}

}  // namespace avsi::analysis
