// ANN training with libtorch (Beskow §4.4–4.5; see ann_training.h): the
// recurrent time-delay networks as torch modules, backpropagation through
// time by autograd over whole padded utterances, Adam, masked loss, early
// stopping on the held-out error. The only file that includes torch.
#include "avsi/learn/ann_training.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <fmt/format.h>
#include <torch/torch.h>

#include "avsi/core/error.h"
#include "avsi/core/log.h"

namespace avsi::learn {
namespace {

// One utterance as tensors at the model frame rate.
struct Prepared {
    torch::Tensor x;     // [n, inputs]
    torch::Tensor y;     // [n, 10] range-normalised targets, 0 where missing
    torch::Tensor mask;  // [n, 10] 1 where the target is present
    std::int64_t frames = 0;
};

double target_at(const ParamTrack& track, std::size_t p, double t) {
    if (!track.present[p] || track.frames.empty()) return std::nan("");
    const double pos = (t - track.start_s) * track.fps;
    if (pos < -1e-6 || pos > static_cast<double>(track.frames.size() - 1) + 1e-6) return std::nan("");
    const double clamped = std::clamp(pos, 0.0, static_cast<double>(track.frames.size() - 1));
    const auto k = static_cast<std::size_t>(std::floor(clamped));
    const double frac = clamped - static_cast<double>(k);
    if (frac < 1e-9 || k + 1 >= track.frames.size()) return track.frames[k][p];
    return (1.0 - frac) * track.frames[k][p] + frac * track.frames[k + 1][p];
}

Prepared prepare(const CorpusUtterance& u, const AnnConfig& config) {
    check_phones_for_synthesis(u.phones, u.id);
    const std::size_t n = frame_count(u.phones.back().end_s, config.fps);
    const std::vector<FeatureVector> features = encode_frame_features(u.phones, config.fps, n);
    Prepared out;
    out.frames = static_cast<std::int64_t>(n);
    out.x = torch::empty({out.frames, static_cast<std::int64_t>(config.inputs())}, torch::kFloat32);
    out.y = torch::zeros({out.frames, static_cast<std::int64_t>(param_count)}, torch::kFloat32);
    out.mask = torch::zeros({out.frames, static_cast<std::int64_t>(param_count)}, torch::kFloat32);
    float* x = out.x.data_ptr<float>();
    float* y = out.y.data_ptr<float>();
    float* m = out.mask.data_ptr<float>();
    for (std::size_t k = 0; k < n; ++k) {
        window_input(features, static_cast<std::ptrdiff_t>(k), config,
                     std::span<float>(x + k * config.inputs(), config.inputs()));
        const double t = static_cast<double>(k) / config.fps;
        for (std::size_t p = 0; p < param_count; ++p) {
            const double v = target_at(u.track, p, t);
            if (!std::isfinite(v)) continue;
            const ParamInfo& info = params()[p];
            y[k * param_count + p] = static_cast<float>((v - info.neutral) / info.range());
            m[k * param_count + p] = 1.0f;
        }
    }
    return out;
}

// A batch padded to its longest utterance (padding masked out).
struct Batch {
    torch::Tensor x, y, mask;
};

Batch make_batch(const std::vector<Prepared>& data, const std::vector<std::int64_t>& ids) {
    std::int64_t t_max = 0;
    for (auto i : ids) t_max = std::max(t_max, data[static_cast<std::size_t>(i)].frames);
    const auto b = static_cast<std::int64_t>(ids.size());
    const std::int64_t inputs = data.front().x.size(1);
    Batch out{torch::zeros({b, t_max, inputs}), torch::zeros({b, t_max, static_cast<std::int64_t>(param_count)}),
              torch::zeros({b, t_max, static_cast<std::int64_t>(param_count)})};
    for (std::int64_t j = 0; j < b; ++j) {
        const Prepared& p = data[static_cast<std::size_t>(ids[static_cast<std::size_t>(j)])];
        out.x[j].narrow(0, 0, p.frames).copy_(p.x);
        out.y[j].narrow(0, 0, p.frames).copy_(p.y);
        out.mask[j].narrow(0, 0, p.frames).copy_(p.mask);
    }
    return out;
}

// h_t = tanh(W x_t + Σ_d U_d h_{t−d} + b), o_t = V h_t + c.
struct RecurrentNet : torch::nn::Module {
    torch::Tensor W, U, b, V, c;
    int hidden, delays;

    RecurrentNet(std::int64_t inputs, int hidden_units, std::int64_t outputs, int delay_count)
        : hidden(hidden_units), delays(delay_count) {
        const double a_in = 1.0 / std::sqrt(static_cast<double>(inputs));
        const double a_rec = 0.5 / std::sqrt(static_cast<double>(hidden * delays));
        const double a_out = 1.0 / std::sqrt(static_cast<double>(hidden));
        W = register_parameter("W", torch::empty({hidden, inputs}).uniform_(-a_in, a_in));
        U = register_parameter("U", torch::empty({hidden, static_cast<std::int64_t>(hidden) * delays}).uniform_(-a_rec, a_rec));
        b = register_parameter("b", torch::zeros({hidden}));
        V = register_parameter("V", torch::empty({outputs, hidden}).uniform_(-a_out, a_out));
        c = register_parameter("c", torch::zeros({outputs}));
    }

    // x: [B, T, inputs] → [B, T, outputs]
    torch::Tensor forward(const torch::Tensor& x) {
        const std::int64_t batch = x.size(0), steps = x.size(1);
        const torch::Tensor drive = torch::matmul(x, W.t()) + b;   // [B, T, H]
        const torch::Tensor Ut = U.t();
        std::vector<torch::Tensor> history(static_cast<std::size_t>(delays), torch::zeros({batch, hidden}));
        std::vector<torch::Tensor> hs;
        hs.reserve(static_cast<std::size_t>(steps));
        for (std::int64_t t = 0; t < steps; ++t) {
            const torch::Tensor prev = torch::cat(history, 1);   // [h_{t−1}, …, h_{t−D}]
            torch::Tensor h = torch::tanh(drive.select(1, t) + torch::matmul(prev, Ut));
            history.pop_back();
            history.insert(history.begin(), h);
            hs.push_back(std::move(h));
        }
        return torch::matmul(torch::stack(hs, 1), V.t()) + c;
    }
};

std::vector<float> to_vector(const torch::Tensor& t) {
    const torch::Tensor c = t.detach().contiguous().to(torch::kFloat32);
    return std::vector<float>(c.data_ptr<float>(), c.data_ptr<float>() + c.numel());
}

// Sum of squared masked errors and the count, over a data set.
std::pair<double, double> masked_sse(RecurrentNet& net, const std::vector<Prepared>& data,
                                     const torch::Tensor& cols, int batch_size) {
    torch::NoGradGuard no_grad;
    double sse = 0, count = 0;
    for (std::size_t i = 0; i < data.size(); i += static_cast<std::size_t>(batch_size)) {
        std::vector<std::int64_t> ids;
        for (std::size_t j = i; j < std::min(data.size(), i + static_cast<std::size_t>(batch_size)); ++j)
            ids.push_back(static_cast<std::int64_t>(j));
        const Batch b = make_batch(data, ids);
        const torch::Tensor out = net.forward(b.x);
        const torch::Tensor y = b.y.index_select(2, cols), m = b.mask.index_select(2, cols);
        sse += ((out - y).pow(2) * m).sum().item<double>();
        count += m.sum().item<double>();
    }
    return {sse, count};
}

double rmse_percent(const std::pair<double, double>& s) {
    return s.second > 0 ? 100.0 * std::sqrt(s.first / s.second) : std::nan("");
}

struct TrainedNet {
    AnnNetwork network;
    AnnNetworkReport report;
};

TrainedNet train_network(const AnnTrainingSettings& s, const AnnGroup& group, std::size_t group_index,
                         const std::vector<Prepared>& train, const std::vector<Prepared>& whole_train,
                         const std::vector<Prepared>& held_out) {
    const auto start = std::chrono::steady_clock::now();
    torch::manual_seed(s.seed + 1000003ULL * group_index);
    std::vector<std::int64_t> col_ids;
    for (Param p : group.params) col_ids.push_back(static_cast<std::int64_t>(index(p)));
    const torch::Tensor cols = torch::tensor(col_ids, torch::kInt64);
    RecurrentNet net(static_cast<std::int64_t>(s.config.inputs()), group.hidden,
                     static_cast<std::int64_t>(group.params.size()), s.config.delays);
    torch::optim::Adam optimizer(net.parameters(), torch::optim::AdamOptions(s.learning_rate));

    TrainedNet out;
    out.network.group = group;
    out.report.name = group.name;
    double best = std::numeric_limits<double>::infinity();
    int since_best = 0;
    Progress progress(fmt::format("training ANN network {} (A={}, B={})", group.name, s.config.look_ahead,
                                  s.config.look_back),
                      static_cast<std::size_t>(s.max_epochs));
    const auto n = static_cast<std::int64_t>(train.size());
    for (int epoch = 1; epoch <= s.max_epochs; ++epoch) {
        const torch::Tensor order = torch::randperm(n, torch::kInt64);
        const auto* ord = order.data_ptr<std::int64_t>();
        for (std::int64_t i = 0; i < n; i += s.batch_utterances) {
            std::vector<std::int64_t> ids(ord + i, ord + std::min(n, i + s.batch_utterances));
            const Batch b = make_batch(train, ids);
            const torch::Tensor y = b.y.index_select(2, cols), m = b.mask.index_select(2, cols);
            const torch::Tensor denom = m.sum().clamp_min(1.0);
            optimizer.zero_grad();
            const torch::Tensor loss = ((net.forward(b.x) - y).pow(2) * m).sum() / denom;
            loss.backward();
            optimizer.step();
        }
        const double test_error = rmse_percent(masked_sse(net, held_out, cols, 64));
        out.report.test_curve.push_back(test_error);
        out.report.epochs = epoch;
        progress.advance();
        if (test_error < best) {
            best = test_error;
            since_best = 0;
            out.report.best_epoch = epoch;
            out.report.test_rmse_percent = test_error;
            out.network.W = to_vector(net.W);
            out.network.U = to_vector(net.U);
            out.network.b = to_vector(net.b);
            out.network.V = to_vector(net.V);
            out.network.c = to_vector(net.c);
        } else if (++since_best >= s.patience) {
            break;
        }
        const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        if (s.max_seconds > 0 && elapsed > s.max_seconds) {
            log_info("ANN {}: stopping at epoch {} on the time budget of {} s", group.name, epoch, s.max_seconds);
            break;
        }
    }
    progress.finish();
    // The train error of the kept weights.
    {
        torch::NoGradGuard no_grad;
        net.W.copy_(torch::from_blob(out.network.W.data(), net.W.sizes(), torch::kFloat32));
        net.U.copy_(torch::from_blob(out.network.U.data(), net.U.sizes(), torch::kFloat32));
        net.b.copy_(torch::from_blob(out.network.b.data(), net.b.sizes(), torch::kFloat32));
        net.V.copy_(torch::from_blob(out.network.V.data(), net.V.sizes(), torch::kFloat32));
        net.c.copy_(torch::from_blob(out.network.c.data(), net.c.sizes(), torch::kFloat32));
    }
    out.report.train_rmse_percent = rmse_percent(masked_sse(net, whole_train, cols, 64));
    out.report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    log_info("ANN {}: {} epochs, kept epoch {}, train {:.2f} %, held-out {:.2f} % of range, {:.1f} s", group.name,
             out.report.epochs, out.report.best_epoch, out.report.train_rmse_percent, out.report.test_rmse_percent,
             out.report.seconds);
    return out;
}

std::vector<Prepared> prepare_all(const std::vector<CorpusUtterance>& utterances, const AnnConfig& config) {
    std::vector<Prepared> out;
    out.reserve(utterances.size());
    for (const auto& u : utterances) out.push_back(prepare(u, config));
    return out;
}

// Chunks of `chunk` frames with `warmup` frames before each (masked out).
std::vector<Prepared> chunk_all(const std::vector<Prepared>& data, int chunk, int warmup) {
    std::vector<Prepared> out;
    for (const auto& d : data) {
        for (std::int64_t s = 0; s < d.frames; s += chunk) {
            const std::int64_t from = std::max<std::int64_t>(0, s - warmup);
            const std::int64_t to = std::min<std::int64_t>(d.frames, s + chunk);
            Prepared c;
            c.frames = to - from;
            c.x = d.x.narrow(0, from, c.frames);
            c.y = d.y.narrow(0, from, c.frames);
            c.mask = d.mask.narrow(0, from, c.frames).clone();
            c.mask.narrow(0, 0, s - from).zero_();
            out.push_back(std::move(c));
        }
    }
    return out;
}

bool group_has_data(const std::vector<Prepared>& data, const AnnGroup& group) {
    for (const auto& d : data)
        for (Param p : group.params)
            if (d.mask.select(1, static_cast<std::int64_t>(index(p))).sum().item<double>() > 0) return true;
    return false;
}

}  // namespace

AnnTrainingReport train_ann(const AnnTrainingSettings& settings, const std::vector<CorpusUtterance>& train,
                            const std::vector<CorpusUtterance>& test) {
    if (train.empty()) throw InputError(Diagnostic{"", 0, 0, "train", "expected training utterances, got none"});
    if (settings.max_epochs < 1 || settings.batch_utterances < 1 || settings.patience < 1 || settings.threads < 1)
        throw InputError(Diagnostic{"", 0, 0, "settings",
                                    "expected max_epochs, batch_utterances, patience and threads >= 1"});
    const auto start = std::chrono::steady_clock::now();
    at::set_num_threads(settings.threads);
    at::globalContext().setDeterministicAlgorithms(true, false);
    const std::vector<Prepared> whole_train = prepare_all(train, settings.config);
    const std::vector<Prepared> train_data =
        settings.chunk_frames > 0 ? chunk_all(whole_train, settings.chunk_frames, std::max(0, settings.warmup_frames))
                                  : whole_train;
    const std::vector<Prepared> test_data = test.empty() ? whole_train : prepare_all(test, settings.config);
    if (test.empty()) log_warning("ANN training: no held-out utterances; early stopping on the training error");

    AnnTrainingReport report;
    std::vector<AnnNetwork> networks;
    for (std::size_t g = 0; g < settings.groups.size(); ++g) {
        const AnnGroup& group = settings.groups[g];
        if (!group_has_data(train_data, group)) {
            log_warning("ANN {}: the corpus has none of its parameters; the network is left out", group.name);
            continue;
        }
        TrainedNet t = train_network(settings, group, g, train_data, whole_train, test_data);
        networks.push_back(std::move(t.network));
        report.networks.push_back(std::move(t.report));
    }
    if (networks.empty())
        throw InputError(Diagnostic{"", 0, 0, "corpus", "expected values of at least one network's parameters, got none"});
    report.model = std::make_unique<AnnModel>(settings.config, std::move(networks));
    report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return report;
}

std::vector<LookaheadPoint> sweep_lookahead(const AnnTrainingSettings& settings, int first, int last, int window,
                                            const std::vector<CorpusUtterance>& train,
                                            const std::vector<CorpusUtterance>& test) {
    if (first < 0 || last < first || last > window - 1)
        throw InputError(Diagnostic{"", 0, 0, "sweep-lookahead",
                                    fmt::format("expected 0 <= first <= last <= {}, got {}..{}", window - 1, first, last)});
    std::vector<LookaheadPoint> points;
    for (int a = first; a <= last; ++a) {
        AnnTrainingSettings s = settings;
        s.config.look_ahead = a;
        s.config.look_back = window - 1 - a;
        s.groups = {ann_groups().front()};   // the occlusion network, as in §4.5
        const AnnTrainingReport r = train_ann(s, train, test);
        const AnnNetworkReport& n = r.networks.front();
        points.push_back(LookaheadPoint{a, s.config.look_back, n.epochs, n.train_rmse_percent, n.test_rmse_percent,
                                        n.seconds});
        log_info("look-ahead {}: held-out {:.3f} % of range", a, n.test_rmse_percent);
    }
    return points;
}

}  // namespace avsi::learn
