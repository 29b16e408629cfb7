// Optical recordings → a parameter-track corpus with a fit report
// (marker_corpus.h).
#include "avsi/learn/marker_corpus.h"

#include <cmath>
#include <set>

#include <fmt/format.h>

#include "avsi/core/csv.h"
#include "avsi/core/error.h"
#include "avsi/core/files.h"
#include "avsi/core/log.h"

namespace avsi::learn {
namespace fs = std::filesystem;

namespace {

struct Recording {
    std::string id;
    fs::path markers, labels, audio;
    std::optional<SplitPart> split;
};

std::string cell(const CsvTable& t, const CsvRow& row, const char* column) {
    const auto c = t.column(column);
    return c && *c < row.fields.size() ? std::string(row.fields[*c]) : std::string();
}

// The recording list, every bad row reported at once.
std::vector<Recording> read_recording_list(const fs::path& path) {
    const CsvTable t = read_csv(path);
    t.require_column("id");
    t.require_column("markers");
    t.require_column("labels");
    const fs::path dir = path.parent_path();
    DiagnosticList problems;
    std::vector<Recording> out;
    std::set<std::string> ids;
    for (const auto& row : t.rows) {
        Recording r;
        r.id = cell(t, row, "id");
        if (r.id.empty() || r.id.find_first_of("/\\ ") != std::string::npos)
            problems.add(path.string(), row.line, 0, "id", fmt::format("expected a name without / or spaces, got \"{}\"", r.id));
        else if (!ids.insert(r.id).second)
            problems.add(path.string(), row.line, 0, "id", fmt::format("\"{}\" appears twice", r.id));
        for (auto [column, target] : {std::pair{"markers", &r.markers}, {"labels", &r.labels}, {"audio", &r.audio}}) {
            const std::string v = cell(t, row, column);
            if (v.empty()) continue;
            *target = dir / v;
            if (!fs::exists(*target)) problems.add(path.string(), row.line, 0, column, fmt::format("no file {}", target->string()));
        }
        if (r.markers.empty() || r.labels.empty())
            problems.add(path.string(), row.line, 0, r.markers.empty() ? "markers" : "labels", "expected a file");
        const std::string split = cell(t, row, "split");
        if (split == "train") r.split = SplitPart::Train;
        else if (split == "test") r.split = SplitPart::Test;
        else if (!split.empty())
            problems.add(path.string(), row.line, 0, "split", fmt::format("expected \"train\" or \"test\", got \"{}\"", split));
        out.push_back(r);
    }
    if (out.empty()) problems.add(path.string(), 1, 0, "", "no recordings listed");
    problems.throw_if_any();
    return out;
}

std::string fmt_mm(double v) { return std::isfinite(v) ? fmt::format("{:.2f}", v) : std::string("–"); }

// The report's section of one recording.
std::string report_section(const Recording& r, const MarkerFitResult& fit) {
    std::size_t fitted = 0;
    for (const auto& f : fit.track.frames) fitted += std::isfinite(f[0]) ? 1 : 0;
    std::string s = fmt::format("## {}\n\n`{}`: {} frames at {} Hz, {} fitted; reference frame {}; orientation fit "
                                "scale {:.4f}, RMS {:.2f} mm over the strategic markers; {} frames without three "
                                "reference markers, {} with too few face markers.\n\n",
                                r.id, r.markers.filename().string(), fit.track.size(), fit.track.fps, fitted,
                                fit.reference_frame, fit.orientation.scale, fit.orientation_rms_mm,
                                fit.frames_unplaced, fit.frames_too_few_markers);
    for (const auto& n : fit.notes) s += "- " + n + "\n";
    s += fmt::format("\n![residual]({}.residual.svg)\n\n| marker | dropouts (frames) | RMS (mm) | largest (mm) |\n"
                     "| --- | --- | --- | --- |\n", r.id);
    for (std::size_t m = 0; m < fit.markers.size(); ++m) {
        double sq = 0, mx = 0;
        std::size_t n = 0;
        for (std::size_t f = 0; f < fit.track.size(); ++f) {
            const double v = fit.residual(f, m);
            if (!std::isfinite(v)) continue;
            sq += v * v, mx = std::max(mx, v), ++n;
        }
        s += fmt::format("| {} | {} | {} | {} |\n", fit.markers[m], fit.dropouts[m],
                         fmt_mm(n ? std::sqrt(sq / double(n)) : NAN), fmt_mm(n ? mx : NAN));
    }
    return s + "\n";
}

}  // namespace

MarkerCorpusSummary fit_marker_corpus(const MarkerCorpusSettings& settings, const synth::MarkerModel& model) {
    const std::vector<Recording> list = read_recording_list(settings.list_path);
    const fs::path out = settings.out_dir;
    for (const char* sub : {"tracks", "labels", "fit"}) fs::create_directories(out / sub);
    MarkerCorpusSummary summary;
    std::vector<CorpusEntry> entries;
    std::string report = fmt::format("# Marker fit: {}\n\nHead: {}; layout: `{}`. The residual is the distance from "
                                     "each marker to its virtual marker on the fitted head (Beskow 2004 §3.5).\n\n",
                                     settings.name, settings.head_name, model.source);
    double sq = 0;
    std::size_t n = 0;
    for (const Recording& r : list) {
        const MarkerRecording rec = read_marker_file(r.markers);
        const MarkerFitResult fit = fit_markers(rec, model, settings.fit, r.markers.string());
        CorpusEntry e;
        e.id = r.id;
        e.kind = TrackKind::Parameters;
        e.track = out / "tracks" / (r.id + ".csv");
        e.labels = out / "labels" / (r.id + r.labels.extension().string());
        e.fixed_split = r.split;
        write_param_track_csv(e.track, fit.track);
        fs::copy_file(r.labels, e.labels, fs::copy_options::overwrite_existing);
        if (!r.audio.empty()) {
            fs::create_directories(out / "audio");
            e.audio = out / "audio" / (r.id + r.audio.extension().string());
            fs::copy_file(r.audio, e.audio, fs::copy_options::overwrite_existing);
        }
        write_fit_residuals_csv(out / "fit" / (r.id + ".residual.csv"), fit);
        write_fit_residual_plot(out / "fit" / (r.id + ".residual.svg"), fit, r.id);
        report += report_section(r, fit);
        for (double v : fit.residual_mm)
            if (std::isfinite(v)) sq += v * v, ++n;
        summary.frames += fit.track.size();
        for (const auto& f : fit.track.frames) summary.frames_fitted += std::isfinite(f[0]) ? 1 : 0;
        entries.push_back(e);
        log_info("{}: {} frames fitted of {}", r.id, summary.frames_fitted, summary.frames);
    }
    summary.recordings = list.size();
    summary.residual_rms_mm = n ? std::sqrt(sq / double(n)) : NAN;
    write_text_file(out / "fit" / "report.md", report);
    write_corpus_manifest(out, settings.name, entries, settings.split_seed, settings.test_fraction);
    return summary;
}

}  // namespace avsi::learn
