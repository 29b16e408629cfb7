// Marker layouts on a head and the head's rig posed at the markers only
// (marker_layout.h).
#include "avsi/stimuli/marker_layout.h"

#include <array>
#include <cmath>
#include <optional>
#include <limits>
#include <map>
#include <memory>
#include <set>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/json.h"

namespace avsi::stimuli {

std::filesystem::path default_marker_layout() {
    return std::filesystem::path(AVSI_PROTOCOLS_DIR) / "head" / "markers.json";
}

namespace {

using nlohmann::json;

struct LayoutReader {
    const Head& head;
    std::string file;
    DiagnosticList problems;

    void problem(const std::string& field, const std::string& message) { problems.add(file, 0, 0, field, message); }

    std::optional<std::array<double, 3>> point(const json& j, const std::string& field) {
        if (!j.is_array() || j.size() != 3 || !j[0].is_number() || !j[1].is_number() || !j[2].is_number()) {
            problem(field, "expected [x, y, z] in mm");
            return std::nullopt;
        }
        std::array<double, 3> p{j[0].get<double>(), j[1].get<double>(), j[2].get<double>()};
        for (double v : p)
            if (!std::isfinite(v) || std::abs(v) > 1e5) {
                problem(field, fmt::format("expected coordinates within 100 m, got {}", v));
                return std::nullopt;
            }
        return p;
    }

    std::optional<std::size_t> vertex(const json& j, const std::string& field) {
        const std::size_t n = head.mesh.positions.size();
        if (!j.is_number_integer() || j.get<long long>() < 0 || j.get<long long>() >= static_cast<long long>(n)) {
            problem(field, fmt::format("expected a vertex index in [0, {}), got {}", n, j.dump()));
            return std::nullopt;
        }
        return j.get<std::size_t>();
    }

    // The first triangle with vertex v, as (v, a, b).
    std::optional<std::array<std::size_t, 3>> triangle_of(std::size_t v, const std::string& field) {
        const auto& idx = head.mesh.indices;
        for (std::size_t t = 0; t + 2 < idx.size(); t += 3)
            for (int k = 0; k < 3; ++k)
                if (idx[t + k] == v) return std::array<std::size_t, 3>{v, idx[t + (k + 1) % 3], idx[t + (k + 2) % 3]};
        problem(field, fmt::format("vertex {} is on no triangle of the mesh", v));
        return std::nullopt;
    }

    std::optional<std::size_t> nearest(const std::array<double, 3>& p, const json& groups, const std::string& field) {
        std::set<int> allowed;
        if (groups.is_array())
            for (const auto& g : groups) {
                const int gi = g.is_string() ? head.mesh.group_index(g.get<std::string>()) : -1;
                if (gi < 0) problem(field + ".groups", fmt::format("no group {} in the head's mesh", g.dump()));
                allowed.insert(gi);
            }
        std::vector<char> in_group(head.mesh.positions.size(), allowed.empty() ? 1 : 0);
        if (!allowed.empty())
            for (std::size_t t = 0; t < head.mesh.triangle_count(); ++t)
                if (allowed.count(head.mesh.triangle_group[t]))
                    for (int k = 0; k < 3; ++k) in_group[head.mesh.indices[3 * t + k]] = 1;
        std::optional<std::size_t> best;
        double best_d = std::numeric_limits<double>::max();
        for (std::size_t v = 0; v < head.mesh.positions.size(); ++v) {
            if (!in_group[v]) continue;
            const auto& q = head.mesh.positions[v];
            const double d = std::pow(q.x - p[0], 2) + std::pow(q.y - p[1], 2) + std::pow(q.z - p[2], 2);
            if (d < best_d) best_d = d, best = v;
        }
        if (!best) problem(field, "no vertex in the groups given");
        return best;
    }

    // A face marker's triangle and weights from "vertex", "triangle" or "near".
    bool place(const json& m, const std::string& field, synth::ModelMarker& out) {
        std::optional<std::size_t> v;
        if (m.contains("triangle")) {
            const json& t = m["triangle"];
            if (!t.is_array() || t.size() != 3) {
                problem(field + ".triangle", "expected three vertex indices");
                return false;
            }
            for (int k = 0; k < 3; ++k) {
                const auto vk = vertex(t[k], fmt::format("{}.triangle[{}]", field, k));
                if (!vk) return false;
                out.points[k] = *vk;
            }
            out.weights = {1.0 / 3, 1.0 / 3, 1.0 / 3};
            if (m.contains("weights")) {
                const auto w = point(m["weights"], field + ".weights");
                if (!w) return false;
                if (std::abs((*w)[0] + (*w)[1] + (*w)[2] - 1.0) > 1e-6) {
                    problem(field + ".weights", "expected three weights summing to 1");
                    return false;
                }
                out.weights = *w;
            }
            return true;
        }
        if (m.contains("vertex")) v = vertex(m["vertex"], field + ".vertex");
        else if (m.contains("near")) {
            const auto p = point(m["near"], field + ".near");
            if (p) v = nearest(*p, m.contains("groups") ? m["groups"] : json(), field);
        } else {
            problem(field, "a face marker needs \"vertex\", \"triangle\" or \"near\" (or \"reference\": true and \"point\")");
        }
        if (!v) return false;
        const auto tri = triangle_of(*v, field);
        if (!tri) return false;
        out.points = *tri;
        out.weights = {1, 0, 0};
        return true;
    }

    std::vector<synth::ModelMarker> read(const json& doc) {
        if (!doc.is_object() || json_string(doc, "format") != "avsi-marker-layout")
            throw InputError(file, 0, 0, "format", "expected \"avsi-marker-layout\"");
        if (!doc.contains("markers") || !doc["markers"].is_array() || doc["markers"].empty())
            throw InputError(file, 0, 0, "markers", "expected a non-empty array of markers");
        std::vector<synth::ModelMarker> out;
        std::set<std::string> names;
        for (std::size_t i = 0; i < doc["markers"].size(); ++i) {
            const json& m = doc["markers"][i];
            const std::string field = fmt::format("markers[{}]", i);
            synth::ModelMarker marker;
            marker.name = json_string(m, "name");
            if (marker.name.empty()) problem(field + ".name", "expected the marker's label in the recording");
            else if (!names.insert(marker.name).second) problem(field + ".name", fmt::format("\"{}\" appears twice", marker.name));
            marker.reference = m.is_object() && m.value("reference", false);
            marker.orientation = m.is_object() && m.value("orientation", false);
            if (marker.reference) {
                const auto p = m.contains("point") ? point(m["point"], field + ".point") : std::nullopt;
                if (!m.contains("point")) problem(field + ".point", "a reference marker needs its point in the head frame");
                if (p) marker.frame_point = *p;
            } else if (!place(m, field, marker)) {
                continue;
            }
            out.push_back(marker);
        }
        problems.throw_if_any();
        return out;
    }
};

// A head holding only the marker triangles' vertices, with the rig's
// transforms restricted to them (vertex indices renumbered).
std::shared_ptr<const Head> marker_head(const Head& head, std::vector<synth::ModelMarker>& markers) {
    std::map<std::size_t, std::size_t> slot;
    auto mini = std::make_shared<Head>();
    for (auto& m : markers) {
        if (m.reference) continue;
        for (auto& p : m.points) {
            auto [it, added] = slot.try_emplace(p, mini->mesh.positions.size());
            if (added) mini->mesh.positions.push_back(head.mesh.positions[p]);
            p = it->second;
        }
    }
    for (const auto& t : head.transforms) {
        RigTransform r = t;
        r.vertices.clear();
        r.weights.clear();
        r.offsets.clear();
        for (std::size_t k = 0; k < t.vertices.size(); ++k) {
            const auto it = slot.find(t.vertices[k]);
            if (it == slot.end()) continue;
            r.vertices.push_back(static_cast<std::uint32_t>(it->second));
            r.weights.push_back(t.weights[k]);
            if (!t.offsets.empty()) r.offsets.push_back(t.offsets[k]);
        }
        if (!r.vertices.empty()) mini->transforms.push_back(std::move(r));
    }
    return mini;
}

// The rig's arithmetic (pose_positions, head.cpp) with each parameter's
// sides given apart; the channels beyond the 10 parameters stay at rest.
void pose_sides(const Head& mini, const synth::Frame& positive, const synth::Frame& negative, std::vector<double>& xyz) {
    thread_local std::vector<glm::vec3> posed;
    thread_local std::vector<std::uint32_t> identity;
    posed = mini.mesh.positions;
    for (const auto& t : mini.transforms) {
        if (t.channel_index < 0 || std::size_t(t.channel_index) >= synth::param_count) continue;
        const std::size_t c = std::size_t(t.channel_index);
        const double amount = t.side == ChannelSide::Positive   ? positive[c]
                              : t.side == ChannelSide::Negative ? negative[c]
                                                                : positive[c] + negative[c];
        if (amount == 0.0) continue;
        while (identity.size() < t.vertices.size()) identity.push_back(static_cast<std::uint32_t>(identity.size()));
        apply_transform(t, static_cast<float>(amount), std::span(identity.data(), t.vertices.size()), t.vertices, posed);
    }
    xyz.resize(posed.size() * 3);
    for (std::size_t i = 0; i < posed.size(); ++i)
        for (int k = 0; k < 3; ++k) xyz[3 * i + k] = posed[i][k];
}

}  // namespace

synth::MarkerModel load_marker_model(const Head& head, const std::filesystem::path& layout_path) {
    LayoutReader reader{head, layout_path.string(), {}};
    const json doc = read_json_file(layout_path);
    synth::MarkerModel model;
    model.source = layout_path.string();
    model.markers = with_json_context(layout_path, [&] { return reader.read(doc); });
    const auto mini = marker_head(head, model.markers);
    model.point_count = mini->mesh.positions.size();
    model.pose = [mini](const synth::Frame& params, std::vector<double>& xyz) {
        thread_local std::vector<glm::vec3> posed;
        Pose pose;
        pose.params = params;
        pose_positions(*mini, pose, posed);
        xyz.resize(posed.size() * 3);
        for (std::size_t i = 0; i < posed.size(); ++i)
            for (int k = 0; k < 3; ++k) xyz[3 * i + k] = posed[i][k];
    };
    model.pose_sides = [mini](const synth::Frame& positive, const synth::Frame& negative, std::vector<double>& xyz) {
        pose_sides(*mini, positive, negative, xyz);
    };
    for (const auto& t : mini->transforms)
        if (t.channel_index >= 0 && std::size_t(t.channel_index) < synth::param_count && t.side != ChannelSide::Both)
            model.two_sided[std::size_t(t.channel_index)] = true;
    return model;
}

}  // namespace avsi::stimuli
