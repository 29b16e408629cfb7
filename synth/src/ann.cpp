// ANN control models, inference side (Beskow §4.4–4.5; see ann.h): the
// frame feature encoding, the time-delay window, the recurrent networks run
// with Eigen, the streaming runner, and the model file (kind "ann").
#include "avsi/synth/ann.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include <Eigen/Core>
#include <fmt/format.h>

#include "avsi/core/error.h"
#include "model_json.h"

namespace avsi::synth {
namespace {

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

const FeatureVector& silence_features() {
    static const FeatureVector f = PhoneInventory::builtin().features_of(Phone{"sil", 0.0, 1.0, false});
    return f;
}

// ---- base64 of little-endian float32 ----

constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";

std::string encode_floats(const std::vector<float>& values) {
    std::vector<std::uint8_t> bytes(values.size() * 4);
    for (std::size_t i = 0; i < values.size(); ++i) {
        std::uint32_t u = 0;
        std::memcpy(&u, &values[i], 4);
        for (int j = 0; j < 4; ++j) bytes[i * 4 + static_cast<std::size_t>(j)] = static_cast<std::uint8_t>(u >> (8 * j));
    }
    std::string out;
    out.reserve((bytes.size() + 2) / 3 * 4);
    for (std::size_t i = 0; i < bytes.size(); i += 3) {
        const std::uint32_t n = (static_cast<std::uint32_t>(bytes[i]) << 16) |
                                (i + 1 < bytes.size() ? static_cast<std::uint32_t>(bytes[i + 1]) << 8 : 0u) |
                                (i + 2 < bytes.size() ? static_cast<std::uint32_t>(bytes[i + 2]) : 0u);
        out += kAlphabet[(n >> 18) & 63];
        out += kAlphabet[(n >> 12) & 63];
        out += i + 1 < bytes.size() ? kAlphabet[(n >> 6) & 63] : '=';
        out += i + 2 < bytes.size() ? kAlphabet[n & 63] : '=';
    }
    return out;
}

// Decodes; returns false on a malformed string.
bool decode_floats(const std::string& text, std::vector<float>& values) {
    if (text.size() % 4 != 0) return false;
    std::vector<std::uint8_t> bytes;
    bytes.reserve(text.size() / 4 * 3);
    auto value_of = [](char ch) -> int {
        if (ch >= 'A' && ch <= 'Z') return ch - 'A';
        if (ch >= 'a' && ch <= 'z') return ch - 'a' + 26;
        if (ch >= '0' && ch <= '9') return ch - '0' + 52;
        if (ch == '+') return 62;
        if (ch == '/') return 63;
        return -1;
    };
    for (std::size_t i = 0; i < text.size(); i += 4) {
        std::uint32_t n = 0;
        int pad = 0;
        for (int j = 0; j < 4; ++j) {
            const char ch = text[i + static_cast<std::size_t>(j)];
            int v = 0;
            if (ch == '=' && i + 4 == text.size() && j >= 2) {
                ++pad;
            } else {
                if (pad > 0) return false;
                v = value_of(ch);
                if (v < 0) return false;
            }
            n = (n << 6) | static_cast<std::uint32_t>(v);
        }
        bytes.push_back(static_cast<std::uint8_t>(n >> 16));
        if (pad < 2) bytes.push_back(static_cast<std::uint8_t>(n >> 8));
        if (pad < 1) bytes.push_back(static_cast<std::uint8_t>(n));
    }
    if (bytes.size() % 4 != 0) return false;
    values.resize(bytes.size() / 4);
    for (std::size_t i = 0; i < values.size(); ++i) {
        std::uint32_t u = 0;
        for (int j = 0; j < 4; ++j) u |= static_cast<std::uint32_t>(bytes[i * 4 + static_cast<std::size_t>(j)]) << (8 * j);
        std::memcpy(&values[i], &u, 4);
    }
    return true;
}

}  // namespace

AnnConfig ann1_config() { return AnnConfig{60.0, 15, 15, 5}; }
AnnConfig ann2_config() { return AnnConfig{60.0, 2, 28, 5}; }

const std::vector<AnnGroup>& ann_groups() {
    static const std::vector<AnnGroup> groups{
        {"occlusion", {Param::JawRotation, Param::UpperLipRaise, Param::LowerLipDepression}, 50},
        {"rounding", {Param::LipRounding, Param::MouthCornerStretchLeft, Param::MouthCornerStretchRight}, 50},
        {"protrusion", {Param::UpperLipRetraction, Param::LowerLipRetraction}, 30},
        {"jaw", {Param::JawThrust, Param::JawShift}, 30},
    };
    return groups;
}

std::vector<FeatureVector> encode_frame_features(const PhoneSequence& phones, double fps, std::size_t frames) {
    const auto& inventory = PhoneInventory::builtin();
    std::vector<FeatureVector> out(frames, silence_features());
    std::size_t p = 0;
    for (std::size_t k = 0; k < frames; ++k) {
        const double t = static_cast<double>(k) / fps;
        while (p < phones.size() && !(t < phones[p].end_s)) ++p;
        if (p == phones.size()) break;
        if (t >= phones[p].start_s) out[k] = inventory.features_of(phones[p]);
    }
    return out;
}

void window_input(std::span<const FeatureVector> features, std::ptrdiff_t k, const AnnConfig& config,
                  std::span<float> out) {
    AVSI_ASSERT(out.size() == config.inputs());
    const auto n = static_cast<std::ptrdiff_t>(features.size());
    std::size_t o = 0;
    for (std::ptrdiff_t j = k - config.look_back; j <= k + config.look_ahead; ++j) {
        const FeatureVector& f = (j >= 0 && j < n) ? features[static_cast<std::size_t>(j)] : silence_features();
        std::copy(f.begin(), f.end(), out.begin() + static_cast<std::ptrdiff_t>(o));
        o += feature_count;
    }
}

void AnnNetwork::check_sizes(const AnnConfig& config, const std::string& what) const {
    const auto h = static_cast<std::size_t>(group.hidden);
    const std::size_t p = group.params.size();
    const std::pair<const std::vector<float>*, std::size_t> expected[] = {
        {&W, h * config.inputs()}, {&U, h * h * static_cast<std::size_t>(config.delays)},
        {&b, h}, {&V, p * h}, {&c, p}};
    const char* names[] = {"W", "U", "b", "V", "c"};
    DiagnosticList problems;
    for (std::size_t i = 0; i < 5; ++i) {
        if (expected[i].first->size() != expected[i].second)
            problems.add(what, 0, 0, fmt::format("{}/{}", group.name, names[i]),
                         fmt::format("expected {} weights, got {}", expected[i].second, expected[i].first->size()));
    }
    problems.throw_if_any();
}

AnnRecurrentState::AnnRecurrentState(const AnnNetwork& network, const AnnConfig& config)
    : m_net(&network),
      m_delays(config.delays),
      m_history(static_cast<std::size_t>(config.delays * network.group.hidden), 0.0f),
      m_pre(static_cast<std::size_t>(network.group.hidden)),
      m_h(static_cast<std::size_t>(network.group.hidden)) {}

void AnnRecurrentState::step(std::span<const float> x, Frame& frame) {
    const Eigen::Index h = m_net->group.hidden;
    const auto in = static_cast<Eigen::Index>(x.size());
    const Eigen::Map<const RowMatrix> W(m_net->W.data(), h, in);
    const Eigen::Map<const RowMatrix> U(m_net->U.data(), h, h * m_delays);
    const Eigen::Map<const Eigen::VectorXf> b(m_net->b.data(), h);
    const Eigen::Map<const Eigen::VectorXf> xv(x.data(), in);
    const Eigen::Map<const Eigen::VectorXf> hist(m_history.data(), h * m_delays);
    Eigen::Map<Eigen::VectorXf> pre(m_pre.data(), h);
    pre.noalias() = W * xv;
    pre.noalias() += U * hist;
    pre += b;
    Eigen::Map<Eigen::VectorXf> hv(m_h.data(), h);
    hv = pre.array().tanh();
    // Shift the history: h_{t−d} → slot d.
    std::copy_backward(m_history.begin(), m_history.end() - h, m_history.end());
    std::copy(m_h.begin(), m_h.end(), m_history.begin());
    const auto p = static_cast<Eigen::Index>(m_net->group.params.size());
    const Eigen::Map<const RowMatrix> V(m_net->V.data(), p, h);
    const Eigen::VectorXf o = V * hv + Eigen::Map<const Eigen::VectorXf>(m_net->c.data(), p);
    for (Eigen::Index i = 0; i < p; ++i) {
        const ParamInfo& info = param_info(m_net->group.params[static_cast<std::size_t>(i)]);
        frame[index(info.param)] = info.neutral + info.range() * static_cast<double>(o[i]);
    }
}

AnnModel::AnnModel(AnnConfig config, std::vector<AnnNetwork> networks)
    : m_config(config), m_networks(std::move(networks)) {
    for (const auto& n : m_networks) n.check_sizes(m_config, "ann model");
}

std::vector<Frame> AnnModel::run_frames(const PhoneSequence& phones, std::size_t frames) const {
    // The look-ahead of the last frames reads the phones beyond them.
    const std::vector<FeatureVector> features =
        encode_frame_features(phones, m_config.fps, frames + static_cast<std::size_t>(m_config.look_ahead));
    Frame neutral{};
    for (const auto& info : params()) neutral[index(info.param)] = info.neutral;
    std::vector<Frame> out(frames, neutral);
    std::vector<float> x(m_config.inputs());
    std::vector<AnnRecurrentState> states;
    for (const auto& n : m_networks) states.emplace_back(n, m_config);
    for (std::size_t k = 0; k < frames; ++k) {
        window_input(features, static_cast<std::ptrdiff_t>(k), m_config, x);
        for (auto& s : states) s.step(x, out[k]);
    }
    return out;
}

void AnnModel::evaluate(const PhoneSequence& phones, std::span<const double> times_s,
                        std::vector<Frame>& out) const {
    check_phones_for_synthesis(phones);
    out.clear();
    if (times_s.empty()) return;
    double t_max = 0.0;
    for (double t : times_s) {
        if (!std::isfinite(t)) throw InputError(Diagnostic{"", 0, 0, "times", fmt::format("expected finite times, got {}", t)});
        t_max = std::max(t_max, t);
    }
    const auto frames = static_cast<std::size_t>(std::floor(t_max * m_config.fps)) + 2;
    const std::vector<Frame> f = run_frames(phones, frames);
    out.resize(times_s.size());
    for (std::size_t i = 0; i < times_s.size(); ++i) {
        const double pos = std::max(0.0, times_s[i] * m_config.fps);
        const auto k = std::min(static_cast<std::size_t>(std::floor(pos)), frames - 2);
        const double frac = std::clamp(pos - static_cast<double>(k), 0.0, 1.0);
        if (frac < 1e-9) {
            out[i] = f[k];
            continue;
        }
        for (std::size_t p = 0; p < param_count; ++p) out[i][p] = (1.0 - frac) * f[k][p] + frac * f[k + 1][p];
    }
}

std::string AnnModel::to_json_text() const {
    using detail::json;
    json root = detail::model_header(*this);
    root["config"] = json{{"fps", m_config.fps},
                          {"look_ahead", m_config.look_ahead},
                          {"look_back", m_config.look_back},
                          {"delays", m_config.delays}};
    json nets = json::array();
    for (const auto& n : m_networks) {
        json names = json::array();
        for (Param p : n.group.params) names.push_back(std::string(param_info(p).name));
        nets.push_back(json{{"name", n.group.name},
                            {"params", names},
                            {"hidden", n.group.hidden},
                            {"encoding", "base64-f32le"},
                            {"W", encode_floats(n.W)},
                            {"U", encode_floats(n.U)},
                            {"b", encode_floats(n.b)},
                            {"V", encode_floats(n.V)},
                            {"c", encode_floats(n.c)}});
    }
    root["networks"] = nets;
    root["training"] = training_json.empty() ? json::object() : json::parse(training_json);
    return root.dump(1) + "\n";
}

namespace detail {

std::unique_ptr<ControlModel> load_ann(const json& root, const std::filesystem::path& /*path*/, JsonReader& reader) {
    reader.check_keys(root, {"kind", "version", "provenance", "config", "networks", "training"}, "");
    AnnConfig config;
    bool ok = true;
    if (const json* c = reader.require(root, "config", "/config")) {
        reader.check_keys(*c, {"fps", "look_ahead", "look_back", "delays"}, "/config");
        const auto fps = reader.number_field(*c, "fps", "/config/fps", 0.0, 1000.0, true);
        const auto a = reader.number_field(*c, "look_ahead", "/config/look_ahead", 0, 200);
        const auto b = reader.number_field(*c, "look_back", "/config/look_back", 0, 200);
        const auto d = reader.number_field(*c, "delays", "/config/delays", 1, 50);
        if (fps && a && b && d) {
            config = AnnConfig{*fps, static_cast<int>(*a), static_cast<int>(*b), static_cast<int>(*d)};
            for (double v : {*a, *b, *d})
                if (v != std::floor(v)) {
                    reader.error("/config", fmt::format("expected whole frame counts, got {}", v));
                    ok = false;
                }
        } else {
            ok = false;
        }
    } else {
        ok = false;
    }
    std::vector<AnnNetwork> networks;
    const json* nets = reader.require(root, "networks", "/networks");
    if (nets && !nets->is_array()) {
        reader.error("/networks", fmt::format("expected an array, got {}", nets->type_name()));
        nets = nullptr;
    }
    if (!nets) ok = false;
    std::vector<bool> covered(param_count, false);
    if (nets) {
        for (std::size_t i = 0; i < nets->size(); ++i) {
            const json& n = (*nets)[i];
            const std::string at = fmt::format("/networks/{}", i);
            if (!n.is_object()) {
                reader.error(at, "expected an object");
                ok = false;
                continue;
            }
            reader.check_keys(n, {"name", "params", "hidden", "encoding", "W", "U", "b", "V", "c"}, at);
            AnnNetwork net;
            if (auto name = reader.string_field(n, "name", at + "/name")) net.group.name = *name;
            if (auto h = reader.number_field(n, "hidden", at + "/hidden", 1, 4096)) net.group.hidden = static_cast<int>(*h);
            else ok = false;
            if (const json* ps = reader.require(n, "params", at + "/params")) {
                if (!ps->is_array() || ps->empty()) {
                    reader.error(at + "/params", "expected a non-empty array of parameter names");
                    ok = false;
                } else {
                    for (std::size_t j = 0; j < ps->size(); ++j) {
                        const json& v = (*ps)[j];
                        const auto param = v.is_string() ? param_from_name(v.get<std::string>()) : std::nullopt;
                        if (!param) {
                            reader.error(fmt::format("{}/params/{}", at, j),
                                         fmt::format("expected a parameter name, got {}", v.dump()));
                            ok = false;
                        } else if (covered[index(*param)]) {
                            reader.error(fmt::format("{}/params/{}", at, j),
                                         fmt::format("parameter {} is predicted by two networks", v.dump()));
                            ok = false;
                        } else {
                            covered[index(*param)] = true;
                            net.group.params.push_back(*param);
                        }
                    }
                }
            } else {
                ok = false;
            }
            if (auto enc = reader.string_field(n, "encoding", at + "/encoding"); enc && *enc != "base64-f32le") {
                reader.error(at + "/encoding", fmt::format("expected \"base64-f32le\", got \"{}\"", *enc));
                ok = false;
            }
            std::vector<float>* blobs[] = {&net.W, &net.U, &net.b, &net.V, &net.c};
            const char* names[] = {"W", "U", "b", "V", "c"};
            for (std::size_t j = 0; j < 5; ++j) {
                const auto s = reader.string_field(n, names[j], at + "/" + names[j]);
                if (!s || !decode_floats(*s, *blobs[j])) {
                    if (s) reader.error(at + "/" + names[j], "expected base64 of little-endian float32 values");
                    ok = false;
                    continue;
                }
                for (float v : *blobs[j])
                    if (!std::isfinite(v)) {
                        reader.error(at + "/" + names[j], "expected finite weights, got NaN or infinity");
                        ok = false;
                        break;
                    }
            }
            networks.push_back(std::move(net));
        }
    }
    if (!ok) return nullptr;
    DiagnosticList size_problems;
    for (std::size_t i = 0; i < networks.size(); ++i) {
        try {
            networks[i].check_sizes(config, reader.path());
        } catch (const InputError&) {
            reader.error(fmt::format("/networks/{}", i),
                         fmt::format("expected weight sizes for {} hidden units, {} inputs, {} delays", networks[i].group.hidden,
                                     config.inputs(), config.delays));
            ok = false;
        }
    }
    if (!ok) return nullptr;
    auto model = std::make_unique<AnnModel>(config, std::move(networks));
    if (const auto it = root.find("training"); it != root.end()) model->training_json = it->dump();
    return model;
}

}  // namespace detail

AnnStreamer::AnnStreamer(const AnnModel& model) : m_model(&model), m_x(model.config().inputs()) {
    for (const auto& n : model.networks()) m_states.emplace_back(n, model.config());
}

void AnnStreamer::push(const Phone& phone) {
    if (m_finished) throw InputError(Diagnostic{"", 0, 0, "phone", "expected no phones after the end of the stream"});
    if (!std::isfinite(phone.start_s) || !std::isfinite(phone.end_s) || !(phone.end_s > phone.start_s) ||
        phone.start_s < 0.0)
        throw InputError(Diagnostic{"", 0, 0, fmt::format("phone '{}'", phone.symbol),
                                    fmt::format("expected 0 <= start < end, got start {} s, end {} s", phone.start_s,
                                                phone.end_s)});
    if (phone.start_s < m_known_until_s - 1e-6)
        throw InputError(Diagnostic{"", 0, 0, fmt::format("phone '{}'", phone.symbol),
                                    fmt::format("expected to start at or after the previous phone's end {} s, got {} s",
                                                m_known_until_s, phone.start_s)});
    const FeatureVector f = PhoneInventory::builtin().features_of(phone);
    const double fps = m_model->config().fps;
    for (std::size_t j = m_features.size();; ++j) {
        const double t = static_cast<double>(j) / fps;
        if (!(t < phone.end_s)) break;
        m_features.push_back(t >= phone.start_s ? f : silence_features());
    }
    m_known_until_s = phone.end_s;
    advance();
}

void AnnStreamer::finish() {
    if (m_finished) return;
    m_finished = true;
    m_total_frames = frame_count(m_known_until_s, m_model->config().fps);
    advance();
}

void AnnStreamer::advance() {
    const AnnConfig& c = m_model->config();
    Frame neutral{};
    for (const auto& info : params()) neutral[index(info.param)] = info.neutral;
    while (true) {
        if (m_finished) {
            if (m_next >= m_total_frames) break;
        } else if (m_next + static_cast<std::size_t>(c.look_ahead) >= m_features.size()) {
            break;
        }
        // Frames past the known ones are silence (window_input pads them), which
        // only happens after finish().
        window_input(m_features, static_cast<std::ptrdiff_t>(m_next), c, m_x);
        StreamFrame out{m_next, static_cast<double>(m_next) / c.fps, neutral};
        for (auto& s : m_states) s.step(m_x, out.values);
        m_ready.push_back(out);
        ++m_next;
    }
}

std::vector<StreamFrame> AnnStreamer::take_ready() {
    std::vector<StreamFrame> out;
    out.swap(m_ready);
    return out;
}

}  // namespace avsi::synth
