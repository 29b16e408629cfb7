// Layered animation: the layers, their blend (Charisma paper §3, eq. 1–4)
// and the settings of a condition's [condition.layers] table.
#include "avsi/stimuli/layers.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <nlohmann/json.hpp>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/json.h"
#include "avsi/core/log.h"
#include "avsi/core/rng.h"

namespace avsi::stimuli {

using json = nlohmann::json;

namespace {

constexpr std::array<std::string_view, feature_group_count> k_group_names = {
    "jaw", "eyes", "eyebrows", "cheeks", "tongue", "head", "outer_lips", "nose", "ears"};

std::size_t group_slot(FeatureGroup g) { return static_cast<std::size_t>(g); }

// The effective weight of layer `l` on group `g` at a channel where
// `module_sets` says whether some module sets it.
double layer_weight(const Layer& l, FeatureGroup g, bool module_sets) {
    if (const auto& w = l.group_weights[group_slot(g)]) return *w;
    if (l.weight) return *l.weight;
    return l.set == LayerSet::Stream && module_sets ? 0.0 : 1.0;
}

}  // namespace

std::string_view feature_group_name(FeatureGroup group) { return k_group_names[group_slot(group)]; }

std::optional<FeatureGroup> feature_group_from_name(std::string_view name) {
    for (std::size_t g = 0; g < feature_group_count; ++g)
        if (k_group_names[g] == name) return static_cast<FeatureGroup>(g);
    return std::nullopt;
}

FeatureGroup fap_feature_group(int fap) {
    AVSI_ASSERT(fap >= 3 && fap <= synth::fap_count);
    if (fap <= 18) return FeatureGroup::Jaw;
    if (fap <= 30) return FeatureGroup::Eyes;
    if (fap <= 38) return FeatureGroup::Eyebrows;
    if (fap <= 42) return FeatureGroup::Cheeks;
    if (fap <= 47) return FeatureGroup::Tongue;
    if (fap <= 50) return FeatureGroup::Head;
    if (fap <= 60) return FeatureGroup::OuterLips;
    if (fap <= 64) return FeatureGroup::Nose;
    return FeatureGroup::Ears;
}

FeatureGroup channel_group(std::size_t c) {
    AVSI_ASSERT(c < channel_count);
    if (c < synth::param_count) {
        const auto p = static_cast<synth::Param>(c);
        return p == synth::Param::JawRotation || p == synth::Param::JawThrust || p == synth::Param::JawShift
                   ? FeatureGroup::Jaw
                   : FeatureGroup::OuterLips;
    }
    if (c == tongue_tip_channel) return FeatureGroup::Tongue;
    if (c == brow_inner_raise_channel || c == brow_outer_raise_channel) return FeatureGroup::Eyebrows;
    if (c == cheek_raise_channel) return FeatureGroup::Cheeks;
    return FeatureGroup::Eyes;
}

bool is_mouth_group(FeatureGroup g) {
    return g == FeatureGroup::Jaw || g == FeatureGroup::OuterLips || g == FeatureGroup::Tongue;
}

Pose blend_frame(const std::vector<Layer>& layers, std::size_t k, bool speech_owns_mouth) {
    for (const auto& l : layers) AVSI_ASSERT(k < l.frames.size());
    Pose pose;
    for (std::size_t c = 0; c < channel_count; ++c) {
        const FeatureGroup g = channel_group(c);
        bool module_sets = false;
        for (const auto& l : layers)
            if (l.set == LayerSet::Module && l.frames[k].set[c]) module_sets = true;
        double sum = 0.0, total = 0.0;
        for (const auto& l : layers) {
            const LayerFrame& f = l.frames[k];
            if (!f.set[c]) continue;
            // The speech layer's mouth: its values alone, unweighted.
            if (speech_owns_mouth && is_mouth_group(g)) {
                if (!l.is_speech) continue;
                sum = f.values[c], total = 1.0;
                break;
            }
            const double w = layer_weight(l, g, module_sets);
            if (w <= 0.0) continue;
            sum += w * f.values[c];
            total += w;
        }
        if (total > 0.0) pose.set_channel(c, total > 1.0 ? sum / total : sum);
    }
    // The head's rotation: a running weighted SLERP (exact for two layers).
    bool module_rotates = false;
    for (const auto& l : layers)
        if (l.set == LayerSet::Module && l.frames[k].sets_rotation) module_rotates = true;
    glm::quat q(1.0f, 0.0f, 0.0f, 0.0f);
    double total = 0.0;
    for (const auto& l : layers) {
        const LayerFrame& f = l.frames[k];
        if (!f.sets_rotation) continue;
        const double w = layer_weight(l, FeatureGroup::Head, module_rotates);
        if (w <= 0.0) continue;
        total += w;
        q = glm::slerp(q, f.rotation, static_cast<float>(w / total));
    }
    if (total > 0.0 && total < 1.0) q = glm::slerp(glm::quat(1.0f, 0.0f, 0.0f, 0.0f), q, static_cast<float>(total));
    pose.head_rotation = q;
    return pose;
}

// ---- The layers -----------------------------------------------------------

Layer speech_layer(const synth::Trajectory& trajectory, const PhoneSequence* phones) {
    Layer l;
    l.name = "speech";
    l.is_speech = true;
    l.frames.resize(trajectory.size());
    const auto tongue = phones ? tongue_tip_track(*phones, trajectory.size(), trajectory.fps)
                               : std::vector<double>(trajectory.size(), 0.0);
    for (std::size_t k = 0; k < trajectory.size(); ++k) {
        for (std::size_t p = 0; p < synth::param_count; ++p) l.frames[k].set_channel(p, trajectory.frames[k][p]);
        l.frames[k].set_channel(tongue_tip_channel, tongue[k]);
    }
    return l;
}

Layer blink_layer(std::size_t frames, double fps, const BlinkSettings& settings) {
    Layer l;
    l.name = "blink";
    l.frames.resize(frames);
    const auto track = blink_track(frames, fps, settings);
    for (std::size_t k = 0; k < frames; ++k) l.frames[k].set_channel(blink_channel, track[k]);
    return l;
}

std::vector<Saccade> gaze_saccades(double duration_s, const GazeSettings& s) {
    std::vector<Saccade> out;
    Rng rng = Rng(s.seed).derive("gaze");
    const double extra = std::max(s.mean_fixation_s - s.min_fixation_s, 0.01);
    double left = 0.0, up = 0.0;
    double t = rng.uniform() * s.mean_fixation_s;
    while (t < duration_s) {
        double to_left = 0.0, to_up = 0.0;
        const bool away = left != 0.0 || up != 0.0;
        if (!(away && rng.uniform() < s.return_probability)) {
            // A new point round the camera: exponential amplitude, uniform direction.
            double amplitude = 0.0;
            do amplitude = -s.mean_amplitude_deg * std::log(1.0 - rng.uniform());
            while (amplitude > s.max_amplitude_deg);
            const double angle = rng.uniform(0.0, 2.0 * M_PI);
            to_left = amplitude * std::cos(angle);
            to_up = amplitude * std::sin(angle) * s.vertical_scale;
        }
        Saccade sc;
        sc.onset_s = t;
        sc.amplitude_deg = std::hypot(to_left - left, to_up - up);
        sc.duration_s = 0.021 + 0.0022 * sc.amplitude_deg;
        sc.to_left_deg = to_left;
        sc.to_up_deg = to_up;
        out.push_back(sc);
        left = to_left, up = to_up;
        t += sc.duration_s + s.min_fixation_s - extra * std::log(1.0 - rng.uniform());
    }
    return out;
}

std::vector<std::array<double, 2>> gaze_track_deg(std::size_t frames, double fps, const GazeSettings& settings) {
    std::vector<std::array<double, 2>> track(frames, {0.0, 0.0});
    const auto saccades = gaze_saccades(static_cast<double>(frames) / fps, settings);
    double from_left = 0.0, from_up = 0.0;
    std::size_t next = 0;
    for (std::size_t k = 0; k < frames; ++k) {
        const double t = static_cast<double>(k) / fps;
        // Saccades finished by t land; the one in flight is part way.
        while (next < saccades.size() && saccades[next].onset_s + saccades[next].duration_s <= t) {
            from_left = saccades[next].to_left_deg, from_up = saccades[next].to_up_deg;
            ++next;
        }
        double left = from_left, up = from_up;
        if (next < saccades.size() && saccades[next].onset_s <= t) {
            const auto& sc = saccades[next];
            const double a = 0.5 - 0.5 * std::cos(M_PI * (t - sc.onset_s) / sc.duration_s);
            left += a * (sc.to_left_deg - from_left);
            up += a * (sc.to_up_deg - from_up);
        }
        track[k] = {left, up};
    }
    return track;
}

double gaze_unit_deg(const Head& head) {
    for (const auto& t : head.transforms)
        if (static_cast<std::size_t>(t.channel_index) == gaze_left_channel && t.kind == TransformKind::Rotate)
            return std::abs(static_cast<double>(t.angle_deg));
    return 0.0;
}

Layer gaze_layer(std::size_t frames, double fps, const GazeSettings& settings, double unit_deg) {
    Layer l;
    l.name = "gaze";
    l.frames.resize(frames);
    if (unit_deg <= 0.0) return l;
    const auto track = gaze_track_deg(frames, fps, settings);
    for (std::size_t k = 0; k < frames; ++k) {
        l.frames[k].set_channel(gaze_left_channel, track[k][0] / unit_deg);
        l.frames[k].set_channel(gaze_up_channel, track[k][1] / unit_deg);
    }
    return l;
}

glm::quat head_rotation_from_angles(double pitch_rad, double yaw_rad, double roll_rad) {
    // x to the speaker's left, y up, z forward: a positive pitch nods the
    // face down (about +x), a positive yaw turns it to the speaker's left
    // (about +y), a positive roll turns it about +z (the forward axis).
    const glm::quat pitch = glm::angleAxis(static_cast<float>(pitch_rad), glm::vec3(1, 0, 0));
    const glm::quat yaw = glm::angleAxis(static_cast<float>(yaw_rad), glm::vec3(0, 1, 0));
    const glm::quat roll = glm::angleAxis(static_cast<float>(roll_rad), glm::vec3(0, 0, 1));
    return yaw * pitch * roll;
}

std::vector<glm::quat> idle_head_motion(std::size_t frames, double fps, const HeadMotionSettings& s) {
    Rng rng = Rng(s.seed).derive("head-motion");
    struct Axis {
        std::array<double, 3> freq_hz{}, phase{}, amp{};
    };
    std::array<Axis, 3> axes;
    const std::array<double, 3> rms = {s.pitch_rms_deg, s.yaw_rms_deg, s.roll_rms_deg};
    for (std::size_t a = 0; a < 3; ++a) {
        double power = 0.0;
        for (std::size_t i = 0; i < 3; ++i) {
            axes[a].freq_hz[i] = rng.uniform(0.05, 0.4);
            axes[a].phase[i] = rng.uniform(0.0, 2.0 * M_PI);
            axes[a].amp[i] = rng.uniform(0.5, 1.0);
            power += 0.5 * axes[a].amp[i] * axes[a].amp[i];
        }
        // Scaled so the sum's RMS (over a long time) is the axis's.
        for (auto& amp : axes[a].amp) amp *= rms[a] / std::sqrt(power);
    }
    std::vector<glm::quat> out(frames);
    for (std::size_t k = 0; k < frames; ++k) {
        const double t = static_cast<double>(k) / fps;
        std::array<double, 3> deg{};
        for (std::size_t a = 0; a < 3; ++a)
            for (std::size_t i = 0; i < 3; ++i)
                deg[a] += axes[a].amp[i] * std::sin(2.0 * M_PI * axes[a].freq_hz[i] * t + axes[a].phase[i]);
        out[k] = head_rotation_from_angles(deg[0] * M_PI / 180.0, deg[1] * M_PI / 180.0, deg[2] * M_PI / 180.0);
    }
    return out;
}

// ---- FAPs → channels --------------------------------------------------------

namespace {

// The largest vertex displacement of channel c at `value` (mesh units).
double channel_reach(const Head& head, std::size_t c, double value) {
    bool any = false;
    for (const auto& t : head.transforms) any = any || static_cast<std::size_t>(t.channel_index) == c;
    if (!any) return 0.0;
    Pose pose;
    pose.set_channel(c, value);
    std::vector<glm::vec3> posed;
    pose_positions(head, pose, posed);
    double reach = 0.0;
    for (std::size_t i = 0; i < posed.size(); ++i)
        reach = std::max(reach, static_cast<double>(glm::length(posed[i] - head.mesh.positions[i])));
    return reach;
}

bool fap_has(const synth::FapFrame& f, int fap) { return f.mask[static_cast<std::size_t>(fap - 1)]; }
double fap_value(const synth::FapFrame& f, int fap) { return f.values[static_cast<std::size_t>(fap - 1)]; }

// The mean of the FAPs of a left/right pair that are present (nullopt: none).
std::optional<double> pair_mean(const synth::FapFrame& f, int a, int b) {
    if (fap_has(f, a) && fap_has(f, b)) return 0.5 * (fap_value(f, a) + fap_value(f, b));
    if (fap_has(f, a)) return fap_value(f, a);
    if (fap_has(f, b)) return fap_value(f, b);
    return std::nullopt;
}

// FAPs the player maps (besides the jaw and lip FAPs of synth/fap.h).
const std::vector<int>& played_faps() {
    static const std::vector<int> faps = [] {
        std::vector<int> out = synth::mapped_faps();
        for (int f : {19, 20, 23, 24, 25, 26, 31, 32, 33, 34, 35, 36, 37, 38, 41, 42, 44, 48, 49, 50}) out.push_back(f);
        return out;
    }();
    return faps;
}

constexpr double au_to_rad = 1e-5;

}  // namespace

FapPlayer::FapPlayer(const Head& head) {
    const Fapu f = fapu(head);
    m_irisd = f.irisd, m_ens = f.ens, m_es = f.es, m_mns = f.mns;
    m_units.mouth_nose_separation_mm = f.mns;
    m_units.mouth_width_mm = f.mw;
    m_units.eye_nose_separation_mm = f.ens;
    m_units.eye_separation_mm = f.es;
    m_units.iris_diameter_mm = f.irisd;
    for (std::size_t c : {brow_inner_raise_channel, brow_outer_raise_channel, cheek_raise_channel, tongue_tip_channel}) {
        m_reach_positive[c] = channel_reach(head, c, 1.0);
        m_reach_negative[c] = channel_reach(head, c, -1.0);
    }
    m_gaze_unit_deg = gaze_unit_deg(head);
    // The FAPs each parameter drives (its column of the mapping).
    for (std::size_t p = 0; p < synth::param_count; ++p) {
        synth::Trajectory unit;
        unit.fps = 25.0;
        unit.frames.assign(1, synth::Frame{});
        unit.frames[0][p] = 1.0;
        const auto s = synth::trajectory_to_fap(unit, m_units);
        for (int f = 1; f <= synth::fap_count; ++f)
            if (s.frames[0].mask[static_cast<std::size_t>(f - 1)] && s.frames[0].values[static_cast<std::size_t>(f - 1)] != 0.0)
                m_param_faps[p].push_back(f);
    }
}

LayerFrame FapPlayer::frame(const synth::FapFrame& fap) const {
    synth::FapStream one;
    one.name = "FAP set";
    one.frames.push_back(fap);
    return play(one)[0];
}

std::vector<LayerFrame> FapPlayer::play(const synth::FapStream& stream, bool with_mouth) const {
    std::vector<LayerFrame> out(stream.frames.size());
    // Jaw and lips: the least-squares inverse over the mapped FAPs present,
    // once for the stream.
    bool mouth = false;
    if (with_mouth)
    for (const auto& f : stream.frames)
        for (int fap : synth::mapped_faps()) mouth = mouth || fap_has(f, fap);
    if (mouth) {
        const auto t = synth::fap_to_trajectory(stream, m_units);
        // Only the parameters a present FAP drives are set: the inverse
        // leaves the others neutral, and a layer that sets only the lip
        // corners must not hold the jaw at rest.
        for (std::size_t k = 0; k < stream.frames.size(); ++k)
            for (std::size_t p = 0; p < synth::param_count; ++p) {
                bool depends = false;
                for (int f : m_param_faps[p]) depends = depends || fap_has(stream.frames[k], f);
                if (depends) out[k].set_channel(p, t.frames[k][p]);
            }
    }
    for (std::size_t k = 0; k < stream.frames.size(); ++k) upper_face(stream.frames[k], out[k]);
    return out;
}

void FapPlayer::upper_face(const synth::FapFrame& fap, LayerFrame& out) const {
    auto by_reach = [&](std::size_t c, double distance) {
        const double reach = distance >= 0 ? m_reach_positive[c] : m_reach_negative[c];
        if (reach > 0.0) out.set_channel(c, (distance >= 0 ? 1.0 : -1.0) * std::abs(distance) / reach);
    };
    if (const auto v = pair_mean(fap, 19, 20)) out.set_channel(blink_channel, *v / 1024.0);
    if (m_gaze_unit_deg > 0.0) {
        if (const auto v = pair_mean(fap, 23, 24))
            out.set_channel(gaze_left_channel, *v * au_to_rad * 180.0 / M_PI / m_gaze_unit_deg);
        // MPEG-4 pitch is positive down; the gaze_up channel positive up.
        if (const auto v = pair_mean(fap, 25, 26))
            out.set_channel(gaze_up_channel, -*v * au_to_rad * 180.0 / M_PI / m_gaze_unit_deg);
    }
    const auto middle = pair_mean(fap, 33, 34);
    auto inner = pair_mean(fap, 31, 32);
    if (!inner) inner = middle;
    auto outer = pair_mean(fap, 35, 36);
    if (!outer) outer = middle;
    const auto squeeze = pair_mean(fap, 37, 38);
    if (inner || squeeze) {
        double d = inner ? *inner * m_ens / 1024.0 : 0.0;
        // A squeeze draws the brows together and down: the inner brows' negative end.
        if (squeeze) d -= std::abs(*squeeze) * m_es / 1024.0;
        by_reach(brow_inner_raise_channel, d);
    }
    if (outer) by_reach(brow_outer_raise_channel, *outer * m_ens / 1024.0);
    if (const auto v = pair_mean(fap, 41, 42)) by_reach(cheek_raise_channel, *v * m_ens / 1024.0);
    if (fap_has(fap, 44)) by_reach(tongue_tip_channel, fap_value(fap, 44) * m_mns / 1024.0);
    if (fap_has(fap, 48) || fap_has(fap, 49) || fap_has(fap, 50))
        out.set_rotation(head_rotation_from_angles(fap_has(fap, 48) ? fap_value(fap, 48) * au_to_rad : 0.0,
                                                   fap_has(fap, 49) ? fap_value(fap, 49) * au_to_rad : 0.0,
                                                   fap_has(fap, 50) ? fap_value(fap, 50) * au_to_rad : 0.0));
}

std::vector<std::string> FapPlayer::unplayable_faps(const synth::FapStream& stream) const {
    std::array<bool, synth::fap_count> present = stream.present_in_file;
    for (const auto& f : stream.frames)
        for (std::size_t i = 0; i < present.size(); ++i) present[i] = present[i] || f.mask[i];
    std::vector<std::string> out;
    const auto& played = played_faps();
    for (int fap = 1; fap <= synth::fap_count; ++fap)
        if (present[static_cast<std::size_t>(fap - 1)] && std::find(played.begin(), played.end(), fap) == played.end())
            out.push_back(fmt::format("{} {}", fap, synth::fap_name(fap)));
    return out;
}

std::vector<std::string> FapPlayer::missing_channels(const synth::FapStream& stream) const {
    std::array<bool, synth::fap_count> present{};
    for (const auto& f : stream.frames)
        for (std::size_t i = 0; i < present.size(); ++i) present[i] = present[i] || f.mask[i];
    auto any = [&](std::initializer_list<int> faps) {
        for (int f : faps)
            if (present[static_cast<std::size_t>(f - 1)]) return true;
        return false;
    };
    std::vector<std::string> out;
    if (any({31, 32, 33, 34, 37, 38}) && m_reach_positive[brow_inner_raise_channel] == 0.0) out.emplace_back("brow_inner_raise");
    if (any({33, 34, 35, 36}) && m_reach_positive[brow_outer_raise_channel] == 0.0) out.emplace_back("brow_outer_raise");
    if (any({41, 42}) && m_reach_positive[cheek_raise_channel] == 0.0) out.emplace_back("cheek_raise");
    if (any({23, 24, 25, 26}) && m_gaze_unit_deg == 0.0) out.emplace_back("gaze_left/gaze_up");
    return out;
}

std::optional<std::size_t> stream_frame_at(const synth::FapStream& stream, std::size_t k, double fps) {
    if (stream.frames.empty()) return std::nullopt;
    // A small tolerance so that equal rates map frame to frame.
    const double index = std::floor(static_cast<double>(k) / fps * stream.fps + 1e-9);
    if (index >= static_cast<double>(stream.frames.size())) return std::nullopt;
    return static_cast<std::size_t>(index);
}

// ---- Named expressions --------------------------------------------------------

std::filesystem::path default_expressions_file() { return std::filesystem::path(AVSI_PROTOCOLS_DIR) / "expressions.json"; }

namespace {

struct ExpressionFile {
    std::map<std::string, synth::FapFrame> expressions;
};

ExpressionFile read_expressions(const std::filesystem::path& file) {
    const std::string text = read_text_file(file);
    json doc;
    try {
        doc = json::parse(text);
    } catch (const json::parse_error& e) {
        throw InputError(file.string(), 0, 0, "", fmt::format("expected JSON: {}", e.what()));
    }
    DiagnosticList problems;
    auto problem = [&](const std::string& field, const std::string& message) {
        problems.add(file.string(), 0, 0, field, message);
    };
    if (!doc.is_object() || json_string(doc, "format") != "avsi-expressions") {
        problem("format", "expected \"avsi-expressions\"");
        problems.throw_if_any();
    }
    std::map<std::string, int> by_name;
    for (int f = 3; f <= synth::fap_count; ++f) by_name[std::string(synth::fap_name(f))] = f;
    std::vector<std::string> names;
    for (const auto& [n, f] : by_name) names.push_back(n);
    ExpressionFile out;
    const json& e = doc.value("expressions", json::object());
    if (!e.is_object() || e.empty()) problem("expressions", "expected an object of named FAP sets");
    for (const auto& [name, faps] : e.items()) {
        const std::string field = "expressions." + name;
        if (!faps.is_object()) {
            problem(field, "expected an object of FAP name → value (FAPU)");
            continue;
        }
        synth::FapFrame frame;
        for (const auto& [fap, value] : faps.items()) {
            const auto it = by_name.find(fap);
            if (it == by_name.end()) {
                const auto hint = closest_match(fap, names);
                problem(field + "." + fap, "expected an MPEG-4 FAP name (FAPs 3–68)" +
                                               (hint.empty() ? std::string() : " (did you mean '" + hint + "'?)"));
                continue;
            }
            if (!value.is_number() || std::abs(value.get<double>()) > 2000.0) {
                problem(field + "." + fap, "expected a number of FAPU in [-2000, 2000], got " + value.dump());
                continue;
            }
            frame.mask[static_cast<std::size_t>(it->second - 1)] = true;
            frame.values[static_cast<std::size_t>(it->second - 1)] = value.get<double>();
        }
        out.expressions[name] = frame;
    }
    problems.throw_if_any();
    return out;
}

}  // namespace

synth::FapFrame named_expression(const std::filesystem::path& file, const std::string& name) {
    const auto e = read_expressions(file);
    const auto it = e.expressions.find(name);
    if (it == e.expressions.end()) {
        std::vector<std::string> names;
        for (const auto& [n, f] : e.expressions) names.push_back(n);
        throw InputError(file.string(), 0, 0, "expressions",
                         fmt::format("expected one of {}, got \"{}\"", fmt::join(names, ", "), name));
    }
    return it->second;
}

std::vector<std::string> expression_names(const std::filesystem::path& file) {
    std::vector<std::string> names;
    for (const auto& [n, f] : read_expressions(file).expressions) names.push_back(n);
    return names;
}

// ---- Settings ---------------------------------------------------------------

std::string_view to_string(LayerKind kind) {
    switch (kind) {
        case LayerKind::Blink: return "blink";
        case LayerKind::Gaze: return "gaze";
        case LayerKind::HeadMotion: return "head_motion";
        case LayerKind::Expression: return "expression";
        case LayerKind::Fap: return "fap";
    }
    return "";
}

LayerSettings LayerSettings::speech_only() {
    LayerSettings s;
    LayerSpec blink;
    blink.kind = LayerKind::Blink;
    s.layers.push_back(blink);
    return s;
}

namespace {

// weight = w and groups = { eyebrows = w, … } of a layer's table.
void read_weights(const ConfigSection& t, std::optional<double>& weight,
                  std::array<std::optional<double>, feature_group_count>& groups, DiagnosticList& problems,
                  bool owns_mouth, bool is_speech) {
    if (t.has("weight")) weight = t.get_number("weight", 1.0, 0.0, 1.0, problems);
    if (const ConfigSection* g = t.get_table("groups", problems)) {
        std::vector<std::string> names(k_group_names.begin(), k_group_names.end());
        for (const auto& key : g->keys()) {
            const auto group = feature_group_from_name(key);
            if (!group) {
                const auto hint = closest_match(key, names);
                g->report(key, fmt::format("expected a feature-point group ({}), got \"{}\"{}", fmt::join(names, ", "), key,
                                           hint.empty() ? "" : " (did you mean '" + hint + "'?)"),
                          problems);
                continue;
            }
            const double w = g->get_number(key, 1.0, 0.0, 1.0, problems);
            if (owns_mouth && !is_speech && is_mouth_group(*group))
                g->report(key,
                          fmt::format("the speech layer owns the mouth groups (jaw, outer_lips, tongue): set "
                                      "speech_owns_mouth = false to blend another layer into \"{}\"",
                                      key),
                          problems);
            groups[group_slot(*group)] = w;
        }
    }
}

void check_layer_file(const ConfigSection& s, std::string_view key, const std::filesystem::path& file, DiagnosticList& problems) {
    if (!std::filesystem::is_regular_file(file))
        s.report(key, fmt::format("expected a readable file, got \"{}\" (not found)", file.string()), problems);
}

}  // namespace

namespace {

// [condition.layers.blink] as a table: the blink timing.
bool read_blink_table(LayerSpec& s, const ConfigSection& t, DiagnosticList& problems) {
    s.blink.mean_interval_s = t.get_number("mean_interval_s", s.blink.mean_interval_s, 0.5, 60.0, problems);
    s.blink.min_interval_s = t.get_number("min_interval_s", s.blink.min_interval_s, 0.3, 60.0, problems);
    s.blink.closing_s = t.get_number("closing_s", s.blink.closing_s, 0.02, 0.5, problems);
    s.blink.opening_s = t.get_number("opening_s", s.blink.opening_s, 0.02, 1.0, problems);
    if (s.blink.min_interval_s > s.blink.mean_interval_s)
        t.report("min_interval_s", "expected min_interval_s <= mean_interval_s", problems);
    return true;
}

// [condition.layers.gaze] as a table: fixations and saccades.
bool read_gaze_table(LayerSpec& s, const ConfigSection& t, DiagnosticList& problems) {
    auto& g = s.gaze;
    g.mean_fixation_s = t.get_number("mean_fixation_s", g.mean_fixation_s, 0.1, 30.0, problems);
    g.min_fixation_s = t.get_number("min_fixation_s", g.min_fixation_s, 0.05, 30.0, problems);
    g.mean_amplitude_deg = t.get_number("mean_amplitude_deg", g.mean_amplitude_deg, 0.1, 15.0, problems);
    g.max_amplitude_deg = t.get_number("max_amplitude_deg", g.max_amplitude_deg, 0.5, 20.0, problems);
    g.return_probability = t.get_number("return_probability", g.return_probability, 0.0, 1.0, problems);
    if (g.min_fixation_s > g.mean_fixation_s)
        t.report("min_fixation_s", "expected min_fixation_s <= mean_fixation_s", problems);
    return true;
}

// A head motion's source named by a string: "idle" only (a file comes in a table).
bool head_motion_source(LayerSpec& s, const std::string& source, const ConfigSection& at, std::string_view key,
                        DiagnosticList& problems) {
    if (source == "idle") {
        s.source = "idle";
        return true;
    }
    at.report(key, fmt::format("expected \"idle\" (or a table with fap = or quaternions = a file), got \"{}\"", source),
              problems);
    return false;
}

// [condition.layers.head_motion] as a table: a FAP or quaternion file, or
// the idle motion, and the motion's size.
bool read_head_motion_table(LayerSpec& s, const ConfigSection& t, const std::filesystem::path& base_dir,
                            DiagnosticList& problems) {
    const std::string fap = t.get_string("fap", "", problems);
    const std::string quats = t.get_string("quaternions", "", problems);
    const std::string source = t.get_string("source", "", problems);
    if (!fap.empty() && !quats.empty()) {
        t.report("quaternions", "expected one of fap and quaternions, got both", problems);
        return false;
    }
    if (!fap.empty() || !quats.empty()) {
        s.source = fap.empty() ? "quaternions" : "fap";
        s.file = base_dir / (fap.empty() ? quats : fap);
        check_layer_file(t, fap.empty() ? "quaternions" : "fap", s.file, problems);
    } else if (!head_motion_source(s, source.empty() ? "idle" : source, t, "source", problems)) {
        return false;
    }
    s.head.pitch_rms_deg = t.get_number("pitch_rms_deg", s.head.pitch_rms_deg, 0.0, 10.0, problems);
    s.head.yaw_rms_deg = t.get_number("yaw_rms_deg", s.head.yaw_rms_deg, 0.0, 10.0, problems);
    s.head.roll_rms_deg = t.get_number("roll_rms_deg", s.head.roll_rms_deg, 0.0, 10.0, problems);
    return true;
}

}  // namespace

LayerSettings parse_layer_settings(const ConfigSection& section, const std::filesystem::path& base_dir,
                                   DiagnosticList& problems) {
    if (!section.present()) return LayerSettings::speech_only();
    LayerSettings out;
    out.configured = true;
    out.speech_owns_mouth = section.get_bool("speech_owns_mouth", true, problems);
    const std::string expressions = section.get_string("expressions_file", "", problems);
    if (!expressions.empty()) {
        out.expressions_file = base_dir / expressions;
        check_layer_file(section, "expressions_file", out.expressions_file, problems);
    }
    if (const ConfigSection* sp = section.get_table("speech", problems)) {
        read_weights(*sp, out.speech_weight, out.speech_group_weights, problems, out.speech_owns_mouth, true);
        if (out.speech_owns_mouth && (sp->has("weight") || sp->has("groups")))
            sp->report(sp->has("weight") ? "weight" : "groups",
                       "the speech layer's weights act only when it shares the mouth: set speech_owns_mouth = false",
                       problems);
        sp->check_unknown_keys(problems);
    }
    // A layer's value: true/false, a string (its source), or a table.
    auto layer = [&](std::string_view key, LayerKind kind, auto&& read_table, auto&& read_string) {
        const ConfigValue* v = section.find(key);
        if (!v) return;
        LayerSpec spec;
        spec.kind = kind;
        if (v->type == ConfigValue::Type::Boolean) {
            if (!v->boolean) return;
        } else if (v->type == ConfigValue::Type::String) {
            if (!read_string(spec, v->string)) return;
        } else if (v->type == ConfigValue::Type::Table) {
            const ConfigSection& t = *v->table;
            read_weights(t, spec.weight, spec.group_weights, problems, out.speech_owns_mouth, false);
            if (!read_table(spec, t)) return;
            t.check_unknown_keys(problems);
        } else {
            section.report(key, fmt::format("expected true, false, a string or a table, got {}", v->describe()), problems);
            return;
        }
        out.layers.push_back(std::move(spec));
    };
    // Blinks are on unless blink = false.
    if (!section.has("blink")) out.layers.push_back(LayerSettings::speech_only().layers[0]);
    layer("blink", LayerKind::Blink,
          [&](LayerSpec& s, const ConfigSection& t) { return read_blink_table(s, t, problems); },
          [&](LayerSpec&, const std::string& text) {
              section.report("blink", fmt::format("expected true, false or a table, got \"{}\"", text), problems);
              return false;
          });
    layer("gaze", LayerKind::Gaze,
          [&](LayerSpec& s, const ConfigSection& t) { return read_gaze_table(s, t, problems); },
          [&](LayerSpec&, const std::string& text) {
              section.report("gaze", fmt::format("expected true, false or a table, got \"{}\"", text), problems);
              return false;
          });
    layer("head_motion", LayerKind::HeadMotion,
          [&](LayerSpec& s, const ConfigSection& t) { return read_head_motion_table(s, t, base_dir, problems); },
          [&](LayerSpec& s, const std::string& text) {
              return head_motion_source(s, text, section, "head_motion", problems);
          });
    auto expression_name = [&](LayerSpec& s, const std::string& name, const ConfigSection& at, std::string_view key) {
        std::vector<std::string> names;
        try {
            names = expression_names(out.expressions_file);
        } catch (const InputError& e) {
            for (const auto& d : e.diagnostics()) problems.add(d);
            return false;
        }
        if (std::find(names.begin(), names.end(), name) == names.end()) {
            const auto hint = closest_match(name, names);
            at.report(key,
                      fmt::format("expected an expression of {} ({}), got \"{}\"{}", out.expressions_file.filename().string(),
                                  fmt::join(names, ", "), name, hint.empty() ? "" : " (did you mean '" + hint + "'?)"),
                      problems);
            return false;
        }
        s.source = name;
        return true;
    };
    layer("expression", LayerKind::Expression,
          [&](LayerSpec& s, const ConfigSection& t) {
              const std::string name = t.get_string("name", "", problems);
              const std::string fap = t.get_string("fap", "", problems);
              if (name.empty() == fap.empty()) {
                  t.report(name.empty() ? "name" : "fap", "expected one of name = \"<expression>\" and fap = \"<file>\"",
                           problems);
                  return false;
              }
              if (!fap.empty()) {
                  s.file = base_dir / fap;
                  check_layer_file(t, "fap", s.file, problems);
                  return true;
              }
              return expression_name(s, name, t, "name");
          },
          [&](LayerSpec& s, const std::string& text) { return expression_name(s, text, section, "expression"); });
    layer("fap", LayerKind::Fap,
          [&](LayerSpec& s, const ConfigSection& t) {
              if (!t.require("file", problems)) return false;
              s.file = base_dir / t.get_string("file", "", problems);
              check_layer_file(t, "file", s.file, problems);
              return true;
          },
          [&](LayerSpec& s, const std::string& text) {
              s.file = base_dir / text;
              check_layer_file(section, "fap", s.file, problems);
              return true;
          });
    section.check_unknown_keys(problems);
    return out;
}

LayerSettings read_layer_settings(const std::filesystem::path& path) {
    const ConfigSection root = read_config(path);
    DiagnosticList problems;
    const ConfigSection* layers = root.get_table("layers", problems);
    if (!layers && problems.empty()) problems.add(path.string(), 0, 0, "layers", "missing required table [layers]");
    root.check_unknown_keys(problems);
    problems.throw_if_any();
    LayerSettings out = parse_layer_settings(*layers, path.parent_path(), problems);
    problems.throw_if_any();
    return out;
}

std::string layer_settings_json(const LayerSettings& settings) {
    json out = {{"speech_owns_mouth", settings.speech_owns_mouth}};
    json stack = json::array();
    for (const auto& spec : settings.layers) {
        json w = json::object();
        if (spec.weight) w["layer"] = *spec.weight;
        for (std::size_t g = 0; g < feature_group_count; ++g)
            if (spec.group_weights[g]) w[std::string(k_group_names[g])] = *spec.group_weights[g];
        json l = {{"kind", to_string(spec.kind)}, {"weights", w}, {"source", spec.source}};
        if (!spec.file.empty()) l["sha256"] = sha256_file(spec.file);
        if (spec.kind == LayerKind::Expression && spec.file.empty()) l["expressions_sha256"] = sha256_file(settings.expressions_file);
        if (spec.kind == LayerKind::Blink)
            l["blink"] = {spec.blink.mean_interval_s, spec.blink.min_interval_s, spec.blink.closing_s, spec.blink.opening_s};
        if (spec.kind == LayerKind::Gaze)
            l["gaze"] = {spec.gaze.mean_fixation_s, spec.gaze.min_fixation_s, spec.gaze.mean_amplitude_deg,
                         spec.gaze.max_amplitude_deg, spec.gaze.return_probability, spec.gaze.vertical_scale};
        if (spec.kind == LayerKind::HeadMotion)
            l["head"] = {spec.head.pitch_rms_deg, spec.head.yaw_rms_deg, spec.head.roll_rms_deg};
        stack.push_back(std::move(l));
    }
    out["layers"] = std::move(stack);
    return out.dump();
}

// ---- animate ----------------------------------------------------------------

namespace {

// A quaternion stream: CSV time_s,w,x,y,z (header line), times ascending.
std::vector<std::pair<double, glm::quat>> read_quaternions(const std::filesystem::path& path) {
    std::ifstream in(path);
    if (!in) throw InputError(path, "cannot read the quaternion stream");
    std::vector<std::pair<double, glm::quat>> out;
    std::string line;
    int n = 0;
    while (std::getline(in, line)) {
        ++n;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (line.empty() || line[0] == '#') continue;
        if (n == 1 || line.rfind("time_s", 0) == 0) {
            if (line.rfind("time_s,w,x,y,z", 0) != 0)
                throw InputError(path.string(), n, 1, "header", fmt::format("expected \"time_s,w,x,y,z\", got \"{}\"", line));
            continue;
        }
        std::array<double, 5> v{};
        std::stringstream ss(line);
        std::string cell;
        int col = 0;
        for (; col < 5 && std::getline(ss, cell, ','); ++col) {
            char* end = nullptr;
            v[static_cast<std::size_t>(col)] = std::strtod(cell.c_str(), &end);
            while (end && (*end == ' ' || *end == '\t')) ++end;
            if (end == cell.c_str() || *end != '\0' || !std::isfinite(v[static_cast<std::size_t>(col)]))
                throw InputError(path.string(), n, col + 1, std::string(std::array<const char*, 5>{"time_s", "w", "x", "y", "z"}[static_cast<std::size_t>(col)]),
                                 fmt::format("expected a number, got \"{}\"", cell));
        }
        if (col != 5) throw InputError(path.string(), n, 1, "row", fmt::format("expected 5 values, got {}", col));
        const glm::quat q(static_cast<float>(v[1]), static_cast<float>(v[2]), static_cast<float>(v[3]), static_cast<float>(v[4]));
        const double len = glm::length(q);
        if (std::abs(len - 1.0) > 1e-3)
            throw InputError(path.string(), n, 2, "w", fmt::format("expected a unit quaternion, got length {:.6f}", len));
        if (!out.empty() && v[0] <= out.back().first)
            throw InputError(path.string(), n, 1, "time_s", fmt::format("expected times ascending, got {} after {}", v[0], out.back().first));
        out.push_back({v[0], glm::normalize(q)});
    }
    if (out.empty()) throw InputError(path.string(), n, 0, "", "expected at least one quaternion row");
    return out;
}

json weights_json(const std::optional<double>& weight, const std::array<std::optional<double>, feature_group_count>& groups) {
    json w = json::object();
    w["layer"] = weight ? json(*weight) : json("default");
    for (std::size_t g = 0; g < feature_group_count; ++g)
        if (groups[g]) w[std::string(k_group_names[g])] = *groups[g];
    return w;
}

// Sets each frame's head rotation from timed quaternions (slerp between
// rows); frames before the first row or more than a frame after the last
// stay unset.
void set_rotations_from_quaternions(const std::vector<std::pair<double, glm::quat>>& q, double fps, Layer& l) {
    std::size_t j = 0;
    for (std::size_t k = 0; k < l.frames.size(); ++k) {
        const double t = static_cast<double>(k) / fps;
        while (j + 1 < q.size() && q[j + 1].first <= t) ++j;
        if (t < q.front().first || (j + 1 == q.size() && t > q.back().first + 1.0 / fps)) continue;
        glm::quat v = q[j].second;
        if (j + 1 < q.size())
            v = glm::slerp(q[j].second, q[j + 1].second,
                           static_cast<float>((t - q[j].first) / (q[j + 1].first - q[j].first)));
        l.frames[k].set_rotation(v);
    }
}

// The blink layer of a spec with its seed, and its settings in the record.
Layer recorded_blink_layer(const LayerSpec& spec, const LayerSeeds& seeds, std::size_t frames, double fps, json& r) {
    BlinkSettings b = spec.blink;
    b.seed = seeds.blink;
    Layer l = blink_layer(frames, fps, b);
    r["seed"] = b.seed;
    r["mean_interval_s"] = b.mean_interval_s;
    r["min_interval_s"] = b.min_interval_s;
    r["closing_s"] = b.closing_s;
    r["opening_s"] = b.opening_s;
    return l;
}

// The gaze layer of a spec with its seed on the head's gaze transforms (a
// warning when it has none), and its settings in the record.
Layer recorded_gaze_layer(const Head& head, const LayerSpec& spec, const LayerSeeds& seeds, std::size_t frames,
                          double fps, json& r, std::vector<std::string>& warnings) {
    GazeSettings g = spec.gaze;
    g.seed = seeds.gaze;
    const double unit = gaze_unit_deg(head);
    if (unit <= 0.0) warnings.push_back("gaze: the head's rig has no gaze transforms: the eyes stay still");
    Layer l = gaze_layer(frames, fps, g, unit);
    r["seed"] = g.seed;
    r["mean_fixation_s"] = g.mean_fixation_s;
    r["min_fixation_s"] = g.min_fixation_s;
    r["mean_amplitude_deg"] = g.mean_amplitude_deg;
    r["max_amplitude_deg"] = g.max_amplitude_deg;
    r["return_probability"] = g.return_probability;
    return l;
}

// A warning for each expression channel the stack moves that the head's rig cannot show.
void warn_unrigged_expressions(const Head& head, const std::vector<Layer>& stack, std::vector<std::string>& warnings) {
    for (std::size_t c : {brow_inner_raise_channel, brow_outer_raise_channel, cheek_raise_channel}) {
        bool used = false, rigged = false;
        for (const auto& l : stack)
            for (const auto& f : l.frames) used = used || (f.set[c] && f.values[c] != 0.0);
        for (const auto& t : head.transforms) rigged = rigged || static_cast<std::size_t>(t.channel_index) == c;
        if (used && !rigged)
            warnings.push_back(fmt::format("the head's rig ({}) has no {} transforms: that channel moves nothing",
                                           head.rig_path.filename().string(), channel_names()[c]));
    }
}

}  // namespace

Animation animate(const Head& head, const synth::Trajectory& trajectory, const PhoneSequence* phones,
                  const LayerSettings& settings, const LayerSeeds& seeds) {
    const std::size_t frames = trajectory.size();
    const double fps = trajectory.fps;
    Animation out;
    std::vector<Layer> stack;
    json record = json::array();
    Layer speech = speech_layer(trajectory, phones);
    speech.weight = settings.speech_weight;
    speech.group_weights = settings.speech_group_weights;
    stack.push_back(std::move(speech));
    record.push_back({{"kind", "speech"}, {"owns_mouth", settings.speech_owns_mouth},
                      {"weights", weights_json(settings.speech_weight, settings.speech_group_weights)}});
    std::optional<FapPlayer> player;
    auto fap_player = [&]() -> const FapPlayer& {
        if (!player) player.emplace(head);
        return *player;
    };
    auto warn_stream = [&](const std::string& what, const synth::FapStream& stream) {
        const auto& p = fap_player();
        const auto unplayable = p.unplayable_faps(stream);
        if (!unplayable.empty())
            out.warnings.push_back(fmt::format("{}: FAPs with no channel on the head, not played: {}", what,
                                               fmt::join(unplayable, ", ")));
        const auto missing = p.missing_channels(stream);
        if (!missing.empty())
            out.warnings.push_back(fmt::format("{}: the head's rig has no {} transforms: those FAPs move nothing", what,
                                               fmt::join(missing, ", ")));
    };
    // A FAP file played into the layer frame by frame (frames outside the
    // stream stay unset), warned about under `what` and recorded by name and hash.
    auto play_fap_file = [&](const std::string& what, const std::filesystem::path& file, Layer& l, json& r) {
        const auto stream = synth::read_fap(file);
        warn_stream(what + " " + file.filename().string(), stream);
        const auto played = fap_player().play(stream, !settings.speech_owns_mouth);
        for (std::size_t k = 0; k < frames; ++k)
            if (const auto i = stream_frame_at(stream, k, fps)) l.frames[k] = played[*i];
        r["file"] = file.filename().string();
        r["sha256"] = sha256_file(file);
    };
    for (const auto& spec : settings.layers) {
        Layer l;
        json r = {{"kind", to_string(spec.kind)}, {"weights", weights_json(spec.weight, spec.group_weights)}};
        switch (spec.kind) {
            case LayerKind::Blink: l = recorded_blink_layer(spec, seeds, frames, fps, r); break;
            case LayerKind::Gaze: l = recorded_gaze_layer(head, spec, seeds, frames, fps, r, out.warnings); break;
            case LayerKind::HeadMotion: {
                l.name = "head_motion";
                l.frames.resize(frames);
                r["source"] = spec.source;
                if (spec.source == "idle") {
                    HeadMotionSettings h = spec.head;
                    h.seed = seeds.head;
                    const auto q = idle_head_motion(frames, fps, h);
                    for (std::size_t k = 0; k < frames; ++k) l.frames[k].set_rotation(q[k]);
                    r["seed"] = h.seed;
                    r["rms_deg"] = {h.pitch_rms_deg, h.yaw_rms_deg, h.roll_rms_deg};
                } else if (spec.source == "fap") {
                    // Direct mode: a stream layer, the head-rotation FAPs only.
                    l.set = LayerSet::Stream;
                    const auto stream = synth::read_fap(spec.file);
                    const auto played = fap_player().play(stream, false);
                    for (std::size_t k = 0; k < frames; ++k)
                        if (const auto i = stream_frame_at(stream, k, fps))
                            if (played[*i].sets_rotation) l.frames[k].set_rotation(played[*i].rotation);
                    r["file"] = spec.file.filename().string();
                    r["sha256"] = sha256_file(spec.file);
                } else {
                    l.set = LayerSet::Stream;
                    set_rotations_from_quaternions(read_quaternions(spec.file), fps, l);
                    r["file"] = spec.file.filename().string();
                    r["sha256"] = sha256_file(spec.file);
                }
                break;
            }
            case LayerKind::Expression: {
                l.name = "expression";
                l.frames.resize(frames);
                if (spec.file.empty()) {
                    synth::FapStream one;
                    one.name = "expression " + spec.source;
                    one.frames.push_back(named_expression(settings.expressions_file, spec.source));
                    warn_stream("expression " + spec.source, one);
                    const LayerFrame f = fap_player().play(one, !settings.speech_owns_mouth)[0];
                    std::fill(l.frames.begin(), l.frames.end(), f);
                    r["name"] = spec.source;
                    r["file"] = settings.expressions_file.filename().string();
                    r["sha256"] = sha256_file(settings.expressions_file);
                } else {
                    play_fap_file("expression", spec.file, l, r);
                }
                break;
            }
            case LayerKind::Fap: {
                l.name = "fap";
                l.set = LayerSet::Stream;
                l.frames.resize(frames);
                play_fap_file("fap", spec.file, l, r);
                break;
            }
        }
        l.weight = spec.weight;
        l.group_weights = spec.group_weights;
        stack.push_back(std::move(l));
        record.push_back(std::move(r));
    }
    warn_unrigged_expressions(head, stack, out.warnings);
    out.poses.resize(frames);
    for (std::size_t k = 0; k < frames; ++k) out.poses[k] = blend_frame(stack, k, settings.speech_owns_mouth);
    out.record_json = record.dump();
    return out;
}

}  // namespace avsi::stimuli
