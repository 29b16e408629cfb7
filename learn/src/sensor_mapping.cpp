// Midsagittal sensors → articulatory parameters: head-motion removal by a
// per-frame rigid 2-D Procrustes fit to reference sensors (Beskow §3.2), then
// the documented direct mapping of sensor_mapping.h.
#include "avsi/learn/sensor_mapping.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/learn/articulatory_corpus.h"

namespace avsi::learn {

namespace {

struct SensorColumns {
    std::size_t x, y;
};

SensorColumns find_sensor(const EstTrack& t, const std::string& sensor, const SensorMappingSettings& s,
                          const std::string& source) {
    SensorColumns cols{t.channel(sensor + s.x_suffix), t.channel(sensor + s.y_suffix)};
    for (const auto& [col, name] : {std::pair{cols.x, sensor + s.x_suffix}, std::pair{cols.y, sensor + s.y_suffix}})
        if (col == EstTrack::npos) {
            const std::string hint = closest_match(name, t.channels);
            std::string present;
            for (const auto& c : t.channels) present += (present.empty() ? "" : " ") + c;
            throw InputError(source, 0, 0, name,
                             fmt::format("sensor channel not found{}; channels present: {}",
                                         hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint),
                                         present));
        }
    return cols;
}

double value(const EstTrack& t, std::size_t k, std::size_t c) {
    if (!t.present[k]) return missing_value;
    return static_cast<double>(t.values[k][c]);
}

// The q-th percentile (0–100) of the finite values, by linear interpolation.
double percentile(std::vector<double> v, double q) {
    v.erase(std::remove_if(v.begin(), v.end(), [](double x) { return !std::isfinite(x); }), v.end());
    if (v.empty()) return missing_value;
    std::sort(v.begin(), v.end());
    const double pos = std::clamp(q, 0.0, 100.0) / 100.0 * static_cast<double>(v.size() - 1);
    const auto lo = static_cast<std::size_t>(std::floor(pos));
    const auto hi = std::min(lo + 1, v.size() - 1);
    return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
}

double mean_finite(const std::vector<double>& v) {
    double sum = 0.0;
    std::size_t n = 0;
    for (double x : v)
        if (std::isfinite(x)) {
            sum += x;
            ++n;
        }
    return n ? sum / static_cast<double>(n) : missing_value;
}

// The lateral column of a sensor, or npos without lateral data.
std::size_t lateral_column(const EstTrack& t, const std::string& sensor, const SensorMappingSettings& s,
                           const std::string& source) {
    if (s.lateral_suffix.empty()) return EstTrack::npos;
    const std::string name = sensor + s.lateral_suffix;
    const std::size_t c = t.channel(name);
    if (c == EstTrack::npos) {
        const std::string hint = closest_match(name, t.channels);
        throw InputError(source, 0, 0, name,
                         fmt::format("lateral sensor channel not found{}",
                                     hint.empty() ? "" : fmt::format(" (did you mean \"{}\"?)", hint)));
    }
    return c;
}

}  // namespace

std::optional<SensorMappingSettings> sensor_mapping_preset(std::string_view name) {
    SensorMappingSettings s;
    if (name == "mocha") {
        // MOCHA-TIMIT's EMA: 2-D midsagittal, 1/100 mm, bridge of the nose and
        // upper incisor fixed to the skull.
        s.mm_per_unit = 0.01;
        return s;
    }
    if (name == "haskins") {
        // The Haskins IEEE rate database: 3-D, mm, already head-corrected
        // (no upper-incisor or reference sensors); JAW is the lower incisor.
        s.upper_incisor.clear();
        s.lower_incisor = "JAW";
        s.upper_lip = "UL";
        s.lower_lip = "LL";
        s.reference_sensors.clear();
        s.x_suffix = "_x";
        s.y_suffix = "_z";
        s.lateral_suffix = "_y";
        s.mouth_corner_left = "ML";
        s.mm_per_unit = 1.0;
        return s;
    }
    return std::nullopt;
}

std::array<bool, param_count> drivable_parameters(const SensorMappingSettings& s) {
    std::array<bool, param_count> out{};
    for (Param p : {Param::JawRotation, Param::JawThrust, Param::UpperLipRaise, Param::LowerLipDepression,
                    Param::UpperLipRetraction, Param::LowerLipRetraction, Param::LipRounding})
        out[index(p)] = true;
    const bool lateral = !s.lateral_suffix.empty();
    out[index(Param::JawShift)] = lateral;
    out[index(Param::MouthCornerStretchLeft)] = lateral && !s.mouth_corner_left.empty();
    out[index(Param::MouthCornerStretchRight)] = lateral && !s.mouth_corner_right.empty();
    return out;
}

void remove_head_motion(EstTrack& t, const SensorMappingSettings& s, const std::string& source) {
    if (s.reference_sensors.empty()) return;
    std::vector<SensorColumns> refs;
    for (const auto& r : s.reference_sensors) refs.push_back(find_sensor(t, r, s, source));
    // Every sensor with both coordinates moves with the head transform.
    std::vector<SensorColumns> all;
    for (std::size_t c = 0; c < t.channels.size(); ++c) {
        const std::string& name = t.channels[c];
        if (name.size() > s.x_suffix.size() && name.ends_with(s.x_suffix)) {
            const std::string base = name.substr(0, name.size() - s.x_suffix.size());
            const std::size_t y = t.channel(base + s.y_suffix);
            if (y != EstTrack::npos) all.push_back({c, y});
        }
    }
    // Mean reference positions over frames with data.
    std::vector<double> mx(refs.size(), 0.0), my(refs.size(), 0.0);
    std::size_t n = 0;
    for (std::size_t k = 0; k < t.frame_count(); ++k) {
        if (!t.present[k]) continue;
        bool ok = true;
        for (const auto& r : refs) ok = ok && std::isfinite(t.values[k][r.x]) && std::isfinite(t.values[k][r.y]);
        if (!ok) continue;
        for (std::size_t i = 0; i < refs.size(); ++i) {
            mx[i] += t.values[k][refs[i].x];
            my[i] += t.values[k][refs[i].y];
        }
        ++n;
    }
    if (n == 0) throw InputError(source, 0, 0, "reference sensors", "no frame has reference sensor data");
    for (std::size_t i = 0; i < refs.size(); ++i) {
        mx[i] /= static_cast<double>(n);
        my[i] /= static_cast<double>(n);
    }
    double cmx = 0.0, cmy = 0.0;
    for (std::size_t i = 0; i < refs.size(); ++i) {
        cmx += mx[i] / static_cast<double>(refs.size());
        cmy += my[i] / static_cast<double>(refs.size());
    }
    // Per frame: rotation angle and translation of the 2-D Procrustes fit
    // (one reference sensor: translation only).
    for (std::size_t k = 0; k < t.frame_count(); ++k) {
        if (!t.present[k]) continue;
        double cpx = 0.0, cpy = 0.0;
        for (const auto& r : refs) {
            cpx += t.values[k][r.x] / static_cast<double>(refs.size());
            cpy += t.values[k][r.y] / static_cast<double>(refs.size());
        }
        if (!std::isfinite(cpx) || !std::isfinite(cpy)) {
            t.present[k] = false;
            continue;
        }
        double dot = 0.0, cross = 0.0;
        for (std::size_t i = 0; i < refs.size(); ++i) {
            const double ax = t.values[k][refs[i].x] - cpx, ay = t.values[k][refs[i].y] - cpy;
            const double bx = mx[i] - cmx, by = my[i] - cmy;
            dot += ax * bx + ay * by;
            cross += ax * by - ay * bx;
        }
        const double angle = refs.size() > 1 ? std::atan2(cross, dot) : 0.0;
        const double c = std::cos(angle), sn = std::sin(angle);
        for (const auto& p : all) {
            const double x = t.values[k][p.x] - cpx, y = t.values[k][p.y] - cpy;
            t.values[k][p.x] = static_cast<float>(c * x - sn * y + cmx);
            t.values[k][p.y] = static_cast<float>(sn * x + c * y + cmy);
        }
    }
}

namespace {

// Jaw thrust: the part of the forward incisor position (mm) a line in the
// jaw gap does not explain (least squares over the frames with both).
std::vector<double> jaw_thrust_residual(const std::vector<double>& gap, const std::vector<double>& li_fwd) {
    const std::size_t n = gap.size();
    double sg = 0, sx = 0, sgg = 0, sgx = 0, m = 0;
    for (std::size_t k = 0; k < n; ++k)
        if (std::isfinite(gap[k]) && std::isfinite(li_fwd[k])) {
            sg += gap[k];
            sx += li_fwd[k];
            sgg += gap[k] * gap[k];
            sgx += gap[k] * li_fwd[k];
            m += 1;
        }
    const double var = m > 1 ? sgg - sg * sg / m : 0.0;
    const double slope = var > 1e-12 ? (sgx - sg * sx / m) / var : 0.0;
    std::vector<double> thrust(n);
    for (std::size_t k = 0; k < n; ++k) thrust[k] = li_fwd[k] - slope * gap[k];
    return thrust;
}

// The parameter frames at the sensor times resampled to the output rate
// (s.fps) by linear interpolation between sensor frames.
ParamTrack resample_to_fps(const std::vector<double>& times_s, const std::vector<Frame>& raw,
                           const SensorMappingSettings& s) {
    const std::size_t n = raw.size();
    ParamTrack out;
    out.fps = s.fps;
    out.start_s = times_s.front();
    out.present = drivable_parameters(s);
    const double end_s = times_s.back();
    std::size_t j = 0;
    for (std::size_t k = 0;; ++k) {
        const double time = out.start_s + static_cast<double>(k) / s.fps;
        if (time > end_s + 1e-9) break;
        while (j + 2 < n && times_s[j + 1] <= time) ++j;
        const double t0 = times_s[j], t1 = times_s[j + 1];
        const double w = std::clamp((time - t0) / (t1 - t0), 0.0, 1.0);
        Frame f;
        for (std::size_t p = 0; p < param_count; ++p)
            f[p] = out.present[p] ? (1.0 - w) * raw[j][p] + w * raw[j + 1][p] : missing_value;
        out.frames.push_back(f);
    }
    return out;
}

}  // namespace

ParamTrack map_sensors_to_params(const EstTrack& input, const SensorMappingSettings& s,
                                 const std::string& source) {
    if (input.frame_count() < 2) throw InputError(source, 0, 0, "NumFrames", "expected at least 2 frames");
    if (!(s.fps > 0.0) || !(s.mm_per_unit > 0.0))
        throw InputError(source, 0, 0, "sensor_mapping", "expected fps > 0 and mm_per_unit > 0");
    EstTrack t = input;
    remove_head_motion(t, s, source);
    // Without an upper-incisor sensor the data is in the head frame: the lower
    // incisor's position alone gives the gap.
    const bool have_ui = !s.upper_incisor.empty();
    const SensorColumns li = find_sensor(t, s.lower_incisor, s, source);
    const SensorColumns ui = have_ui ? find_sensor(t, s.upper_incisor, s, source) : li;
    const SensorColumns ul = find_sensor(t, s.upper_lip, s, source);
    const SensorColumns ll = find_sensor(t, s.lower_lip, s, source);
    const std::size_t n = t.frame_count();

    // Orientation from mean positions.
    auto column = [&](std::size_t c) {
        std::vector<double> v(n);
        for (std::size_t k = 0; k < n; ++k) v[k] = value(t, k, c);
        return v;
    };
    const double fwd = mean_finite(column(ul.x)) >= mean_finite(column(have_ui ? ui.x : li.x)) ? 1.0 : -1.0;
    const double up = mean_finite(column(ul.y)) >= mean_finite(column(ll.y)) ? 1.0 : -1.0;
    auto X = [&](std::size_t k, const SensorColumns& c) { return fwd * value(t, k, c.x) * s.mm_per_unit; };
    auto Y = [&](std::size_t k, const SensorColumns& c) { return up * value(t, k, c.y) * s.mm_per_unit; };

    // Raw measures per sensor frame, in mm.
    std::vector<double> gap(n), li_fwd(n), ul_up(n), ll_rel_up(n), ul_fwd(n), ll_rel_fwd(n);
    for (std::size_t k = 0; k < n; ++k) {
        gap[k] = have_ui ? Y(k, ui) - Y(k, li) : -Y(k, li);
        li_fwd[k] = X(k, li);
        ul_up[k] = Y(k, ul);
        ll_rel_up[k] = Y(k, ll) - Y(k, li);
        ul_fwd[k] = X(k, ul);
        ll_rel_fwd[k] = X(k, ll) - X(k, li);
    }
    const std::vector<double> thrust = jaw_thrust_residual(gap, li_fwd);

    const double gap_rest = percentile(gap, s.rest_percentile);
    const double thrust_rest = percentile(thrust, 50.0);
    const double ul_up_rest = percentile(ul_up, 50.0);
    const double ll_up_rest = percentile(ll_rel_up, 50.0);
    const double ul_fwd_rest = percentile(ul_fwd, 50.0);
    const double ll_fwd_rest = percentile(ll_rel_fwd, 50.0);

    // Lateral measures (3-D data): jaw shift and the corners' distance from the midline.
    const std::size_t li_lat = lateral_column(t, s.lower_incisor, s, source);
    const std::size_t ul_lat = lateral_column(t, s.upper_lip, s, source);
    const std::size_t ll_lat = lateral_column(t, s.lower_lip, s, source);
    const std::size_t ml_lat = s.mouth_corner_left.empty() ? EstTrack::npos
                                                           : lateral_column(t, s.mouth_corner_left, s, source);
    const std::size_t mr_lat = s.mouth_corner_right.empty() ? EstTrack::npos
                                                            : lateral_column(t, s.mouth_corner_right, s, source);
    const double left = s.lateral_positive_left ? 1.0 : -1.0;
    std::vector<double> shift(n, missing_value), corner_l(n, missing_value), corner_r(n, missing_value);
    if (li_lat != EstTrack::npos)
        for (std::size_t k = 0; k < n; ++k) {
            const double mid = 0.5 * (value(t, k, ul_lat) + value(t, k, ll_lat)) * s.mm_per_unit;
            shift[k] = left * value(t, k, li_lat) * s.mm_per_unit;
            if (ml_lat != EstTrack::npos) corner_l[k] = left * (value(t, k, ml_lat) * s.mm_per_unit - mid);
            if (mr_lat != EstTrack::npos) corner_r[k] = -left * (value(t, k, mr_lat) * s.mm_per_unit - mid);
        }
    const double shift_rest = percentile(shift, 50.0);
    const double corner_l_rest = percentile(corner_l, 50.0);
    const double corner_r_rest = percentile(corner_r, 50.0);

    std::vector<Frame> raw(n);
    for (std::size_t k = 0; k < n; ++k) {
        Frame f;
        f.fill(missing_value);
        f[index(Param::JawRotation)] = (gap[k] - gap_rest) / s.jaw_opening_full_mm;
        f[index(Param::JawThrust)] = (thrust[k] - thrust_rest) / s.jaw_thrust_full_mm;
        f[index(Param::UpperLipRaise)] = (ul_up[k] - ul_up_rest) / s.lip_vertical_full_mm;
        f[index(Param::LowerLipDepression)] = -(ll_rel_up[k] - ll_up_rest) / s.lip_vertical_full_mm;
        const double ul_ret = -(ul_fwd[k] - ul_fwd_rest) / s.lip_protrusion_full_mm;
        const double ll_ret = -(ll_rel_fwd[k] - ll_fwd_rest) / s.lip_protrusion_full_mm;
        f[index(Param::UpperLipRetraction)] = ul_ret;
        f[index(Param::LowerLipRetraction)] = ll_ret;
        f[index(Param::LipRounding)] = -0.5 * (ul_ret + ll_ret);
        f[index(Param::JawShift)] = (shift[k] - shift_rest) / s.jaw_shift_full_mm;
        f[index(Param::MouthCornerStretchLeft)] = (corner_l[k] - corner_l_rest) / s.corner_stretch_full_mm;
        f[index(Param::MouthCornerStretchRight)] = (corner_r[k] - corner_r_rest) / s.corner_stretch_full_mm;
        raw[k] = f;
    }

    ParamTrack out = resample_to_fps(t.times_s, raw, s);
    // Coordinates in the wrong unit give parameters far outside their range.
    std::vector<double> jaw;
    for (const Frame& f : out.frames) jaw.push_back(std::abs(f[index(Param::JawRotation)]));
    const double jaw95 = percentile(jaw, 95.0);
    if (jaw95 > 5.0)
        log_warning("{}: jaw_rotation reaches {:.1f} (its range is [{}, {}]): are the coordinates in the unit "
                    "sensor_mapping.mm_per_unit says ({} mm)? MOCHA's are 1/100 mm (preset \"mocha\")",
                    source, jaw95, param_info(Param::JawRotation).min, param_info(Param::JawRotation).max,
                    s.mm_per_unit);
    return out;
}

}  // namespace avsi::learn
