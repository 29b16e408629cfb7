// `avsi export`: a session database to tidy CSV (responses, timing, frames,
// sessions, events).
#include <filesystem>
#include <memory>
#include <string>

#include "avsi/core/error.h"
#include "avsi/core/log.h"
#include "avsi/experiment/store.h"
#include "command.h"

namespace avsi::cli {
namespace {

struct ExportOptions {
    std::string database;
    std::string out = "export";
};

int run_export(const ExportOptions& o) {
    if (!std::filesystem::exists(o.database)) throw InputError(std::filesystem::path(o.database), "no such database");
    const experiment::Store store(o.database);
    const auto files = experiment::export_store(store, o.out);
    for (const auto& f : files) log_info("wrote {}", f.string());
    return 0;
}

const bool registered_export = register_command({
    "export",
    "Export a session database to tidy CSV (responses, timing per trial and per session, frames, sessions, events)",
    [](CLI::App& sub) -> std::function<int()> {
        auto o = std::make_shared<ExportOptions>();
        sub.add_option("database", o->database, "Session database (SQLite) written by `avsi run`")->required();
        sub.add_option("--out", o->out, "Output folder")->capture_default_str();
        return [o] { return run_export(*o); };
    }});

}  // namespace
}  // namespace avsi::cli
