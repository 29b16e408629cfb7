// Training control models (Beskow §4; training.h): Levenberg-Marquardt in
// Ceres Solver minimising eq. 5 with analytic Jacobians — eq. 9–14 for
// Cohen-Massaro (and MPEG-4 CM) from the terms of the model's own pointwise
// sum (eq. 7–8, CmPointwiseSum in synth's cohen_massaro.h), eq. 18–20 for
// Öhman from the model's own blends (eq. 16–17, ohman_value in ohman.h) —
// bounds, per-parameter problems in parallel, early stopping on the
// held-out error.
#include "avsi/learn/training.h"

#include <algorithm>
#include <atomic>
#include <cctype>
#include <chrono>
#include <cmath>
#include <functional>
#include <future>
#include <limits>
#include <map>
#include <mutex>
#include <thread>

#include <ceres/ceres.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"
#include "avsi/learn/evaluation.h"
#include "avsi/synth/mpeg4_cohen_massaro.h"
#include "avsi/synth/ohman.h"

namespace avsi::learn {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------
// Analytic derivatives.

namespace {

// Eq. 8 at each time by the model's pointwise sum (cohen_massaro.h) and,
// when `partials` (then need_dc says whether ∂/∂c is wanted), each
// contributing segment's partials of eq. 9–14 from its terms, handed to
// visit(k, segment, d) in the sum's segment-walk order.
template <class Visit>
void cm_partials_visit(std::span<const CmSegment> segments, std::span<const double> times_s,
                       std::vector<double>& z, bool partials, bool need_dc, const Visit& visit) {
    CmPointwiseSum frame_sum(segments);
    z.assign(times_s.size(), 0.0);
    for (std::size_t k = 0; k < times_s.size(); ++k) {
        const double zk = frame_sum.evaluate(times_s[k], partials && need_dc);
        z[k] = zk;
        if (!partials) continue;
        const double sum = frame_sum.weight_sum();
        for (const CmTerm& term : frame_sum.terms()) {
            const CmSegment& s = segments[term.segment];
            const double w = term.weight / sum;          // D_i / ΣD
            const double g = w * (s.target - zk);        // eq. 10 with ∂D/∂ψ = D·∂lnD/∂ψ
            const double rate = term.before ? s.theta_per_s : s.phi_per_s;
            const double xc = term.distance_c;
            std::array<double, 6> d{};
            d[0] = w;                                    // eq. 9
            d[1] = g / s.alpha;                          // eq. 11
            d[2] = term.before ? -xc * g : 0.0;          // eq. 12
            d[3] = term.before ? 0.0 : -xc * g;          // eq. 13
            d[4] = need_dc && term.distance_s > 0 ? -rate * xc * term.log_distance * g : 0.0;  // eq. 14 (with its sign)
            const double dxc = term.distance_s > 0 ? s.c * xc / term.distance_s : 0.0;  // d(x^c)/dx
            d[5] = (term.before ? -rate * dxc : rate * dxc) * g;          // ∂/∂τ
            visit(k, term.segment, d);
        }
    }
}

}  // namespace

void cohen_massaro_partials(std::span<const CmSegment> segments, std::span<const double> times_s,
                            std::vector<double>& z, CmPartials* partials, bool need_dc) {
    if (!partials) {
        cm_partials_visit(segments, times_s, z, false, need_dc, [](std::size_t, std::uint32_t, const auto&) {});
        return;
    }
    partials->row_start.assign(1, 0);
    partials->segment.clear();
    partials->d.clear();
    std::size_t row = 0;
    cm_partials_visit(segments, times_s, z, true, need_dc,
                      [&](std::size_t k, std::uint32_t i, const std::array<double, 6>& d) {
                          for (; row < k; ++row) partials->row_start.push_back(partials->segment.size());
                          partials->segment.push_back(i);
                          partials->d.push_back(d);
                      });
    for (; row < times_s.size(); ++row) partials->row_start.push_back(partials->segment.size());
}

namespace {

void cohen_massaro_keyed_impl(const KeyedUtterance& u, std::span<const double> x, std::vector<double>& z,
                              std::vector<double>* jacobian, bool need_dc) {
    std::vector<CmSegment> segs(u.centres_s.size());
    for (std::size_t i = 0; i < segs.size(); ++i) {
        const double* q = x.data() + 5 * static_cast<std::size_t>(u.key[i]);
        segs[i] = {u.centres_s[i], q[0], q[1], q[2], q[3], q[4]};
    }
    if (!jacobian) {
        cohen_massaro_partials(segs, u.times_s, z, nullptr);
        return;
    }
    const std::size_t cols = x.size();
    jacobian->assign(u.times_s.size() * cols, 0.0);
    cm_partials_visit(segs, u.times_s, z, true, need_dc,
                      [&](std::size_t k, std::uint32_t i, const std::array<double, 6>& d) {
                          double* row = jacobian->data() + k * cols + 5 * static_cast<std::size_t>(u.key[i]);
                          for (int j = 0; j < 5; ++j) row[j] += d[static_cast<std::size_t>(j)];  // per phone class
                      });
}

// The same with c held fixed: no ∂z/∂c (column 4 stays 0), so no ln|τ − t|.
void cohen_massaro_keyed_fixed_c(const KeyedUtterance& u, std::span<const double> x, std::vector<double>& z,
                                 std::vector<double>* jacobian) {
    cohen_massaro_keyed_impl(u, x, z, jacobian, false);
}

}  // namespace

void cohen_massaro_keyed(const KeyedUtterance& u, std::span<const double> x, std::vector<double>& z,
                         std::vector<double>* jacobian) {
    cohen_massaro_keyed_impl(u, x, z, jacobian, true);
}

namespace {

long bracket(const std::vector<double>& centres, double t) {
    return static_cast<long>(std::upper_bound(centres.begin(), centres.end(), t) - centres.begin()) - 1;
}

}  // namespace

void ohman_keyed(const KeyedUtterance& u, std::span<const double> x, std::vector<double>& z,
                 std::vector<double>* jacobian) {
    std::vector<double> anchor_centres;
    std::vector<int> anchor_keys;
    for (std::size_t i = 0; i < u.centres_s.size(); ++i)
        if (u.anchor[i]) {
            anchor_centres.push_back(u.centres_s[i]);
            anchor_keys.push_back(u.key[i]);
        }
    const std::size_t cols = x.size();
    auto anchor_column = [&](long j) { return 2 * static_cast<std::size_t>(anchor_keys[static_cast<std::size_t>(j)]); };
    auto consonant_column = [&](std::size_t i) { return 2 * static_cast<std::size_t>(u.key[i]); };
    z.assign(u.times_s.size(), 0.0);
    if (jacobian) jacobian->assign(u.times_s.size() * cols, 0.0);
    for (std::size_t k = 0; k < u.times_s.size(); ++k) {
        // The model's forward pass (ohman.h, eq. 16–17); every parameter's
        // neutral value is 0 (parameters.h).
        const OhmanBlends b = ohman_blends(u.centres_s, anchor_centres, u.anchor, u.times_s[k]);
        const OhmanValue value = ohman_value(
            b, 0.0, [&](long j) { return x[anchor_column(j)]; },
            [&](std::size_t i) { return std::pair{x[consonant_column(i)], x[consonant_column(i) + 1]}; });
        z[k] = value.z;
        if (!jacobian) continue;
        double* row = jacobian->data() + k * cols;
        for (int e = 0; e < b.consonants; ++e) {
            const auto ue = static_cast<std::size_t>(e);
            const std::size_t q = consonant_column(b.consonant[ue]);
            row[q] += x[q + 1] * b.k[ue];                  // eq. 19
            row[q + 1] += b.k[ue] * (x[q] - value.v);      // eq. 18
        }
        if (b.vowel.left >= 0) row[anchor_column(b.vowel.left)] += b.vowel.w_left * (1.0 - value.pull);  // eq. 20
        if (b.vowel.right >= 0) row[anchor_column(b.vowel.right)] += b.vowel.w_right * (1.0 - value.pull);
    }
}

// ---------------------------------------------------------------------------
// Problem set-up.

namespace {

enum class Kind { CohenMassaro, Ohman, Mpeg4 };

Kind parse_kind(const std::string& name) {
    if (name == "cohen-massaro") return Kind::CohenMassaro;
    if (name == "ohman") return Kind::Ohman;
    if (name == "mpeg4-cohen-massaro" || name == "mpeg4-cm") return Kind::Mpeg4;
    const std::vector<std::string> kinds = {"cohen-massaro", "ohman", "mpeg4-cohen-massaro"};
    const std::string hint = closest_match(name, kinds);
    throw InputError("", 0, 0, "--model",
                     fmt::format("expected cohen-massaro, ohman or mpeg4-cohen-massaro{}, got \"{}\"",
                                 hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint), name));
}

std::string phone_key(const Phone& p, bool stress_keys) {
    if (stress_keys && p.symbol != "sil" && PhoneInventory::builtin().is_vowel(p.symbol))
        return p.symbol + (p.stressed ? "1" : "0");
    return p.symbol;
}

// One (utterance, parameter) data set: the frames with a target value.
struct Series {
    KeyedUtterance u;
    std::vector<double> y;
};

struct Prepared {
    std::vector<std::string> keys;            // key index → key string
    std::vector<bool> key_is_anchor;
    std::vector<bool> key_trained;            // appears in the training set
    // [param][utterance]
    std::array<std::vector<Series>, param_count> train, test;
    std::array<bool, param_count> present{};  // some training frame has the parameter
};

Prepared prepare(const std::vector<CorpusUtterance>& train, const std::vector<CorpusUtterance>& test,
                 const std::function<std::string(const Phone&)>& key_of) {
    Prepared p;
    std::map<std::string, int> index_of;
    const PhoneInventory& inv = PhoneInventory::builtin();
    auto add = [&](const std::vector<CorpusUtterance>& set, auto& out, bool is_train) {
        for (const auto& utt : set) {
            KeyedUtterance base;
            for (const auto& ph : utt.phones) {
                const std::string key = key_of(ph);
                auto [it, fresh] = index_of.try_emplace(key, static_cast<int>(p.keys.size()));
                if (fresh) {
                    p.keys.push_back(key);
                    p.key_is_anchor.push_back(ph.symbol == "sil" || inv.is_vowel(ph.symbol));
                    p.key_trained.push_back(false);
                }
                if (is_train) p.key_trained[static_cast<std::size_t>(it->second)] = true;
                base.centres_s.push_back(ph.centre_s());
                base.key.push_back(it->second);
                base.anchor.push_back(ph.symbol == "sil" || inv.is_vowel(ph.symbol));
            }
            for (std::size_t q = 0; q < param_count; ++q) {
                Series s;
                s.u = base;
                for (std::size_t k = 0; k < utt.track.size(); ++k) {
                    const double y = utt.track.frames[k][q];
                    const double t = utt.track.time_s(k);
                    if (!utt.track.present[q] || !std::isfinite(y)) continue;
                    if (t < utt.phones.front().start_s || t > utt.phones.back().end_s) continue;
                    s.u.times_s.push_back(t);
                    s.y.push_back(y);
                }
                if (s.y.empty()) continue;
                if (is_train) p.present[q] = true;
                out[q].push_back(std::move(s));
            }
        }
    };
    add(train, p.train, true);
    add(test, p.test, false);
    return p;
}

// Mean target per key over the frames of its segments (initial targets).
std::vector<double> mean_target_per_key(const Prepared& p, std::size_t q, double fallback) {
    std::vector<double> sum(p.keys.size(), 0.0), n(p.keys.size(), 0.0);
    for (const auto& s : p.train[q]) {
        const auto& c = s.u.centres_s;
        for (std::size_t k = 0; k < s.y.size(); ++k) {
            const double t = s.u.times_s[k];
            // nearest segment centre stands for "the segment t falls in"
            const long j = std::clamp<long>(bracket(c, t), 0, static_cast<long>(c.size()) - 1);
            std::size_t i = static_cast<std::size_t>(j);
            if (i + 1 < c.size() && std::abs(c[i + 1] - t) < std::abs(c[i] - t)) ++i;
            sum[static_cast<std::size_t>(s.u.key[i])] += s.y[k];
            n[static_cast<std::size_t>(s.u.key[i])] += 1;
        }
    }
    std::vector<double> out(p.keys.size(), fallback);
    for (std::size_t i = 0; i < out.size(); ++i)
        if (n[i] > 0) out[i] = sum[i] / n[i];
    return out;
}

using KeyedFunction = void (*)(const KeyedUtterance&, std::span<const double>, std::vector<double>&,
                               std::vector<double>*);

// Residuals z − y of one series; parameter blocks are the keys the utterance
// uses, each the first `free` of the key's `stride` values (1 for Öhman
// anchors); the rest are held at their values in `x` when the cost is made.
class KeyedCost : public ceres::CostFunction {
public:
    KeyedCost(const Series& s, KeyedFunction f, int stride, int free, const std::vector<bool>& key_is_anchor,
              bool ohman, const std::vector<double>& x)
        : m_series(s), m_f(f), m_stride(stride) {
        std::map<int, int> local;
        for (int key : s.u.key)
            if (local.try_emplace(key, static_cast<int>(m_keys.size())).second) m_keys.push_back(key);
        for (int& key : m_series.u.key) key = local[key];
        for (int key : m_keys) {
            const int size = ohman && key_is_anchor[static_cast<std::size_t>(key)] ? 1 : free;
            m_sizes.push_back(size);
            mutable_parameter_block_sizes()->push_back(size);
            for (int j = 0; j < stride; ++j)
                m_held.push_back(j < size ? 0.0 : x[static_cast<std::size_t>(key * stride + j)]);
        }
        set_num_residuals(static_cast<int>(s.y.size()));
    }

    const std::vector<int>& keys() const { return m_keys; }

    bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
        const std::size_t cols = m_keys.size() * static_cast<std::size_t>(m_stride);
        std::vector<double> x(m_held), z, jac;
        for (std::size_t b = 0; b < m_keys.size(); ++b)
            for (int j = 0; j < m_sizes[b]; ++j) x[b * m_stride + j] = parameters[b][j];
        m_f(m_series.u, x, z, jacobians ? &jac : nullptr);
        const std::size_t rows = m_series.y.size();
        for (std::size_t k = 0; k < rows; ++k) residuals[k] = z[k] - m_series.y[k];
        if (jacobians)
            for (std::size_t b = 0; b < m_keys.size(); ++b) {
                if (!jacobians[b]) continue;
                for (std::size_t k = 0; k < rows; ++k)
                    for (int j = 0; j < m_sizes[b]; ++j)
                        jacobians[b][k * m_sizes[b] + j] = jac[k * cols + b * m_stride + j];
            }
        return true;
    }

private:
    Series m_series;
    KeyedFunction m_f;
    int m_stride;
    std::vector<int> m_keys;
    std::vector<int> m_sizes;
    std::vector<double> m_held;  // per local key `stride` values; the held ones
};

// Held-out error after every iteration; stops when it has not fallen for
// `patience` iterations and remembers the best parameters.
class EarlyStopping : public ceres::IterationCallback {
public:
    EarlyStopping(std::function<double()> test_error, std::function<void()> save_best, int patience)
        : m_test_error(std::move(test_error)), m_save_best(std::move(save_best)), m_patience(patience) {}

    ceres::CallbackReturnType operator()(const ceres::IterationSummary& summary) override {
        m_iterations = summary.iteration;
        const double e = m_test_error();
        if (e < m_best) {
            m_best = e;
            m_since_best = 0;
            m_save_best();
        } else if (++m_since_best >= m_patience) {
            return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
        }
        return ceres::SOLVER_CONTINUE;
    }
    double best() const { return m_best; }
    int iterations() const { return m_iterations; }

private:
    std::function<double()> m_test_error;
    std::function<void()> m_save_best;
    int m_patience;
    double m_best = std::numeric_limits<double>::infinity();
    int m_since_best = 0;
    int m_iterations = 0;
};

ceres::Solver::Options solver_options(const TrainingSettings& s, int threads) {
    ceres::Solver::Options o;
    o.minimizer_type = ceres::TRUST_REGION;
    o.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
    if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::SUITE_SPARSE)) {
        o.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
        o.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
    } else if (ceres::IsSparseLinearAlgebraLibraryTypeAvailable(ceres::EIGEN_SPARSE)) {
        o.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
        o.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
    } else {
        o.linear_solver_type = ceres::DENSE_QR;
    }
    o.max_num_iterations = s.max_iterations;
    o.function_tolerance = s.function_tolerance;
    o.num_threads = threads;
    o.update_state_every_iteration = true;
    o.logging_type = ceres::SILENT;
    o.minimizer_progress_to_stdout = false;
    return o;
}

double series_sse(const std::vector<Series>& set, KeyedFunction f, std::span<const double> x) {
    double sse = 0.0;
    std::vector<double> z;
    for (const auto& s : set) {
        f(s.u, x, z, nullptr);
        for (std::size_t k = 0; k < z.size(); ++k) sse += (z[k] - s.y[k]) * (z[k] - s.y[k]);
    }
    return sse;
}

// Fits one parameter's phone-keyed problem in place (x: stride values per key).
int fit_keyed(const Prepared& p, std::size_t q, KeyedFunction f, int stride, int free, bool ohman,
              std::vector<double>& x, const std::function<void(ceres::Problem&, int key, double* block)>& bound,
              const TrainingSettings& settings) {
    ceres::Problem::Options po;
    po.cost_function_ownership = ceres::TAKE_OWNERSHIP;
    ceres::Problem problem(po);
    std::vector<bool> added(p.keys.size(), false);
    for (const auto& s : p.train[q]) {
        auto* cost = new KeyedCost(s, f, stride, free, p.key_is_anchor, ohman, x);
        std::vector<double*> blocks;
        for (int key : cost->keys()) blocks.push_back(x.data() + stride * key);
        problem.AddResidualBlock(cost, nullptr, blocks);
        for (std::size_t b = 0; b < blocks.size(); ++b) {
            const int key = cost->keys()[b];
            if (!added[static_cast<std::size_t>(key)]) {
                added[static_cast<std::size_t>(key)] = true;
                bound(problem, key, blocks[b]);
            }
        }
    }
    if (problem.NumResidualBlocks() == 0) return 0;
    std::vector<double> best = x;
    EarlyStopping stop([&] { return series_sse(p.test[q], f, x); }, [&] { best = x; }, settings.patience);
    ceres::Solver::Options options = solver_options(settings, 1);
    const bool has_test = !p.test[q].empty();
    if (has_test) options.callbacks.push_back(&stop);
    ceres::Solver::Summary summary;
    const auto start = std::chrono::steady_clock::now();
    ceres::Solve(options, &problem, &summary);
    if (has_test) x = best;
    log_info("  {}: {} iterations in {:.1f} s, train cost {:.4g} -> {:.4g}, held-out SSE {:.4g}", params()[q].name,
             summary.iterations.size(),
             std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), summary.initial_cost,
             summary.final_cost, has_test ? stop.best() : 0.0);
    return static_cast<int>(summary.iterations.size());
}

// Runs job(q) for each present parameter on `threads` workers.
void parallel_params(const Prepared& p, int threads, const std::function<void(std::size_t)>& job) {
    std::atomic<std::size_t> next{0};
    std::vector<std::future<void>> workers;
    for (int w = 0; w < threads; ++w)
        workers.push_back(std::async(std::launch::async, [&] {
            for (std::size_t q; (q = next++) < param_count;)
                if (p.present[q]) job(q);
        }));
    for (auto& w : workers) w.get();
}

// The start model's key to copy for a key it lacks: the nearest phone by
// features (PhoneInventory::nearest_by_features) that the model has, with
// the key's stress digit if it has one ("YY1" -> "UW1"); "" if none.
std::string start_key_by_features(const std::string& key, const std::function<bool(const std::string&)>& has) {
    const PhoneInventory& inv = PhoneInventory::builtin();
    const bool digit = !key.empty() && std::isdigit(static_cast<unsigned char>(key.back()));
    const std::string symbol = digit ? key.substr(0, key.size() - 1) : key;
    const std::string suffix = digit ? key.substr(key.size() - 1) : std::string();
    if (!inv.contains(symbol)) return {};
    auto key_of = [&](const std::string& s) -> std::string {
        for (const std::string& k : {s + suffix, s, s + "1", s + "0"})
            if (has(k)) return k;
        return {};
    };
    const std::string nearest = inv.nearest_by_features(symbol, [&](const std::string& s) { return !key_of(s).empty(); });
    if (nearest.empty()) return {};
    log_info("train: \"{}\" starts from the start model's \"{}\" (the nearest phone by features)", key, key_of(nearest));
    return key_of(nearest);
}

fs::path default_init(Kind kind) {
    const fs::path dir = fs::path(AVSI_PROTOCOLS_DIR) / "models";
    switch (kind) {
        case Kind::CohenMassaro: return dir / "cohen-massaro.json";
        case Kind::Ohman: return dir / "ohman.json";
        case Kind::Mpeg4: return dir / "mpeg4-cohen-massaro.json";
    }
    return {};
}

template <typename T>
T* model_as(std::unique_ptr<ControlModel>& m, const fs::path& path, const char* kind) {
    auto* typed = dynamic_cast<T*>(m.get());
    if (!typed) throw InputError(path, fmt::format("expected a {} model to start from, got kind \"{}\"", kind, m->kind()));
    return typed;
}

// ---- Cohen-Massaro ----

std::unique_ptr<ControlModel> train_cohen_massaro(std::unique_ptr<ControlModel> init, const fs::path& init_path,
                                                  const std::vector<CorpusUtterance>& train,
                                                  const std::vector<CorpusUtterance>& test,
                                                  const TrainingSettings& settings, int threads, int& iterations) {
    auto* model = model_as<CohenMassaroModel>(init, init_path, "cohen-massaro");
    const Prepared p = prepare(train, test, [](const Phone& ph) { return phone_key(ph, true); });
    CohenMassaroModel::Table& table = model->phones();
    // Entries for new stress keys start as copies of their base phone's; a
    // phone the start model lacks (another language's) from the nearest
    // phone it has by features.
    for (const auto& key : p.keys)
        if (!table.count(key)) {
            const std::string base = key.substr(0, key.size() - 1);
            if (table.count(base)) {
                table[key] = table.at(base);
                continue;
            }
            const std::string source = start_key_by_features(key, [&](const std::string& k) { return table.count(k) > 0; });
            if (source.empty()) throw InputError(init_path, fmt::format("the start model has no entry for \"{}\"", base));
            table[key] = table.at(source);
        }
    std::array<std::vector<double>, param_count> x;
    std::atomic<int> total{0};
    const double min_rate = settings.min_rate_per_s;
    const double min_c = settings.min_c, max_c = settings.max_c;
    if (!(min_c > 0.0 && min_c <= max_c && max_c <= 10.0))
        throw InputError("", 0, 0, "--c-range",
                         fmt::format("expected 0 < min c <= max c <= 10, got [{}, {}]", min_c, max_c));
    const bool fixed_c = min_c == max_c;
    auto bound = [min_rate, min_c, max_c](std::size_t q, bool fix_c) {
        return [q, fix_c, min_rate, min_c, max_c](ceres::Problem& problem, int, double* b) {
            const ParamInfo& info = params()[q];
            problem.SetParameterLowerBound(b, 0, info.min);
            problem.SetParameterUpperBound(b, 0, info.max);
            problem.SetParameterLowerBound(b, 1, 1e-3);
            problem.SetParameterUpperBound(b, 1, 1e3);
            for (int j : {2, 3}) {
                problem.SetParameterLowerBound(b, j, min_rate);
                problem.SetParameterUpperBound(b, j, 1e4);
            }
            if (!fix_c) {  // (fixed: c is not part of the block)
                problem.SetParameterLowerBound(b, 4, min_c);
                problem.SetParameterUpperBound(b, 4, max_c);
            }
        };
    };
    // Start values: the mean target over each key's frames, α = 1, rates
    // max(20, floor), c = 1 clamped into its range.
    const double start_c = std::clamp(1.0, min_c, max_c);
    for (std::size_t q = 0; q < param_count; ++q) {
        if (!p.present[q]) continue;
        const ParamInfo& info = params()[q];
        const std::vector<double> mean = mean_target_per_key(p, q, info.neutral);
        x[q].assign(5 * p.keys.size(), 0.0);
        for (std::size_t k = 0; k < p.keys.size(); ++k) {
            const CohenMassaroParams& e = table.at(p.keys[k]).params[q];
            const double target = p.key_trained[k] ? mean[k] : e.target;
            const double rate = std::max(20.0, settings.min_rate_per_s);
            const double init_x[5] = {std::clamp(target, info.min, info.max), 1.0, rate, rate, start_c};
            std::copy(init_x, init_x + 5, x[q].begin() + 5 * k);
        }
    }
    // Stage 1 (c free): all five free per parameter.
    if (!fixed_c)
        parallel_params(p, threads, [&](std::size_t q) {
            total += fit_keyed(p, q, cohen_massaro_keyed, 5, 5, false, x[q], bound(q, false), settings);
        });
    // One c per phone key: the median over the trained parameters.
    std::vector<double> c(p.keys.size(), start_c);
    for (std::size_t k = 0; k < p.keys.size() && !fixed_c; ++k) {
        std::vector<double> cs;
        for (std::size_t q = 0; q < param_count; ++q)
            if (p.present[q]) cs.push_back(x[q][5 * k + 4]);
        if (cs.empty()) continue;
        std::sort(cs.begin(), cs.end());
        c[k] = cs.size() % 2 ? cs[cs.size() / 2] : 0.5 * (cs[cs.size() / 2 - 1] + cs[cs.size() / 2]);
    }
    // Stage 2: T, α, θ, φ again with the shared c fixed.
    parallel_params(p, threads, [&](std::size_t q) {
        for (std::size_t k = 0; k < p.keys.size(); ++k) x[q][5 * k + 4] = c[k];
        total += fit_keyed(p, q, cohen_massaro_keyed_fixed_c, 5, 4, false, x[q], bound(q, true), settings);
    });
    for (std::size_t k = 0; k < p.keys.size(); ++k) {
        if (!p.key_trained[k]) continue;
        CohenMassaroPhone& entry = table[p.keys[k]];
        entry.c = c[k];
        for (std::size_t q = 0; q < param_count; ++q) {
            if (!p.present[q]) continue;
            const double* v = x[q].data() + 5 * k;
            entry.params[q] = {v[0], v[1], v[2], v[3]};
        }
    }
    // Entries the corpus does not train keep the start model's values, their
    // rates raised to the floor and c clamped into its range so the whole
    // file obeys the bounds.
    for (auto& [key, entry] : table) {
        entry.c = std::clamp(entry.c, min_c, max_c);
        for (auto& q : entry.params) {
            q.theta_per_s = std::max(q.theta_per_s, settings.min_rate_per_s);
            q.phi_per_s = std::max(q.phi_per_s, settings.min_rate_per_s);
        }
    }
    iterations = total;
    return init;
}

// ---- Öhman ----

std::unique_ptr<ControlModel> train_ohman(std::unique_ptr<ControlModel> init, const fs::path& init_path,
                                          const std::vector<CorpusUtterance>& train,
                                          const std::vector<CorpusUtterance>& test, const TrainingSettings& settings,
                                          int threads, int& iterations) {
    auto* model = model_as<OhmanModel>(init, init_path, "ohman");
    const Prepared p = prepare(train, test, [](const Phone& ph) { return phone_key(ph, true); });
    auto& vowels = model->vowels();
    auto& consonants = model->consonants();
    for (std::size_t k = 0; k < p.keys.size(); ++k) {
        const std::string& key = p.keys[k];
        const std::string base = p.key_is_anchor[k] && key != "sil" ? key.substr(0, key.size() - 1) : key;
        if (p.key_is_anchor[k] && !vowels.count(key)) {
            const std::string source =
                vowels.count(base) ? base
                                   : start_key_by_features(key, [&](const std::string& s) { return vowels.count(s) > 0; });
            if (source.empty()) throw InputError(init_path, fmt::format("the start model has no vowel \"{}\"", base));
            vowels[key] = vowels.at(source);
        }
        if (!p.key_is_anchor[k] && !consonants.count(key)) {
            const std::string source =
                start_key_by_features(key, [&](const std::string& s) { return consonants.count(s) > 0; });
            if (source.empty()) throw InputError(init_path, fmt::format("the start model has no consonant \"{}\"", key));
            consonants[key] = consonants.at(source);
        }
    }
    std::array<std::vector<double>, param_count> x;
    std::atomic<int> total{0};
    parallel_params(p, threads, [&](std::size_t q) {
        const ParamInfo& info = params()[q];
        const std::vector<double> mean = mean_target_per_key(p, q, info.neutral);
        x[q].assign(2 * p.keys.size(), 0.0);
        for (std::size_t k = 0; k < p.keys.size(); ++k) {
            const double start = p.key_trained[k]
                                     ? mean[k]
                                     : (p.key_is_anchor[k] ? vowels.at(p.keys[k])[q] : consonants.at(p.keys[k])[q].target);
            x[q][2 * k] = std::clamp(start, info.min, info.max);
            x[q][2 * k + 1] = p.key_is_anchor[k] ? 0.0 : (p.key_trained[k] ? 0.5 : consonants.at(p.keys[k])[q].coarticulation_factor);
        }
        auto bound = [&](ceres::Problem& problem, int key, double* b) {
            problem.SetParameterLowerBound(b, 0, info.min);
            problem.SetParameterUpperBound(b, 0, info.max);
            if (!p.key_is_anchor[static_cast<std::size_t>(key)]) {
                problem.SetParameterLowerBound(b, 1, 0.0);
                problem.SetParameterUpperBound(b, 1, 1.0);
            }
        };
        total += fit_keyed(p, q, ohman_keyed, 2, 2, true, x[q], bound, settings);
    });
    for (std::size_t k = 0; k < p.keys.size(); ++k) {
        if (!p.key_trained[k]) continue;
        for (std::size_t q = 0; q < param_count; ++q) {
            if (!p.present[q]) continue;
            if (p.key_is_anchor[k])
                vowels[p.keys[k]][q] = x[q][2 * k];
            else
                consonants[p.keys[k]][q] = {x[q][2 * k], x[q][2 * k + 1]};
        }
    }
    iterations = total;
    return init;
}

// ---- MPEG-4 Cohen-Massaro ----

// Residuals of one (utterance, parameter): blocks are the viseme targets the
// utterance uses for that parameter, then the shared [θ←, θ→, t0].
class Mpeg4Cost : public ceres::CostFunction {
public:
    Mpeg4Cost(const Series& s, const std::vector<double>& alphas) : m_series(s) {
        std::map<int, int> local;
        for (int v : s.u.key)
            if (local.try_emplace(v, static_cast<int>(m_visemes.size())).second) m_visemes.push_back(v);
        for (int v : s.u.key) m_local.push_back(local[v]);
        for (int v : s.u.key) m_alpha.push_back(alphas[static_cast<std::size_t>(v)]);
        for (std::size_t i = 0; i < m_visemes.size(); ++i) mutable_parameter_block_sizes()->push_back(1);
        mutable_parameter_block_sizes()->push_back(3);
        set_num_residuals(static_cast<int>(s.y.size()));
    }
    const std::vector<int>& visemes() const { return m_visemes; }

    bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
        const double* g = parameters[m_visemes.size()];
        const std::size_t n = m_series.u.centres_s.size();
        std::vector<CmSegment> segs(n);
        for (std::size_t i = 0; i < n; ++i)
            segs[i] = mpeg4_segment(m_series.u.centres_s[i], g[2], parameters[m_local[i]][0], m_alpha[i], g[0], g[1]);
        std::vector<double> z;
        CmPartials dz;
        cohen_massaro_partials(segs, m_series.u.times_s, z, jacobians ? &dz : nullptr);
        const std::size_t rows = m_series.y.size();
        for (std::size_t k = 0; k < rows; ++k) residuals[k] = z[k] - m_series.y[k];
        if (!jacobians) return true;
        for (std::size_t b = 0; b < m_visemes.size(); ++b)
            if (jacobians[b]) std::fill(jacobians[b], jacobians[b] + rows, 0.0);
        double* jg = jacobians[m_visemes.size()];
        if (jg) std::fill(jg, jg + 3 * rows, 0.0);
        for (std::size_t k = 0; k < rows; ++k)
            for (std::size_t e = dz.row_start[k]; e < dz.row_start[k + 1]; ++e) {
                const auto& d = dz.d[e];
                if (double* jt = jacobians[m_local[dz.segment[e]]]) jt[k] += d[0];
                if (jg) {
                    jg[3 * k + 0] += d[2];
                    jg[3 * k + 1] += d[3];
                    jg[3 * k + 2] += d[5];
                }
            }
        return true;
    }

private:
    Series m_series;
    std::vector<int> m_visemes, m_local;
    std::vector<double> m_alpha;
};

std::unique_ptr<ControlModel> train_mpeg4(std::unique_ptr<ControlModel> init, const fs::path& init_path,
                                          const std::vector<CorpusUtterance>& train,
                                          const std::vector<CorpusUtterance>& test, const TrainingSettings& settings,
                                          int threads, int& iterations, VisemeSet& trained_set) {
    auto* model = model_as<Mpeg4CohenMassaroModel>(init, init_path, "mpeg4-cohen-massaro");
    trained_set = model->viseme_set();
    for (const auto* set : {&train, &test})
        for (const auto& utt : *set)
            for (const auto& ph : utt.phones)
                if (!trained_set.phone_to_viseme.count(ph.symbol))
                    throw InputError(init_path, 0, 0, "viseme_set",
                                     fmt::format("the start model's viseme set \"{}\" (language {}) has no viseme for "
                                                 "phone \"{}\" of utterance {}; start from a model whose set maps the "
                                                 "corpus's language (protocols/models/<lang>/mpeg4-cohen-massaro.json)",
                                                 trained_set.name, trained_set.language, ph.symbol, utt.id));
    const std::vector<double> alphas = model->alphas();
    // Keys are viseme indices, named by viseme so prepare() can map phones.
    const Prepared p = prepare(train, test, [&](const Phone& ph) {
        return std::to_string(trained_set.phone_to_viseme.at(ph.symbol));
    });
    std::vector<int> viseme_of_key(p.keys.size());
    for (std::size_t k = 0; k < p.keys.size(); ++k) viseme_of_key[k] = std::stoi(p.keys[k]);
    auto remap = [&](std::array<std::vector<Series>, param_count> sets) {
        for (auto& per_param : sets)
            for (auto& s : per_param)
                for (int& key : s.u.key) key = viseme_of_key[static_cast<std::size_t>(key)];
        return sets;
    };
    const auto train_sets = remap(p.train), test_sets = remap(p.test);
    const std::size_t nv = trained_set.visemes.size();
    std::vector<double> targets(nv * param_count);  // [viseme][param]
    for (std::size_t q = 0; q < param_count; ++q) {
        const std::vector<double> mean = mean_target_per_key(p, q, params()[q].neutral);
        for (std::size_t v = 0; v < nv; ++v) targets[v * param_count + q] = trained_set.visemes[v].targets[q];
        for (std::size_t k = 0; k < p.keys.size(); ++k)
            if (p.key_trained[k])
                targets[static_cast<std::size_t>(viseme_of_key[k]) * param_count + q] =
                    std::clamp(mean[k], params()[q].min, params()[q].max);
    }
    const Mpeg4CmSettings& ms = model->settings();
    std::array<double, 3> global = {std::max(ms.theta_anticipatory_per_s, settings.min_rate_per_s),
                                    std::max(ms.theta_carryover_per_s, settings.min_rate_per_s), ms.t0_s};

    ceres::Problem::Options po;
    ceres::Problem problem(po);
    for (std::size_t q = 0; q < param_count; ++q) {
        if (!p.present[q]) continue;
        for (const auto& s : train_sets[q]) {
            auto* cost = new Mpeg4Cost(s, alphas);
            std::vector<double*> blocks;
            for (int v : cost->visemes()) blocks.push_back(&targets[static_cast<std::size_t>(v) * param_count + q]);
            blocks.push_back(global.data());
            problem.AddResidualBlock(cost, nullptr, blocks);
            for (std::size_t b = 0; b + 1 < blocks.size(); ++b) {
                problem.SetParameterLowerBound(blocks[b], 0, params()[q].min);
                problem.SetParameterUpperBound(blocks[b], 0, params()[q].max);
            }
        }
    }
    problem.SetParameterLowerBound(global.data(), 0, settings.min_rate_per_s);
    problem.SetParameterUpperBound(global.data(), 0, 1e4);
    problem.SetParameterLowerBound(global.data(), 1, settings.min_rate_per_s);
    problem.SetParameterUpperBound(global.data(), 1, 1e4);
    problem.SetParameterLowerBound(global.data(), 2, -0.1);
    problem.SetParameterUpperBound(global.data(), 2, 0.1);

    auto test_error = [&] {
        double sse = 0.0;
        std::vector<double> z;
        for (std::size_t q = 0; q < param_count; ++q)
            for (const auto& s : test_sets[q]) {
                std::vector<CmSegment> segs(s.u.centres_s.size());
                for (std::size_t i = 0; i < segs.size(); ++i) {
                    const auto v = static_cast<std::size_t>(s.u.key[i]);
                    segs[i] = mpeg4_segment(s.u.centres_s[i], global[2], targets[v * param_count + q], alphas[v],
                                            global[0], global[1]);
                }
                cohen_massaro_partials(segs, s.u.times_s, z, nullptr);
                for (std::size_t k = 0; k < z.size(); ++k) sse += (z[k] - s.y[k]) * (z[k] - s.y[k]);
            }
        return sse;
    };
    std::vector<double> best_targets = targets;
    std::array<double, 3> best_global = global;
    EarlyStopping stop(test_error, [&] { best_targets = targets; best_global = global; }, settings.patience);
    ceres::Solver::Options options = solver_options(settings, threads);
    const bool has_test = !test.empty();
    if (has_test) options.callbacks.push_back(&stop);
    ceres::Solver::Summary summary;
    ceres::Solve(options, &problem, &summary);
    if (has_test) {
        targets = best_targets;
        global = best_global;
    }
    for (std::size_t v = 0; v < nv; ++v)
        for (std::size_t q = 0; q < param_count; ++q) trained_set.visemes[v].targets[q] = targets[v * param_count + q];
    Mpeg4CmSettings out = ms;
    out.theta_anticipatory_per_s = global[0];
    out.theta_carryover_per_s = global[1];
    out.t0_s = global[2];
    out.t0_s_by_viseme.clear();
    iterations = static_cast<int>(summary.iterations.size());
    init = std::make_unique<Mpeg4CohenMassaroModel>(trained_set, "", out);
    // Keep the start model's file reference until run_training names the new set.
    return init;
}

ModelScores score(const ControlModel& model, const std::vector<CorpusUtterance>& set, const std::string& name) {
    return evaluate_predictors(set, {{name, [&model](const PhoneSequence& ph, std::span<const double> t,
                                                      std::vector<Frame>& out) { model.evaluate(ph, t, out); }}})
        .front();
}

std::string viseme_set_json(const VisemeSet& set, const std::string& source) {
    nlohmann::json j;
    j["name"] = set.name + "-trained";
    j["source"] = source;
    if (set.language != "en") j["language"] = set.language;
    j["visemes"] = nlohmann::json::array();
    for (const auto& v : set.visemes) {
        nlohmann::json t = nlohmann::json::object();
        for (const auto& info : params()) t[std::string(info.name)] = v.targets[index(info.param)];
        j["visemes"].push_back({{"id", v.id}, {"name", v.name}, {"phones", v.phones}, {"width_mm", v.width_mm},
                                {"height_mm", v.height_mm}, {"targets", t}});
    }
    return j.dump(2) + "\n";
}

}  // namespace

std::array<bool, param_count> measured_parameters(const std::vector<CorpusUtterance>& utterances) {
    std::array<bool, param_count> out{};
    for (const auto& u : utterances) {
        if (u.phones.empty()) continue;
        for (std::size_t q = 0; q < param_count; ++q) {
            if (out[q] || !u.track.present[q]) continue;
            for (std::size_t k = 0; k < u.track.size() && !out[q]; ++k) {
                const double t = u.track.time_s(k);
                out[q] = std::isfinite(u.track.frames[k][q]) && t >= u.phones.front().start_s &&
                         t <= u.phones.back().end_s;
            }
        }
    }
    return out;
}

TrainingReport train_model(const TrainingSettings& settings, const std::vector<CorpusUtterance>& train,
                           const std::vector<CorpusUtterance>& test) {
    const auto start = std::chrono::steady_clock::now();
    const Kind kind = parse_kind(settings.model);
    if (train.empty()) throw InputError("", 0, 0, "train split", "no training utterances");
    const fs::path init_path = settings.init_model.empty() ? default_init(kind) : settings.init_model;
    std::unique_ptr<ControlModel> init = load_model(init_path);
    const int threads = settings.threads > 0 ? settings.threads
                                             : std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
    TrainingReport report;
    report.trained = measured_parameters(train);
    VisemeSet set;
    switch (kind) {
        case Kind::CohenMassaro:
            report.model = train_cohen_massaro(std::move(init), init_path, train, test, settings, threads, report.iterations);
            break;
        case Kind::Ohman:
            report.model = train_ohman(std::move(init), init_path, train, test, settings, threads, report.iterations);
            break;
        case Kind::Mpeg4:
            report.model = train_mpeg4(std::move(init), init_path, train, test, settings, threads, report.iterations, set);
            break;
    }
    const auto all = static_cast<std::size_t>(FrameSubset::AllNonSilence);
    const ModelScores tr = score(*report.model, train, "train");
    report.train_rmse_percent = tr.mean[all].rmse_percent;
    report.train_pearson = tr.mean[all].pearson;
    if (!test.empty()) {
        const ModelScores te = score(*report.model, test, "test");
        report.test_rmse_percent = te.mean[all].rmse_percent;
        report.test_pearson = te.mean[all].pearson;
    }
    report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return report;
}

TrainingReport run_training(const TrainCommandSettings& s) {
    if (s.out.empty()) throw InputError("", 0, 0, "--out", "expected the model file to write");
    const ArticulatoryCorpus corpus = load_articulatory_corpus(s.corpus);
    const CorpusSplit split = split_corpus(corpus, s.split);
    log_info("training {} on {} ({} train / {} test utterances)", s.training.model, corpus.name,
             split.train_ids.size(), split.test_ids.size());
    const auto train = load_corpus_utterances(corpus, split.train_ids);
    const auto test = load_corpus_utterances(corpus, split.test_ids);
    TrainingReport report = train_model(s.training, train, test);
    std::vector<std::string> trained, kept;
    for (const auto& info : params()) (report.trained[index(info.param)] ? trained : kept).emplace_back(info.name);
    if (!kept.empty())
        log_info("{} measures {} of the 10 parameters; trained: {}; not measured, kept from {}: {}", corpus.name,
                 trained.size(), fmt::join(trained, ", "),
                 s.training.init_model.empty() ? std::string("the default model") : s.training.init_model.string(),
                 fmt::join(kept, ", "));

    ModelProvenance prov;
    prov.method = "trained";
    prov.data = fmt::format("{} (sha256 {})", corpus.name, corpus.hash);
    prov.split = fmt::format("{} train / {} test, seed {}, test fraction {}", split.train_ids.size(),
                             split.test_ids.size(), split.seed, split.test_fraction);
    prov.errors = {{"train_rmse_percent", report.train_rmse_percent},
                   {"test_rmse_percent", report.test_rmse_percent},
                   {"train_pearson", report.train_pearson},
                   {"test_pearson", report.test_pearson},
                   {"iterations", static_cast<double>(report.iterations)}};
    prov.notes = fmt::format(
        "Trained by `avsi train --model {}` (Levenberg-Marquardt, Ceres Solver, analytic Jacobians; early stopping "
        "on the test split, patience {}{}): {} iterations in {:.1f} s. Errors are RMSE in % of range and Pearson rho, "
        "mean over parameters, non-silence frames.",
        s.training.model, s.training.patience,
        parse_kind(s.training.model) == Kind::Ohman
            ? std::string()
            : fmt::format("; dominance rates theta, phi >= {} s^-c{}", s.training.min_rate_per_s,
                          parse_kind(s.training.model) != Kind::CohenMassaro ? std::string()
                          : s.training.min_c == s.training.max_c
                              ? fmt::format("; exponent c = {}", s.training.min_c)
                              : fmt::format("; exponent c in [{}, {}]", s.training.min_c, s.training.max_c)),
        report.iterations, report.seconds);
    if (!kept.empty())
        prov.notes += fmt::format(" Trained parameters (measured by the corpus): {}. Not measured, so kept from the "
                                  "initial model: {}.",
                                  fmt::join(trained, ", "), fmt::join(kept, ", "));
    if (auto* m = dynamic_cast<Mpeg4CohenMassaroModel*>(report.model.get())) {
        // The trained targets live in a viseme set beside the model file.
        const fs::path set_path = fs::path(s.out.string() + "").replace_extension(".visemes.json");
        write_text_file(set_path, viseme_set_json(m->viseme_set(), "targets trained by avsi train on " + prov.data));
        report.model = std::make_unique<Mpeg4CohenMassaroModel>(m->viseme_set(), set_path.filename().string(),
                                                                m->settings());
    }
    report.model->set_provenance(prov);
    save_model(*report.model, s.out);
    log_info("wrote {}: train RMSE {:.2f} %, test RMSE {:.2f} % of range, test rho {:.3f}, {} iterations, {:.1f} s",
             s.out.string(), report.train_rmse_percent, report.test_rmse_percent, report.test_pearson,
             report.iterations, report.seconds);
    return report;
}

}  // namespace avsi::learn
