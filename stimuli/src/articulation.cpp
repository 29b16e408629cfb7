// Articulation measures of the posed head and the phonetic constraints of a
// stimulus (see articulation.h).
#include "avsi/stimuli/articulation.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include <fmt/format.h>
#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>

#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/text.h"

namespace avsi::stimuli {

namespace {

// Distance from p to the segment a–b.
float segment_distance(glm::vec3 p, glm::vec3 a, glm::vec3 b) {
    const glm::vec3 ab = b - a;
    const float len2 = glm::dot(ab, ab);
    const float t = len2 > 0.0f ? std::clamp(glm::dot(p - a, ab) / len2, 0.0f, 1.0f) : 0.0f;
    return glm::length(p - (a + t * ab));
}

glm::vec3 midpoint_of(const std::vector<glm::vec3>& points, const std::vector<std::uint32_t>& slots) {
    glm::vec3 sum{0.0f};
    for (auto s : slots) sum += points[s];
    return sum / float(slots.size());
}


}  // namespace


ArticulationMeter::ArticulationMeter(const Head& head) : m_head(head) {
    if (!head.articulation) {
        std::string names;
        for (const auto& n : articulation_landmark_names()) names += (names.empty() ? "" : ", ") + n;
        throw InputError(head.rig_path.string(), 0, 0, "articulation",
                         "the rig names no articulation landmarks, so the lips and teeth cannot be measured; "
                         "add an \"articulation\" section with: " + names +
                             " (vertex indices; see stimuli/include/avsi/stimuli/head.h)");
    }
    const ArticulationLandmarks& L = *head.articulation;
    m_up = L.up;
    m_forward = L.forward;
    // One slot per landmark occurrence; the same vertex may serve twice.
    auto add = [&](std::uint32_t v) {
        m_vertices.push_back(v);
        return static_cast<std::uint32_t>(m_vertices.size() - 1);
    };
    for (auto v : L.upper_lip_contour) m_upper.push_back(add(v));
    for (auto v : L.lower_lip_contour) m_lower.push_back(add(v));
    for (auto v : L.upper_incisor_edge) m_upper_edge.push_back(add(v));
    for (auto v : L.lower_incisor_edge) m_lower_edge.push_back(add(v));
    for (auto v : L.lower_lip_surface) m_lip_surface.push_back(add(v));
    m_corner_left = add(L.mouth_corner_left);
    m_corner_right = add(L.mouth_corner_right);
    m_upper_front = add(L.upper_lip_point);
    m_lower_front = add(L.lower_lip_point);

    m_rest.reserve(m_vertices.size());
    for (auto v : m_vertices) m_rest.push_back(head.mesh.positions[v]);

    // Which landmark slots each transform moves, with what weight.
    std::map<std::uint32_t, std::vector<std::uint32_t>> slots_of;
    for (std::uint32_t s = 0; s < m_vertices.size(); ++s) slots_of[m_vertices[s]].push_back(s);
    for (const auto& t : head.transforms) {
        Sparse sparse;
        for (std::size_t k = 0; k < t.vertices.size(); ++k) {
            const auto it = slots_of.find(t.vertices[k]);
            if (it == slots_of.end()) continue;
            for (auto s : it->second) {
                sparse.slots.push_back(s);
                sparse.entries.push_back(static_cast<std::uint32_t>(k));
            }
        }
        m_transforms.push_back(std::move(sparse));
    }

    // The midline pair and the central third, by each pair's lateral position at rest.
    const glm::vec3 lateral = glm::normalize(glm::cross(m_up, m_forward));
    const float left = glm::dot(m_rest[m_corner_left], lateral), right = glm::dot(m_rest[m_corner_right], lateral);
    const float centre = 0.5f * (left + right), third = std::abs(left - right) / 6.0f;
    float best = std::numeric_limits<float>::max();
    for (std::size_t i = 0; i < m_upper.size(); ++i) {
        const float x = 0.5f * (glm::dot(m_rest[m_upper[i]], lateral) + glm::dot(m_rest[m_lower[i]], lateral));
        if (std::abs(x - centre) < best) {
            best = std::abs(x - centre);
            m_mid_pair = i;
        }
        if (std::abs(x - centre) <= third) m_central_pairs.push_back(i);
    }
    if (m_central_pairs.empty()) m_central_pairs.push_back(m_mid_pair);

    // The landmark slots the lip contact reads and moves.
    if (head.lip_contact) {
        const auto& c = head.lip_contact->mesh;
        m_contact.upper = m_upper;
        m_contact.lower = m_lower;
        for (std::size_t k = 0; k < c.moved.size(); ++k) {
            const auto it = slots_of.find(c.moved[k]);
            if (it == slots_of.end()) continue;
            for (auto s : it->second) {
                m_contact.moved.push_back(s);
                m_contact.sign_weight.push_back(c.sign_weight[k]);
                m_contact.lateral.push_back(c.lateral[k]);
                m_contact.pair.push_back(c.pair[k]);
            }
        }
    }

    m_rest_upper_front = glm::dot(m_rest[m_upper_front], m_forward);
    m_rest_lower_front = glm::dot(m_rest[m_lower_front], m_forward);
    m_rest_incisor_gap =
        glm::dot(midpoint_of(m_rest, m_upper_edge) - midpoint_of(m_rest, m_lower_edge), m_up);
}

// The same arithmetic as pose_head (head.cpp), on the landmark slots only.
void ArticulationMeter::pose_landmarks(const Pose& pose, std::vector<glm::vec3>& out) const {
    out = m_rest;
    for (std::size_t ti = 0; ti < m_transforms.size(); ++ti) {
        const RigTransform& t = m_head.transforms[ti];
        const Sparse& s = m_transforms[ti];
        if (s.slots.empty()) continue;
        const double amount = channel_amount(t, pose);
        if (amount == 0.0) continue;
        apply_transform(t, static_cast<float>(amount), s.entries, s.slots, out);
    }
    if (m_head.lip_contact) apply_lip_contact(*m_head.lip_contact, m_contact, out);
}

ArticulationMeasures ArticulationMeter::measure(const Pose& pose) const {
    std::vector<glm::vec3> p;
    pose_landmarks(pose, p);
    ArticulationMeasures m;
    auto aperture = [&](std::size_t i) { return double(glm::dot(p[m_upper[i]] - p[m_lower[i]], m_up)); };
    m.aperture_mid_mm = aperture(m_mid_pair);
    m.aperture_min_mm = std::numeric_limits<double>::max();
    m.aperture_max_mm = std::numeric_limits<double>::lowest();
    for (auto i : m_central_pairs) {
        m.aperture_min_mm = std::min(m.aperture_min_mm, aperture(i));
        m.aperture_max_mm = std::max(m.aperture_max_mm, aperture(i));
    }
    m.aperture_all_min_mm = std::numeric_limits<double>::max();
    for (std::size_t i = 0; i < m_upper.size(); ++i) m.aperture_all_min_mm = std::min(m.aperture_all_min_mm, aperture(i));
    m.mouth_width_mm = glm::length(p[m_corner_left] - p[m_corner_right]);
    m.upper_protrusion_mm = glm::dot(p[m_upper_front], m_forward) - m_rest_upper_front;
    m.lower_protrusion_mm = glm::dot(p[m_lower_front], m_forward) - m_rest_lower_front;
    m.jaw_opening_mm =
        glm::dot(midpoint_of(p, m_upper_edge) - midpoint_of(p, m_lower_edge), m_up) - m_rest_incisor_gap;
    float nearest = std::numeric_limits<float>::max();
    for (auto s : m_lip_surface)
        for (std::size_t k = 0; k + 1 < m_upper_edge.size(); ++k)
            nearest = std::min(nearest, segment_distance(p[s], p[m_upper_edge[k]], p[m_upper_edge[k + 1]]));
    m.lip_to_incisors_mm = nearest;
    return m;
}

std::vector<ArticulationMeasures> ArticulationMeter::measure(const synth::Trajectory& trajectory) const {
    std::vector<ArticulationMeasures> out;
    out.reserve(trajectory.size());
    Pose pose;
    for (std::size_t k = 0; k < trajectory.size(); ++k) {
        pose.params = trajectory.frames[k];
        auto m = measure(pose);
        m.time_s = trajectory.time_s(k);
        out.push_back(m);
    }
    return out;
}


std::string aperture_plot_svg(const std::string& title, const PhoneSequence& phones,
                              const std::vector<ArticulationMeasures>& measures, const ArticulationSummary& summary,
                              const ArticulationLimits& limits) {
    const double width = 900, height = 300, left = 56, right = 16, top = 30, bottom = 48;
    const double plot_w = width - left - right, plot_h = height - top - bottom;
    const double t_end = std::max({measures.empty() ? 0.0 : measures.back().time_s,
                                   phones.empty() ? 0.0 : phones.back().end_s, 1e-3});
    double lo = -1.0, hi = 4.0;
    for (const auto& m : measures) {
        lo = std::min(lo, std::floor(m.aperture_all_min_mm));
        hi = std::max(hi, std::ceil(std::max(m.aperture_max_mm, 0.0)));
    }
    auto x_of = [&](double t) { return left + t / t_end * plot_w; };
    auto y_of = [&](double v) { return top + (hi - v) / (hi - lo) * plot_h; };
    std::string svg = fmt::format(
        "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" viewBox=\"0 0 {0} {1}\" "
        "font-family=\"sans-serif\" font-size=\"11\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n",
        width, height);
    svg += fmt::format("<text x=\"{}\" y=\"18\" font-size=\"13\">{}</text>\n", left, xml_escape(title));
    // Shaded /p b m/ (and /f v/) segments, red where the constraint fails.
    for (const auto& c : summary.segments) {
        const bool bilabial = c.kind == SegmentClass::Bilabial;
        const char* fill = !c.ok ? "#f4b6b6" : bilabial ? "#dbe8f6" : "#e6f2dc";
        svg += fmt::format("<rect x=\"{:.1f}\" y=\"{}\" width=\"{:.1f}\" height=\"{}\" fill=\"{}\"/>\n", x_of(c.start_s),
                           top, std::max(1.0, x_of(c.end_s) - x_of(c.start_s)), plot_h, fill);
    }
    // Value grid and labels (mm).
    const double step = hi - lo > 12 ? 4.0 : hi - lo > 6 ? 2.0 : 1.0;
    for (double v = std::ceil(lo / step) * step; v <= hi + 1e-9; v += step) {
        svg += fmt::format("<line x1=\"{}\" y1=\"{:.1f}\" x2=\"{}\" y2=\"{:.1f}\" stroke=\"{}\"/>\n", left, y_of(v),
                           left + plot_w, y_of(v), v == 0.0 ? "#888" : "#e4e4e4");
        svg += fmt::format("<text x=\"{}\" y=\"{:.1f}\" text-anchor=\"end\">{:g}</text>\n", left - 5, y_of(v) + 4,
                           v == 0.0 ? 0.0 : v);
    }
    svg += fmt::format("<line x1=\"{}\" y1=\"{:.1f}\" x2=\"{}\" y2=\"{:.1f}\" stroke=\"#d62728\" stroke-dasharray=\"4 3\"/>\n",
                       left, y_of(limits.closure_mm), left + plot_w, y_of(limits.closure_mm));
    svg += fmt::format("<text transform=\"translate(14,{:.1f}) rotate(-90)\" text-anchor=\"middle\">lip aperture (mm)</text>\n",
                       top + plot_h / 2);
    // Central-third band, midline curve, sampled frames.
    if (!measures.empty()) {
        std::string band, mid;
        for (const auto& m : measures) band += fmt::format("{:.1f},{:.2f} ", x_of(m.time_s), y_of(m.aperture_max_mm));
        for (auto it = measures.rbegin(); it != measures.rend(); ++it)
            band += fmt::format("{:.1f},{:.2f} ", x_of(it->time_s), y_of(it->aperture_min_mm));
        for (const auto& m : measures) mid += fmt::format("{:.1f},{:.2f} ", x_of(m.time_s), y_of(m.aperture_mid_mm));
        svg += fmt::format("<polygon points=\"{}\" fill=\"#1f77b4\" fill-opacity=\"0.25\" stroke=\"none\"/>\n", band);
        svg += fmt::format("<polyline points=\"{}\" fill=\"none\" stroke=\"#1f77b4\" stroke-width=\"1.5\"/>\n", mid);
        for (const auto& m : measures)
            svg += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.2f}\" r=\"1.6\" fill=\"#1f77b4\"/>\n", x_of(m.time_s),
                               y_of(m.aperture_mid_mm));
    }
    // Lower lip to upper incisors (dashed green) through each /f v/ segment
    // and a frame either side.
    for (const auto& c : summary.segments) {
        if (c.kind != SegmentClass::Labiodental) continue;
        std::string line;
        for (const auto& m : measures)
            if (m.time_s >= c.start_s - 0.05 && m.time_s <= c.end_s + 0.05)
                line += fmt::format("{:.1f},{:.2f} ", x_of(m.time_s), y_of(std::min(m.lip_to_incisors_mm, hi)));
        if (!line.empty())
            svg += fmt::format("<polyline points=\"{}\" fill=\"none\" stroke=\"#2ca02c\" stroke-width=\"1.5\" "
                               "stroke-dasharray=\"3 2\"/>\n",
                               line);
    }
    // The frame each checked segment was judged by.
    for (const auto& c : summary.segments) {
        if (c.best_frame >= measures.size()) continue;
        svg += fmt::format("<circle cx=\"{:.1f}\" cy=\"{:.2f}\" r=\"3.2\" fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\"/>\n",
                           x_of(measures[c.best_frame].time_s), y_of(c.best_mm), c.ok ? "#2ca02c" : "#d62728");
    }
    svg += fmt::format("<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{}\" fill=\"none\" stroke=\"black\"/>\n", left, top,
                       plot_w, plot_h);
    // Phone labels and boundaries.
    for (const auto& ph : phones) {
        svg += fmt::format("<line x1=\"{0:.1f}\" y1=\"{1}\" x2=\"{0:.1f}\" y2=\"{2}\" stroke=\"#999\"/>\n", x_of(ph.start_s),
                           top + plot_h, top + plot_h + 16);
        if (ph.symbol != "sil")
            svg += fmt::format("<text x=\"{:.1f}\" y=\"{}\" text-anchor=\"middle\">{}</text>\n", x_of(ph.centre_s()),
                               top + plot_h + 13, ph.symbol);
    }
    svg += fmt::format("<text x=\"{:.1f}\" y=\"{}\" text-anchor=\"middle\" fill=\"#555\">time (s), 0 – {:.2f}</text>\n",
                       left + plot_w / 2, height - 8, t_end);
    svg += "</svg>\n";
    return svg;
}

void write_aperture_plot(const std::filesystem::path& path, const std::string& title, const PhoneSequence& phones,
                         const std::vector<ArticulationMeasures>& measures, const ArticulationSummary& summary,
                         const ArticulationLimits& limits) {
    write_text_file(path, aperture_plot_svg(title, phones, measures, summary, limits));
}

std::vector<ConditionArticulation> articulation_by_condition(const std::vector<QcStimulus>& stimuli,
                                                             std::size_t worst_listed) {
    std::vector<ConditionArticulation> out;
    std::map<std::string, std::size_t> at;
    for (const auto& st : stimuli) {
        auto [it, added] = at.try_emplace(st.condition, out.size());
        if (added) {
            ConditionArticulation c;
            c.condition = st.condition;
            c.policy = st.policy;
            c.closure_required = st.closure_required;
            c.aperture_min_mm = std::numeric_limits<double>::max();
            c.aperture_max_mm = std::numeric_limits<double>::lowest();
            out.push_back(std::move(c));
        }
        ConditionArticulation& c = out[it->second];
        const ArticulationSummary& s = st.summary;
        ++c.stimuli;
        c.bilabials += s.bilabials;
        c.bilabials_closed += s.bilabials_closed;
        c.labiodentals += s.labiodentals;
        c.labiodentals_reached += s.labiodentals_reached;
        c.interpenetrating_frames += s.interpenetrating_frames;
        c.aperture_min_mm = std::min(c.aperture_min_mm, s.aperture_min_mm);
        c.aperture_max_mm = std::max(c.aperture_max_mm, s.aperture_max_mm);
        if (s.rounding_checked) {
            ++c.rounding_checked;
            c.rounding_ok += s.rounding_ok ? 1 : 0;
        }
        if (!s.failures(st.closure_required).empty()) ++c.failing;
        c.closure_change.add(st.closure_change);
        for (const auto& seg : s.segments) {
            WorstSegment w{st.path, st.sentence, seg.phone, seg.start_s, seg.end_s, seg.best_mm, seg.ok};
            (seg.kind == SegmentClass::Bilabial ? c.worst_bilabials : c.worst_labiodentals).push_back(std::move(w));
        }
    }
    for (auto& c : out)
        for (auto* list : {&c.worst_bilabials, &c.worst_labiodentals}) {
            std::stable_sort(list->begin(), list->end(),
                             [](const WorstSegment& a, const WorstSegment& b) { return a.distance_mm > b.distance_mm; });
            if (list->size() > worst_listed) list->resize(worst_listed);
        }
    return out;
}

namespace {

std::string percent(std::size_t part, std::size_t whole) {
    return whole ? fmt::format("{:.1f} %", 100.0 * double(part) / double(whole)) : std::string("–");
}

std::string worst_rows(const std::vector<WorstSegment>& worst, const char* measure) {
    std::string html;
    for (const auto& w : worst)
        html += fmt::format("<tr><td><code>{}</code></td><td>{}</td><td>{:.3f} – {:.3f}</td><td class=\"{}\">{:.2f}</td>"
                            "</tr>\n",
                            xml_escape(w.path), xml_escape(w.phone), w.start_s, w.end_s, w.met ? "ok" : "bad",
                            w.distance_mm);
    if (html.empty()) return "";
    return fmt::format("<table><tr><th>stimulus</th><th>phone</th><th>segment (s)</th><th>{} (mm)</th></tr>\n{}"
                       "</table>\n",
                       measure, html);
}

}  // namespace

std::string articulation_qc_html(const std::string& title, const std::vector<QcStimulus>& stimuli,
                                 const ArticulationLimits& limits, const std::string& viseme_page) {
    const auto conditions = articulation_by_condition(stimuli);
    std::size_t failing = 0;
    for (const auto& c : conditions) failing += c.failing;
    std::string html = fmt::format(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{0}</title>\n<style>"
        "body{{font-family:sans-serif;max-width:960px;margin:2em auto;color:#222}}"
        "table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #ccc;padding:4px 8px;text-align:right}}"
        "th{{background:#f2f2f2}}td:first-child,th:first-child{{text-align:left}}.bad{{color:#b00}}.ok{{color:#070}}"
        "figure{{margin:1.5em 0}}figcaption{{font-size:90%;color:#444}}</style></head><body>\n<h1>{0}</h1>\n",
        xml_escape(title));
    html += fmt::format(
        "<p>What each control model puts on the lips, measured on every model stimulus on the head it was rendered "
        "with (<code>avsi measure</code>). A /p b m/ segment counts as closed when the lips close (central-third "
        "aperture ≤ {:.1f} mm) at a sampled frame of the segment; an /f v/ segment is in contact when the lower lip "
        "comes within {:.1f} mm of the upper incisors. For a model shown as trained these shares are results of the "
        "model, to read and report (docs/articulation.md), not constraints. A stimulus fails only when the lips pass "
        "through each other, or when its condition asked for closure (<code>closure = \"hold\"</code>) and did not "
        "get it. <b class=\"{}\">{} of {} stimuli fail.</b></p>\n",
        limits.closure_mm, limits.labiodental_mm, failing ? "bad" : "ok", failing, stimuli.size());
    if (!viseme_page.empty())
        html += fmt::format("<p>What each model's face carries about the viseme class of each phone (a "
                            "cross-validated classifier on these measures, with its confusions): <a href=\"{0}\">{0}</a>."
                            "</p>\n",
                            xml_escape(viseme_page));
    html += "<table><tr><th>condition</th><th>policy</th><th>stimuli</th><th>/p b m/ closed</th><th>/f v/ in "
            "contact</th><th>rounding contrast</th><th>aperture range (mm)</th><th>frames changed by the hold</th>"
            "<th>failing stimuli</th></tr>\n";
    for (const auto& c : conditions) {
        const std::string changed =
            c.closure_required ? fmt::format("{} of {} ({})", c.closure_change.frames_changed, c.closure_change.frames,
                                             percent(c.closure_change.frames_changed, c.closure_change.frames))
                               : std::string("–");
        html += fmt::format(
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{} of {} ({})</td><td>{} of {} ({})</td><td>{} of {}</td>"
            "<td>{:.2f} – {:.2f}</td><td>{}</td><td class=\"{}\">{}</td></tr>\n",
            xml_escape(c.condition), xml_escape(c.policy), c.stimuli, c.bilabials_closed, c.bilabials,
            percent(c.bilabials_closed, c.bilabials), c.labiodentals_reached, c.labiodentals,
            percent(c.labiodentals_reached, c.labiodentals), c.rounding_ok, c.rounding_checked, c.aperture_min_mm,
            c.aperture_max_mm, changed, c.failing ? "bad" : "ok", c.failing);
    }
    html += "</table>\n";
    if (failing) {
        html += "<h2>Failing stimuli</h2>\n<ul>\n";
        for (const auto& st : stimuli)
            for (const auto& p : st.summary.failures(st.closure_required, limits))
                html += fmt::format("<li><code>{}</code>: {}</li>\n", xml_escape(st.path), xml_escape(p));
        html += "</ul>\n";
    }
    html += "<h2>Worst segments per condition</h2>\n<p>The /p b m/ segments whose lips stayed furthest apart and "
            "the /f v/ segments whose lower lip stayed furthest from the upper incisors, at the frame each is judged "
            "by (red: beyond the limit).</p>\n";
    for (const auto& c : conditions) {
        html += fmt::format("<h3>{} ({})</h3>\n", xml_escape(c.condition), xml_escape(c.policy));
        html += worst_rows(c.worst_bilabials, "lip aperture");
        html += worst_rows(c.worst_labiodentals, "lower lip to upper incisors");
    }
    html += "<h2>Lip aperture of the worst stimuli</h2>\n<p>Midline aperture (line; dots are the video frames) and "
            "the central third's range (band); /p b m/ shaded blue, /f v/ green with the lower lip's distance to the "
            "upper incisors dashed, a segment beyond its limit red; the circle marks the frame each segment "
            "is judged by; the red dashed line is the closure limit.</p>\n";
    for (const auto& st : stimuli) {
        if (st.measures.empty()) continue;
        html += fmt::format("<figure>{}<figcaption><code>{}</code> — “{}”: bilabials closed {} of {}, labiodentals {} of "
                            "{}</figcaption></figure>\n",
                            aperture_plot_svg(st.condition + " / " + st.sentence, st.phones, st.measures, st.summary,
                                              limits),
                            xml_escape(st.path), xml_escape(st.text), st.summary.bilabials_closed, st.summary.bilabials,
                            st.summary.labiodentals_reached, st.summary.labiodentals);
    }
    html += "</body></html>\n";
    return html;
}

}  // namespace avsi::stimuli
