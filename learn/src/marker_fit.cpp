// The marker fit: head-motion removal, orientation fit, per-frame shape fit
// (marker_fit.h; Beskow 2004 §3.2–3.5).
#include "avsi/learn/marker_fit.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>

#include <ceres/ceres.h>
#include <Eigen/Dense>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include "avsi/core/error.h"

namespace avsi::learn {

std::array<double, 3> Similarity::apply(const double* x) const {
    std::array<double, 3> y{};
    for (int r = 0; r < 3; ++r)
        y[r] = scale * (rotation[3 * r] * x[0] + rotation[3 * r + 1] * x[1] + rotation[3 * r + 2] * x[2]) +
               translation[r];
    return y;
}

Similarity fit_similarity(const std::vector<double>& from, const std::vector<double>& to, bool with_scale) {
    const std::size_t n = from.size() / 3;
    AVSI_ASSERT(n >= 3 && to.size() == from.size());
    const Eigen::Map<const Eigen::Matrix<double, 3, Eigen::Dynamic>> X(from.data(), 3, Eigen::Index(n));
    const Eigen::Map<const Eigen::Matrix<double, 3, Eigen::Dynamic>> Y(to.data(), 3, Eigen::Index(n));
    const Eigen::Vector3d mx = X.rowwise().mean(), my = Y.rowwise().mean();
    const Eigen::Matrix3Xd Xc = X.colwise() - mx, Yc = Y.colwise() - my;
    // Umeyama (1991): the SVD of the cross-covariance, with a reflection guard.
    const Eigen::Matrix3d cov = Yc * Xc.transpose() / double(n);
    Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
    Eigen::Vector3d d(1, 1, 1);
    if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0) d(2) = -1;
    const Eigen::Matrix3d R = svd.matrixU() * d.asDiagonal() * svd.matrixV().transpose();
    const double var_x = Xc.squaredNorm() / double(n);
    const double s = with_scale && var_x > 0 ? svd.singularValues().dot(d) / var_x : 1.0;
    const Eigen::Vector3d t = my - s * R * mx;
    Similarity out;
    out.scale = s;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) out.rotation[3 * r + c] = R(r, c);
        out.translation[r] = t(r);
    }
    return out;
}

namespace {

constexpr double nan = std::numeric_limits<double>::quiet_NaN();

// Which recording marker each model marker reads, and what is left out.
struct MarkerMatch {
    std::vector<std::size_t> reference;   // recording indices
    std::vector<std::size_t> face_model;  // model indices of the face markers
    std::vector<std::size_t> face_rec;    // their recording indices
    std::vector<std::size_t> strategic;   // positions in face_* of the orientation markers
    std::vector<std::string> notes;
};

MarkerMatch match_markers(const MarkerRecording& rec, const synth::MarkerModel& model, const std::string& source) {
    MarkerMatch m;
    std::vector<std::string> absent;
    for (std::size_t i = 0; i < model.markers.size(); ++i) {
        const auto& mm = model.markers[i];
        const std::size_t r = rec.marker(mm.name);
        if (r == MarkerRecording::npos) {
            absent.push_back(mm.name);
            continue;
        }
        if (mm.reference) {
            m.reference.push_back(r);
            continue;
        }
        if (mm.orientation) m.strategic.push_back(m.face_model.size());
        m.face_model.push_back(i);
        m.face_rec.push_back(r);
    }
    if (!absent.empty())
        m.notes.push_back(fmt::format("{} layout markers are not in the recording: {}", absent.size(), fmt::join(absent, " ")));
    std::vector<std::string> unused;
    for (const auto& l : rec.labels)
        if (model.marker(l) == synth::MarkerModel::npos) unused.push_back(l);
    if (!unused.empty())
        m.notes.push_back(fmt::format("{} recording markers are not in the layout ({}), not used: {}", unused.size(),
                                      model.source, fmt::join(unused, " ")));
    if (m.strategic.size() < 3)
        throw InputError(source, 0, 0, "markers",
                         fmt::format("the orientation fit needs 3 strategic markers (\"orientation\": true in {}), "
                                     "the recording has {}", model.source, m.strategic.size()));
    return m;
}

bool all_seen(const MarkerRecording& rec, std::size_t f, const std::vector<std::size_t>& markers) {
    return std::all_of(markers.begin(), markers.end(), [&](std::size_t m) { return rec.seen(f, m); });
}

std::size_t choose_reference_frame(const MarkerRecording& rec, const MarkerMatch& m, const MarkerFitSettings& s,
                                   const std::string& source) {
    if (s.reference_frame) {
        if (*s.reference_frame >= rec.frames)
            throw InputError(source, 0, 0, "reference frame",
                             fmt::format("frame {} given, the recording has {} frames", *s.reference_frame, rec.frames));
        return *s.reference_frame;
    }
    std::vector<std::size_t> strategic;
    for (auto k : m.strategic) strategic.push_back(m.face_rec[k]);
    for (std::size_t f = 0; f < rec.frames; ++f)
        if (all_seen(rec, f, m.reference) && all_seen(rec, f, strategic)) return f;
    throw InputError(source, 0, 0, "reference frame",
                     "no frame shows every reference and strategic marker; give the reference frame");
}

// Step 1: every frame moved rigidly so its reference markers meet the
// reference frame's; frames that cannot be placed become dropouts throughout.
MarkerRecording remove_head_motion(const MarkerRecording& rec, const MarkerMatch& m, std::size_t ref,
                                   std::size_t min_markers, std::size_t& unplaced) {
    MarkerRecording out = rec;
    unplaced = 0;
    if (m.reference.empty()) return out;
    for (std::size_t f = 0; f < rec.frames; ++f) {
        std::vector<double> from, to;
        for (auto r : m.reference)
            if (rec.seen(f, r) && rec.seen(ref, r)) {
                from.insert(from.end(), rec.point(f, r), rec.point(f, r) + 3);
                to.insert(to.end(), rec.point(ref, r), rec.point(ref, r) + 3);
            }
        if (from.size() / 3 < std::max<std::size_t>(min_markers, 3)) {
            ++unplaced;
            std::fill(out.point(f, 0), out.point(f, 0) + 3 * rec.marker_count(), nan);
            continue;
        }
        const Similarity rigid = fit_similarity(from, to, false);
        for (std::size_t k = 0; k < rec.marker_count(); ++k)
            if (rec.seen(f, k)) {
                const auto p = rigid.apply(rec.point(f, k));
                std::copy(p.begin(), p.end(), out.point(f, k));
            }
    }
    return out;
}

// A face marker's surface point Σ w_k v_k from posed points.
std::array<double, 3> surface_point(const synth::ModelMarker& mm, const std::vector<double>& xyz) {
    std::array<double, 3> p{};
    for (int k = 0; k < 3; ++k)
        for (int c = 0; c < 3; ++c) p[c] += mm.weights[k] * xyz[3 * mm.points[k] + c];
    return p;
}

// Eq. 2's coordinates (s, t, u) of a point in a marker's triangle frame, or
// an offset from v1 when the triangle is degenerate (u_is_offset).
struct VirtualMarker {
    std::size_t model = 0;
    Eigen::Vector3d coords = Eigen::Vector3d::Zero();
    bool offset = false;
};

Eigen::Vector3d point_of(const std::vector<double>& xyz, std::size_t i) {
    return {xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]};
}

VirtualMarker tie_virtual_marker(const synth::ModelMarker& mm, std::size_t model, const std::vector<double>& rest,
                                 const Eigen::Vector3d& p) {
    VirtualMarker v;
    v.model = model;
    const Eigen::Vector3d v1 = point_of(rest, mm.points[0]);
    const Eigen::Vector3d e1 = point_of(rest, mm.points[1]) - v1, e2 = point_of(rest, mm.points[2]) - v1;
    const Eigen::Vector3d n = e1.cross(e2);
    if (n.norm() < 1e-9 * std::max(1.0, e1.squaredNorm())) {
        v.offset = true;
        v.coords = p - v1;
        return v;
    }
    Eigen::Matrix3d A;
    A << e1, e2, n.normalized();
    v.coords = A.partialPivLu().solve(p - v1);
    return v;
}

Eigen::Vector3d virtual_position(const synth::ModelMarker& mm, const VirtualMarker& v, const std::vector<double>& xyz) {
    const Eigen::Vector3d v1 = point_of(xyz, mm.points[0]);
    if (v.offset) return v1 + v.coords;
    const Eigen::Vector3d e1 = point_of(xyz, mm.points[1]) - v1, e2 = point_of(xyz, mm.points[2]) - v1;
    return v1 + v.coords(0) * e1 + v.coords(1) * e2 + v.coords(2) * e1.cross(e2).normalized();
}

// The shape fit's variables: per parameter one value, and for a two-sided
// parameter (synth::MarkerModel::two_sided) its two sides apart (the rig is
// smooth in those): z[j] the value (two-sided: its positive side, ≥ 0), then
// z[param_count + k] the negative side (≤ 0) of the k-th two-sided parameter.
class SideVariables {
public:
    explicit SideVariables(const synth::MarkerModel& model) {
        for (std::size_t j = 0; j < synth::param_count; ++j)
            m_negative_slot[j] = model.two_sided[j] ? int(synth::param_count + m_extra++) : -1;
    }
    std::size_t size() const { return synth::param_count + m_extra; }
    void split(const double* z, synth::Frame& positive, synth::Frame& negative) const {
        for (std::size_t j = 0; j < synth::param_count; ++j) {
            positive[j] = z[j];
            negative[j] = m_negative_slot[j] < 0 ? 0.0 : z[m_negative_slot[j]];
        }
    }
    // The parameter frame the variables stand for.
    synth::Frame frame(const double* z) const {
        synth::Frame p, n;
        split(z, p, n);
        for (std::size_t j = 0; j < synth::param_count; ++j) p[j] += n[j];
        return p;
    }
    // Variables for a parameter frame (each side of a two-sided one from its sign).
    std::vector<double> variables(const synth::Frame& y) const {
        std::vector<double> z(size(), 0.0);
        for (std::size_t j = 0; j < synth::param_count; ++j) {
            if (m_negative_slot[j] < 0) z[j] = y[j];
            else if (y[j] >= 0) z[j] = y[j];
            else z[m_negative_slot[j]] = y[j];
        }
        return z;
    }
    void set_bounds(ceres::Problem& problem, double* z) const {
        for (std::size_t j = 0; j < synth::param_count; ++j) {
            const auto& info = synth::params()[j];
            const double lo = m_negative_slot[j] < 0 ? info.min : 0.0;
            z[j] = std::clamp(z[j], lo, info.max);
            problem.SetParameterLowerBound(z, int(j), lo);
            problem.SetParameterUpperBound(z, int(j), info.max);
            if (m_negative_slot[j] < 0) continue;
            double& zn = z[m_negative_slot[j]];
            zn = std::clamp(zn, info.min, 0.0);
            problem.SetParameterLowerBound(z, m_negative_slot[j], info.min);
            problem.SetParameterUpperBound(z, m_negative_slot[j], 0.0);
        }
    }

private:
    std::array<int, synth::param_count> m_negative_slot{};
    std::size_t m_extra = 0;
};

// Eq. 3 for one frame: the residuals q_i − p_i of the markers seen, posed
// with the sides apart, with forward-difference Jacobians of the rig.
class ShapeCost : public ceres::CostFunction {
public:
    ShapeCost(const synth::MarkerModel& model, const SideVariables& vars, const std::vector<VirtualMarker>& virtuals,
              std::vector<std::size_t> seen, std::vector<Eigen::Vector3d> targets, double step)
        : m_model(model), m_vars(vars), m_virtuals(virtuals), m_seen(std::move(seen)), m_targets(std::move(targets)),
          m_step(step) {
        set_num_residuals(static_cast<int>(3 * m_seen.size()));
        mutable_parameter_block_sizes()->push_back(static_cast<int>(vars.size()));
    }

    bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
        const std::size_t nz = m_vars.size(), nr = 3 * m_seen.size();
        thread_local std::vector<double> z, moved;
        z.assign(parameters[0], parameters[0] + nz);
        sided_positions(z.data(), residuals);
        if (!jacobians || !jacobians[0]) return true;
        moved.resize(nr);
        for (std::size_t j = 0; j < nz; ++j) {
            const double keep = z[j];
            z[j] += m_step;
            sided_positions(z.data(), moved.data());
            z[j] = keep;
            for (std::size_t r = 0; r < nr; ++r) jacobians[0][r * nz + j] = (moved[r] - residuals[r]) / m_step;
        }
        return true;
    }

    // q_i − p_i for the variables z.
    void sided_positions(const double* z, double* out) const {
        thread_local std::vector<double> xyz;
        synth::Frame positive, negative;
        m_vars.split(z, positive, negative);
        m_model.pose_sides(positive, negative, xyz);
        differences(xyz, out);
    }
    // q_i − p_i for a parameter frame, posed as the rig poses it.
    void frame_differences(const synth::Frame& y, double* out) const {
        thread_local std::vector<double> xyz;
        m_model.pose(y, xyz);
        differences(xyz, out);
    }

private:
    void differences(const std::vector<double>& xyz, double* out) const {
        for (std::size_t i = 0; i < m_seen.size(); ++i) {
            const VirtualMarker& v = m_virtuals[m_seen[i]];
            const Eigen::Vector3d q = virtual_position(m_model.markers[v.model], v, xyz) - m_targets[i];
            for (int c = 0; c < 3; ++c) out[3 * i + c] = q(c);
        }
    }

    const synth::MarkerModel& m_model;
    const SideVariables& m_vars;
    const std::vector<VirtualMarker>& m_virtuals;
    std::vector<std::size_t> m_seen;   // into m_virtuals
    std::vector<Eigen::Vector3d> m_targets;
    double m_step;
};

ceres::Solver::Options shape_solver_options(const MarkerFitSettings& s) {
    ceres::Solver::Options o;
    o.linear_solver_type = ceres::DENSE_QR;
    o.max_num_iterations = s.max_iterations;
    o.num_threads = 1;
    o.logging_type = ceres::SILENT;
    o.function_tolerance = 1e-7;
    o.parameter_tolerance = 1e-6;
    return o;
}

// The data a frame's fit reads: the markers in model coordinates.
struct FitInput {
    const synth::MarkerModel& model;
    const SideVariables& vars;
    const std::vector<VirtualMarker>& virtuals;
    const std::vector<std::size_t>& rec_index;  // per virtual marker: recording index
    const MarkerRecording& placed;              // head-fixed and oriented
    const MarkerFitSettings& settings;
};

// Fits one frame starting from the variables `z` (updated); the frame's
// parameters, or nullopt when too few markers are seen.
std::optional<synth::Frame> fit_frame(const FitInput& in, std::size_t f, std::vector<double>& z, double* residual_row) {
    std::vector<std::size_t> seen;
    std::vector<Eigen::Vector3d> targets;
    for (std::size_t i = 0; i < in.virtuals.size(); ++i)
        if (in.placed.seen(f, in.rec_index[i])) {
            seen.push_back(i);
            const double* p = in.placed.point(f, in.rec_index[i]);
            targets.emplace_back(p[0], p[1], p[2]);
        }
    if (seen.size() < in.settings.min_face_markers) return std::nullopt;
    ceres::Problem::Options po;
    po.cost_function_ownership = ceres::TAKE_OWNERSHIP;
    ceres::Problem problem(po);
    auto* cost = new ShapeCost(in.model, in.vars, in.virtuals, seen, targets, in.settings.derivative_step);
    problem.AddResidualBlock(cost, nullptr, z.data());
    in.vars.set_bounds(problem, z.data());
    ceres::Solver::Summary summary;
    ceres::Solve(shape_solver_options(in.settings), &problem, &summary);
    synth::Frame y = in.vars.frame(z.data());
    for (std::size_t j = 0; j < synth::param_count; ++j) y[j] = std::clamp(y[j], synth::params()[j].min, synth::params()[j].max);
    std::vector<double> r(3 * seen.size());
    cost->frame_differences(y, r.data());
    for (std::size_t i = 0; i < seen.size(); ++i)
        residual_row[seen[i]] = std::sqrt(r[3 * i] * r[3 * i] + r[3 * i + 1] * r[3 * i + 1] + r[3 * i + 2] * r[3 * i + 2]);
    return y;
}

// Step 3 over every frame: chunks of frames in parallel, each chunk a
// warm-started chain from rest.
void fit_all_frames(const FitInput& in, MarkerFitResult& out) {
    const std::size_t frames = in.placed.frames, chunk = std::max<std::size_t>(in.settings.chunk_frames, 1);
    const std::size_t chunks = (frames + chunk - 1) / chunk;
    std::atomic<std::size_t> next{0}, too_few{0};
    auto work = [&] {
        for (std::size_t c = next++; c < chunks; c = next++) {
            std::vector<double> z(in.vars.size(), 0.0);
            for (std::size_t f = c * chunk; f < std::min(frames, (c + 1) * chunk); ++f) {
                double* row = out.residual_mm.data() + f * in.virtuals.size();
                std::vector<double> start = z;
                if (const auto y = fit_frame(in, f, start, row)) {
                    z = in.vars.variables(*y);  // one side of each parameter, as the rig poses it
                    out.track.frames[f] = *y;
                } else {
                    ++too_few;
                }
            }
        }
    };
    std::size_t threads = in.settings.threads ? in.settings.threads : std::max(1u, std::thread::hardware_concurrency());
    threads = std::min(threads, std::max<std::size_t>(chunks, 1));
    std::vector<std::thread> pool;
    for (std::size_t t = 1; t < threads; ++t) pool.emplace_back(work);
    work();
    for (auto& t : pool) t.join();
    out.frames_too_few_markers = too_few;
}

}  // namespace

MarkerFitResult fit_markers(const MarkerRecording& recording, const synth::MarkerModel& model,
                            const MarkerFitSettings& settings, const std::string& source) {
    const MarkerMatch match = match_markers(recording, model, source);
    MarkerFitResult out;
    out.notes = match.notes;
    out.reference_frame = choose_reference_frame(recording, match, settings, source);
    MarkerRecording placed = remove_head_motion(recording, match, out.reference_frame, settings.min_reference_markers,
                                                out.frames_unplaced);
    // Step 2: the orientation fit on the reference frame, applied to every frame.
    std::vector<double> rest;
    model.pose(synth::Frame{}, rest);
    std::vector<double> from, to;
    for (auto k : match.strategic) {
        const std::size_t r = match.face_rec[k];
        if (!placed.seen(out.reference_frame, r)) continue;
        from.insert(from.end(), placed.point(out.reference_frame, r), placed.point(out.reference_frame, r) + 3);
        const auto v = surface_point(model.markers[match.face_model[k]], rest);
        to.insert(to.end(), v.begin(), v.end());
    }
    if (from.size() < 9)
        throw InputError(source, 0, 0, "reference frame",
                         fmt::format("frame {} shows {} strategic markers, the orientation fit needs 3",
                                     out.reference_frame, from.size() / 3));
    out.orientation = fit_similarity(from, to, true);
    double sq = 0;
    for (std::size_t i = 0; i < from.size() / 3; ++i) {
        const auto p = out.orientation.apply(&from[3 * i]);
        for (int c = 0; c < 3; ++c) sq += std::pow(p[c] - to[3 * i + c], 2);
    }
    out.orientation_rms_mm = std::sqrt(sq / double(from.size() / 3));
    for (std::size_t f = 0; f < placed.frames; ++f)
        for (std::size_t k = 0; k < placed.marker_count(); ++k)
            if (placed.seen(f, k)) {
                const auto p = out.orientation.apply(placed.point(f, k));
                std::copy(p.begin(), p.end(), placed.point(f, k));
            }
    // Step 3: virtual markers tied in the reference frame, then every frame's shape fit.
    std::vector<VirtualMarker> virtuals;
    std::vector<std::size_t> rec_index;
    std::vector<std::string> untied;
    for (std::size_t i = 0; i < match.face_model.size(); ++i) {
        const std::size_t r = match.face_rec[i];
        const auto& mm = model.markers[match.face_model[i]];
        if (!placed.seen(out.reference_frame, r)) {
            untied.push_back(mm.name);
            continue;
        }
        const double* p = placed.point(out.reference_frame, r);
        virtuals.push_back(tie_virtual_marker(mm, match.face_model[i], rest, {p[0], p[1], p[2]}));
        rec_index.push_back(r);
        out.markers.push_back(mm.name);
    }
    if (!untied.empty())
        out.notes.push_back(fmt::format("not seen in the reference frame {}, so left out: {}", out.reference_frame,
                                        fmt::join(untied, " ")));
    for (auto r : rec_index) {
        std::size_t n = 0;
        for (std::size_t f = 0; f < recording.frames; ++f) n += recording.seen(f, r) ? 0 : 1;
        out.dropouts.push_back(n);
    }
    out.track.fps = recording.rate_hz;
    out.track.start_s = recording.start_s;
    out.track.present.fill(true);
    synth::Frame missing;
    missing.fill(nan);
    out.track.frames.assign(recording.frames, missing);
    out.residual_mm.assign(recording.frames * virtuals.size(), nan);
    const SideVariables vars(model);
    fit_all_frames({model, vars, virtuals, rec_index, placed, settings}, out);
    out.frames_too_few_markers -= std::min(out.frames_too_few_markers, out.frames_unplaced);
    return out;
}

}  // namespace avsi::learn
