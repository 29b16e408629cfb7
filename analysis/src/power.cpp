// Power by simulation (see power.h for the model).
#include "avsi/analysis/power.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "avsi/analysis/pairwise.h"
#include "avsi/analysis/rm_anova.h"
#include "avsi/analysis/scores.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/core/rng.h"
#include "simulation_shards.h"

namespace avsi::analysis {

namespace {

std::vector<std::string> split(const std::string& s, char sep) {
    std::vector<std::string> out;
    std::string part;
    for (char c : s + sep) {
        if (c == sep) {
            out.push_back(part);
            part.clear();
        } else if (c != ' ') {
            part += c;
        }
    }
    return out;
}

InputError option_error(const std::string& option, const std::string& message) {
    return InputError("", 0, 0, option, message);
}

struct SimOutcome {
    bool anova = false, anova_gg = false, contrast = false;
    double mean_percent = 0.0;
};

SimOutcome simulate_one(const PowerSettings& s, std::size_t n, std::size_t a, std::size_t b, Rng rng) {
    const std::size_t k = s.means_percent.size();
    const std::size_t spc = s.sentences_per_cell;
    std::vector<double> u(n), v(k * spc), base(k);
    for (auto& x : u) x = rng.normal(0.0, s.subject_sd);
    for (auto& x : v) x = rng.normal(0.0, s.sentence_sd);
    // Subject × condition slopes from their own stream, so the other draws
    // (and so every result with condition_sd = 0) stay what they were.
    std::vector<double> w(n * k, 0.0);
    if (s.condition_sd > 0.0) {
        Rng slopes = rng.derive("subject x condition");
        for (auto& x : w) x = slopes.normal(0.0, s.condition_sd);
    }
    for (std::size_t j = 0; j < k; ++j) base[j] = std::log(s.means_percent[j] / (100.0 - s.means_percent[j]));
    std::vector<double> values(n * k, 0.0);
    const double per_cell = double(spc * s.keywords_per_sentence);
    double total = 0.0;
    for (std::size_t i = 0; i < n; ++i)
        for (std::size_t list = 0; list < k; ++list) {
            const std::size_t condition = (list + i) % k;
            std::size_t correct = 0;
            for (std::size_t q = 0; q < spc; ++q) {
                const double eta = base[condition] + u[i] + v[list * spc + q] + w[i * k + condition];
                const double p = 1.0 / (1.0 + std::exp(-eta));
                for (std::size_t w = 0; w < s.keywords_per_sentence; ++w) correct += rng.uniform() < p ? 1 : 0;
            }
            values[i * k + condition] = 100.0 * double(correct) / per_cell;
            total += values[i * k + condition];
        }
    std::vector<std::string> subjects(n), conditions(k);
    const WithinData data = make_within_data(std::move(subjects), std::move(conditions), std::move(values));
    const AnovaResult anova = rm_anova(data);
    SimOutcome out;
    out.anova = anova.p_value && *anova.p_value < s.alpha;
    out.anova_gg = anova.greenhouse_geisser.p_value && *anova.greenhouse_geisser.p_value < s.alpha;
    const PairwiseComparison c = paired_comparison(data, a, b);
    out.contrast = c.p_value && *c.p_value < s.alpha;
    out.mean_percent = total / double(n * k);
    return out;
}

}  // namespace

std::vector<std::size_t> parse_subject_counts(const std::string& text) {
    std::vector<std::size_t> out;
    auto number = [&](const std::string& t) {
        const auto v = parse_int(t);
        if (!v || *v < 2 || *v > 100000)
            throw option_error("--subjects", fmt::format("expected subject counts ≥ 2 like 10..40, 10..40:5 or "
                                                         "10,20,30, got \"{}\"",
                                                         text));
        return std::size_t(*v);
    };
    if (const auto dots = text.find(".."); dots != std::string::npos) {
        std::string rest = text.substr(dots + 2);
        std::size_t step = 5;
        if (const auto colon = rest.find(':'); colon != std::string::npos) {
            step = number(rest.substr(colon + 1));
            rest = rest.substr(0, colon);
        }
        const std::size_t lo = number(text.substr(0, dots)), hi = number(rest);
        if (hi < lo) throw option_error("--subjects", fmt::format("expected low..high, got \"{}\"", text));
        for (std::size_t n = lo; n <= hi; n += step) out.push_back(n);
        if (out.back() != hi) out.push_back(hi);
        return out;
    }
    for (const auto& part : split(text, ',')) out.push_back(number(part));
    return out;
}

std::vector<double> parse_means(const std::string& text) {
    std::vector<double> out;
    for (const auto& part : split(text, ',')) {
        const auto v = parse_double(part);
        if (!v || *v <= 0.0 || *v >= 100.0)
            throw option_error("--means", fmt::format("expected percentages strictly between 0 and 100 separated by "
                                                      "commas, got \"{}\"",
                                                      part));
        out.push_back(*v);
    }
    if (out.size() < 2)
        throw option_error("--means", fmt::format("expected at least 2 condition means, got {}", out.size()));
    return out;
}

std::pair<std::size_t, std::size_t> parse_contrast(const std::string& text, std::size_t k) {
    const auto parts = split(text, '-');
    auto index = [&](std::string t) -> std::size_t {
        if (!t.empty() && (t[0] == 'c' || t[0] == 'C')) t.erase(0, 1);
        const auto v = parse_int(t);
        if (!v || *v < 1 || std::size_t(*v) > k)
            throw option_error("--contrast", fmt::format("expected two condition numbers in 1..{} like \"2-1\", got "
                                                         "\"{}\"",
                                                         k, text));
        return std::size_t(*v - 1);
    };
    if (parts.size() != 2)
        throw option_error("--contrast", fmt::format("expected a-b like \"2-1\", got \"{}\"", text));
    const auto a = index(parts[0]), b = index(parts[1]);
    if (a == b) throw option_error("--contrast", fmt::format("expected two different conditions, got \"{}\"", text));
    return {a, b};
}

namespace {

// The settings validated (InputError naming the option), the contrast's
// default (last minus first) filled in.
PowerSettings checked_settings(const PowerSettings& settings) {
    PowerSettings s = settings;
    const std::size_t k = s.means_percent.size();
    DiagnosticList problems;
    if (k < 2) problems.add("", 0, 0, "--means", fmt::format("expected at least 2 condition means, got {}", k));
    for (double m : s.means_percent)
        if (!(m > 0.0 && m < 100.0))
            problems.add("", 0, 0, "--means", fmt::format("expected percentages in (0, 100), got {}", m));
    if (s.subject_counts.empty()) problems.add("", 0, 0, "--subjects", "expected at least one subject count");
    for (std::size_t n : s.subject_counts)
        if (n < 2) problems.add("", 0, 0, "--subjects", fmt::format("expected at least 2 subjects, got {}", n));
    if (s.sentences_per_cell < 1) problems.add("", 0, 0, "--sentences-per-cell", "expected at least 1");
    if (s.keywords_per_sentence < 1) problems.add("", 0, 0, "--keywords", "expected at least 1");
    if (s.simulations < 1) problems.add("", 0, 0, "--sims", "expected at least 1 simulation");
    if (!(s.subject_sd >= 0.0)) problems.add("", 0, 0, "--subject-sd", "expected a non-negative SD (logit scale)");
    if (!(s.sentence_sd >= 0.0)) problems.add("", 0, 0, "--sentence-sd", "expected a non-negative SD (logit scale)");
    if (!(s.condition_sd >= 0.0 && s.condition_sd <= 5.0))
        problems.add("", 0, 0, "--condition-sd",
                     fmt::format("expected an SD in [0, 5] (logit scale), got {}", s.condition_sd));
    if (!(s.alpha > 0.0 && s.alpha < 1.0)) problems.add("", 0, 0, "--alpha", "expected a level in (0, 1)");
    if (k >= 2 && (s.contrast_a >= k || s.contrast_b >= k))
        problems.add("", 0, 0, "--contrast", fmt::format("expected conditions in 1..{}", k));
    problems.throw_if_any();
    if (s.contrast_a == s.contrast_b) {
        s.contrast_a = k - 1;
        s.contrast_b = 0;
    }
    return s;
}

// The outcomes of the simulated experiments [first, last) with n subjects,
// each from its own seed (so any split of the experiments gives the same
// outcomes), on the settings' threads.
std::vector<SimOutcome> simulate_outcomes(const PowerSettings& s, std::size_t n, std::size_t first, std::size_t last,
                                          Progress& progress) {
    const std::size_t threads =
        std::max<std::size_t>(1, s.threads ? s.threads : std::size_t(std::thread::hardware_concurrency()));
    const Rng root(s.seed);
    std::vector<SimOutcome> outcomes(last - first);
    std::atomic<std::size_t> next{first};
    auto worker = [&] {
        for (std::size_t sim = next++; sim < last; sim = next++) {
            outcomes[sim - first] = simulate_one(s, n, s.contrast_a, s.contrast_b,
                                                 root.derive(fmt::format("subjects{}/sim{}", n, sim)));
            progress.advance();
        }
    };
    std::vector<std::thread> pool;
    for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(worker);
    worker();
    for (auto& t : pool) t.join();
    return outcomes;
}

// The power at n subjects from every experiment's outcome, in order.
PowerPoint summarize(std::size_t n, const std::vector<SimOutcome>& outcomes) {
    PowerPoint point;
    point.subjects = n;
    point.simulations = outcomes.size();
    for (const auto& o : outcomes) {
        point.power_anova += o.anova ? 1.0 : 0.0;
        point.power_anova_gg += o.anova_gg ? 1.0 : 0.0;
        point.power_contrast += o.contrast ? 1.0 : 0.0;
        point.mean_percent += o.mean_percent;
    }
    const double sims = double(outcomes.size());
    point.power_anova /= sims;
    point.power_anova_gg /= sims;
    point.power_contrast /= sims;
    point.mean_percent /= sims;
    point.mc_se_anova = std::sqrt(point.power_anova * (1.0 - point.power_anova) / sims);
    point.mc_se_contrast = std::sqrt(point.power_contrast * (1.0 - point.power_contrast) / sims);
    return point;
}

PowerResult result_header(const PowerSettings& s) {
    PowerResult result;
    result.settings = s;
    result.contrast = fmt::format("c{} - c{}", s.contrast_a + 1, s.contrast_b + 1);
    return result;
}

// The settings a shard file records and the merge compares: every one the
// results depend on (not the thread count).
nlohmann::json settings_json(const PowerSettings& s) {
    return {{"means_percent", s.means_percent},   {"subject_counts", s.subject_counts},
            {"sentences_per_cell", s.sentences_per_cell}, {"keywords_per_sentence", s.keywords_per_sentence},
            {"subject_sd", s.subject_sd},         {"sentence_sd", s.sentence_sd},
            {"condition_sd", s.condition_sd},     {"simulations", s.simulations},
            {"seed", s.seed},                     {"contrast", {s.contrast_a + 1, s.contrast_b + 1}},
            {"alpha", s.alpha}};
}

const detail::ShardKind& power_shard_kind() {
    static const detail::ShardKind kind{"avsi-power-shard", "power",
                                        {"subjects", "simulation", "anova", "anova_gg", "contrast", "mean_percent"},
                                        "avsi power … --out DIR"};
    return kind;
}

}  // namespace

PowerResult simulate_power(const PowerSettings& settings) {
    const PowerSettings s = checked_settings(settings);
    PowerResult result = result_header(s);
    Progress progress("power simulation", s.subject_counts.size() * s.simulations);
    for (std::size_t n : s.subject_counts)
        result.points.push_back(summarize(n, simulate_outcomes(s, n, 0, s.simulations, progress)));
    progress.finish();
    return result;
}

void simulate_power_shard(const PowerSettings& settings, ShardSpec shard, const std::filesystem::path& out_dir) {
    const PowerSettings s = checked_settings(settings);
    const auto [first, last] = shard_range(s.simulations, shard);
    Progress progress("power simulation, shard " + shard.text(), s.subject_counts.size() * (last - first));
    std::string rows;
    for (std::size_t n : s.subject_counts) {
        const std::vector<SimOutcome> outcomes = simulate_outcomes(s, n, first, last, progress);
        for (std::size_t i = 0; i < outcomes.size(); ++i) {
            const SimOutcome& o = outcomes[i];
            rows += fmt::format("{},{},{:d},{:d},{:d},{}\n", n, first + i, o.anova, o.anova_gg, o.contrast,
                                o.mean_percent);
        }
    }
    progress.finish();
    detail::write_shard_file(out_dir, power_shard_kind(), shard, settings_json(s), rows);
    log_info("power: shard {} wrote {} of the {} experiments of each subject count to {}", shard.text(),
             first < last ? fmt::format("experiments {}..{}", first, last - 1) : std::string("none"), s.simulations,
             detail::shard_file_path(out_dir, power_shard_kind(), shard).string());
}

PowerResult merge_power_shards(const PowerSettings& settings, const std::filesystem::path& out_dir) {
    const PowerSettings s = checked_settings(settings);
    std::vector<std::vector<SimOutcome>> outcomes(s.subject_counts.size());
    std::size_t at = 0, count = 0, sim = 0;  // the next row expected: subject count `at`, experiment `sim`
    const auto row = [&](ShardSpec shard, const detail::ShardRow& r) {
        const auto [first, last] = shard_range(s.simulations, shard);
        if (at >= s.subject_counts.size() || first == last)
            r.fail(0, fmt::format("expected the end of shard {}, got another row", shard.text()));
        const long long n = r.integer(0), i = r.integer(1);
        if (n != static_cast<long long>(s.subject_counts[at]) || i != static_cast<long long>(sim))
            r.fail(n != static_cast<long long>(s.subject_counts[at]) ? 0 : 1,
                   fmt::format("expected subjects {} simulation {} (shard {} holds simulations {}..{} of each "
                               "subject count), got subjects {} simulation {}",
                               s.subject_counts[at], sim, shard.text(), first, last - 1, n, i));
        SimOutcome o;
        const auto flag = [&](std::size_t column) {
            const long long v = r.integer(column);
            if (v != 0 && v != 1) r.fail(column, fmt::format("expected 0 or 1, got {}", v));
            return v == 1;
        };
        o.anova = flag(2);
        o.anova_gg = flag(3);
        o.contrast = flag(4);
        o.mean_percent = r.number(5);
        if (!(o.mean_percent >= 0.0 && o.mean_percent <= 100.0))
            r.fail(5, fmt::format("expected a percentage in [0, 100], got {}", o.mean_percent));
        outcomes[at].push_back(o);
        if (++sim == last) {
            sim = first, ++at;
        }
        ++count;
    };
    const auto end = [&](ShardSpec shard, const std::function<void(const std::string&)>& fail) {
        const auto [first, last] = shard_range(s.simulations, shard);
        if (at < s.subject_counts.size() && first < last)
            fail(fmt::format("cut short: shard {} ends before subjects {} simulation {} (it holds simulations "
                             "{}..{} for each subject count: {})",
                             shard.text(), s.subject_counts[at], sim, first, last - 1,
                             fmt::join(s.subject_counts, ", ")));
        const auto next = shard_range(s.simulations, ShardSpec{shard.index + 1, shard.count});
        at = 0;
        sim = next.first;
    };
    sim = 0;
    const std::size_t shards = detail::read_shard_files(out_dir, power_shard_kind(), settings_json(s), row, end);
    PowerResult result = result_header(s);
    for (std::size_t j = 0; j < s.subject_counts.size(); ++j)
        result.points.push_back(summarize(s.subject_counts[j], outcomes[j]));
    log_info("power: merged {} simulated experiments from {} shards in {}", count, shards, out_dir.string());
    return result;
}

std::string power_table(const PowerResult& r) {
    const PowerSettings& s = r.settings;
    std::string out = fmt::format(
        "Power by simulation ({} simulated experiments per row; a planning aid, not an analytic power "
        "calculation)\nmeans {} %, {} sentences per cell × {} keywords, subject SD {}, sentence SD {} and subject × "
        "condition SD {} (logit), alpha {}, seed {}\n{}\n\n",
        s.simulations, fmt::join(s.means_percent, "/"), s.sentences_per_cell, s.keywords_per_sentence, s.subject_sd,
        s.sentence_sd, s.condition_sd, s.alpha, s.seed,
        s.condition_sd == kConditionSdDefault
            ? fmt::format("subject × condition SD {} is the default, from {}", kConditionSdDefault, kConditionSdSource)
            : fmt::format("subject × condition SD {} as given (default {}, from {})", s.condition_sd,
                          kConditionSdDefault, kConditionSdSource));
    out += fmt::format("{:>8}  {:>14}  {:>14}  {:>20}  {:>9}\n", "subjects", "ANOVA power", "ANOVA GG power",
                       fmt::format("LSD {} power", r.contrast), "mean %");
    for (const auto& p : r.points)
        out += fmt::format("{:>8}  {:>7.3f} ±{:.3f}  {:>14.3f}  {:>12.3f} ±{:.3f}  {:>9.1f}\n", p.subjects,
                           p.power_anova, p.mc_se_anova, p.power_anova_gg, p.power_contrast, p.mc_se_contrast,
                           p.mean_percent);
    out += "(± Monte Carlo standard error; simulation results)\n";
    return out;
}

void write_power_files(const std::filesystem::path& out_dir, const PowerResult& r) {
    const PowerSettings& s = r.settings;
    std::string csv = fmt::format("# power by simulation: {} simulated experiments per row, seed {}\n",
                                  s.simulations, s.seed);
    if (s.condition_sd > 0.0)
        csv += fmt::format("# subject x condition SD {} (logit; default {}: {})\n", s.condition_sd, kConditionSdDefault,
                           kConditionSdSource);
    csv += csv_line({"method", "subjects", "simulations", "power_anova", "mc_se_anova", "power_anova_gg",
                     "contrast", "power_contrast", "mc_se_contrast", "mean_percent", "alpha"});
    nlohmann::json points = nlohmann::json::array();
    for (const auto& p : r.points) {
        csv += csv_line({"simulation", std::to_string(p.subjects), std::to_string(p.simulations),
                         fmt::format("{}", p.power_anova), fmt::format("{}", p.mc_se_anova),
                         fmt::format("{}", p.power_anova_gg), r.contrast, fmt::format("{}", p.power_contrast),
                         fmt::format("{}", p.mc_se_contrast), fmt::format("{}", p.mean_percent),
                         fmt::format("{}", s.alpha)});
        points.push_back({{"subjects", p.subjects},
                          {"power_anova", p.power_anova},
                          {"mc_se_anova", p.mc_se_anova},
                          {"power_anova_gg", p.power_anova_gg},
                          {"power_contrast", p.power_contrast},
                          {"mc_se_contrast", p.mc_se_contrast},
                          {"mean_percent", p.mean_percent}});
    }
    const nlohmann::json doc = {
        {"method", "simulation"},
        {"note", "power estimated by simulating keyword-level data; a planning aid, not an analytic calculation"},
        {"settings",
         {{"means_percent", s.means_percent},
          {"sentences_per_cell", s.sentences_per_cell},
          {"keywords_per_sentence", s.keywords_per_sentence},
          {"subject_sd_logit", s.subject_sd},
          {"sentence_sd_logit", s.sentence_sd},
          {"condition_sd_logit", s.condition_sd},
          {"condition_sd_default_source", kConditionSdSource},
          {"simulations", s.simulations},
          {"seed", s.seed},
          {"alpha", s.alpha},
          {"contrast", r.contrast}}},
        {"points", points}};
    write_text_file(out_dir / "power.csv", csv);
    write_text_file(out_dir / "power.json", doc.dump(2) + "\n");
    write_text_file(out_dir / "power.txt", power_table(r));
}

}  // namespace avsi::analysis
