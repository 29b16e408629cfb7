// `avsi stream`: low-latency streaming synthesis with an ANN model (Beskow
// §4.5, synth/ann.h): reads timed phones from stdin as they arrive, one per
// line "start_s end_s phone" (e.g. "0.120 0.185 AA1"; a recogniser may send a
// phone in pieces; a first line "start_s end_s phone", the header of the TSV
// that `avsi phones` writes, is skipped, so `avsi phones … --out - | avsi
// stream` works), and writes each frame as CSV "time_s,<10 parameters>" to
// stdout as soon as its look-ahead is known, flushing every line. At end of
// input the remaining frames follow. With --latency-log, each frame's
// emission is timed: latency_s = emission wall time − (origin + time_s), the
// origin being the wall time of the first line minus that line's end time —
// so for a feeder that sends each piece at its end time, latency_s is how
// long after real time the frame came out.
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>
#include <string>

#include <fmt/format.h>

#include "avsi/core/error.h"
#include "avsi/synth/ann.h"
#include "command.h"

namespace avsi::cli {
namespace {

struct StreamOptions {
    std::filesystem::path model;
    std::filesystem::path latency_log;
};

int run_stream(const StreamOptions& o) {
    const auto loaded = synth::load_model(o.model);
    const auto* model = dynamic_cast<const synth::AnnModel*>(loaded.get());
    if (!model)
        throw InputError(Diagnostic{o.model.string(), 0, 0, "/kind",
                                    fmt::format("expected an \"ann\" model for streaming, got \"{}\"", loaded->kind())});
    synth::AnnStreamer streamer(*model);
    using Clock = std::chrono::steady_clock;
    std::ofstream latency;
    if (!o.latency_log.empty()) {
        latency.open(o.latency_log);
        if (!latency) throw InputError(Diagnostic{o.latency_log.string(), 0, 0, "", "cannot open for writing"});
        latency << "frame,time_s,latency_s\n";
    }
    bool have_origin = false;
    Clock::time_point origin;
    std::string header = "time_s";
    for (const auto& info : synth::params()) header += "," + std::string(info.name);
    std::fputs((header + "\n").c_str(), stdout);
    std::fflush(stdout);
    auto emit = [&](const std::vector<synth::StreamFrame>& frames) {
        for (const auto& f : frames) {
            std::string row = fmt::format("{:.6f}", f.time_s);
            for (double v : f.values) row += fmt::format(",{:.6f}", v);
            row += "\n";
            std::fputs(row.c_str(), stdout);
            std::fflush(stdout);
            if (latency.is_open() && have_origin) {
                const double now = std::chrono::duration<double>(Clock::now() - origin).count();
                latency << fmt::format("{},{:.6f},{:.6f}\n", f.index, f.time_s, now - f.time_s);
            }
        }
    };
    const auto& inventory = PhoneInventory::builtin();
    std::string line;
    int line_no = 0;
    bool first = true;
    while (std::getline(std::cin, line)) {
        ++line_no;
        if (line.find_first_not_of(" \t\r") == std::string::npos || line[line.find_first_not_of(" \t")] == '#')
            continue;
        if (first) {
            first = false;
            std::istringstream words(line);
            std::string a, b, c, d;
            if ((words >> a >> b >> c) && !(words >> d) && a == "start_s" && b == "end_s" && c == "phone")
                continue;  // the header of `avsi phones` TSV
        }
        std::istringstream in(line);
        double start = 0, end = 0;
        std::string label, extra;
        if (!(in >> start >> end >> label) || (in >> extra))
            throw InputError("<stdin>", line_no, 1, "phone line",
                             fmt::format("expected \"start_s end_s phone\", got \"{}\"", line));
        Phone phone = inventory.parse_label(label, fmt::format("<stdin>:{}", line_no));
        phone.start_s = start;
        phone.end_s = end;
        if (!have_origin) {
            origin = Clock::now() - std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(end));
            have_origin = true;
        }
        try {
            streamer.push(phone);
        } catch (const InputError& e) {
            throw InputError("<stdin>", line_no, 1, e.first().field, e.first().message);
        }
        emit(streamer.take_ready());
    }
    streamer.finish();
    emit(streamer.take_ready());
    return 0;
}

const bool registered_stream = register_command({
    "stream",
    "Stream timed phones from stdin through an ANN model (e.g. ANN 2) to frames on stdout, low latency",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<StreamOptions>();
        o->model = std::filesystem::path(AVSI_PROTOCOLS_DIR) / "models" / "ann2.json";
        sub.add_option("--model", o->model, "ANN model file (JSON, kind \"ann\")")->capture_default_str();
        sub.add_option("--latency-log", o->latency_log,
                       "Write per-frame emission latency (CSV frame,time_s,latency_s) here")
            ->capture_default_str();
        return [o] { return run_stream(*o); };
    },
});

}  // namespace
}  // namespace avsi::cli
