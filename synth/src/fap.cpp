// MPEG-4 FAP streams: the parameter ↔ FAP mapping and the v2.1 text format
// (see fap.h). The mapping rows, FAP by FAP (MPEG-4 names, FAPU, direction):
//
//   3  open_jaw              MNS  down+     jaw_rotation · jaw_open_mm
//   4  lower_t_midlip        MNS  down+    −upper_lip_raise · lip_raise_mm
//   5  raise_b_midlip        MNS  up+      −lower_lip_depression · lip_depress_mm
//   6  stretch_l_cornerlip   MW   out+      stretch_left · corner_stretch_mm − lip_rounding · rounding_mm
//   7  stretch_r_cornerlip   MW   out+      stretch_right · corner_stretch_mm − lip_rounding · rounding_mm
//   8  lower_t_lip_lm        MNS  down+     side_fraction × FAP 4
//   9  lower_t_lip_rm        MNS  down+     side_fraction × FAP 4
//   10 raise_b_lip_lm        MNS  up+       side_fraction × FAP 5
//   11 raise_b_lip_rm        MNS  up+       side_fraction × FAP 5
//   12 raise_l_cornerlip     MNS  up+       stretch_left · corner_raise_fraction · corner_stretch_mm
//   13 raise_r_cornerlip     MNS  up+       stretch_right · corner_raise_fraction · corner_stretch_mm
//   14 thrust_jaw            MNS  fwd+      jaw_thrust · jaw_thrust_mm
//   15 shift_jaw             MW   right+   −jaw_shift · jaw_shift_mm   (jaw_shift is toward the speaker's left)
//   16 push_b_lip            MNS  fwd+     −lower_lip_retraction · lip_protrusion_mm
//   17 push_t_lip            MNS  fwd+     −upper_lip_retraction · lip_protrusion_mm
//   51–60                    the outer-lip twins of 4–13, same rows
//
// FAP 18 (depress_chin) is not driven by any parameter and is not written.
#include "avsi/synth/fap.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <map>
#include <sstream>

#include <Eigen/Dense>
#include <fmt/format.h>
#include <fmt/ranges.h>

#include "avsi/core/checks.h"
#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"

namespace avsi::synth {

namespace {

struct FapRow {
    int fap;  // 1-based
    Fapu unit;
    Frame mm_per_unit{};  // displacement (mm) per unit of each parameter
};

std::vector<FapRow> mapping_rows(const FapMapping& m) {
    auto row = [](int fap, Fapu unit) { return FapRow{fap, unit, {}}; };
    const auto P = [](Param p) { return index(p); };
    std::vector<FapRow> rows;
    FapRow r = row(3, Fapu::MNS);
    r.mm_per_unit[P(Param::JawRotation)] = m.jaw_open_mm;
    rows.push_back(r);
    for (int outer : {0, 1}) {
        const int o = outer ? 47 : 0;  // 4 → 51, …, 13 → 60
        r = row(4 + o, Fapu::MNS);
        r.mm_per_unit[P(Param::UpperLipRaise)] = -m.lip_raise_mm;
        rows.push_back(r);
        r = row(5 + o, Fapu::MNS);
        r.mm_per_unit[P(Param::LowerLipDepression)] = -m.lip_depress_mm;
        rows.push_back(r);
        r = row(6 + o, Fapu::MW);
        r.mm_per_unit[P(Param::MouthCornerStretchLeft)] = m.corner_stretch_mm;
        r.mm_per_unit[P(Param::LipRounding)] = -m.rounding_mm;
        rows.push_back(r);
        r = row(7 + o, Fapu::MW);
        r.mm_per_unit[P(Param::MouthCornerStretchRight)] = m.corner_stretch_mm;
        r.mm_per_unit[P(Param::LipRounding)] = -m.rounding_mm;
        rows.push_back(r);
        for (int fap : {8, 9}) {
            r = row(fap + o, Fapu::MNS);
            r.mm_per_unit[P(Param::UpperLipRaise)] = -m.side_fraction * m.lip_raise_mm;
            rows.push_back(r);
        }
        for (int fap : {10, 11}) {
            r = row(fap + o, Fapu::MNS);
            r.mm_per_unit[P(Param::LowerLipDepression)] = -m.side_fraction * m.lip_depress_mm;
            rows.push_back(r);
        }
        r = row(12 + o, Fapu::MNS);
        r.mm_per_unit[P(Param::MouthCornerStretchLeft)] = m.corner_raise_fraction * m.corner_stretch_mm;
        rows.push_back(r);
        r = row(13 + o, Fapu::MNS);
        r.mm_per_unit[P(Param::MouthCornerStretchRight)] = m.corner_raise_fraction * m.corner_stretch_mm;
        rows.push_back(r);
    }
    r = row(14, Fapu::MNS);
    r.mm_per_unit[P(Param::JawThrust)] = m.jaw_thrust_mm;
    rows.push_back(r);
    r = row(15, Fapu::MW);
    r.mm_per_unit[P(Param::JawShift)] = -m.jaw_shift_mm;
    rows.push_back(r);
    r = row(16, Fapu::MNS);
    r.mm_per_unit[P(Param::LowerLipRetraction)] = -m.lip_protrusion_mm;
    rows.push_back(r);
    r = row(17, Fapu::MNS);
    r.mm_per_unit[P(Param::UpperLipRetraction)] = -m.lip_protrusion_mm;
    rows.push_back(r);
    std::sort(rows.begin(), rows.end(), [](const FapRow& a, const FapRow& b) { return a.fap < b.fap; });
    return rows;
}

double fapu_mm(Fapu unit, const FapUnits& units) { return unit == Fapu::MNS ? units.mns_mm() : units.mw_mm(); }

// The matrix from parameters to FAP values in FAPU, for the given rows.
Eigen::MatrixXd fapu_matrix(const std::vector<FapRow>& rows, const FapUnits& units) {
    Eigen::MatrixXd a(static_cast<Eigen::Index>(rows.size()), static_cast<Eigen::Index>(param_count));
    for (std::size_t r = 0; r < rows.size(); ++r)
        for (std::size_t p = 0; p < param_count; ++p)
            a(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(p)) =
                rows[r].mm_per_unit[p] / fapu_mm(rows[r].unit, units);
    return a;
}

Eigen::MatrixXd pseudo_inverse(const Eigen::MatrixXd& a) {
    return Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(a).pseudoInverse();
}

// The 68 FAP names of ISO/IEC 14496-2 (Annex C), index 0 = FAP 1.
constexpr std::array<std::string_view, fap_count> k_fap_names = {
    "viseme", "expression", "open_jaw", "lower_t_midlip", "raise_b_midlip", "stretch_l_cornerlip",
    "stretch_r_cornerlip", "lower_t_lip_lm", "lower_t_lip_rm", "raise_b_lip_lm", "raise_b_lip_rm",
    "raise_l_cornerlip", "raise_r_cornerlip", "thrust_jaw", "shift_jaw", "push_b_lip", "push_t_lip",
    "depress_chin", "close_t_l_eyelid", "close_t_r_eyelid", "close_b_l_eyelid", "close_b_r_eyelid",
    "yaw_l_eyeball", "yaw_r_eyeball", "pitch_l_eyeball", "pitch_r_eyeball", "thrust_l_eyeball",
    "thrust_r_eyeball", "dilate_l_pupil", "dilate_r_pupil", "raise_l_i_eyebrow", "raise_r_i_eyebrow",
    "raise_l_m_eyebrow", "raise_r_m_eyebrow", "raise_l_o_eyebrow", "raise_r_o_eyebrow", "squeeze_l_eyebrow",
    "squeeze_r_eyebrow", "puff_l_cheek", "puff_r_cheek", "lift_l_cheek", "lift_r_cheek", "shift_tongue_tip",
    "raise_tongue_tip", "thrust_tongue_tip", "raise_tongue", "tongue_roll", "head_pitch", "head_yaw",
    "head_roll", "lower_t_midlip_o", "raise_b_midlip_o", "stretch_l_cornerlip_o", "stretch_r_cornerlip_o",
    "lower_t_lip_lm_o", "lower_t_lip_rm_o", "raise_b_lip_lm_o", "raise_b_lip_rm_o", "raise_l_cornerlip_o",
    "raise_r_cornerlip_o", "stretch_l_nose", "stretch_r_nose", "raise_nose", "bend_nose", "raise_l_ear",
    "raise_r_ear", "pull_l_ear", "pull_r_ear"};

}  // namespace

const std::vector<FapGroup>& fap_groups() {
    static const std::vector<FapGroup> groups = {
        {"visemes and expressions", 1, 2}, {"jaw, chin, inner lip and lip corners", 3, 18},
        {"eyeballs, pupils and eyelids", 19, 30}, {"eyebrows", 31, 38},
        {"cheeks", 39, 42}, {"tongue", 43, 47},
        {"head rotation", 48, 50}, {"outer lip", 51, 60},
        {"nose", 61, 64}, {"ears", 65, 68}};
    return groups;
}

std::string_view fap_name(int fap) {
    AVSI_ASSERT(fap >= 1 && fap <= fap_count);
    return k_fap_names[static_cast<std::size_t>(fap - 1)];
}

std::vector<std::string> unmapped_fap_groups(const FapStream& stream) {
    const auto& mapped = mapped_faps();
    std::vector<std::string> out;
    for (const FapGroup& g : fap_groups()) {
        std::vector<std::string> names;
        for (int fap = g.first; fap <= g.last; ++fap)
            if (stream.present_in_file[static_cast<std::size_t>(fap - 1)] &&
                std::find(mapped.begin(), mapped.end(), fap) == mapped.end())
                names.push_back(fmt::format("{} {}", fap, fap_name(fap)));
        if (!names.empty())
            out.push_back(fmt::format("{} (FAP {})", g.name, fmt::join(names, ", ")));
    }
    return out;
}

const std::vector<int>& mapped_faps() {
    static const std::vector<int> faps = [] {
        std::vector<int> out;
        for (const auto& r : mapping_rows(FapMapping{})) out.push_back(r.fap);
        return out;
    }();
    return faps;
}

FapStream trajectory_to_fap(const Trajectory& trajectory, const FapUnits& units, const FapMapping& mapping,
                            const std::string& name) {
    const auto rows = mapping_rows(mapping);
    FapStream out;
    out.name = name;
    out.fps = trajectory.fps;
    out.frames.reserve(trajectory.size());
    for (const Frame& f : trajectory.frames) {
        FapFrame frame;
        for (const auto& r : rows) {
            double mm = 0.0;
            for (std::size_t p = 0; p < param_count; ++p) mm += r.mm_per_unit[p] * f[p];
            frame.mask[r.fap - 1] = true;
            frame.values[r.fap - 1] = std::round(mm / fapu_mm(r.unit, units)) + 0.0;  // + 0.0: no "-0"
        }
        out.frames.push_back(frame);
    }
    return out;
}

Trajectory fap_to_trajectory(const FapStream& stream, const FapUnits& units, const FapMapping& mapping) {
    const auto all_rows = mapping_rows(mapping);
    Trajectory out;
    out.fps = stream.fps;
    out.frames.reserve(stream.frames.size());
    // One least-squares solve per distinct mask (usually one per file; Xface
    // writes a mask of the non-zero FAPs per frame).
    struct Solver {
        std::vector<std::size_t> rows_present;
        Eigen::MatrixXd pinv;
        std::array<bool, param_count> undetermined{};
    };
    std::map<std::string, Solver> solvers;
    std::array<std::size_t, param_count> undetermined_frames{};
    for (const FapFrame& frame : stream.frames) {
        std::string key;
        std::vector<std::size_t> present;
        for (std::size_t r = 0; r < all_rows.size(); ++r) {
            const bool has = frame.mask[all_rows[r].fap - 1];
            key += has ? '1' : '0';
            if (has) present.push_back(r);
        }
        auto it = solvers.find(key);
        if (it == solvers.end()) {
            std::vector<FapRow> rows;
            for (std::size_t r : present) rows.push_back(all_rows[r]);
            Eigen::MatrixXd pinv = rows.empty() ? Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(param_count), 0)
                                                : pseudo_inverse(fapu_matrix(rows, units));
            Solver solver{present, std::move(pinv), {}};
            for (const auto& info : params()) {
                bool used = false;
                for (const auto& r : rows) used = used || r.mm_per_unit[index(info.param)] != 0.0;
                solver.undetermined[index(info.param)] = !used;
            }
            it = solvers.emplace(key, std::move(solver)).first;
        }
        const auto& [rows_present, pinv, undetermined] = it->second;
        for (std::size_t p = 0; p < param_count; ++p) undetermined_frames[p] += undetermined[p];
        Eigen::VectorXd b(static_cast<Eigen::Index>(rows_present.size()));
        for (std::size_t q = 0; q < rows_present.size(); ++q)
            b(static_cast<Eigen::Index>(q)) = frame.values[all_rows[rows_present[q]].fap - 1];
        Frame f{};
        if (!rows_present.empty()) {
            const Eigen::VectorXd x = pinv * b;
            for (std::size_t p = 0; p < param_count; ++p) f[p] = x(static_cast<Eigen::Index>(p));
        }
        out.frames.push_back(f);
    }
    // One warning per stream: the parameters no FAP present drives, in how many frames.
    std::vector<std::string> undetermined;
    for (const auto& info : params()) {
        const std::size_t n = undetermined_frames[index(info.param)];
        if (n == stream.frames.size()) undetermined.emplace_back(info.name);
        else if (n > 0) undetermined.push_back(fmt::format("{} (in {} of {} frames)", info.name, n, stream.frames.size()));
    }
    if (!undetermined.empty())
        log_warning("FAP stream \"{}\": no FAP present drives {}; left at neutral", stream.name,
                    fmt::join(undetermined, ", "));
    return out;
}

Frame fap_quantisation_bound(const FapUnits& units, const FapMapping& mapping) {
    const Eigen::MatrixXd pinv = pseudo_inverse(fapu_matrix(mapping_rows(mapping), units));
    Frame out{};
    for (std::size_t p = 0; p < param_count; ++p)
        out[p] = 0.5 * pinv.row(static_cast<Eigen::Index>(p)).cwiseAbs().sum();
    return out;
}

Trajectory decode_fap_file(const std::filesystem::path& path, const FapDecodeSettings& settings) {
    const FapStream stream = read_fap(path);
    const std::string file = path.string();
    const auto unmapped = unmapped_fap_groups(stream);
    if (!unmapped.empty())
        log_warning("{}: FAPs present but not mapped to the 10 articulatory parameters, so not shown: {}", file,
                    fmt::join(unmapped, "; "));
    Trajectory trajectory = fap_to_trajectory(stream, settings.units, settings.mapping);
    const RangeReport range = check_ranges(trajectory, settings.clamp);
    for (const auto& info : params()) {
        const std::size_t p = index(info.param);
        if (range.frames_outside[p] == 0) continue;
        log_warning("{}: {} outside its range [{}, {}] in {} of {} frames (furthest {:.3f} at frame {}, {:.3f} s){}",
                    file, info.name, info.min, info.max, range.frames_outside[p], trajectory.size(), range.worst[p],
                    range.worst_frame[p], trajectory.time_s(range.worst_frame[p]),
                    settings.clamp ? "; clamped to the range" : "; --clamp limits it to the range");
    }
    return trajectory;
}

void write_fap(const std::filesystem::path& path, const FapStream& stream, FapTarget target) {
    const bool greta = target == FapTarget::Greta;
    if (greta && std::abs(stream.fps - 25.0) > 1e-9)
        throw InputError(path.string(), 0, 0, "fps",
                         fmt::format("Greta plays every FAP file at 25 fps; expected a 25 fps stream, got {} fps",
                                     stream.fps));
    std::string name = stream.name.empty() ? "avsi" : stream.name;
    for (char& ch : name)
        if (std::isspace(static_cast<unsigned char>(ch))) ch = '_';
    // Greta's writer: 69 mask entries (its table's extra slot, 0 here), each
    // followed by a space, as are the values.
    const int entries = greta ? fap_count + 1 : fap_count;
    std::string text = fmt::format("2.1 {} {} {}\n", name, stream.fps, stream.frames.size());
    for (std::size_t k = 0; k < stream.frames.size(); ++k) {
        const FapFrame& f = stream.frames[k];
        AVSI_ASSERT(!f.mask[0] && !f.mask[1]);
        for (int i = 0; i < entries; ++i) {
            text += i < fap_count && f.mask[i] ? '1' : '0';
            text += greta || i + 1 < entries ? ' ' : '\n';
        }
        if (greta) text += '\n';
        text += std::to_string(k);
        for (int i = 0; i < fap_count; ++i)
            if (f.mask[i]) text += fmt::format(" {}", f.values[i]);
        text += greta ? " \n" : "\n";
    }
    write_text_file(path, text);
}

namespace {

// The meaningful lines of a FAP file (not blank, not # comments), each as
// its number and its whitespace-separated tokens.
std::vector<std::pair<int, std::vector<std::string>>> fap_file_lines(const std::string& text) {
    std::vector<std::pair<int, std::vector<std::string>>> lines;
    std::istringstream in(text);
    std::string line;
    int number = 0;
    while (std::getline(in, line)) {
        ++number;
        if (!line.empty() && line.back() == '\r') line.pop_back();
        std::istringstream words(line);
        std::vector<std::string> tokens;
        for (std::string w; words >> w;) tokens.push_back(w);
        if (tokens.empty() || tokens[0][0] == '#') continue;
        lines.emplace_back(number, std::move(tokens));
    }
    return lines;
}

}  // namespace

FapStream read_fap(const std::filesystem::path& path) {
    const std::string text = read_text_file(path);
    const std::string file = path.string();
    const std::vector<std::pair<int, std::vector<std::string>>> lines = fap_file_lines(text);
    if (lines.empty()) throw InputError(path, "empty FAP file: expected a header `2.1 name fps frames`");
    FapStream out;
    const auto& [header_line, header] = lines[0];
    // `2.1 name… fps frames`: the name is every token between the version and the last two.
    if (header.size() < 4 || header[0] != "2.1")
        throw InputError(file, header_line, 1, "header",
                         fmt::format("expected `2.1 name fps frames`, got \"{}\"", fmt::join(header, " ")));
    out.name = fmt::format("{}", fmt::join(header.begin() + 1, header.end() - 2, " "));
    const std::string& fps_text = header[header.size() - 2];
    const std::string& frames_text = header.back();
    const auto fps = parse_double(fps_text);
    if (!fps || !(*fps > 0.0) || !(*fps <= 1000.0))
        throw InputError(file, header_line, 0, "fps", fmt::format("expected a frame rate in (0, 1000], got \"{}\"", fps_text));
    out.fps = *fps;
    const auto declared = parse_int(frames_text);
    if (!declared || *declared < 0)
        throw InputError(file, header_line, 0, "frames",
                         fmt::format("expected a non-negative integer, got \"{}\"", frames_text));
    if (static_cast<std::size_t>(*declared) > (lines.size() - 1) / 2)
        throw InputError(file, lines.back().first, 0, "frames",
                         fmt::format("header declares {} frames, the file has lines for at most {}", *declared,
                                     (lines.size() - 1) / 2));
    std::size_t li = 1;
    long long first_number = 0;
    std::size_t extra_set_frames = 0;  // frames with a set mask entry after the 68th
    int extra_first_line = 0;
    std::size_t widest_mask = fap_count;
    for (long long k = 0; k < *declared; ++k) {
        const auto& [mask_line, mask_tokens] = lines[li];
        if (mask_tokens.size() < static_cast<std::size_t>(fap_count))
            throw InputError(file, mask_line, 0, fmt::format("frame {} mask", k),
                             fmt::format("expected {} mask entries (0/1; Greta writes 69), got {}", fap_count,
                                         mask_tokens.size()));
        widest_mask = std::max(widest_mask, mask_tokens.size());
        FapFrame frame;
        std::size_t low_level = 0;       // set FAPs 3…68: one value each
        std::size_t extra_set = 0;       // set entries after the 68th: one value each (Greta)
        bool viseme = false, expression = false;
        for (std::size_t i = 0; i < mask_tokens.size(); ++i) {
            const std::string& m = mask_tokens[i];
            if (m != "0" && m != "1")
                throw InputError(file, mask_line, 0, fmt::format("frame {} mask entry {}", k, i + 1),
                                 fmt::format("expected 0 or 1, got \"{}\"", m));
            if (m == "0") continue;
            if (i >= static_cast<std::size_t>(fap_count)) {
                ++extra_set;
                continue;
            }
            frame.mask[i] = true;
            out.present_in_file[i] = true;
            if (i == 0) viseme = true;
            else if (i == 1) expression = true;
            else ++low_level;
        }
        if (extra_set > 0 && extra_set_frames++ == 0) extra_first_line = mask_line;
        const auto& [value_line, values] = lines[li + 1];
        const auto number = parse_int(values[0]);
        if (!number)
            throw InputError(file, value_line, 0, fmt::format("frame {} number", k),
                             fmt::format("expected an integer frame number, got \"{}\"", values[0]));
        if (k == 0) first_number = *number;
        if (*number != first_number + k)
            throw InputError(file, value_line, 0, fmt::format("frame {} number", k),
                             fmt::format("expected frame number {}, got {}", first_number + k, *number));
        // A set viseme/expression takes 4/6 values (the specification, Xface) or 1 (Greta).
        const std::size_t got = values.size() - 1;
        const std::size_t spec = low_level + extra_set + (viseme ? 4 : 0) + (expression ? 6 : 0);
        const std::size_t one_each = low_level + extra_set + (viseme ? 1 : 0) + (expression ? 1 : 0);
        if (got != spec && got != one_each)
            throw InputError(file, value_line, 0, fmt::format("frame {} values", k),
                             spec == one_each
                                 ? fmt::format("expected {} values for the {} entries set in the mask, got {}", spec,
                                               low_level + extra_set, got)
                                 : fmt::format("expected {} values for the entries set in the mask (viseme 4, "
                                               "expression 6 values) or {} (one each, as Greta writes), got {}",
                                               spec, one_each, got));
        const std::size_t viseme_width = got == spec ? 4 : 1, expression_width = got == spec ? 6 : 1;
        std::size_t v = 1;
        for (int i = 0; i < fap_count; ++i) {
            if (!frame.mask[i]) continue;
            const std::size_t width = i == 0 ? viseme_width : i == 1 ? expression_width : 1;
            for (std::size_t w = 0; w < width; ++w, ++v) {
                const auto x = parse_double(values[v]);
                if (!x || !std::isfinite(*x))
                    throw InputError(file, value_line, 0, fmt::format("frame {} FAP {}", k, i + 1),
                                     fmt::format("expected a number, got \"{}\"", values[v]));
                // 10⁵ FAPU is ~100 times a face's key distances (1024 FAPU each).
                require_in_range(*x, -1e5, 1e5, at(file, value_line, 0, fmt::format("frame {} FAP {}", k, i + 1)),
                                 "a FAP value in FAPU");
                if (width == 1 && i > 1) frame.values[i] = *x;
            }
        }
        for (; v < values.size(); ++v)  // the values of set entries after the 68th
            if (!parse_double(values[v]))
                throw InputError(file, value_line, 0, fmt::format("frame {} values", k),
                                 fmt::format("expected a number, got \"{}\"", values[v]));
        frame.mask[0] = frame.mask[1] = false;  // viseme/expression values dropped
        out.frames.push_back(frame);
        li += 2;
    }
    if (li < lines.size())
        throw InputError(file, lines[li].first, 0, "frames",
                         fmt::format("header declares {} frames, but more lines follow", *declared));
    if (extra_set_frames > 0)
        log_warning("{}:{}: mask entries after the 68th are not MPEG-4 FAPs; {} frame{} set one (the mask has {} "
                    "entries): their values are dropped",
                    file, extra_first_line, extra_set_frames, extra_set_frames == 1 ? "" : "s", widest_mask);
    return out;
}

}  // namespace avsi::synth
