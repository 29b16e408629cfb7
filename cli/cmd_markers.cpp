// `avsi markers FILE --out markers.csv`: an optical motion-capture file (C3D,
// Qualisys TSV, Motive CSV) written as read — one row per frame, time and
// x y z per marker in mm, a dropout as empty cells — for inspection and for
// checking the reader against other tools (learn/markers.h).
#include <memory>
#include <string>

#include "avsi/core/log.h"
#include "avsi/learn/markers.h"
#include "command.h"

namespace avsi::cli {
namespace {

struct MarkersOptions {
    std::string in;
    std::string out;
};

int run_markers(const MarkersOptions& o) {
    const learn::MarkerRecording rec = learn::read_marker_file(o.in);
    learn::write_markers_csv(o.out, rec);
    std::size_t dropouts = 0;
    for (std::size_t f = 0; f < rec.frames; ++f)
        for (std::size_t m = 0; m < rec.marker_count(); ++m) dropouts += rec.seen(f, m) ? 0 : 1;
    log_info("{}: {} markers, {} frames at {} Hz, {} dropouts (marker-frames); wrote {}", o.in, rec.marker_count(),
             rec.frames, rec.rate_hz, dropouts, o.out);
    return 0;
}

const bool registered_markers = register_command({
    "markers",
    "Optical motion capture (.c3d, Qualisys .tsv, Motive .csv) to a markers CSV in mm",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<MarkersOptions>();
        sub.add_option("input", o->in, "Marker file: .c3d (Intel, DEC or MIPS; int or float), .tsv (Qualisys), "
                                       ".csv (OptiTrack Motive)")->required();
        sub.add_option("--out", o->out, "CSV to write: time_s, then <marker>_x/_y/_z in mm; a dropout is empty")
            ->required();
        return [o] { return run_markers(*o); };
    }});

}  // namespace
}  // namespace avsi::cli
